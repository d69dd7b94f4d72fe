//! Embedded-controller mode (docs/protocol.md §5): the controller and its reference schedule run on the
//! board. The host uploads the parameters and the schedule (`CtrlParam`, `CtrlSegment`), starts the
//! controller (`CtrlStart`, answered by `CtrlReady`), then sends one `CtrlSensors` per tick and receives one
//! `CtrlOutput` (valve command and telemetry). Values travel as IEEE-754 f64 so that the board computes
//! with exactly the numbers the host simulation uses.
//!
//! The wire form of the setup is here (the frames, segment kinds) so that both ends share it; what a
//! controller's parameters are, and their ids, is the control crate's (`pneuflex_control::setup`).

use pneuflex_control::setup::{ControllerSetup, SetupError};
use pneuflex_control::{Reference, SetpointSchedule};

use crate::crc::crc16_update;
use crate::{Message, Reader, ValveMode, Writer, msg_type};

/// Embedded-controller status bits (`CtrlOutput.status`).
pub mod status {
    /// The valve is in its safe state (the command is not applied).
    pub const SAFE: u8 = 0x01;
    /// The safe state is latched by a fault (watchdog, CRC storm); only Reset clears it.
    pub const LATCHED: u8 = 0x02;
}

/// One controller parameter: an id ([`param`]) and its value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamPayload {
    /// Which parameter ([`param`]).
    pub id: u8,
    /// Its value; enumerations are small integers.
    pub value: f64,
}

/// One reference segment: which signal, which reference shape, its start and up to four numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SegmentPayload {
    /// 0 force f_r (N), 1 desired position x_d (m).
    pub signal: u8,
    /// 0 constant (a), 1 step (a initial, b final, c t_step), 2 sine (a bias, b amplitude, c Hz, d phase),
    /// 3 ramp (a start, b slope).
    pub kind: u8,
    /// Start time of the segment, s.
    pub t_start_s: f64,
    /// The shape's numbers (unused ones 0).
    pub v: [f64; 4],
}

/// End of the setup: the controller kind, the period, the board's watchdog and what was sent.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StartPayload {
    /// 1 impedance, 2 adaptive impedance.
    pub controller: u8,
    /// Control period, s.
    pub dt_s: f64,
    /// No valid frame for this long (board clock) → safe state, latched. 0 is refused.
    pub watchdog_ms: u16,
    /// The safe state the board applies.
    pub safe_mode: ValveMode,
    /// Number of CtrlParam frames the host sent.
    pub n_params: u8,
    /// Number of CtrlSegment frames the host sent.
    pub n_segments: u8,
    /// CRC-16 of the payloads of those frames in the order sent: a lost or reordered frame is detected.
    pub setup_crc: u16,
}

/// One tick's sensors (SI, pressures absolute), as `pneuflex_control::Sensors`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorsPayload {
    /// Host tick number (echoed in the output).
    pub tick: u32,
    /// Time, s.
    pub t: f64,
    /// Position, m.
    pub x: f64,
    /// Velocity, m/s.
    pub x_dot: f64,
    /// Contact force, N.
    pub f_e: f64,
    /// Chamber A pressure, Pa.
    pub p_a: f64,
    /// Chamber B pressure, Pa.
    pub p_b: f64,
}

/// Most of a controller's own signals one CtrlOutput carries (`Controller::signals()`, in SI).
pub const MAX_SIGNALS: usize = 8;

/// CtrlOutput's length without its signals; each signal adds 8 bytes (docs/protocol.md §5).
pub const OUTPUT_BASE_LEN: usize = 46;

/// The board's answer to one CtrlSensors.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutputPayload {
    /// The tick of the sensors this answers.
    pub tick: u32,
    /// Valve command u in [-1, 1] as the controller computed it (0 in the safe state).
    pub u: f64,
    /// Reference position x_r, m.
    pub x_r: f64,
    /// The board's own setpoint at t: f_r, N.
    pub f_ref: f64,
    /// The board's own setpoint at t: x_d, m.
    pub x_d: f64,
    /// Board clock when the output was sent, µs.
    pub board_time_us: u32,
    /// Duration of the controller update on the board clock, ns (0 when no update ran).
    pub update_ns: u32,
    /// [`status`] bits.
    pub status: u8,
    /// How many of `signals` travel: the controller's own signals as it declares them (0 in the safe
    /// state). At most [`MAX_SIGNALS`].
    pub n_signals: u8,
    /// The controller's own signals after the update (`Controller::record`), in declared order; the
    /// unused slots are 0.
    pub signals: [f64; MAX_SIGNALS],
}

