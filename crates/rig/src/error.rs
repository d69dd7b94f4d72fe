//! Rig errors with a `kind()`, in the spirit of embedded-hal's `Error::kind()`.

use std::fmt;

/// What went wrong on the rig, independent of which layer noticed it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorKind {
    /// No fresh sample within the watchdog timeout (missing data, stalled board).
    Timeout,
    /// A sensor value stopped changing for longer than allowed (stuck sensor, frozen ADC).
    Stale,
    /// Frames failed their CRC more often than the threshold allows.
    Crc,
    /// The serial link went away (port closed, device unplugged, emulator gone).
    LinkLost,
    /// A position, force or pressure limit was crossed.
    Limit,
    /// A sensor value or a controller output was NaN or infinite.
    NotANumber,
    /// The I/O board reported a fault of its own.
    BoardFault,
    /// The operator stopped the run (Ctrl-C).
    Interrupted,
    /// The controller panicked.
    Panic,
    /// Any other I/O failure.
    Io,
}

impl ErrorKind {
    /// A short stable name, used in the trace's `fault` column.
    pub fn name(self) -> &'static str {
        match self {
            ErrorKind::Timeout => "timeout",
            ErrorKind::Stale => "stale",
            ErrorKind::Crc => "crc",
            ErrorKind::LinkLost => "link_lost",
            ErrorKind::Limit => "limit",
            ErrorKind::NotANumber => "nan",
            ErrorKind::BoardFault => "board_fault",
            ErrorKind::Interrupted => "interrupted",
            ErrorKind::Panic => "panic",
            ErrorKind::Io => "io",
        }
    }
}

impl fmt::Display for ErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A rig failure: its kind and a message that says what was seen.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{kind}: {message}")]
pub struct RigError {
    kind: ErrorKind,
    message: String,
}

impl RigError {
    /// A new error of `kind` with a human-readable message.
    pub fn new(kind: ErrorKind, message: impl Into<String>) -> Self {
        Self {
            kind,
            message: message.into(),
        }
    }

    /// The error's kind, what the supervisor acts on.
    pub fn kind(&self) -> ErrorKind {
        self.kind
    }

    /// The message without the kind prefix.
    pub fn message(&self) -> &str {
        &self.message
    }
}

impl From<std::io::Error> for RigError {
    fn from(e: std::io::Error) -> Self {
        use std::io::ErrorKind as K;
        let kind = match e.kind() {
            K::BrokenPipe | K::NotConnected | K::ConnectionReset | K::UnexpectedEof => {
                ErrorKind::LinkLost
            }
            K::TimedOut | K::WouldBlock => ErrorKind::Timeout,
            _ => ErrorKind::Io,
        };
        RigError::new(kind, e.to_string())
    }
}
