//! The framed binary protocol between the host and the rig's I/O board (see docs/protocol.md).
//!
//! Frame: `A5 5A | LEN | SEQ | TYPE | PAYLOAD[LEN] | CRC16 (LE)`, the CRC (CRC-16/CCITT-FALSE) covering
//! LEN..PAYLOAD. All multi-byte fields are little-endian. The decoder is a streaming, no-panic state machine
//! that resynchronises on the next start marker after garbage or a bad CRC.
//!
//! `no_std` and allocation-free: the host (`crates/rig`, `crates/pil`) and the firmware (`firmware/`) run this
//! same code, so both ends agree on every byte. [`ctrl`] holds the embedded-controller messages.
#![cfg_attr(not(test), no_std)]

pub mod channels;
pub mod crc;
pub mod ctrl;

use crate::crc::crc16;
pub use channels::{
    AppliedAllPayload, ChannelFaultPayload, ChannelSample, ChannelValve, MAX_CHANNELS,
    SamplesPayload, ValvesPayload,
};
pub use ctrl::{
    OutputPayload, ParamPayload, ReadyPayload, SafePayload, SegmentPayload, SensorsPayload,
    StartPayload, TextPayload,
};

/// First start-of-frame byte.
pub const SOF0: u8 = 0xA5;
/// Second start-of-frame byte.
pub const SOF1: u8 = 0x5A;
/// Bytes before the payload: SOF0, SOF1, LEN, SEQ, TYPE.
pub const HEADER_LEN: usize = 5;
/// Bytes after the payload: the CRC.
pub const TRAILER_LEN: usize = 2;
/// Largest payload a frame may carry: a CtrlOutput with [`ctrl::MAX_SIGNALS`] signals.
pub const MAX_PAYLOAD: usize = ctrl::OUTPUT_BASE_LEN + 8 * ctrl::MAX_SIGNALS;
/// Largest frame on the wire.
pub const MAX_FRAME: usize = HEADER_LEN + MAX_PAYLOAD + TRAILER_LEN;
/// Magic value a Reset message must carry, so that a corrupted frame cannot clear a fault by accident.
pub const RESET_MAGIC: u16 = 0x5AFE;

/// Message type codes (the TYPE byte).
pub mod msg_type {
    /// Board -> host: one sensor sample.
    pub const SAMPLE: u8 = 0x01;
    /// Host -> board: valve command.
    pub const VALVE: u8 = 0x02;
    /// Either direction: liveness; the board echoes the host's heartbeat.
    pub const HEARTBEAT: u8 = 0x03;
    /// Board -> host: the board latched a fault.
    pub const FAULT: u8 = 0x04;
    /// Host -> board: clear the board's latched fault.
    pub const RESET: u8 = 0x05;
    /// Host -> board: sample period, board watchdog and safe state.
    pub const CONFIG: u8 = 0x06;
    /// Board -> host: the valve command the board applied, and when (its own clock).
    pub const APPLIED: u8 = 0x07;
    /// Board -> host: every channel's sample (several actuators, docs/protocol.md §6).
    pub const SAMPLES: u8 = 0x08;
    /// Host -> board: every channel's valve command for one tick.
    pub const VALVES: u8 = 0x09;
    /// Board -> host: every channel's applied valve command, and when.
    pub const APPLIED_ALL: u8 = 0x0A;
    /// Board -> host: a fault of one channel.
    pub const CHANNEL_FAULT: u8 = 0x0B;
    /// Host -> embedded controller: one controller parameter (setup).
    pub const CTRL_PARAM: u8 = 0x10;
    /// Host -> embedded controller: one reference schedule segment (setup).
    pub const CTRL_SEGMENT: u8 = 0x11;
    /// Host -> embedded controller: end of setup, start the controller.
    pub const CTRL_START: u8 = 0x12;
    /// Host -> embedded controller: one tick's sensor sample (SI, f64).
    pub const CTRL_SENSORS: u8 = 0x13;
    /// Embedded controller -> host: the tick's valve command and telemetry.
    pub const CTRL_OUTPUT: u8 = 0x14;
    /// Embedded controller -> host: the answer to Start (setup accepted or why not).
    pub const CTRL_READY: u8 = 0x15;
    /// Board -> host: a piece of text (a panic message).
    pub const TEXT: u8 = 0x16;
    /// Embedded controller -> host: the valve is in its safe state, why, and when (board clock).
    pub const SAFE: u8 = 0x17;
    /// Host -> embedded controller: the channel (actuator) the controller frames that follow address, on a
    /// board running one controller per actuator (docs/protocol.md §5, "Several controllers").
    pub const CTRL_CHANNEL: u8 = 0x18;
}

/// Sample status bits.
pub mod status {
    /// The valve is in its safe state.
    pub const SAFE: u8 = 0x01;
    /// The safe state is "hold" (both chambers closed) rather than "vent".
    pub const SAFE_HOLD: u8 = 0x02;
    /// The board has a latched fault.
    pub const BOARD_FAULT: u8 = 0x04;
    /// The board's own command watchdog tripped.
    pub const WATCHDOG: u8 = 0x08;
}

/// Board fault codes carried by a Fault message.
pub mod fault_code {
    /// No valve command or heartbeat within the configured board watchdog time.
    pub const HOST_SILENT: u8 = 0x01;
    /// An ADC conversion failed or timed out.
    pub const ADC: u8 = 0x02;
    /// Coil driver over-current.
    pub const COIL: u8 = 0x03;
    /// Received frames failed CRC past the board's threshold.
    pub const CRC: u8 = 0x04;
    /// The firmware panicked (detail: the source line, 0 if unknown).
    pub const PANIC: u8 = 0x05;
    /// The host commanded the safe state (a Valve frame with a safe mode; the end of a run).
    pub const HOST_REQUEST: u8 = 0x06;
}

