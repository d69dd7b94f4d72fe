//! The host driver: a [`Rig`] of raw samples over a serial port speaking docs/protocol.md.

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::time::Duration;

use pneuflex_control::ValveCommand;

use crate::clock::{Clock, WallClock};
use crate::error::{ErrorKind, RigError};
use crate::protocol::{
    ConfigPayload, DecodeEvent, Decoder, MAX_FRAME, Message, RESET_MAGIC, ValveMode, ValvePayload,
    encode, fault_code, from_q15, status, to_q15,
};
use crate::rig::{Applied, BoardSample, LinkStats, RawSample, Rig};
use crate::rigfile::{RigFile, SafeState};

/// A byte link to the board: non-blocking reads, whole-frame writes.
pub trait Link: Send {
    /// Reads what is available now (0 if nothing); a closed link is `ErrorKind::LinkLost`.
    fn read_now(&mut self, buf: &mut [u8]) -> Result<usize, RigError>;
    /// Writes all bytes.
    fn write_all_bytes(&mut self, bytes: &[u8]) -> Result<(), RigError>;
}

impl Link for Box<dyn serialport::SerialPort> {
    fn read_now(&mut self, buf: &mut [u8]) -> Result<usize, RigError> {
        use std::io::ErrorKind as K;
        match self.read(buf) {
            Ok(0) => Err(RigError::new(
                ErrorKind::LinkLost,
                "serial port closed (end of file)",
            )),
            Ok(n) => Ok(n),
            Err(e) if e.kind() == K::TimedOut || e.kind() == K::WouldBlock => Ok(0),
            Err(e) if e.kind() == K::Interrupted => Ok(0),
            Err(e) => Err(RigError::new(
                ErrorKind::LinkLost,
                format!("serial read: {e}"),
            )),
        }
    }

    fn write_all_bytes(&mut self, bytes: &[u8]) -> Result<(), RigError> {
        use std::io::ErrorKind as K;
        self.write_all(bytes).map_err(|e| match e.kind() {
            K::TimedOut | K::WouldBlock => RigError::new(
                ErrorKind::Timeout,
                "serial write would block: the board is not reading",
            ),
            _ => RigError::new(ErrorKind::LinkLost, format!("serial write: {e}")),
        })
    }
}

/// Connecting to a rig failed.
#[derive(Debug, thiserror::Error)]
pub enum ConnectError {
    /// The port named in the rig file (or on the command line) cannot be opened.
    #[error("{file}: field `{field}`: cannot open serial port `{port}` at {baud} baud: {message}")]
    Port {
        /// Rig file.
        file: PathBuf,
        /// `link.port`, or `--port` when given on the command line.
        field: String,
        /// The port.
        port: String,
        /// Baud rate.
        baud: u32,
        /// The OS's reason.
        message: String,
    },
    /// The port opened but no board answered the heartbeat.
    #[error("{file}: port `{port}` opened but no board answered within {timeout_ms} ms: {message}")]
    Handshake {
        /// Rig file.
        file: PathBuf,
        /// The port.
        port: String,
        /// `link.handshake_timeout_ms`.
        timeout_ms: u64,
        /// What happened.
        message: String,
    },
}

/// The link quality a rig run shows its observers beside the loop's signals (a live Rerun view; not in
/// trace.csv), declared once: counters since the run's start, and the tick's period error.
pub const LINK_SIGNALS: [pneuflex_control::Signal; 4] = [
    pneuflex_control::Signal {
        name: "frames",
        unit: "1",
        group: "link",
        description: "valid frames received since the start",
    },
    pneuflex_control::Signal {
        name: "crc_errors",
        unit: "1",
        group: "link",
        description: "frames dropped for a bad CRC since the start",
    },
    pneuflex_control::Signal {
        name: "seq_gaps",
        unit: "1",
        group: "link",
        description: "samples missing by their sequence numbers since the start",
    },
    pneuflex_control::Signal {
        name: "period_error",
        unit: "s",
        group: "timing",
        description: "|this tick's start - the last tick's start - dt|",
    },
];

/// Samples and applied echoes a [`SerialRig`] keeps each for the record (a loop that takes one of each a
/// tick keeps up: the board sends one sample a period and one echo per command).
pub const RECORD_CAP: usize = 4096;