impl OutputPayload {
    /// The signals that travel (the first `n_signals`).
    pub fn signals(&self) -> &[f64] {
        &self.signals[..usize::from(self.n_signals).min(MAX_SIGNALS)]
    }
}

/// The answer to CtrlStart.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadyPayload {
    /// [`ready`] code.
    pub result: u8,
    /// For a bad parameter its id, for a bad segment its index.
    pub detail: u8,
}

/// Codes of [`ReadyPayload::result`].
pub mod ready {
    /// Setup accepted; the controller runs from the next CtrlSensors.
    pub const OK: u8 = 0;
    /// Fewer or more CtrlParam / CtrlSegment frames arrived than CtrlStart announces.
    pub const COUNT: u8 = 1;
    /// The setup CRC differs.
    pub const CRC: u8 = 2;
    /// A parameter is unknown, missing or out of range (detail: its id).
    pub const PARAM: u8 = 3;
    /// A segment is invalid or out of order (detail: its index).
    pub const SEGMENT: u8 = 4;
    /// Unknown controller kind, bad period, watchdog 0, a Hold safe mode with the 5/2 valve, or (detail 2)
    /// a controller declaring more than [`super::MAX_SIGNALS`] signals.
    pub const START: u8 = 5;
}

/// Length of a Text payload's text.
pub const TEXT_LEN: usize = 40;

/// A piece of text (UTF-8 bytes, possibly cut inside a character at a piece boundary).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TextPayload {
    /// Bytes used in `bytes`.
    pub len: u8,
    /// The text, zero-padded.
    pub bytes: [u8; TEXT_LEN],
}

impl TextPayload {
    /// The used bytes.
    pub fn text(&self) -> &[u8] {
        &self.bytes[..usize::from(self.len).min(TEXT_LEN)]
    }
}

/// The board is in its safe state: why and when.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SafePayload {
    /// `fault_code` (HOST_SILENT, CRC, PANIC, HOST_REQUEST).
    pub reason: u8,
    /// The last tick the controller ran.
    pub last_tick: u32,
    /// Board clock of the last valid frame, µs.
    pub last_valid_us: u32,
    /// Board clock when the safe state was applied, µs.
    pub safe_at_us: u32,
    /// CRC errors counted since start.
    pub crc_errors: u16,
    /// The safe state applied.
    pub mode: ValveMode,
    /// Stack high-water mark so far, bytes (painted-stack scan; 0 if the board cannot tell).
    pub stack_peak_bytes: u16,
}

/// Payload lengths of this mode's messages (CtrlOutput's without its signals).
pub(crate) fn payload_len(t: u8) -> Option<usize> {
    match t {
        msg_type::CTRL_PARAM => Some(9),
        msg_type::CTRL_SEGMENT => Some(42),
        msg_type::CTRL_START => Some(16),
        msg_type::CTRL_SENSORS => Some(52),
        msg_type::CTRL_OUTPUT => Some(OUTPUT_BASE_LEN),
        msg_type::CTRL_READY => Some(2),
        msg_type::TEXT => Some(1 + TEXT_LEN),
        msg_type::SAFE => Some(18),
        msg_type::CTRL_CHANNEL => Some(1),
        _ => None,
    }
}