/// How the valve is driven.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ValveMode {
    /// Normal operation: apply the signed duty.
    Run,
    /// Safe state: both chambers to exhaust.
    SafeVent,
    /// Safe state: both chambers closed (hold the piston).
    SafeHold,
}

impl ValveMode {
    /// The wire code.
    pub fn code(self) -> u8 {
        match self {
            ValveMode::Run => 0,
            ValveMode::SafeVent => 1,
            ValveMode::SafeHold => 2,
        }
    }

    /// The mode for a wire code, if valid.
    pub fn from_code(c: u8) -> Option<Self> {
        match c {
            0 => Some(ValveMode::Run),
            1 => Some(ValveMode::SafeVent),
            2 => Some(ValveMode::SafeHold),
            _ => None,
        }
    }

    /// Whether this is one of the safe states.
    pub fn is_safe(self) -> bool {
        !matches!(self, ValveMode::Run)
    }
}

/// One raw sample as the board sends it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SamplePayload {
    /// Board clock at the conversion, µs (wraps after ~71 min).
    pub board_time_us: u32,
    /// Tick number of the last valve command the board applied.
    pub last_cmd_tick: u32,
    /// Position sensor, ADC counts.
    pub position: u16,
    /// Chamber A pressure transmitter, ADC counts.
    pub p_a: u16,
    /// Chamber B pressure transmitter, ADC counts.
    pub p_b: u16,
    /// Supply pressure transmitter, ADC counts.
    pub p_supply: u16,
    /// Load cell bridge, signed counts (24-bit ADC, sign-extended).
    pub load: i32,
    /// Signed duty the board applies, Q15 (32767 = +1).
    pub duty_q15: i16,
    /// Status bits (see [`status`]).
    pub status: u8,
}

/// A valve command from the host.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ValvePayload {
    /// The host's control tick number.
    pub tick: u32,
    /// Signed duty, Q15 (32767 = +1, -32767 = -1).
    pub duty_q15: i16,
    /// Run or a safe state.
    pub mode: ValveMode,
}

/// The board's echo of a valve command it applied: which one, what it drives, and when by the board's clock
/// (the clock that stamps the samples), so that a log replays what the valve did and when, whatever the
/// host's timing (docs/protocol.md §3, 0x07).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AppliedPayload {
    /// Board clock when the command took effect, µs (the samples' clock).
    pub board_time_us: u32,
    /// The `tick` of the Valve frame applied.
    pub tick: u32,
    /// Signed duty now driven, Q15 (0 in a safe state, or while a latched fault keeps the valve safe).
    pub duty_q15: i16,
    /// What the valve now does: Run, or the safe state it is in.
    pub mode: ValveMode,
}

/// Board configuration sent by the host before a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ConfigPayload {
    /// Sample period, µs.
    pub sample_period_us: u32,
    /// The board goes to its safe state if no valve command or heartbeat arrives within this, ms (0 = off).
    pub watchdog_ms: u16,
    /// The safe state the board itself uses on its watchdog.
    pub safe_mode: ValveMode,
}

/// A decoded protocol message.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Message {
    /// Board -> host sensor sample.
    Sample(SamplePayload),
    /// Host -> board valve command.
    Valve(ValvePayload),
    /// Liveness counter (host sends, board echoes).
    Heartbeat(u32),
    /// Board fault: code and detail.
    Fault {
        /// Fault code (see [`fault_code`]).
        code: u8,
        /// Code-specific detail.
        detail: u16,
    },
    /// Clear the board's latched fault; carries [`RESET_MAGIC`].
    Reset(u16),
    /// Board configuration.
    Config(ConfigPayload),
    /// Board -> host: the valve command applied, and when.
    Applied(AppliedPayload),
    /// Board -> host: every channel's sample.
    Samples(SamplesPayload),
    /// Host -> board: every channel's valve command.
    Valves(ValvesPayload),
    /// Board -> host: every channel's applied command, and when.
    AppliedAll(AppliedAllPayload),
    /// Board -> host: one channel's fault.
    ChannelFault(ChannelFaultPayload),
    /// Embedded-controller setup: one parameter.
    CtrlParam(ParamPayload),
    /// Embedded-controller setup: one schedule segment.
    CtrlSegment(SegmentPayload),
    /// Embedded-controller setup done: start.
    CtrlStart(StartPayload),
    /// One tick's sensors for the embedded controller.
    CtrlSensors(SensorsPayload),
    /// The embedded controller's output for a tick.
    CtrlOutput(OutputPayload),
    /// The embedded controller's answer to Start.
    CtrlReady(ReadyPayload),
    /// Text from the board (a panic message, in pieces).
    Text(TextPayload),
    /// The embedded controller is in its safe state.
    Safe(SafePayload),
    /// The channel the controller frames that follow address (0 until the first).
    CtrlChannel(u8),
}

/// Payload length of each message type; CtrlOutput's without its signals (8 bytes each), the N-channel
/// messages' without their channels (counted in the payload: [`expected_len`]).
pub fn payload_len(msg_type: u8) -> Option<usize> {
    match msg_type {
        msg_type::SAMPLE => Some(23),
        msg_type::VALVE => Some(7),
        msg_type::HEARTBEAT => Some(4),
        msg_type::FAULT => Some(3),
        msg_type::RESET => Some(2),
        msg_type::CONFIG => Some(7),
        msg_type::APPLIED => Some(11),
        t => channels::layout(t)
            .map(|(base, _)| base)
            .or_else(|| ctrl::payload_len(t)),
    }
}