/// The serial host driver: decodes samples, sends valve commands, counts CRC errors against a threshold.
pub struct SerialRig<L: Link> {
    link: L,
    decoder: Decoder,
    tx_seq: u8,
    rx_seq: Option<u8>,
    latest: Option<RawSample>,
    /// Applied echoes not taken yet (at most [`RECORD_CAP`]: the oldest go first).
    applied: VecDeque<Applied>,
    /// Samples not taken for the record yet (at most [`RECORD_CAP`]).
    sampled: VecDeque<BoardSample>,
    /// Whether the loop has read: the record starts with the sample of its first read.
    record_started: bool,
    board_last_us: Option<u32>,
    board_time_s: f64,
    crc_times: VecDeque<f64>,
    crc_max: u32,
    crc_window_s: f64,
    board_fault: Option<(u8, u16)>,
    heartbeat_echo: Option<u32>,
    stats: LinkStats,
}

impl<L: Link> SerialRig<L> {
    /// A driver over an open link with a CRC-error threshold (`crc_max` errors within `crc_window_s`).
    pub fn new(link: L, crc_max: u32, crc_window_s: f64) -> Self {
        Self {
            link,
            decoder: Decoder::new(),
            tx_seq: 0,
            rx_seq: None,
            latest: None,
            // Room for the whole record up front: the real-time loop then never allocates for it.
            applied: VecDeque::with_capacity(RECORD_CAP),
            sampled: VecDeque::with_capacity(RECORD_CAP),
            record_started: false,
            board_last_us: None,
            board_time_s: 0.0,
            crc_times: VecDeque::with_capacity(crc_max as usize + 2),
            crc_max,
            crc_window_s,
            board_fault: None,
            heartbeat_echo: None,
            stats: LinkStats::default(),
        }
    }

    /// Link counters.
    pub fn stats(&self) -> LinkStats {
        LinkStats {
            decoder: self.decoder.stats(),
            ..self.stats
        }
    }

    /// Sends one message.
    pub fn send(&mut self, msg: &Message) -> Result<(), RigError> {
        let mut buf = [0u8; MAX_FRAME];
        let n = encode(self.tx_seq, msg, &mut buf);
        self.tx_seq = self.tx_seq.wrapping_add(1);
        self.stats.sent += 1;
        self.link.write_all_bytes(&buf[..n])
    }

    /// Reads and decodes everything available; returns the first error seen.
    fn pump(&mut self, now_s: f64) -> Result<(), RigError> {
        let mut buf = [0u8; 512];
        let mut first_err: Option<RigError> = None;
        loop {
            let n = self.link.read_now(&mut buf)?;
            if n == 0 {
                break;
            }
            let Self {
                decoder,
                latest,
                applied,
                sampled,
                board_last_us,
                board_time_s,
                crc_times,
                crc_max,
                crc_window_s,
                board_fault,
                heartbeat_echo,
                stats,
                rx_seq,
                ..
            } = self;
            decoder.feed(&buf[..n], |ev| match ev {
                DecodeEvent::Frame(f) => {
                    if let Some(prev) = *rx_seq {
                        stats.seq_gaps += u64::from(f.seq.wrapping_sub(prev).wrapping_sub(1));
                    }
                    *rx_seq = Some(f.seq);
                    match f.msg {
                        Message::Sample(s) => {
                            if let Some(last) = *board_last_us {
                                *board_time_s +=
                                    f64::from(s.board_time_us.wrapping_sub(last)) * 1e-6;
                            }
                            *board_last_us = Some(s.board_time_us);
                            stats.samples += 1;
                            if latest.is_some() {
                                stats.superseded += 1;
                            }
                            *latest = Some(RawSample {
                                host_time_s: now_s,
                                board_time_s: *board_time_s,
                                raw: s,
                            });
                            if sampled.len() == RECORD_CAP {
                                sampled.pop_front();
                                stats.record_dropped += 1;
                            }
                            sampled.push_back(BoardSample {
                                board_time_s: *board_time_s,
                                raw: s,
                                si: None,
                            });
                            if s.status & status::BOARD_FAULT != 0 && board_fault.is_none() {
                                *board_fault = Some((0, 0));
                            }
                        }
                        Message::Applied(a) => {
                            // On the samples' unwrapped clock: the echo's offset from the last
                            // sample's stamp, either side of it (a wrap of the µs counter included).
                            let last = *board_last_us.get_or_insert(a.board_time_us);
                            let offset = a.board_time_us.wrapping_sub(last) as i32;
                            if applied.len() == RECORD_CAP {
                                applied.pop_front();
                                stats.record_dropped += 1;
                            }
                            applied.push_back(Applied {
                                board_time_s: *board_time_s + f64::from(offset) * 1e-6,
                                tick: a.tick,
                                u: from_q15(a.duty_q15),
                                mode: a.mode,
                            });
                        }
                        Message::Heartbeat(c) => {
                            // Only the handshake sends one: what came before its echo predates the
                            // board's Config, i.e. the run (an emulator's last run, a board's idle stream).
                            *latest = None;
                            sampled.clear();
                            applied.clear();
                            *heartbeat_echo = Some(c);
                        }
                        Message::Fault { code, detail } => *board_fault = Some((code, detail)),
                        // An I/O board never sends host-to-board or embedded-controller messages; ignore
                        // rather than fail.
                        _ => {}
                    }
                }
                DecodeEvent::CrcError | DecodeEvent::Malformed { .. } => {
                    crc_times.push_back(now_s);
                    while crc_times
                        .front()
                        .is_some_and(|&t| now_s - t > *crc_window_s)
                        || crc_times.len() > *crc_max as usize + 1
                    {
                        crc_times.pop_front();
                    }
                    if crc_times.len() > *crc_max as usize && first_err.is_none() {
                        first_err = Some(RigError::new(
                            ErrorKind::Crc,
                            format!(
                                "{} bad frames within {:.0} ms (threshold {})",
                                crc_times.len(),
                                *crc_window_s * 1e3,
                                crc_max
                            ),
                        ));
                    }
                }
            });
        }
        if let Some(e) = first_err {
            return Err(e);
        }
        if let Some((code, detail)) = self.board_fault {
            let what = match code {
                fault_code::HOST_SILENT => "host silent past the board watchdog",
                fault_code::ADC => "ADC failure",
                fault_code::COIL => "coil driver over-current",
                fault_code::CRC => "board saw too many bad frames",
                _ => "board status reports a fault",
            };
            return Err(RigError::new(
                ErrorKind::BoardFault,
                format!("board fault code {code} detail {detail}: {what}"),
            ));
        }
        Ok(())
    }