pub(crate) fn write_payload(m: &Message, w: &mut Writer<'_>) {
    let f = |w: &mut Writer<'_>, v: f64| w.put(&v.to_le_bytes());
    match m {
        Message::CtrlParam(p) => {
            w.put(&[p.id]);
            f(w, p.value);
        }
        Message::CtrlSegment(s) => {
            w.put(&[s.signal, s.kind]);
            f(w, s.t_start_s);
            s.v.iter().for_each(|&v| f(w, v));
        }
        Message::CtrlStart(s) => {
            w.put(&[s.controller]);
            f(w, s.dt_s);
            w.put(&s.watchdog_ms.to_le_bytes());
            w.put(&[s.safe_mode.code(), s.n_params, s.n_segments]);
            w.put(&s.setup_crc.to_le_bytes());
        }
        Message::CtrlSensors(s) => {
            w.put(&s.tick.to_le_bytes());
            for v in [s.t, s.x, s.x_dot, s.f_e, s.p_a, s.p_b] {
                f(w, v);
            }
        }
        Message::CtrlOutput(o) => {
            w.put(&o.tick.to_le_bytes());
            for v in [o.u, o.x_r, o.f_ref, o.x_d] {
                f(w, v);
            }
            w.put(&o.board_time_us.to_le_bytes());
            w.put(&o.update_ns.to_le_bytes());
            w.put(&[o.status, o.signals().len() as u8]);
            o.signals().iter().for_each(|&v| f(w, v));
        }
        Message::CtrlReady(r) => w.put(&[r.result, r.detail]),
        Message::CtrlChannel(c) => w.put(&[*c]),
        Message::Text(t) => {
            w.put(&[t.len]);
            w.put(&t.bytes);
        }
        Message::Safe(s) => {
            w.put(&[s.reason]);
            w.put(&s.last_tick.to_le_bytes());
            w.put(&s.last_valid_us.to_le_bytes());
            w.put(&s.safe_at_us.to_le_bytes());
            w.put(&s.crc_errors.to_le_bytes());
            w.put(&[s.mode.code()]);
            w.put(&s.stack_peak_bytes.to_le_bytes());
        }
        // The I/O-board messages are written in lib.rs.
        _ => {}
    }
}

pub(crate) fn parse_fields(t: u8, r: &mut Reader<'_>) -> Option<Message> {
    Some(match t {
        msg_type::CTRL_PARAM => Message::CtrlParam(ParamPayload {
            id: r.u8()?,
            value: r.f64()?,
        }),
        msg_type::CTRL_SEGMENT => Message::CtrlSegment(SegmentPayload {
            signal: r.u8()?,
            kind: r.u8()?,
            t_start_s: r.f64()?,
            v: [r.f64()?, r.f64()?, r.f64()?, r.f64()?],
        }),
        msg_type::CTRL_START => Message::CtrlStart(StartPayload {
            controller: r.u8()?,
            dt_s: r.f64()?,
            watchdog_ms: r.u16()?,
            safe_mode: ValveMode::from_code(r.u8()?)?,
            n_params: r.u8()?,
            n_segments: r.u8()?,
            setup_crc: r.u16()?,
        }),
        msg_type::CTRL_SENSORS => Message::CtrlSensors(SensorsPayload {
            tick: r.u32()?,
            t: r.f64()?,
            x: r.f64()?,
            x_dot: r.f64()?,
            f_e: r.f64()?,
            p_a: r.f64()?,
            p_b: r.f64()?,
        }),
        msg_type::CTRL_OUTPUT => {
            let mut o = OutputPayload {
                tick: r.u32()?,
                u: r.f64()?,
                x_r: r.f64()?,
                f_ref: r.f64()?,
                x_d: r.f64()?,
                board_time_us: r.u32()?,
                update_ns: r.u32()?,
                status: r.u8()?,
                n_signals: r.u8()?,
                signals: [0.0; MAX_SIGNALS],
            };
            let n = usize::from(o.n_signals);
            if n > MAX_SIGNALS {
                return None;
            }
            for v in &mut o.signals[..n] {
                *v = r.f64()?;
            }
            Message::CtrlOutput(o)
        }
        msg_type::CTRL_READY => Message::CtrlReady(ReadyPayload {
            result: r.u8()?,
            detail: r.u8()?,
        }),
        msg_type::TEXT => {
            let len = r.u8()?;
            if usize::from(len) > TEXT_LEN {
                return None;
            }
            let mut bytes = [0u8; TEXT_LEN];
            for b in bytes.iter_mut() {
                *b = r.u8()?;
            }
            Message::Text(TextPayload { len, bytes })
        }
        msg_type::SAFE => Message::Safe(SafePayload {
            reason: r.u8()?,
            last_tick: r.u32()?,
            last_valid_us: r.u32()?,
            safe_at_us: r.u32()?,
            crc_errors: r.u16()?,
            mode: ValveMode::from_code(r.u8()?)?,
            stack_peak_bytes: r.u16()?,
        }),
        msg_type::CTRL_CHANNEL => Message::CtrlChannel(r.u8()?),
        _ => return None,
    })
}

