//! The host's end of the serial link to the board: frames out, a reader thread for the bytes in, the shared
//! decoder, and the link's quality (frames, CRC errors, malformed frames, sequence gaps).

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, channel};
use std::time::{Duration, Instant};

use pneuflex_protocol::{DecodeEvent, Decoder, Frame, MAX_FRAME, Message, encode};

use crate::PilError;

/// Counters of one link, both directions.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct LinkStats {
    /// Valid frames received.
    pub frames_in: u64,
    /// Frames sent.
    pub frames_out: u64,
    /// Received frames with a bad CRC.
    pub crc_errors: u64,
    /// Received frames with a good CRC but bad content.
    pub malformed: u64,
    /// Frames the board sent that never arrived, from its sequence numbers.
    pub seq_gaps: u64,
    /// Bytes received.
    pub bytes_in: u64,
}

/// A framed link over a byte stream (QEMU's stdio pipes, a serial port).
pub struct Link {
    tx: Box<dyn Write + Send>,
    rx: Receiver<Vec<u8>>,
    decoder: Decoder,
    pending: VecDeque<Frame>,
    seq_out: u8,
    last_seq_in: Option<u8>,
    stats: LinkStats,
    closed: bool,
    /// How long `recv` waits for a frame (wall clock): a dead or hung emulator is an error, not a hang.
    pub timeout: Duration,
    /// A signal's number once one came: a wait for the board ends at once with [`PilError::Stopped`].
    pub stop: Option<Arc<AtomicUsize>>,
}

impl Link {
    /// A link writing to `tx` and reading `rx` on a thread of its own.
    pub fn new(tx: impl Write + Send + 'static, mut rx: impl Read + Send + 'static) -> Self {
        let (send, recv) = channel();
        std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            loop {
                match rx.read(&mut buf) {
                    Ok(0) | Err(_) => break,
                    Ok(n) => {
                        if send.send(buf[..n].to_vec()).is_err() {
                            break;
                        }
                    }
                }
            }
        });
        Self {
            tx: Box::new(tx),
            rx: recv,
            decoder: Decoder::new(),
            pending: VecDeque::new(),
            seq_out: 0,
            last_seq_in: None,
            stats: LinkStats::default(),
            closed: false,
            timeout: Duration::from_secs(20),
            stop: None,
        }
    }

    /// The counters so far.
    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    /// Sends one message.
    pub fn send(&mut self, m: &Message) -> Result<(), PilError> {
        let mut buf = [0u8; MAX_FRAME];
        let n = encode(self.seq_out, m, &mut buf);
        self.seq_out = self.seq_out.wrapping_add(1);
        self.stats.frames_out += 1;
        self.send_raw(&buf[..n])
    }

    /// Sends bytes as they are (fault injection: corrupted frames).
    pub fn send_raw(&mut self, bytes: &[u8]) -> Result<(), PilError> {
        self.tx
            .write_all(bytes)
            .and_then(|()| self.tx.flush())
            .map_err(|e| PilError::Link(format!("writing to the board: {e}")))
    }

    fn take(&mut self, bytes: &[u8]) {
        self.stats.bytes_in += bytes.len() as u64;
        let (pending, stats, last) = (&mut self.pending, &mut self.stats, &mut self.last_seq_in);
        self.decoder.feed(bytes, |ev| match ev {
            DecodeEvent::Frame(f) => {
                stats.frames_in += 1;
                if let Some(prev) = *last {
                    stats.seq_gaps += u64::from(f.seq.wrapping_sub(prev).wrapping_sub(1));
                }
                *last = Some(f.seq);
                pending.push_back(f);
            }
            DecodeEvent::CrcError => stats.crc_errors += 1,
            DecodeEvent::Malformed { .. } => stats.malformed += 1,
        });
    }

    /// The next valid frame; waits at most `timeout`.
    pub fn recv(&mut self) -> Result<Frame, PilError> {
        self.recv_within(self.timeout)
    }

    /// The next valid frame, waiting at most `wait`.
    pub fn recv_within(&mut self, wait: Duration) -> Result<Frame, PilError> {
        let deadline = Instant::now() + wait;
        loop {
            if let Some(f) = self.pending.pop_front() {
                return Ok(f);
            }
            if self.closed {
                return Err(PilError::Link(
                    "the board closed the link (QEMU exited)".into(),
                ));
            }
            if self
                .stop
                .as_ref()
                .is_some_and(|s| s.load(Ordering::Relaxed) != 0)
            {
                return Err(PilError::Stopped);
            }
            // In slices, so that a signal is seen while the board is silent.
            let left = deadline
                .saturating_duration_since(Instant::now())
                .min(Duration::from_millis(50));
            if left.is_zero() {
                return Err(PilError::Link(format!(
                    "no frame from the board within {:.1} s",
                    wait.as_secs_f64()
                )));
            }
            match self.rx.recv_timeout(left) {
                Ok(bytes) => self.take(&bytes),
                Err(RecvTimeoutError::Disconnected) => self.closed = true,
                Err(RecvTimeoutError::Timeout) => {}
            }
        }
    }
}