    /// Sends the board configuration and waits for a heartbeat echo (the board is there and speaks the protocol).
    pub fn handshake(&mut self, cfg: ConfigPayload, timeout: Duration) -> Result<(), RigError> {
        self.handshake_with_clock(cfg, timeout, &mut WallClock::new(Duration::ZERO))
    }

    /// [`Self::handshake`] on a given clock (a simulated one steps a lockstep emulator).
    pub fn handshake_with_clock<K: Clock + ?Sized>(
        &mut self,
        cfg: ConfigPayload,
        timeout: Duration,
        clock: &mut K,
    ) -> Result<(), RigError> {
        self.send(&Message::Config(cfg))?;
        let token = 0xC0DE_0001;
        self.send(&Message::Heartbeat(token))?;
        let start = clock.now();
        let timeout = timeout.as_secs_f64();
        while clock.now() - start < timeout {
            // Board faults from before the handshake do not matter yet: the Reset below clears them.
            match self.pump(0.0) {
                Ok(()) => {}
                Err(e) if e.kind() == ErrorKind::BoardFault => {}
                Err(e) => return Err(e),
            }
            if self.heartbeat_echo == Some(token) {
                self.reset()?;
                return Ok(());
            }
            let t = clock.now() + 500e-6;
            clock.wait_until(t);
        }
        Err(RigError::new(
            ErrorKind::Timeout,
            "no heartbeat echo (wrong port, wrong baud rate, or board not running the protocol)",
        ))
    }
}

impl<L: Link> Rig for SerialRig<L> {
    type Sample = RawSample;

    fn link_stats(&self) -> Option<LinkStats> {
        Some(self.stats())
    }

    fn read(&mut self, now_s: f64) -> Result<Option<RawSample>, RigError> {
        self.pump(now_s)?;
        if !self.record_started {
            // What came during the handshake and the set-up is no part of the run's record: it starts with
            // the sample the loop reads first.
            let first = self.sampled.pop_back();
            self.sampled.clear();
            self.sampled.extend(first);
            self.applied.clear();
            self.record_started = true;
        }
        Ok(self.latest.take())
    }

    fn take_applied(&mut self) -> Option<Applied> {
        self.applied.pop_front()
    }

    fn take_sampled(&mut self) -> Option<BoardSample> {
        self.sampled.pop_front()
    }