/// Parameter ids of [`ParamPayload::id`]: the control crate's, beside the setups they encode.
pub use pneuflex_control::setup::{MAX_PARAMS, param};

/// The parameters a setup sends, as CtrlParam payloads; returns the array and how many are used.
pub fn param_payloads(setup: &ControllerSetup) -> ([ParamPayload; MAX_PARAMS], usize) {
    let (params, n) = setup.params();
    let mut out = [ParamPayload { id: 0, value: 0.0 }; MAX_PARAMS];
    for (o, &(id, value)) in out.iter_mut().zip(&params[..n]) {
        *o = ParamPayload { id, value };
    }
    (out, n)
}

/// The segments of a setpoint schedule, force first then position, as sent.
pub fn segments<const N: usize>(
    sp: &SetpointSchedule<N>,
) -> impl Iterator<Item = SegmentPayload> + '_ {
    let one = |signal: u8, (t_start_s, r): (f64, Reference)| {
        let (kind, v) = match r {
            Reference::Constant { value } => (0, [value, 0.0, 0.0, 0.0]),
            Reference::Step {
                initial,
                final_value,
                t_step_s,
            } => (1, [initial, final_value, t_step_s, 0.0]),
            Reference::Sine {
                bias,
                amplitude,
                frequency_hz,
                phase_rad,
            } => (2, [bias, amplitude, frequency_hz, phase_rad]),
            Reference::Ramp { start, slope_per_s } => (3, [start, slope_per_s, 0.0, 0.0]),
        };
        SegmentPayload {
            signal,
            kind,
            t_start_s,
            v,
        }
    };
    (0..sp.force_n.len())
        .filter_map(|i| sp.force_n.segment(i))
        .map(move |s| one(0, s))
        .chain(
            (0..sp.position_m.len())
                .filter_map(|i| sp.position_m.segment(i))
                .map(move |s| one(1, s)),
        )
}

impl SegmentPayload {
    /// The reference this segment describes (None: unknown kind).
    pub fn reference(&self) -> Option<Reference> {
        let [a, b, c, d] = self.v;
        Some(match self.kind {
            0 => Reference::Constant { value: a },
            1 => Reference::Step {
                initial: a,
                final_value: b,
                t_step_s: c,
            },
            2 => Reference::Sine {
                bias: a,
                amplitude: b,
                frequency_hz: c,
                phase_rad: d,
            },
            3 => Reference::Ramp {
                start: a,
                slope_per_s: b,
            },
            _ => return None,
        })
    }
}

/// Continues the setup CRC over one setup message's payload (CtrlParam or CtrlSegment; others unchanged).
pub fn setup_crc_update(crc: u16, m: &Message) -> u16 {
    let mut buf = [0u8; crate::MAX_PAYLOAD];
    let mut w = Writer {
        buf: &mut buf[..],
        pos: 0,
    };
    match m {
        Message::CtrlParam(_) | Message::CtrlSegment(_) => write_payload(m, &mut w),
        _ => return crc,
    }
    let n = w.pos.min(crate::MAX_PAYLOAD);
    crc16_update(crc, &buf[..n])
}

/// The board's side of the setup: collects parameters and segments, then builds the controller's
/// parameters on Start. Unset parameters keep the control crate's defaults only where the host may omit
/// them (the tracking time with clamping); every other one must arrive.
#[derive(Clone, Copy, Debug)]
pub struct SetupCollector {
    values: [f64; param::IDS],
    seen: [bool; param::IDS],
    /// Segments received, force and position schedules.
    pub schedule: SetpointSchedule,
    n_params: u8,
    n_segments: u8,
    crc: u16,
    bad_segment: Option<u8>,
    bad_param: Option<u8>,
}

impl Default for SetupCollector {
    fn default() -> Self {
        Self {
            values: [0.0; param::IDS],
            seen: [false; param::IDS],
            schedule: SetpointSchedule::default(),
            n_params: 0,
            n_segments: 0,
            crc: crate::crc::CRC16_INIT,
            bad_segment: None,
            bad_param: None,
        }
    }
}