/// The length a received payload of `msg_type` must have: [`payload_len`], and for CtrlOutput 8 bytes
/// more for each signal its count byte announces, for an N-channel message each channel's bytes for the
/// channels its count byte (the last before the channels) announces.
pub fn expected_len(msg_type: u8, payload: &[u8]) -> Option<usize> {
    let base = payload_len(msg_type)?;
    let count = || usize::from(payload.get(base - 1).copied().unwrap_or(0));
    Some(match msg_type {
        msg_type::CTRL_OUTPUT => base + 8 * count(),
        t => match channels::layout(t) {
            Some((_, per)) if per > 0 => base + per * count(),
            _ => base,
        },
    })
}

/// A frame: sequence number and message.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Sender's sequence number (wraps at 256).
    pub seq: u8,
    /// The message.
    pub msg: Message,
}

/// A bounded little-endian writer: never panics, records overflow.
pub(crate) struct Writer<'a> {
    buf: &'a mut [u8],
    pos: usize,
}

impl Writer<'_> {
    pub(crate) fn put(&mut self, bytes: &[u8]) {
        for &b in bytes {
            if let Some(slot) = self.buf.get_mut(self.pos) {
                *slot = b;
            }
            self.pos += 1;
        }
    }
}

/// A bounded little-endian reader over a payload.
pub(crate) struct Reader<'a> {
    buf: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let s = self.buf.get(self.pos..self.pos + N)?;
        self.pos += N;
        let mut out = [0u8; N];
        out.copy_from_slice(s);
        Some(out)
    }
    pub(crate) fn u8(&mut self) -> Option<u8> {
        self.take::<1>().map(|b| b[0])
    }
    pub(crate) fn u16(&mut self) -> Option<u16> {
        self.take().map(u16::from_le_bytes)
    }
    pub(crate) fn i16(&mut self) -> Option<i16> {
        self.take().map(i16::from_le_bytes)
    }
    pub(crate) fn u32(&mut self) -> Option<u32> {
        self.take().map(u32::from_le_bytes)
    }
    pub(crate) fn i32(&mut self) -> Option<i32> {
        self.take().map(i32::from_le_bytes)
    }
    pub(crate) fn f64(&mut self) -> Option<f64> {
        self.take().map(f64::from_le_bytes)
    }
}

impl Message {
    /// The TYPE byte.
    pub fn type_code(&self) -> u8 {
        match self {
            Message::Sample(_) => msg_type::SAMPLE,
            Message::Valve(_) => msg_type::VALVE,
            Message::Heartbeat(_) => msg_type::HEARTBEAT,
            Message::Fault { .. } => msg_type::FAULT,
            Message::Reset(_) => msg_type::RESET,
            Message::Config(_) => msg_type::CONFIG,
            Message::Applied(_) => msg_type::APPLIED,
            Message::Samples(_) => msg_type::SAMPLES,
            Message::Valves(_) => msg_type::VALVES,
            Message::AppliedAll(_) => msg_type::APPLIED_ALL,
            Message::ChannelFault(_) => msg_type::CHANNEL_FAULT,
            Message::CtrlParam(_) => msg_type::CTRL_PARAM,
            Message::CtrlSegment(_) => msg_type::CTRL_SEGMENT,
            Message::CtrlStart(_) => msg_type::CTRL_START,
            Message::CtrlSensors(_) => msg_type::CTRL_SENSORS,
            Message::CtrlOutput(_) => msg_type::CTRL_OUTPUT,
            Message::CtrlReady(_) => msg_type::CTRL_READY,
            Message::Text(_) => msg_type::TEXT,
            Message::Safe(_) => msg_type::SAFE,
            Message::CtrlChannel(_) => msg_type::CTRL_CHANNEL,
        }
    }

    /// This message's payload length (LEN).
    pub fn payload_len(&self) -> usize {
        let base = payload_len(self.type_code()).unwrap_or(0);
        match self {
            Message::CtrlOutput(o) => base + 8 * o.signals().len(),
            Message::Samples(s) => base + channels::SAMPLE_CHANNEL_LEN * s.channels().len(),
            Message::Valves(v) => base + channels::VALVE_CHANNEL_LEN * v.channels().len(),
            Message::AppliedAll(a) => base + channels::VALVE_CHANNEL_LEN * a.channels().len(),
            _ => base,
        }
    }

    fn write_payload(&self, w: &mut Writer<'_>) {
        match self {
            Message::Sample(s) => {
                w.put(&s.board_time_us.to_le_bytes());
                w.put(&s.last_cmd_tick.to_le_bytes());
                w.put(&s.position.to_le_bytes());
                w.put(&s.p_a.to_le_bytes());
                w.put(&s.p_b.to_le_bytes());
                w.put(&s.p_supply.to_le_bytes());
                w.put(&s.load.to_le_bytes());
                w.put(&s.duty_q15.to_le_bytes());
                w.put(&[s.status]);
            }
            Message::Valve(v) => {
                w.put(&v.tick.to_le_bytes());
                w.put(&v.duty_q15.to_le_bytes());
                w.put(&[v.mode.code()]);
            }
            Message::Heartbeat(c) => w.put(&c.to_le_bytes()),
            Message::Fault { code, detail } => {
                w.put(&[*code]);
                w.put(&detail.to_le_bytes());
            }
            Message::Reset(m) => w.put(&m.to_le_bytes()),
            Message::Config(c) => {
                w.put(&c.sample_period_us.to_le_bytes());
                w.put(&c.watchdog_ms.to_le_bytes());
                w.put(&[c.safe_mode.code()]);
            }
            Message::Applied(a) => {
                w.put(&a.board_time_us.to_le_bytes());
                w.put(&a.tick.to_le_bytes());
                w.put(&a.duty_q15.to_le_bytes());
                w.put(&[a.mode.code()]);
            }
            m @ (Message::Samples(_)
            | Message::Valves(_)
            | Message::AppliedAll(_)
            | Message::ChannelFault(_)) => channels::write_payload(m, w),
            m => ctrl::write_payload(m, w),
        }
    }