    fn write(&mut self, tick: u32, cmd: ValveCommand) -> Result<(), RigError> {
        self.send(&Message::Valve(ValvePayload {
            tick,
            duty_q15: to_q15(cmd.u),
            mode: ValveMode::Run,
        }))
    }

    fn safe(&mut self, tick: u32, state: SafeState) -> Result<(), RigError> {
        self.send(&Message::Valve(ValvePayload {
            tick,
            duty_q15: 0,
            mode: state.mode(),
        }))
    }

    fn reset(&mut self) -> Result<(), RigError> {
        self.crc_times.clear();
        self.board_fault = None;
        self.send(&Message::Reset(RESET_MAGIC))
    }
}

/// Opens the rig's serial port (`port` overrides `link.port`), configures the board and checks it answers.
pub fn connect(
    rig: &RigFile,
    file: &Path,
    port: Option<&str>,
) -> Result<SerialRig<Box<dyn serialport::SerialPort>>, ConnectError> {
    let (p, name) = open(rig, file, port)?;
    connect_link(p, rig, &mut WallClock::new(Duration::ZERO)).map_err(|e| ConnectError::Handshake {
        file: file.to_path_buf(),
        port: name,
        timeout_ms: rig.link.handshake_timeout_ms,
        message: e.to_string(),
    })
}

/// Opens the rig's serial port (`port` overrides `link.port`) at the rig file's baud rate, non-blocking; the
/// port and its name. A board of several channels speaks its own frames over it (`channel_board`).
pub fn open(
    rig: &RigFile,
    file: &Path,
    port: Option<&str>,
) -> Result<(Box<dyn serialport::SerialPort>, String), ConnectError> {
    let (name, field) = match port {
        Some(p) => (p.to_string(), "--port".to_string()),
        None => (rig.link.port.clone(), "link.port".to_string()),
    };
    let p = serialport::new(&name, rig.link.baud)
        .timeout(Duration::ZERO)
        .open()
        .map_err(|e| ConnectError::Port {
            file: file.to_path_buf(),
            field,
            port: name.clone(),
            baud: rig.link.baud,
            message: e.to_string(),
        })?;
    Ok((p, name))
}

/// Configures the board behind an open link (rate, board watchdog, safe state) and checks that it answers.
pub fn connect_link<L: Link, K: Clock + ?Sized>(
    link: L,
    rig: &RigFile,
    clock: &mut K,
) -> Result<SerialRig<L>, RigError> {
    // This driver reads Sample and sends Valve frames: one actuator. A rig file with several channels needs
    // the N-channel frames (docs/protocol.md §6) end to end; refusing here keeps a one-actuator run from
    // driving channel 0 of a several-actuator board with the top-level tables.
    if rig.channels.len() > 1 {
        return Err(RigError::new(
            ErrorKind::Io,
            format!(
                "the rig file has {} channels ([[channel]]); this host driver drives one actuator",
                rig.channels.len()
            ),
        ));
    }
    let mut s = SerialRig::new(
        link,
        rig.watchdog.crc_errors_max,
        rig.watchdog.crc_window_ms * 1e-3,
    );
    let cfg = ConfigPayload {
        sample_period_us: (1e6 / rig.rt.rate_hz).round() as u32,
        watchdog_ms: rig.watchdog.board_watchdog_ms,
        safe_mode: rig.valve.safe_state.mode(),
    };
    s.handshake_with_clock(
        cfg,
        Duration::from_millis(rig.link.handshake_timeout_ms),
        clock,
    )?;
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clock::SimClock;
    use crate::emulator::MemLink;
    use crate::rigfile::tests::{PAPER, rigs_dir};

    #[test]
    fn a_rig_file_with_two_channels_is_refused_before_anything_is_sent() {
        let text =
            format!("{PAPER}\n[[channel]]\nname = \"left\"\n[[channel]]\nname = \"right\"\n");
        let rig = RigFile::parse(&text, &rigs_dir().join("two.toml")).unwrap();
        let (host, mut board) = MemLink::pair();
        let e = connect_link(host, &rig, &mut SimClock::new())
            .err()
            .expect("refused");
        assert!(e.message().contains("2 channels"), "{e}");
        // No Config reached the board: it is not configured for one channel.
        let mut buf = [0u8; 64];
        assert_eq!(board.read_now(&mut buf).unwrap_or(0), 0);
    }
}
