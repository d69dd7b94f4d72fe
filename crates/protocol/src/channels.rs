//! Several actuators on one board (docs/protocol.md §6): one frame carries every channel's samples, valve
//! commands or applied echoes, so that the channels of one tick travel, and are checked by their CRC, together.
//!
//! A board with one channel keeps the version-1 frames (Sample, Valve, Applied): their bytes do not change, so
//! old recordings and old firmware still read. These messages have their own TYPE codes (§4: a new layout gets
//! a new code), and a count byte `n` (1..=[`MAX_CHANNELS`]) that fixes their length like CtrlOutput's.

use crate::{Message, Reader, SamplePayload, ValveMode, Writer, msg_type};

/// Most channels one frame carries: the longest, a Samples frame, is 9 + 15 n bytes and must fit
/// [`crate::MAX_PAYLOAD`] (110): n = 6 gives 99.
pub const MAX_CHANNELS: usize = 6;

/// Bytes of one channel in a Samples payload.
pub const SAMPLE_CHANNEL_LEN: usize = 15;
/// Bytes of one channel in a Valves or an AppliedAll payload.
pub const VALVE_CHANNEL_LEN: usize = 3;
/// Samples' length before its channels (board_time_us, last_cmd_tick, n).
pub const SAMPLES_BASE_LEN: usize = 9;
/// Valves' length before its channels (tick, n).
pub const VALVES_BASE_LEN: usize = 5;
/// AppliedAll's length before its channels (board_time_us, tick, n).
pub const APPLIED_ALL_BASE_LEN: usize = 9;

// The longest N-channel frame fits the decoder's largest payload, so the buffers do not grow.
const _: () = assert!(SAMPLES_BASE_LEN + SAMPLE_CHANNEL_LEN * MAX_CHANNELS <= crate::MAX_PAYLOAD);

/// One channel's raw readings: the fields of a version-1 Sample that belong to one actuator.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ChannelSample {
    /// Position sensor, ADC counts.
    pub position: u16,
    /// Board channel 1 (chamber A or differential transmitter), ADC counts.
    pub p_a: u16,
    /// Chamber B transmitter, ADC counts.
    pub p_b: u16,
    /// Supply transmitter, ADC counts.
    pub p_supply: u16,
    /// Load cell bridge, signed counts.
    pub load: i32,
    /// Signed duty this channel's valve applies, Q15.
    pub duty_q15: i16,
    /// This channel's status bits ([`crate::status`]).
    pub status: u8,
}

/// One channel's valve: its signed duty and mode (a command, or what the board applied).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChannelValve {
    /// Signed duty, Q15.
    pub duty_q15: i16,
    /// Run or a safe state.
    pub mode: ValveMode,
}

impl Default for ChannelValve {
    fn default() -> Self {
        Self {
            duty_q15: 0,
            mode: ValveMode::Run,
        }
    }
}

/// Every channel's readings at one conversion instant (TYPE 0x08).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SamplesPayload {
    /// Board clock at the conversion, µs.
    pub board_time_us: u32,
    /// Tick of the last Valves frame received.
    pub last_cmd_tick: u32,
    /// Channels that travel (1..=[`MAX_CHANNELS`]).
    pub n: u8,
    /// The channels; slots from `n` on are zero.
    pub ch: [ChannelSample; MAX_CHANNELS],
}

/// One tick's valve commands for every channel (TYPE 0x09).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ValvesPayload {
    /// Host control tick.
    pub tick: u32,
    /// Channels that travel (1..=[`MAX_CHANNELS`]).
    pub n: u8,
    /// The channels; slots from `n` on are zero (Run, duty 0).
    pub ch: [ChannelValve; MAX_CHANNELS],
}

/// The board's echo of a Valves frame: what every valve now does, and when (TYPE 0x0A).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AppliedAllPayload {
    /// Board clock when the commands took effect, µs.
    pub board_time_us: u32,
    /// Tick of the Valves frame applied.
    pub tick: u32,
    /// Channels that travel (1..=[`MAX_CHANNELS`]).
    pub n: u8,
    /// What each valve drives (duty 0 and a safe mode while it is safe); slots from `n` on are zero.
    pub ch: [ChannelValve; MAX_CHANNELS],
}