    /// Parses a payload of a given type; `None` if the type, the length or a field is invalid.
    pub fn parse(msg_type: u8, payload: &[u8]) -> Option<Message> {
        Self::parse_checked(msg_type, payload).ok()
    }

    /// Parses a payload of a given type, saying why it is malformed (docs/protocol.md §1 "Receiving").
    pub fn parse_checked(msg_type: u8, payload: &[u8]) -> Result<Message, MalformedReason> {
        let want = expected_len(msg_type, payload).ok_or(MalformedReason::UnknownType)?;
        if want != payload.len() {
            return Err(MalformedReason::BadLength {
                len: payload.len() as u8,
                expected: u8::try_from(want).unwrap_or(u8::MAX),
            });
        }
        Self::parse_fields(msg_type, payload).ok_or(MalformedReason::BadField)
    }

    fn parse_fields(msg_type: u8, payload: &[u8]) -> Option<Message> {
        let mut r = Reader {
            buf: payload,
            pos: 0,
        };
        let msg = match msg_type {
            msg_type::SAMPLE => Message::Sample(SamplePayload {
                board_time_us: r.u32()?,
                last_cmd_tick: r.u32()?,
                position: r.u16()?,
                p_a: r.u16()?,
                p_b: r.u16()?,
                p_supply: r.u16()?,
                load: r.i32()?,
                duty_q15: r.i16()?,
                status: r.u8()?,
            }),
            msg_type::VALVE => Message::Valve(ValvePayload {
                tick: r.u32()?,
                duty_q15: r.i16()?,
                mode: ValveMode::from_code(r.u8()?)?,
            }),
            msg_type::HEARTBEAT => Message::Heartbeat(r.u32()?),
            msg_type::FAULT => Message::Fault {
                code: r.u8()?,
                detail: r.u16()?,
            },
            msg_type::RESET => Message::Reset(r.u16()?),
            msg_type::CONFIG => Message::Config(ConfigPayload {
                sample_period_us: r.u32()?,
                watchdog_ms: r.u16()?,
                safe_mode: ValveMode::from_code(r.u8()?)?,
            }),
            msg_type::APPLIED => Message::Applied(AppliedPayload {
                board_time_us: r.u32()?,
                tick: r.u32()?,
                duty_q15: r.i16()?,
                mode: ValveMode::from_code(r.u8()?)?,
            }),
            t if channels::layout(t).is_some() => return channels::parse_fields(t, &mut r),
            t => return ctrl::parse_fields(t, &mut r),
        };
        Some(msg)
    }
}

/// Encodes a frame into `out`, returning the number of bytes written.
pub fn encode(seq: u8, msg: &Message, out: &mut [u8; MAX_FRAME]) -> usize {
    let len = msg.payload_len();
    let mut w = Writer {
        buf: &mut out[..],
        pos: 0,
    };
    w.put(&[SOF0, SOF1, len as u8, seq, msg.type_code()]);
    msg.write_payload(&mut w);
    let end = w.pos.min(MAX_FRAME - TRAILER_LEN);
    let crc = crc16(&out[2..end]);
    out[end..end + 2].copy_from_slice(&crc.to_le_bytes());
    end + 2
}

/// Converts a command in [-1, 1] to Q15 (NaN -> 0).
pub fn to_q15(u: f64) -> i16 {
    let u = if u.is_nan() { 0.0 } else { u.clamp(-1.0, 1.0) };
    libm::round(u * 32767.0) as i16
}

/// Converts Q15 to [-1, 1] (-32768 saturates to -1).
pub fn from_q15(q: i16) -> f64 {
    (f64::from(q) / 32767.0).max(-1.0)
}

/// What the decoder saw in the byte stream.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DecodeEvent {
    /// A valid frame.
    Frame(Frame),
    /// A complete frame whose CRC did not match.
    CrcError,
    /// A frame with a valid CRC but an unknown type or a wrong payload length/field.
    Malformed {
        /// The TYPE byte.
        msg_type: u8,
        /// What is wrong with it.
        reason: MalformedReason,
    },
}

/// Why a frame with a valid CRC was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MalformedReason {
    /// TYPE is not in docs/protocol.md §3.
    UnknownType,
    /// LEN is not the length of TYPE's payload.
    BadLength {
        /// LEN as received.
        len: u8,
        /// TYPE's payload length.
        expected: u8,
    },
    /// A field holds an invalid value (a valve or safe mode other than 0, 1, 2).
    BadField,
}

/// Counters kept by the decoder.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DecoderStats {
    /// Valid frames.
    pub frames: u64,
    /// Frames dropped for a bad CRC.
    pub crc_errors: u64,
    /// Frames with a valid CRC but bad content.
    pub malformed: u64,
    /// Bytes skipped while hunting for a start marker.
    pub skipped_bytes: u64,
}

const BUF_LEN: usize = 4 * MAX_FRAME;

/// A streaming frame decoder: feed it bytes in any chunking; it never panics and resynchronises.
#[derive(Clone, Debug)]
pub struct Decoder {
    buf: [u8; BUF_LEN],
    len: usize,
    stats: DecoderStats,
}

impl Default for Decoder {
    fn default() -> Self {
        Self::new()
    }
}