impl SetupCollector {
    /// Takes one setup message (others are ignored).
    pub fn take(&mut self, m: &Message) {
        self.crc = setup_crc_update(self.crc, m);
        match m {
            Message::CtrlParam(p) => {
                self.n_params = self.n_params.saturating_add(1);
                match self.values.get_mut(usize::from(p.id)) {
                    Some(v) => {
                        *v = p.value;
                        self.seen[usize::from(p.id)] = true;
                    }
                    None => {
                        self.bad_param.get_or_insert(p.id);
                    }
                }
            }
            Message::CtrlSegment(s) => {
                let i = self.n_segments;
                self.n_segments = self.n_segments.saturating_add(1);
                let sched = match s.signal {
                    0 => Some(&mut self.schedule.force_n),
                    1 => Some(&mut self.schedule.position_m),
                    _ => None,
                };
                let ok = match (sched, s.reference()) {
                    (Some(sched), Some(r)) => sched.push(s.t_start_s, r).is_ok(),
                    _ => false,
                };
                if !ok {
                    self.bad_segment.get_or_insert(i);
                }
            }
            _ => {}
        }
    }

    /// Checks the setup against Start and builds the controller's parameters (validated by the control
    /// crate's constructors on the board).
    pub fn finish(&self, start: &StartPayload) -> Result<ControllerSetup, ReadyPayload> {
        let fail = |result, detail| ReadyPayload { result, detail };
        if start.n_params != self.n_params || start.n_segments != self.n_segments {
            return Err(fail(ready::COUNT, 0));
        }
        if start.setup_crc != self.crc {
            return Err(fail(ready::CRC, 0));
        }
        if let Some(i) = self.bad_segment {
            return Err(fail(ready::SEGMENT, i));
        }
        if let Some(id) = self.bad_param {
            return Err(fail(ready::PARAM, id));
        }
        if !(start.dt_s.is_finite() && start.dt_s > 0.0) || start.watchdog_ms == 0 {
            return Err(fail(ready::START, 0));
        }
        let value = |id: u8| {
            let i = usize::from(id);
            self.seen
                .get(i)
                .copied()
                .unwrap_or(false)
                .then(|| self.values[i])
        };
        ControllerSetup::from_params(start.controller, value).map_err(|e| match e {
            SetupError::Param(id) => fail(ready::PARAM, id),
            SetupError::Kind(_) => fail(ready::START, 0),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{DecodeEvent, Decoder, Frame, MAX_FRAME, encode};
    use pneuflex_control::{
        AdaptiveParams, AntiWindup, ImpedanceParams, PidParams, VelocitySource,
    };

    fn round_trip(m: Message) -> Message {
        let mut buf = [0u8; MAX_FRAME];
        let n = encode(3, &m, &mut buf);
        assert_eq!(n, 7 + m.payload_len());
        let mut d = Decoder::new();
        let mut got = None;
        d.feed(&buf[..n], |e| {
            if let DecodeEvent::Frame(Frame { msg, .. }) = e {
                got = Some(msg)
            }
        });
        got.expect("decoded")
    }

    #[test]
    fn every_embedded_controller_message_round_trips_bit_for_bit() {
        let msgs = [
            Message::CtrlParam(ParamPayload {
                id: 21,
                value: 0.1 + 0.2,
            }),
            Message::CtrlSegment(SegmentPayload {
                signal: 0,
                kind: 2,
                t_start_s: 3.0,
                v: [10.0, 2.0, 1.0, -0.0],
            }),
            Message::CtrlStart(StartPayload {
                controller: 2,
                dt_s: 1e-3,
                watchdog_ms: 50,
                safe_mode: ValveMode::SafeVent,
                n_params: 29,
                n_segments: 3,
                setup_crc: 0xBEEF,
            }),
            Message::CtrlSensors(SensorsPayload {
                tick: 7,
                t: 0.007,
                x: 1e-300,
                x_dot: -3.5,
                f_e: f64::MIN_POSITIVE,
                p_a: 5e5,
                p_b: 1.01325e5,
            }),
            Message::CtrlOutput(OutputPayload {
                tick: 7,
                u: -0.25,
                x_r: 0.01,
                f_ref: 10.0,
                x_d: 0.0,
                board_time_us: 123,
                update_ns: 4567,
                status: status::SAFE,
                n_signals: 3,
                signals: [1e-9, 2e-9, -3e-9, 0.0, 0.0, 0.0, 0.0, 0.0],
            }),
            Message::CtrlOutput(OutputPayload {
                tick: 8,
                u: 1.0,
                x_r: -0.0,
                f_ref: 0.0,
                x_d: 1e-3,
                board_time_us: 0,
                update_ns: 0,
                status: 0,
                n_signals: 0,
                signals: [0.0; MAX_SIGNALS],
            }),
            Message::CtrlOutput(OutputPayload {
                tick: 9,
                u: 0.5,
                x_r: 0.02,
                f_ref: 5.0,
                x_d: 0.0,
                board_time_us: 7,
                update_ns: 8,
                status: 0,
                n_signals: MAX_SIGNALS as u8,
                signals: [1.0, -2.0, f64::MAX, f64::MIN_POSITIVE, 5.0, 6.0, 7.0, -0.0],
            }),
            Message::CtrlReady(ReadyPayload {
                result: ready::PARAM,
                detail: 33,
            }),
            Message::Text(TextPayload {
                len: 5,
                bytes: *b"panic at tick 500\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0",
            }),
            Message::Safe(SafePayload {
                reason: crate::fault_code::HOST_SILENT,
                last_tick: 99,
                last_valid_us: 1000,
                safe_at_us: 51000,
                crc_errors: 2,
                mode: ValveMode::SafeHold,
                stack_peak_bytes: 2048,
            }),
        ];
        for m in msgs {
            let back = round_trip(m);
            // Bit-exact f64 (-0.0 and 0.1 + 0.2 included): compare the encodings.
            assert_eq!(format!("{back:?}"), format!("{m:?}"));
            assert_eq!(back, m);
        }
    }

    #[test]
    fn a_setup_rebuilds_the_same_parameters_and_schedule_on_the_board() {
        let mut adaptive = AdaptiveParams::paper();
        adaptive.adapt_in_contact_only = true;
        adaptive.velocity_source = VelocitySource::ImpedanceFilter;
        adaptive.g_max_m = 0.02;
        let setup = ControllerSetup::Adaptive {
            impedance: ImpedanceParams::default(),
            adaptive,
            pid: PidParams {
                anti_windup: AntiWindup::BackCalculation {
                    tracking_time_s: 0.05,
                },
                ..PidParams::default()
            },
        };
        let sp = SetpointSchedule::paper_fig3(0.004).unwrap();
        let mut board = SetupCollector::default();
        let mut host_crc = crate::crc::CRC16_INIT;
        let (params, n) = param_payloads(&setup);
        let segs: Vec<_> = segments(&sp).collect();
        for m in params[..n]
            .iter()
            .map(|&p| Message::CtrlParam(p))
            .chain(segs.iter().map(|&s| Message::CtrlSegment(s)))
        {
            host_crc = setup_crc_update(host_crc, &m);
            board.take(&round_trip(m));
        }
        let start = StartPayload {
            controller: setup.code(),
            dt_s: 1e-3,
            watchdog_ms: 50,
            safe_mode: ValveMode::SafeVent,
            n_params: n as u8,
            n_segments: segs.len() as u8,
            setup_crc: host_crc,
        };
        assert_eq!(board.finish(&start), Ok(setup));
        assert_eq!(board.schedule, sp);
        // A lost frame is detected by the count, a changed one by the CRC.
        let lost = StartPayload {
            n_params: n as u8 - 1,
            ..start
        };
        assert_eq!(board.finish(&lost).unwrap_err().result, ready::COUNT);
        let changed = StartPayload {
            setup_crc: host_crc ^ 1,
            ..start
        };
        assert_eq!(board.finish(&changed).unwrap_err().result, ready::CRC);
        // An impedance start without the adaptive gains needs only the impedance and PID parameters.
        let imp = SetupCollector::default();
        assert_eq!(
            imp.finish(&StartPayload {
                n_params: 0,
                n_segments: 0,
                setup_crc: crate::crc::CRC16_INIT,
                ..start
            })
            .unwrap_err(),
            ReadyPayload {
                result: ready::PARAM,
                detail: 1
            }
        );
    }
}