/// A fault of one channel (TYPE 0x0B): its index, a [`crate::fault_code`] and a code-specific detail.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChannelFaultPayload {
    /// The channel (0-based).
    pub channel: u8,
    /// Fault code.
    pub code: u8,
    /// Code-specific detail.
    pub detail: u16,
}

/// Copies `src` into a zeroed array of [`MAX_CHANNELS`]; `None` if there are none or too many.
fn slots<T: Copy + Default>(src: &[T]) -> Option<(u8, [T; MAX_CHANNELS])> {
    if src.is_empty() || src.len() > MAX_CHANNELS {
        return None;
    }
    let mut ch = [T::default(); MAX_CHANNELS];
    ch[..src.len()].copy_from_slice(src);
    Some((src.len() as u8, ch))
}

fn used(n: u8) -> usize {
    usize::from(n).min(MAX_CHANNELS)
}

impl SamplesPayload {
    /// A payload of `channels` (1..=[`MAX_CHANNELS`]).
    pub fn new(board_time_us: u32, last_cmd_tick: u32, channels: &[ChannelSample]) -> Option<Self> {
        let (n, ch) = slots(channels)?;
        Some(Self {
            board_time_us,
            last_cmd_tick,
            n,
            ch,
        })
    }

    /// The channels that travel.
    pub fn channels(&self) -> &[ChannelSample] {
        &self.ch[..used(self.n)]
    }

    /// Channel `i` as a version-1 Sample (same clock and tick), for code that reads one actuator.
    pub fn sample(&self, i: usize) -> Option<SamplePayload> {
        let c = self.channels().get(i)?;
        Some(SamplePayload {
            board_time_us: self.board_time_us,
            last_cmd_tick: self.last_cmd_tick,
            position: c.position,
            p_a: c.p_a,
            p_b: c.p_b,
            p_supply: c.p_supply,
            load: c.load,
            duty_q15: c.duty_q15,
            status: c.status,
        })
    }
}

impl From<&SamplePayload> for ChannelSample {
    fn from(s: &SamplePayload) -> Self {
        Self {
            position: s.position,
            p_a: s.p_a,
            p_b: s.p_b,
            p_supply: s.p_supply,
            load: s.load,
            duty_q15: s.duty_q15,
            status: s.status,
        }
    }
}

impl ValvesPayload {
    /// A payload of `channels` (1..=[`MAX_CHANNELS`]).
    pub fn new(tick: u32, channels: &[ChannelValve]) -> Option<Self> {
        let (n, ch) = slots(channels)?;
        Some(Self { tick, n, ch })
    }

    /// The channels that travel.
    pub fn channels(&self) -> &[ChannelValve] {
        &self.ch[..used(self.n)]
    }
}

impl AppliedAllPayload {
    /// A payload of `channels` (1..=[`MAX_CHANNELS`]).
    pub fn new(board_time_us: u32, tick: u32, channels: &[ChannelValve]) -> Option<Self> {
        let (n, ch) = slots(channels)?;
        Some(Self {
            board_time_us,
            tick,
            n,
            ch,
        })
    }

    /// The channels that travel.
    pub fn channels(&self) -> &[ChannelValve] {
        &self.ch[..used(self.n)]
    }
}

/// The host's valve frame for one tick: a version-1 Valve for one channel (its bytes unchanged), Valves for
/// more. `None` for no channels or more than [`MAX_CHANNELS`].
pub fn valve_message(tick: u32, channels: &[ChannelValve]) -> Option<Message> {
    match channels {
        [one] => Some(Message::Valve(crate::ValvePayload {
            tick,
            duty_q15: one.duty_q15,
            mode: one.mode,
        })),
        _ => ValvesPayload::new(tick, channels).map(Message::Valves),
    }
}