impl Decoder {
    /// An empty decoder.
    pub fn new() -> Self {
        Self {
            buf: [0; BUF_LEN],
            len: 0,
            stats: DecoderStats::default(),
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> DecoderStats {
        self.stats
    }

    /// Feeds bytes; `sink` receives every event in stream order.
    pub fn feed(&mut self, mut data: &[u8], mut sink: impl FnMut(DecodeEvent)) {
        while !data.is_empty() {
            let room = BUF_LEN - self.len;
            let n = room.min(data.len());
            let (head, tail) = data.split_at(n);
            if let Some(dst) = self.buf.get_mut(self.len..self.len + n) {
                dst.copy_from_slice(head);
            }
            self.len += n;
            data = tail;
            self.parse(&mut sink);
        }
    }

    /// Drops the first `n` buffered bytes.
    fn consume(&mut self, n: usize) {
        let n = n.min(self.len);
        self.buf.copy_within(n..self.len, 0);
        self.len -= n;
    }

    fn parse(&mut self, sink: &mut impl FnMut(DecodeEvent)) {
        loop {
            // Hunt for SOF0 SOF1.
            let start = self.buf[..self.len]
                .windows(2)
                .position(|w| w[0] == SOF0 && w[1] == SOF1);
            match start {
                Some(s) => {
                    self.stats.skipped_bytes += s as u64;
                    self.consume(s);
                }
                None => {
                    // Keep a trailing SOF0: it may be the first half of a marker.
                    let keep = usize::from(self.len > 0 && self.buf[self.len - 1] == SOF0);
                    self.stats.skipped_bytes += (self.len - keep) as u64;
                    self.consume(self.len - keep);
                    return;
                }
            }
            if self.len < HEADER_LEN {
                return;
            }
            let plen = usize::from(self.buf[2]);
            if plen > MAX_PAYLOAD {
                // Not a real header: skip this marker and hunt again.
                self.stats.skipped_bytes += 1;
                self.consume(1);
                continue;
            }
            let total = HEADER_LEN + plen + TRAILER_LEN;
            if self.len < total {
                return;
            }
            let body_end = HEADER_LEN + plen;
            let want = u16::from_le_bytes([self.buf[body_end], self.buf[body_end + 1]]);
            if crc16(&self.buf[2..body_end]) != want {
                // Resync: the marker may have been data; rescan from the next byte.
                self.stats.crc_errors += 1;
                sink(DecodeEvent::CrcError);
                self.consume(1);
                continue;
            }
            let seq = self.buf[3];
            let ty = self.buf[4];
            match Message::parse_checked(ty, &self.buf[HEADER_LEN..body_end]) {
                Ok(msg) => {
                    self.stats.frames += 1;
                    sink(DecodeEvent::Frame(Frame { seq, msg }));
                }
                Err(reason) => {
                    self.stats.malformed += 1;
                    sink(DecodeEvent::Malformed {
                        msg_type: ty,
                        reason,
                    });
                }
            }
            self.consume(total);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn arb_mode() -> impl Strategy<Value = ValveMode> {
        prop_oneof![
            Just(ValveMode::Run),
            Just(ValveMode::SafeVent),
            Just(ValveMode::SafeHold)
        ]
    }

    fn arb_message() -> impl Strategy<Value = Message> {
        prop_oneof![
            (
                any::<u32>(),
                any::<u32>(),
                any::<[u16; 4]>(),
                any::<i32>(),
                any::<i16>(),
                any::<u8>()
            )
                .prop_map(|(t, k, a, load, duty, status)| Message::Sample(
                    SamplePayload {
                        board_time_us: t,
                        last_cmd_tick: k,
                        position: a[0],
                        p_a: a[1],
                        p_b: a[2],
                        p_supply: a[3],
                        load,
                        duty_q15: duty,
                        status
                    }
                )),
            (any::<u32>(), any::<i16>(), arb_mode()).prop_map(|(tick, duty_q15, mode)| {
                Message::Valve(ValvePayload {
                    tick,
                    duty_q15,
                    mode,
                })
            }),
            any::<u32>().prop_map(Message::Heartbeat),
            any::<u8>().prop_map(Message::CtrlChannel),
            (any::<u8>(), any::<u16>()).prop_map(|(code, detail)| Message::Fault { code, detail }),
            any::<u16>().prop_map(Message::Reset),
            (any::<u32>(), any::<u16>(), arb_mode()).prop_map(|(p, w, m)| {
                Message::Config(ConfigPayload {
                    sample_period_us: p,
                    watchdog_ms: w,
                    safe_mode: m,
                })
            }),
            (any::<u32>(), any::<u32>(), any::<i16>(), arb_mode()).prop_map(
                |(board_time_us, tick, duty_q15, mode)| Message::Applied(AppliedPayload {
                    board_time_us,
                    tick,
                    duty_q15,
                    mode,
                })
            ),
            // CtrlOutput's length follows its signal count: every count from none to the most.
            (
                any::<(u32, u32, u32, u8)>(),
                any::<[f64; 4]>(),
                0..=ctrl::MAX_SIGNALS,
                any::<[f64; ctrl::MAX_SIGNALS]>()
            )
                .prop_map(|((tick, t_us, ns, status), v, n, mut signals)| {
                    signals[n..].fill(0.0);
                    Message::CtrlOutput(OutputPayload {
                        tick,
                        u: v[0],
                        x_r: v[1],
                        f_ref: v[2],
                        x_d: v[3],
                        board_time_us: t_us,
                        update_ns: ns,
                        status,
                        n_signals: n as u8,
                        signals,
                    })
                }),
            // Several actuators' frames (§6), N in 1..=MAX_CHANNELS.
            channels::tests::arb_channel_message(),
        ]
    }

    fn frames_of(bytes: &[u8], chunk: usize) -> (Vec<Frame>, Decoder) {
        let mut d = Decoder::new();
        let mut out = Vec::new();
        for c in bytes.chunks(chunk.max(1)) {
            d.feed(c, |e| {
                if let DecodeEvent::Frame(f) = e {
                    out.push(f)
                }
            });
        }
        (out, d)
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

        #[test]
        fn never_panics_on_arbitrary_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..2048),
                                            chunk in 1usize..300) {
            let (_frames, d) = frames_of(&bytes, chunk);
            let s = d.stats();
            // Every input byte is accounted for: skipped, inside a frame, or still buffered.
            prop_assert!(s.skipped_bytes as usize <= bytes.len());
        }

        #[test]
        fn round_trips_every_message(msgs in proptest::collection::vec((any::<u8>(), arb_message()), 1..20),
                                     chunk in 1usize..80) {
            let mut wire = Vec::new();
            let mut buf = [0u8; MAX_FRAME];
            for (seq, m) in &msgs {
                let n = encode(*seq, m, &mut buf);
                prop_assert_eq!(n, HEADER_LEN + m.payload_len() + TRAILER_LEN);
                wire.extend_from_slice(&buf[..n]);
            }
            let (frames, d) = frames_of(&wire, chunk);
            let want: Vec<Frame> = msgs.iter().map(|(seq, msg)| Frame { seq: *seq, msg: *msg }).collect();
            prop_assert_eq!(frames, want);
            prop_assert_eq!(d.stats().crc_errors, 0);
            prop_assert_eq!(d.stats().skipped_bytes, 0);
        }

        #[test]
        fn resyncs_after_garbage(garbage in proptest::collection::vec(any::<u8>(), 0..200),
                                 seq in any::<u8>(), m in arb_message()) {
            let mut buf = [0u8; MAX_FRAME];
            let n = encode(seq, &m, &mut buf);
            // Garbage, then copies of the frame for at least two maximal frames: a false header inside the
            // garbage can hold back at most MAX_FRAME bytes before its CRC fails and the decoder rescans.
            let mut wire = garbage.clone();
            while wire.len() < garbage.len() + 2 * MAX_FRAME {
                wire.extend_from_slice(&buf[..n]);
            }
            let (frames, _) = frames_of(&wire, 7);
            let want = Frame { seq, msg: m };
            prop_assert!(frames.contains(&want));
        }

        #[test]
        fn single_bit_flip_is_detected(seq in any::<u8>(), m in arb_message(), bit in 0usize..1000) {
            let mut buf = [0u8; MAX_FRAME];
            let n = encode(seq, &m, &mut buf);
            // Flip one bit in LEN..CRC (a flipped marker is simply not a frame).
            let bit = 16 + bit % ((n - 2) * 8);
            buf[bit / 8] ^= 1 << (bit % 8);
            let (frames, _) = frames_of(&buf[..n], n);
            prop_assert!(frames.is_empty());
        }
    }

    #[test]
    fn worked_examples_from_docs() {
        // docs/protocol.md, CRCs computed independently (bitwise, outside this crate).
        let mut buf = [0u8; MAX_FRAME];
        let n = encode(7, &Message::Heartbeat(1), &mut buf);
        assert_eq!(
            &buf[..n],
            &[
                0xA5, 0x5A, 0x04, 0x07, 0x03, 0x01, 0x00, 0x00, 0x00, 0x2F, 0x60
            ]
        );
        let v = Message::Valve(ValvePayload {
            tick: 1000,
            duty_q15: 0x4000,
            mode: ValveMode::Run,
        });
        let n = encode(0x2A, &v, &mut buf);
        assert_eq!(
            &buf[..n],
            &[
                0xA5, 0x5A, 0x07, 0x2A, 0x02, 0xE8, 0x03, 0x00, 0x00, 0x00, 0x40, 0x00, 0x63, 0x72
            ]
        );
        let a = Message::Applied(AppliedPayload {
            board_time_us: 2_000_000,
            tick: 1000,
            duty_q15: 0x4000,
            mode: ValveMode::Run,
        });
        let n = encode(0x10, &a, &mut buf);
        assert_eq!(
            &buf[..n],
            &[
                0xA5, 0x5A, 0x0B, 0x10, 0x07, 0x80, 0x84, 0x1E, 0x00, 0xE8, 0x03, 0x00, 0x00, 0x00,
                0x40, 0x00, 0x1D, 0x79
            ]
        );
        // §5, several controllers: CtrlChannel 1, SEQ 0.
        let n = encode(0, &Message::CtrlChannel(1), &mut buf);
        assert_eq!(&buf[..n], &[0xA5, 0x5A, 0x01, 0x00, 0x18, 0x01, 0x8F, 0x68]);
    }

    /// A frame with any header and payload and a correct CRC: what a buggy or newer board could send.
    fn raw_frame(seq: u8, ty: u8, payload: &[u8]) -> Vec<u8> {
        let mut f = vec![SOF0, SOF1, payload.len() as u8, seq, ty];
        f.extend_from_slice(payload);
        let crc = crc16(&f[2..]);
        f.extend_from_slice(&crc.to_le_bytes());
        f
    }

    fn events(bytes: &[u8], chunk: usize) -> (Vec<DecodeEvent>, DecoderStats) {
        let mut d = Decoder::new();
        let mut out = Vec::new();
        for c in bytes.chunks(chunk) {
            d.feed(c, |e| out.push(e));
        }
        (out, d.stats())
    }

    #[test]
    fn malformed_frame_corpus_is_rejected_with_its_reason_and_the_next_frame_decodes() {
        use MalformedReason::*;
        let valve = |mode: u8| [0xE8, 0x03, 0, 0, 0x00, 0x40, mode];
        let config = |mode: u8| [0xE8, 0x03, 0, 0, 50, 0, mode];
        // A CtrlOutput whose count byte (the payload's 46th) says `n` signals, carrying `carried`.
        let output = |n: u8, carried: usize| {
            let mut p = vec![0u8; ctrl::OUTPUT_BASE_LEN + 8 * carried];
            p[ctrl::OUTPUT_BASE_LEN - 1] = n;
            p
        };
        let corpus: Vec<(&str, Vec<u8>, u8, MalformedReason)> = vec![
            (
                "unknown type 0x00",
                raw_frame(1, 0x00, &[1, 2, 3]),
                0x00,
                UnknownType,
            ),
            (
                // 0x08..=0x0B are the N-channel messages (§6).
                "unknown type 0x0C",
                raw_frame(1, 0x0C, &[0; 7]),
                0x0C,
                UnknownType,
            ),
            (
                "Applied of a Valve's length",
                raw_frame(1, msg_type::APPLIED, &[0; 7]),
                msg_type::APPLIED,
                BadLength {
                    len: 7,
                    expected: 11,
                },
            ),
            (
                "Applied with mode 3",
                raw_frame(1, msg_type::APPLIED, &[0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 3]),
                msg_type::APPLIED,
                BadField,
            ),
            (
                "unknown type 0xFF, empty",
                raw_frame(1, 0xFF, &[]),
                0xFF,
                UnknownType,
            ),
            (
                "sample one byte short",
                raw_frame(2, msg_type::SAMPLE, &[0; 22]),
                msg_type::SAMPLE,
                BadLength {
                    len: 22,
                    expected: 23,
                },
            ),
            (
                "valve one byte long",
                raw_frame(2, msg_type::VALVE, &[0; 8]),
                msg_type::VALVE,
                BadLength {
                    len: 8,
                    expected: 7,
                },
            ),
            (
                "heartbeat empty",
                raw_frame(2, msg_type::HEARTBEAT, &[]),
                msg_type::HEARTBEAT,
                BadLength {
                    len: 0,
                    expected: 4,
                },
            ),
            (
                "fault at the maximal length",
                raw_frame(2, msg_type::FAULT, &[0; MAX_PAYLOAD]),
                msg_type::FAULT,
                BadLength {
                    len: MAX_PAYLOAD as u8,
                    expected: 3,
                },
            ),
            (
                "reset with a config's length",
                raw_frame(2, msg_type::RESET, &[0; 7]),
                msg_type::RESET,
                BadLength {
                    len: 7,
                    expected: 2,
                },
            ),
            (
                "valve mode 3",
                raw_frame(3, msg_type::VALVE, &valve(3)),
                msg_type::VALVE,
                BadField,
            ),
            (
                "valve mode 0xFF",
                raw_frame(3, msg_type::VALVE, &valve(0xFF)),
                msg_type::VALVE,
                BadField,
            ),
            (
                "config safe mode 3",
                raw_frame(3, msg_type::CONFIG, &config(3)),
                msg_type::CONFIG,
                BadField,
            ),
            (
                "ctrl output announcing 3 signals carrying 2",
                raw_frame(4, msg_type::CTRL_OUTPUT, &output(3, 2)),
                msg_type::CTRL_OUTPUT,
                BadLength {
                    len: 62,
                    expected: 70,
                },
            ),
            (
                "ctrl output announcing 9 signals in the largest payload",
                raw_frame(4, msg_type::CTRL_OUTPUT, &output(9, 8)),
                msg_type::CTRL_OUTPUT,
                BadLength {
                    len: MAX_PAYLOAD as u8,
                    expected: 118,
                },
            ),
            (
                "ctrl output announcing 255 signals carrying none",
                raw_frame(4, msg_type::CTRL_OUTPUT, &output(255, 0)),
                msg_type::CTRL_OUTPUT,
                BadLength {
                    len: 46,
                    expected: u8::MAX,
                },
            ),
        ];
        let mut buf = [0u8; MAX_FRAME];
        let good = Message::Heartbeat(0xC0DE_0001);
        let n = encode(9, &good, &mut buf);
        for (name, bad, ty, reason) in &corpus {
            let mut wire = bad.clone();
            wire.extend_from_slice(&buf[..n]);
            for chunk in [1, 3, wire.len()] {
                let (ev, stats) = events(&wire, chunk);
                assert_eq!(
                    ev,
                    vec![
                        DecodeEvent::Malformed {
                            msg_type: *ty,
                            reason: *reason
                        },
                        DecodeEvent::Frame(Frame { seq: 9, msg: good }),
                    ],
                    "{name}, chunks of {chunk}"
                );
                assert_eq!(
                    (stats.malformed, stats.crc_errors, stats.frames),
                    (1, 0, 1),
                    "{name}"
                );
                assert_eq!(
                    stats.skipped_bytes, 0,
                    "{name}: the whole bad frame is dropped, not rescanned"
                );
            }
        }
        // The same payloads with their right mode are accepted: the corpus fails for the stated reason only.
        assert!(Message::parse(msg_type::VALVE, &valve(2)).is_some());
        assert!(Message::parse(msg_type::CONFIG, &config(1)).is_some());
        // A LEN above MAX_PAYLOAD is no header at all: skipped byte by byte, no malformed event, next frame
        // decodes.
        let mut wire = raw_frame(1, msg_type::SAMPLE, &[0; MAX_PAYLOAD + 1]);
        wire.extend_from_slice(&buf[..n]);
        let (ev, stats) = events(&wire, 5);
        assert_eq!(
            ev.last(),
            Some(&DecodeEvent::Frame(Frame { seq: 9, msg: good }))
        );
        assert_eq!(stats.malformed, 0);
    }

    /// xorshift64*: a fixed, seeded stream for the fuzz test (no dependency, same on every machine).
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
        }
        fn below(&mut self, n: usize) -> usize {
            (self.next() % n as u64) as usize
        }
    }