/// Lengths before the channels, and per channel, of this section's types.
pub(crate) fn layout(t: u8) -> Option<(usize, usize)> {
    match t {
        msg_type::SAMPLES => Some((SAMPLES_BASE_LEN, SAMPLE_CHANNEL_LEN)),
        msg_type::VALVES => Some((VALVES_BASE_LEN, VALVE_CHANNEL_LEN)),
        msg_type::APPLIED_ALL => Some((APPLIED_ALL_BASE_LEN, VALVE_CHANNEL_LEN)),
        msg_type::CHANNEL_FAULT => Some((4, 0)),
        _ => None,
    }
}

fn put_valve(w: &mut Writer<'_>, c: &ChannelValve) {
    w.put(&c.duty_q15.to_le_bytes());
    w.put(&[c.mode.code()]);
}

pub(crate) fn write_payload(m: &Message, w: &mut Writer<'_>) {
    match m {
        Message::Samples(s) => {
            w.put(&s.board_time_us.to_le_bytes());
            w.put(&s.last_cmd_tick.to_le_bytes());
            w.put(&[s.channels().len() as u8]);
            for c in s.channels() {
                w.put(&c.position.to_le_bytes());
                w.put(&c.p_a.to_le_bytes());
                w.put(&c.p_b.to_le_bytes());
                w.put(&c.p_supply.to_le_bytes());
                w.put(&c.load.to_le_bytes());
                w.put(&c.duty_q15.to_le_bytes());
                w.put(&[c.status]);
            }
        }
        Message::Valves(v) => {
            w.put(&v.tick.to_le_bytes());
            w.put(&[v.channels().len() as u8]);
            v.channels().iter().for_each(|c| put_valve(w, c));
        }
        Message::AppliedAll(a) => {
            w.put(&a.board_time_us.to_le_bytes());
            w.put(&a.tick.to_le_bytes());
            w.put(&[a.channels().len() as u8]);
            a.channels().iter().for_each(|c| put_valve(w, c));
        }
        Message::ChannelFault(f) => {
            w.put(&[f.channel, f.code]);
            w.put(&f.detail.to_le_bytes());
        }
        _ => {}
    }
}

/// Reads the count byte and checks it: 1..=[`MAX_CHANNELS`] (the length already matched it).
fn count(r: &mut Reader<'_>) -> Option<u8> {
    let n = r.u8()?;
    (1..=MAX_CHANNELS as u8).contains(&n).then_some(n)
}

fn valve(r: &mut Reader<'_>) -> Option<ChannelValve> {
    Some(ChannelValve {
        duty_q15: r.i16()?,
        mode: ValveMode::from_code(r.u8()?)?,
    })
}