    /// Iterations of [`fuzz_decoder_with_mutated_frames`] (override with PNEUFLEX_FUZZ_ITERS).
    const FUZZ_ITERS: u64 = 200_000;

    /// Stable-Rust fuzzing: valid frames of every type, mutated (bit flips, byte overwrites, insertions,
    /// deletions, truncation, duplication, CRC fixed up or not), fed in random chunks. The decoder must not
    /// panic, and every frame it accepts must re-encode to exactly the bytes it was decoded from.
    #[test]
    fn fuzz_decoder_with_mutated_frames() {
        let iters = std::env::var("PNEUFLEX_FUZZ_ITERS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(FUZZ_ITERS);
        let mut rng = Rng(0x5EED_F0CC_0000_0001);
        let mut stats = DecoderStats::default();
        let mut checked = 0u64;
        let mut buf = [0u8; MAX_FRAME];
        for _ in 0..iters {
            // 1..4 valid frames of random types and fields (modes kept valid: mutations break them).
            let mut wire = Vec::new();
            for _ in 0..1 + rng.below(3) {
                let r = rng.next();
                let msg = match rng.below(8) {
                    0 => Message::Sample(SamplePayload {
                        board_time_us: r as u32,
                        last_cmd_tick: (r >> 32) as u32,
                        position: r as u16,
                        p_a: (r >> 8) as u16,
                        p_b: (r >> 16) as u16,
                        p_supply: (r >> 24) as u16,
                        load: (r >> 3) as i32,
                        duty_q15: (r >> 40) as i16,
                        status: (r >> 56) as u8,
                    }),
                    1 => Message::Valve(ValvePayload {
                        tick: r as u32,
                        duty_q15: (r >> 32) as i16,
                        mode: ValveMode::from_code((r >> 48) as u8 % 3).unwrap(),
                    }),
                    2 => Message::Heartbeat(r as u32),
                    3 => Message::Fault {
                        code: r as u8,
                        detail: (r >> 8) as u16,
                    },
                    4 => Message::Reset(r as u16),
                    5 => Message::Valves(
                        ValvesPayload::new(
                            r as u32,
                            &[ChannelValve {
                                duty_q15: (r >> 32) as i16,
                                mode: ValveMode::from_code((r >> 48) as u8 % 3).unwrap(),
                            }; 2],
                        )
                        .unwrap(),
                    ),
                    6 => Message::Samples(
                        SamplesPayload::new(
                            r as u32,
                            (r >> 32) as u32,
                            &[ChannelSample {
                                position: r as u16,
                                p_a: (r >> 8) as u16,
                                p_b: (r >> 16) as u16,
                                p_supply: (r >> 24) as u16,
                                load: (r >> 3) as i32,
                                duty_q15: (r >> 40) as i16,
                                status: (r >> 56) as u8,
                            }; MAX_CHANNELS][..1 + (r >> 61) as usize % MAX_CHANNELS],
                        )
                        .unwrap(),
                    ),
                    _ => Message::Config(ConfigPayload {
                        sample_period_us: r as u32,
                        watchdog_ms: (r >> 32) as u16,
                        safe_mode: ValveMode::from_code((r >> 48) as u8 % 3).unwrap(),
                    }),
                };
                let n = encode(rng.next() as u8, &msg, &mut buf);
                wire.extend_from_slice(&buf[..n]);
            }
            for _ in 0..rng.below(4) {
                if wire.is_empty() {
                    break;
                }
                let i = rng.below(wire.len());
                match rng.below(7) {
                    0 => wire[i] ^= 1 << rng.below(8),
                    1 => wire[i] = rng.next() as u8,
                    2 => wire.insert(i, rng.next() as u8),
                    3 => {
                        wire.remove(i);
                    }
                    4 => wire.truncate(i),
                    5 => {
                        let j = i + rng.below(wire.len() - i);
                        let copy = wire[i..=j.min(wire.len() - 1)].to_vec();
                        wire.splice(i..i, copy);
                    }
                    _ => {
                        // A header byte changed and the CRC recomputed: reaches the malformed path.
                        let start = wire.windows(2).position(|w| w == [SOF0, SOF1]);
                        if let Some(s) = start.filter(|s| s + HEADER_LEN <= wire.len()) {
                            let field = s + 2 + rng.below(3);
                            wire[field] = rng.next() as u8;
                            let len = usize::from(wire[s + 2]);
                            let end = s + HEADER_LEN + len;
                            if len <= MAX_PAYLOAD && end + 2 <= wire.len() {
                                let crc = crc16(&wire[s + 2..end]);
                                wire[end..end + 2].copy_from_slice(&crc.to_le_bytes());
                            }
                        }
                    }
                }
            }
            let chunk = 1 + rng.below(40);
            let mut d = Decoder::new();
            let mut accepted = Vec::new();
            for c in wire.chunks(chunk) {
                d.feed(c, |e| {
                    if let DecodeEvent::Frame(f) = e {
                        accepted.push(f);
                    }
                });
            }
            for f in accepted {
                let n = encode(f.seq, &f.msg, &mut buf);
                assert!(
                    wire.windows(n).any(|w| w == &buf[..n]),
                    "accepted {f:?}, which re-encodes to bytes not in the input {wire:02X?}"
                );
                checked += 1;
            }
            let s = d.stats();
            stats.frames += s.frames;
            stats.crc_errors += s.crc_errors;
            stats.malformed += s.malformed;
        }
        eprintln!(
            "decoder fuzz: {iters} executions, {} frames accepted and re-encoded, {} CRC errors, {} malformed",
            checked, stats.crc_errors, stats.malformed
        );
        assert_eq!(checked, stats.frames);
        // The mutations reach every path.
        assert!(stats.frames > 0 && stats.crc_errors > 0 && stats.malformed > 0);
    }

    #[test]
    fn q15_round_trip_and_limits() {
        assert_eq!(to_q15(1.0), 32767);
        assert_eq!(to_q15(-1.0), -32767);
        assert_eq!(to_q15(f64::NAN), 0);
        assert_eq!(to_q15(5.0), 32767);
        assert_eq!(from_q15(-32768), -1.0);
        for i in -100..=100 {
            let u = f64::from(i) / 100.0;
            assert!((from_q15(to_q15(u)) - u).abs() <= 0.5 / 32767.0 + 1e-12);
        }
    }
}