pub(crate) fn parse_fields(t: u8, r: &mut Reader<'_>) -> Option<Message> {
    Some(match t {
        msg_type::SAMPLES => {
            let mut s = SamplesPayload {
                board_time_us: r.u32()?,
                last_cmd_tick: r.u32()?,
                n: count(r)?,
                ch: [ChannelSample::default(); MAX_CHANNELS],
            };
            for c in s.ch.iter_mut().take(usize::from(s.n)) {
                *c = ChannelSample {
                    position: r.u16()?,
                    p_a: r.u16()?,
                    p_b: r.u16()?,
                    p_supply: r.u16()?,
                    load: r.i32()?,
                    duty_q15: r.i16()?,
                    status: r.u8()?,
                };
            }
            Message::Samples(s)
        }
        msg_type::VALVES => {
            let mut v = ValvesPayload {
                tick: r.u32()?,
                n: count(r)?,
                ch: [ChannelValve::default(); MAX_CHANNELS],
            };
            for c in v.ch.iter_mut().take(usize::from(v.n)) {
                *c = valve(r)?;
            }
            Message::Valves(v)
        }
        msg_type::APPLIED_ALL => {
            let mut a = AppliedAllPayload {
                board_time_us: r.u32()?,
                tick: r.u32()?,
                n: count(r)?,
                ch: [ChannelValve::default(); MAX_CHANNELS],
            };
            for c in a.ch.iter_mut().take(usize::from(a.n)) {
                *c = valve(r)?;
            }
            Message::AppliedAll(a)
        }
        msg_type::CHANNEL_FAULT => Message::ChannelFault(ChannelFaultPayload {
            channel: r.u8().filter(|&c| usize::from(c) < MAX_CHANNELS)?,
            code: r.u8()?,
            detail: r.u16()?,
        }),
        _ => return None,
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::{
        DecodeEvent, Decoder, Frame, MAX_FRAME, MalformedReason, ValvePayload, encode, expected_len,
    };
    use proptest::prelude::*;

    fn arb_mode() -> impl Strategy<Value = ValveMode> {
        prop_oneof![
            Just(ValveMode::Run),
            Just(ValveMode::SafeVent),
            Just(ValveMode::SafeHold)
        ]
    }

    fn arb_valve() -> impl Strategy<Value = ChannelValve> {
        (any::<i16>(), arb_mode()).prop_map(|(duty_q15, mode)| ChannelValve { duty_q15, mode })
    }

    fn arb_sample() -> impl Strategy<Value = ChannelSample> {
        (any::<[u16; 4]>(), any::<i32>(), any::<i16>(), any::<u8>()).prop_map(
            |(a, load, duty_q15, status)| ChannelSample {
                position: a[0],
                p_a: a[1],
                p_b: a[2],
                p_supply: a[3],
                load,
                duty_q15,
                status,
            },
        )
    }

    /// Any N-channel message, N in 1..=MAX_CHANNELS.
    pub(crate) fn arb_channel_message() -> impl Strategy<Value = Message> {
        let n = 1..=MAX_CHANNELS;
        prop_oneof![
            (
                any::<(u32, u32)>(),
                proptest::collection::vec(arb_sample(), n.clone())
            )
                .prop_map(|((t, k), ch)| Message::Samples(SamplesPayload::new(t, k, &ch).unwrap())),
            (
                any::<u32>(),
                proptest::collection::vec(arb_valve(), n.clone())
            )
                .prop_map(|(k, ch)| Message::Valves(ValvesPayload::new(k, &ch).unwrap())),
            (
                any::<(u32, u32)>(),
                proptest::collection::vec(arb_valve(), n)
            )
                .prop_map(|((t, k), ch)| Message::AppliedAll(
                    AppliedAllPayload::new(t, k, &ch).unwrap()
                )),
            (0..MAX_CHANNELS as u8, any::<u8>(), any::<u16>()).prop_map(
                |(channel, code, detail)| {
                    Message::ChannelFault(ChannelFaultPayload {
                        channel,
                        code,
                        detail,
                    })
                }
            ),
        ]
    }

    fn decode(bytes: &[u8], chunk: usize) -> (Vec<DecodeEvent>, Decoder) {
        let mut d = Decoder::new();
        let mut out = Vec::new();
        for c in bytes.chunks(chunk.max(1)) {
            d.feed(c, |e| out.push(e));
        }
        (out, d)
    }

    fn frames(ev: &[DecodeEvent]) -> Vec<Frame> {
        ev.iter()
            .filter_map(|e| match e {
                DecodeEvent::Frame(f) => Some(*f),
                _ => None,
            })
            .collect()
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

        /// Encode, decode in any chunking: the same messages, the frame length the docs give (§6).
        #[test]
        fn n_channel_frames_round_trip(msgs in proptest::collection::vec((any::<u8>(), arb_channel_message()), 1..12),
                                       chunk in 1usize..64) {
            let mut wire = Vec::new();
            let mut buf = [0u8; MAX_FRAME];
            for (seq, m) in &msgs {
                let len = encode(*seq, m, &mut buf);
                let want = 7 + match m {
                    Message::Samples(s) => 9 + 15 * s.channels().len(),
                    Message::Valves(v) => 5 + 3 * v.channels().len(),
                    Message::AppliedAll(a) => 9 + 3 * a.channels().len(),
                    _ => 4,
                };
                prop_assert_eq!(len, want);
                wire.extend_from_slice(&buf[..len]);
            }
            let (ev, d) = decode(&wire, chunk);
            let want: Vec<Frame> = msgs.iter().map(|(seq, msg)| Frame { seq: *seq, msg: *msg }).collect();
            prop_assert_eq!(frames(&ev), want);
            prop_assert_eq!((d.stats().crc_errors, d.stats().malformed, d.stats().skipped_bytes), (0, 0, 0));
        }

        /// Garbage (random bytes, or pieces of N-channel frames) before a frame: the decoder finds the frame.
        #[test]
        fn n_channel_frame_found_after_garbage(garbage in proptest::collection::vec(any::<u8>(), 0..300),
                                                junk in arb_channel_message(), cut in 0usize..200,
                                                seq in any::<u8>(), m in arb_channel_message(),
                                                chunk in 1usize..40) {
            let mut buf = [0u8; MAX_FRAME];
            // A truncated N-channel frame inside the garbage: a real header whose frame never completes.
            let n = encode(seq.wrapping_add(1), &junk, &mut buf);
            let mut wire = garbage.clone();
            wire.extend_from_slice(&buf[..cut % n]);
            let n = encode(seq, &m, &mut buf);
            // Enough copies that a false header in the garbage (at most MAX_FRAME long) cannot hide them all.
            while wire.len() < garbage.len() + 3 * MAX_FRAME {
                wire.extend_from_slice(&buf[..n]);
            }
            let (ev, _) = decode(&wire, chunk);
            let want = Frame { seq, msg: m };
            prop_assert!(frames(&ev).contains(&want));
        }
    }

    #[test]
    fn one_channel_uses_the_version_1_valve_frame() {
        let one = [ChannelValve {
            duty_q15: 0x4000,
            mode: ValveMode::Run,
        }];
        let m = valve_message(1000, &one).unwrap();
        assert_eq!(
            m,
            Message::Valve(ValvePayload {
                tick: 1000,
                duty_q15: 0x4000,
                mode: ValveMode::Run
            })
        );
        // docs/protocol.md §1's Valve example, unchanged.
        let mut buf = [0u8; MAX_FRAME];
        let n = encode(0x2A, &m, &mut buf);
        assert_eq!(
            &buf[..n],
            &[
                0xA5, 0x5A, 0x07, 0x2A, 0x02, 0xE8, 0x03, 0x00, 0x00, 0x00, 0x40, 0x00, 0x63, 0x72
            ]
        );
        assert!(matches!(valve_message(1, &one.repeat(2)), Some(Message::Valves(v)) if v.n == 2));
        assert_eq!(valve_message(1, &[]), None);
        assert_eq!(valve_message(1, &one.repeat(MAX_CHANNELS + 1)), None);
    }

    /// docs/protocol.md §6's two-channel examples; the CRCs were computed outside this crate with the
    /// bitwise loop of §1 (Python), and the fields decode to what the text says.
    #[test]
    fn two_channel_worked_examples_from_docs() {
        let mut buf = [0u8; MAX_FRAME];
        let run = |duty_q15| ChannelValve {
            duty_q15,
            mode: ValveMode::Run,
        };
        let v = Message::Valves(ValvesPayload::new(1000, &[run(0x4000), run(-0x4000)]).unwrap());
        let n = encode(0x2B, &v, &mut buf);
        let valves = [
            0xA5, 0x5A, 0x0B, 0x2B, 0x09, 0xE8, 0x03, 0x00, 0x00, 0x02, 0x00, 0x40, 0x00, 0x00,
            0xC0, 0x00, 0x73, 0x2D,
        ];
        assert_eq!(&buf[..n], &valves);
        let s = Message::Samples(
            SamplesPayload::new(
                2_000_000,
                1000,
                &[
                    ChannelSample {
                        position: 2048,
                        p_a: 1200,
                        p_b: 1100,
                        p_supply: 3000,
                        load: -5000,
                        duty_q15: 0x4000,
                        status: 0,
                    },
                    ChannelSample {
                        position: 1024,
                        p_a: 1300,
                        p_b: 1000,
                        p_supply: 3000,
                        load: 250,
                        duty_q15: -0x4000,
                        status: 0,
                    },
                ],
            )
            .unwrap(),
        );
        let n = encode(0x11, &s, &mut buf);
        let samples = [
            0xA5, 0x5A, 0x27, 0x11, 0x08, 0x80, 0x84, 0x1E, 0x00, 0xE8, 0x03, 0x00, 0x00, 0x02,
            0x00, 0x08, 0xB0, 0x04, 0x4C, 0x04, 0xB8, 0x0B, 0x78, 0xEC, 0xFF, 0xFF, 0x00, 0x40,
            0x00, 0x00, 0x04, 0x14, 0x05, 0xE8, 0x03, 0xB8, 0x0B, 0xFA, 0x00, 0x00, 0x00, 0x00,
            0xC0, 0x00, 0xD5, 0xFC,
        ];
        assert_eq!(&buf[..n], &samples);
        // And they decode back (a different path from the encoder).
        let mut wire = valves.to_vec();
        wire.extend_from_slice(&samples);
        let (ev, _) = decode(&wire, 5);
        assert_eq!(
            frames(&ev),
            vec![Frame { seq: 0x2B, msg: v }, Frame { seq: 0x11, msg: s }]
        );
    }

    /// A raw frame with a correct CRC (a buggy or newer board's).
    fn raw(ty: u8, payload: &[u8]) -> Vec<u8> {
        let mut f = vec![crate::SOF0, crate::SOF1, payload.len() as u8, 1, ty];
        f.extend_from_slice(payload);
        let crc = crate::crc::crc16(&f[2..]);
        f.extend_from_slice(&crc.to_le_bytes());
        f
    }

    #[test]
    fn bad_channel_counts_and_fields_are_malformed_and_the_next_frame_decodes() {
        use MalformedReason::*;
        let valves = |n: u8, carried: usize, mode: u8| {
            let mut p = vec![0xE8, 0x03, 0, 0, n];
            for _ in 0..carried {
                p.extend_from_slice(&[0, 0x40, mode]);
            }
            p
        };
        let cases: Vec<(&str, Vec<u8>, MalformedReason)> = vec![
            (
                "no channels",
                raw(msg_type::VALVES, &valves(0, 0, 0)),
                BadField,
            ),
            (
                "2 announced, 1 carried",
                raw(msg_type::VALVES, &valves(2, 1, 0)),
                BadLength {
                    len: 8,
                    expected: 11,
                },
            ),
            (
                // 7 channels of 3 bytes fit a frame: the length agrees with the count, the count is too large.
                "more than MAX_CHANNELS",
                raw(
                    msg_type::VALVES,
                    &valves(MAX_CHANNELS as u8 + 1, MAX_CHANNELS + 1, 0),
                ),
                BadField,
            ),
            (
                "channel 1 mode 3",
                raw(msg_type::VALVES, &valves(2, 2, 3)),
                BadField,
            ),
            (
                "fault of channel MAX_CHANNELS",
                raw(msg_type::CHANNEL_FAULT, &[MAX_CHANNELS as u8, 1, 0, 0]),
                BadField,
            ),
            (
                "samples of 7 channels",
                raw(msg_type::SAMPLES, &{
                    let mut p = vec![0u8; 9 + 15 * 6];
                    p[8] = 7;
                    p
                }),
                BadLength {
                    len: 99,
                    expected: 114,
                },
            ),
        ];
        let mut buf = [0u8; MAX_FRAME];
        let good = Message::Heartbeat(5);
        let n = encode(9, &good, &mut buf);
        for (name, bad, reason) in cases {
            let mut wire = bad.clone();
            wire.extend_from_slice(&buf[..n]);
            let (ev, _) = decode(&wire, 3);
            assert_eq!(
                ev,
                vec![
                    DecodeEvent::Malformed {
                        msg_type: bad[4],
                        reason
                    },
                    DecodeEvent::Frame(Frame { seq: 9, msg: good })
                ],
                "{name}"
            );
        }
        assert_eq!(expected_len(msg_type::SAMPLES, &[0; 9]), Some(9));
    }
}
