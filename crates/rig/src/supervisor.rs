//! The safety supervisor: on any fault the valve is commanded to its safe state in the same tick, and the
//! fault stays latched (the safe command is repeated every tick) until [`Supervisor::reset`].
//! [`ChannelSupervisor`] does the same for a board with several actuators: one fault on any channel, every
//! valve safe in that tick.

use pneuflex_control::ValveCommand;

use crate::error::{ErrorKind, RigError};
use crate::protocol::channels::valve_message;
use crate::protocol::{ChannelValve, MAX_CHANNELS, Message, ValveMode, to_q15};
use crate::rig::{Rig, SiSample, check_limits};
use crate::rigfile::{Channel, SafeState};

/// A latched fault.
#[derive(Clone, Debug, PartialEq)]
pub struct Fault {
    /// What kind.
    pub kind: ErrorKind,
    /// What was seen.
    pub message: String,
    /// Control tick at which it was latched.
    pub tick: u64,
    /// Host time, s since the loop started.
    pub host_time_s: f64,
}

/// Wraps a rig: passes commands while healthy, the safe state once a fault is latched.
pub struct Supervisor<R: Rig> {
    rig: R,
    safe_state: SafeState,
    fault: Option<Fault>,
    /// Errors seen after the first fault (the first one stays latched).
    later_errors: u64,
}

impl<R: Rig> Supervisor<R> {
    /// A supervisor over `rig` with the valve's safe state.
    pub fn new(rig: R, safe_state: SafeState) -> Self {
        Self {
            rig,
            safe_state,
            fault: None,
            later_errors: 0,
        }
    }

    /// The latched fault, if any.
    pub fn fault(&self) -> Option<&Fault> {
        self.fault.as_ref()
    }

    /// Errors that occurred while a fault was already latched.
    pub fn later_errors(&self) -> u64 {
        self.later_errors
    }

    /// The supervised rig, read-only.
    pub fn rig(&self) -> &R {
        &self.rig
    }

    /// The supervised rig.
    pub fn rig_mut(&mut self) -> &mut R {
        &mut self.rig
    }

    /// Latches `err` (if nothing is latched yet) and commands the safe state now.
    pub fn trip(&mut self, tick: u64, now_s: f64, err: RigError) {
        if self.fault.is_none() {
            self.fault = Some(Fault {
                kind: err.kind(),
                message: err.message().to_string(),
                tick,
                host_time_s: now_s,
            });
        } else {
            self.later_errors += 1;
        }
        if self.rig.safe(tick as u32, self.safe_state).is_err() {
            self.later_errors += 1;
        }
    }

    /// Reads the rig; an error trips the supervisor. While latched, reads go on (for the trace).
    pub fn sense(&mut self, tick: u64, now_s: f64) -> Option<R::Sample> {
        match self.rig.read(now_s) {
            Ok(s) => s,
            Err(e) => {
                self.trip(tick, now_s, e);
                None
            }
        }
    }

    /// Sends `cmd` while healthy, the safe state while latched; returns what was applied (`None` = safe).
    pub fn actuate(&mut self, tick: u64, now_s: f64, cmd: ValveCommand) -> Option<ValveCommand> {
        if self.fault.is_some() {
            if self.rig.safe(tick as u32, self.safe_state).is_err() {
                self.later_errors += 1;
            }
            return None;
        }
        match self.rig.write(tick as u32, cmd) {
            Ok(()) => Some(cmd),
            Err(e) => {
                self.trip(tick, now_s, e);
                None
            }
        }
    }

    /// Commands the safe state without latching a fault (the normal end of a run).
    pub fn park(&mut self, tick: u64) -> Result<(), RigError> {
        self.rig.safe(tick as u32, self.safe_state)
    }

    /// Clears the latch after the operator has dealt with the cause; the layers below are reset too.
    pub fn reset(&mut self) -> Result<(), RigError> {
        self.rig.reset()?;
        self.fault = None;
        self.later_errors = 0;
        Ok(())
    }
}

impl<R: Rig> Drop for Supervisor<R> {
    /// Whatever ends the run — return, error or panic unwinding — the valve is left in its safe state.
    fn drop(&mut self) {
        let _ = self.rig.safe(u32::MAX, self.safe_state);
    }
}

/// What one channel's valve is told in a tick: the controller's command, or its safe state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ChannelCommand {
    /// Drive the valve with this command.
    Run(ValveCommand),
    /// Put the valve in this safe state.
    Safe(SafeState),
}

impl ChannelCommand {
    /// The channel's slot of a Valves frame (docs/protocol.md §6): Q15 duty and mode, duty 0 when safe.
    pub fn wire(self) -> ChannelValve {
        match self {
            ChannelCommand::Run(c) => ChannelValve {
                duty_q15: to_q15(c.u),
                mode: ValveMode::Run,
            },
            ChannelCommand::Safe(s) => ChannelValve {
                duty_q15: 0,
                mode: s.mode(),
            },
        }
    }
}

/// The one frame that carries a tick's commands for every channel: a version-1 Valve for one channel, a
/// Valves frame for more (docs/protocol.md §6); `None` for none or more than [`MAX_CHANNELS`].
pub fn valve_frame(tick: u32, cmds: &[ChannelCommand]) -> Option<Message> {
    if cmds.len() > MAX_CHANNELS {
        return None;
    }
    let mut slots = [ChannelValve::default(); MAX_CHANNELS];
    for (slot, c) in slots.iter_mut().zip(cmds) {
        *slot = c.wire();
    }
    valve_message(tick, &slots[..cmds.len()])
}

/// A board with several channels (docs/protocol.md §6): one read gives every channel's sample of one
/// conversion, one write sends every channel's command in one frame, so that no tick can reach one valve and
/// miss another.
pub trait ChannelRig {
    /// The newest samples since the last call, one per channel in the rig file's order (`None`: none came).
    fn read(&mut self, now_s: f64) -> Result<Option<Vec<SiSample>>, RigError>;

    /// Sends one tick's commands, one per channel, together.
    fn write(&mut self, tick: u32, cmds: &[ChannelCommand]) -> Result<(), RigError>;

    /// Clears faults latched below this layer (and on the board).
    fn reset(&mut self) -> Result<(), RigError>;
}

impl<R: ChannelRig + ?Sized> ChannelRig for &mut R {
    fn read(&mut self, now_s: f64) -> Result<Option<Vec<SiSample>>, RigError> {
        (**self).read(now_s)
    }
    fn write(&mut self, tick: u32, cmds: &[ChannelCommand]) -> Result<(), RigError> {
        (**self).write(tick, cmds)
    }
    fn reset(&mut self) -> Result<(), RigError> {
        (**self).reset()
    }
}

/// A latched fault of a board with several channels: the fault, and the channel it came from (`None`: the
/// link or the board as a whole).
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelFault {
    /// What, when.
    pub fault: Fault,
    /// The channel whose check failed, if one did.
    pub channel: Option<usize>,
}

/// The supervisor of a board with several actuators: checks every channel's sample against that channel's
/// limits and every command for NaN; **one** fault on any channel sends every valve to its own safe state in
/// the same tick, in one frame, and keeps them there until [`ChannelSupervisor::reset`] (a gripper with one
/// finger limp and the other squeezing drops or crushes what it holds).
pub struct ChannelSupervisor<R: ChannelRig> {
    rig: R,
    channels: Vec<Channel>,
    fault: Option<ChannelFault>,
    later_errors: u64,
}

impl<R: ChannelRig> ChannelSupervisor<R> {
    /// A supervisor over `rig` with the rig file's channels ([`crate::RigFile::channels`]).
    pub fn new(rig: R, channels: Vec<Channel>) -> Self {
        Self {
            rig,
            channels,
            fault: None,
            later_errors: 0,
        }
    }

    /// The channels supervised.
    pub fn channels(&self) -> &[Channel] {
        &self.channels
    }

    /// The latched fault, if any.
    pub fn fault(&self) -> Option<&ChannelFault> {
        self.fault.as_ref()
    }

    /// Errors that occurred while a fault was already latched.
    pub fn later_errors(&self) -> u64 {
        self.later_errors
    }

    /// The supervised rig, read-only.
    pub fn rig(&self) -> &R {
        &self.rig
    }

    /// Every channel's safe state.
    fn safe_commands(&self) -> Vec<ChannelCommand> {
        self.channels
            .iter()
            .map(|c| ChannelCommand::Safe(c.safe_state))
            .collect()
    }

    fn send_safe(&mut self, tick: u64) {
        let safe = self.safe_commands();
        if self.rig.write(tick as u32, &safe).is_err() {
            self.later_errors += 1;
        }
    }

    /// Latches `err` of `channel` (if nothing is latched yet) and sends every valve its safe state now.
    pub fn trip(&mut self, tick: u64, now_s: f64, channel: Option<usize>, err: RigError) {
        if self.fault.is_none() {
            let message = match channel.and_then(|i| self.channels.get(i).map(|c| (i, c))) {
                Some((i, c)) => format!("channel {i} ({}): {}", c.name, err.message()),
                None => err.message().to_string(),
            };
            self.fault = Some(ChannelFault {
                fault: Fault {
                    kind: err.kind(),
                    message,
                    tick,
                    host_time_s: now_s,
                },
                channel,
            });
        } else {
            self.later_errors += 1;
        }
        self.send_safe(tick);
    }

    /// Reads every channel and checks each against its own limits; a failed read or check trips the
    /// supervisor (every valve safe) and gives `None`. While latched, reads go on (for the trace).
    pub fn sense(&mut self, tick: u64, now_s: f64) -> Option<Vec<SiSample>> {
        let samples = match self.rig.read(now_s) {
            Ok(s) => s?,
            Err(e) => {
                self.trip(tick, now_s, None, e);
                return None;
            }
        };
        if samples.len() != self.channels.len() {
            let e = RigError::new(
                ErrorKind::BoardFault,
                format!(
                    "the board sent {} channels, the rig file has {}",
                    samples.len(),
                    self.channels.len()
                ),
            );
            self.trip(tick, now_s, None, e);
            return None;
        }
        let failed = self
            .channels
            .iter()
            .zip(&samples)
            .enumerate()
            .find_map(|(i, (c, s))| check_limits(&c.limits, s).err().map(|e| (i, e)));
        if let Some((i, e)) = failed {
            self.trip(tick, now_s, Some(i), e);
            return None;
        }
        Some(samples)
    }

    /// Sends `cmds` (one per channel) while healthy, every safe state while latched; returns whether the
    /// commands were applied (`false`: every valve is safe). A non-finite command trips the supervisor.
    pub fn actuate(&mut self, tick: u64, now_s: f64, cmds: &[ValveCommand]) -> bool {
        if self.fault.is_some() {
            self.send_safe(tick);
            return false;
        }
        if cmds.len() != self.channels.len() {
            let e = RigError::new(
                ErrorKind::Io,
                format!(
                    "{} commands for {} channels",
                    cmds.len(),
                    self.channels.len()
                ),
            );
            self.trip(tick, now_s, None, e);
            return false;
        }
        if let Some(i) = cmds.iter().position(|c| !c.u.is_finite()) {
            let e = RigError::new(
                ErrorKind::NotANumber,
                format!("valve command u is {}", cmds[i].u),
            );
            self.trip(tick, now_s, Some(i), e);
            return false;
        }
        let run: Vec<ChannelCommand> = cmds.iter().map(|&c| ChannelCommand::Run(c)).collect();
        match self.rig.write(tick as u32, &run) {
            Ok(()) => true,
            Err(e) => {
                self.trip(tick, now_s, None, e);
                false
            }
        }
    }

    /// Sends every valve its safe state without latching a fault (the normal end of a run).
    pub fn park(&mut self, tick: u64) -> Result<(), RigError> {
        let safe = self.safe_commands();
        self.rig.write(tick as u32, &safe)
    }

    /// Clears the latch after the operator has dealt with the cause; the layers below are reset too.
    pub fn reset(&mut self) -> Result<(), RigError> {
        self.rig.reset()?;
        self.fault = None;
        self.later_errors = 0;
        Ok(())
    }
}

impl<R: ChannelRig> Drop for ChannelSupervisor<R> {
    /// Whatever ends the run, every valve is left in its safe state.
    fn drop(&mut self) {
        let safe = self.safe_commands();
        let _ = self.rig.write(u32::MAX, &safe);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rig::tests::Scripted;

    #[test]
    fn fault_is_latched_and_safe_repeated() {
        let mut rig = Scripted::default();
        {
            let mut s = Supervisor::new(&mut rig, SafeState::Hold);
            assert_eq!(
                s.actuate(0, 0.0, ValveCommand { u: 0.3 }),
                Some(ValveCommand { u: 0.3 })
            );
            s.trip(1, 1e-3, RigError::new(ErrorKind::Limit, "x too far"));
            assert_eq!(s.actuate(1, 1e-3, ValveCommand { u: 0.5 }), None);
            assert_eq!(s.actuate(2, 2e-3, ValveCommand { u: 0.5 }), None);
            // A second fault does not overwrite the first.
            s.trip(3, 3e-3, RigError::new(ErrorKind::Timeout, "late"));
            assert_eq!(s.fault().unwrap().kind, ErrorKind::Limit);
            assert_eq!(s.fault().unwrap().tick, 1);
            s.reset().unwrap();
            assert!(s.fault().is_none());
            assert_eq!(
                s.actuate(4, 4e-3, ValveCommand { u: 0.1 }),
                Some(ValveCommand { u: 0.1 })
            );
        }
        assert_eq!(rig.writes, vec![(0, 0.3), (4, 0.1)]);
        // Safe at the trip (tick 1), every latched tick (1, 2), the second trip (3), and on drop.
        let ticks: Vec<u32> = rig.safes.iter().map(|s| s.0).collect();
        assert_eq!(ticks, vec![1, 1, 2, 3, u32::MAX]);
        assert!(rig.safes.iter().all(|s| s.1 == SafeState::Hold));
    }
}

#[cfg(test)]
mod channel_tests {
    use super::*;
    use crate::protocol::{DecodeEvent, Decoder, MAX_FRAME, encode};
    use crate::rig::tests::limits;
    use pneuflex_control::Sensors;
    use std::collections::VecDeque;

    /// A scripted two-channel board: queued samples in, every write kept as the bytes a serial link would
    /// carry.
    #[derive(Default)]
    struct Board {
        samples: VecDeque<Option<Vec<SiSample>>>,
        wire: Vec<u8>,
        seq: u8,
    }

    impl ChannelRig for Board {
        fn read(&mut self, _: f64) -> Result<Option<Vec<SiSample>>, RigError> {
            Ok(self.samples.pop_front().flatten())
        }
        fn write(&mut self, tick: u32, cmds: &[ChannelCommand]) -> Result<(), RigError> {
            let msg = valve_frame(tick, cmds).expect("1..=6 channels");
            let mut buf = [0u8; MAX_FRAME];
            let n = encode(self.seq, &msg, &mut buf);
            self.seq = self.seq.wrapping_add(1);
            self.wire.extend_from_slice(&buf[..n]);
            Ok(())
        }
        fn reset(&mut self) -> Result<(), RigError> {
            Ok(())
        }
    }

    /// The (tick, channels) of every frame on the wire, decoded by the protocol's own decoder.
    fn sent(wire: &[u8]) -> Vec<(u32, Vec<ChannelValve>)> {
        let mut out = Vec::new();
        Decoder::new().feed(wire, |e| match e {
            DecodeEvent::Frame(f) => match f.msg {
                Message::Valves(v) => out.push((v.tick, v.channels().to_vec())),
                m => panic!("unexpected {m:?}"),
            },
            e => panic!("unexpected {e:?}"),
        });
        out
    }

    fn sample(x: f64) -> SiSample {
        SiSample {
            sensors: Sensors {
                x,
                p_a: 3e5,
                p_b: 2e5,
                ..Sensors::default()
            },
            supply_pa: 6e5,
            ..SiSample::default()
        }
    }

    /// Two fingers: the left vents when safe, the right holds, and the right's stroke is shorter.
    fn fingers() -> Vec<Channel> {
        let cal = crate::rigfile::tests::calibration();
        let mut short = limits();
        short.position_m = [0.0, 0.02];
        vec![
            Channel {
                name: "left".into(),
                cal,
                limits: limits(),
                safe_state: SafeState::Vent,
            },
            Channel {
                name: "right".into(),
                cal,
                limits: short,
                safe_state: SafeState::Hold,
            },
        ]
    }

    const SAFE_BOTH: [ChannelValve; 2] = [
        ChannelValve {
            duty_q15: 0,
            mode: ValveMode::SafeVent,
        },
        ChannelValve {
            duty_q15: 0,
            mode: ValveMode::SafeHold,
        },
    ];

    #[test]
    fn a_fault_on_channel_1_puts_both_valves_safe_in_the_same_tick() {
        let mut board = Board::default();
        // Ticks 0-2 inside both channels' limits; at tick 3 the right finger reads 30 mm, past its 20 mm
        // (inside the left's range: each channel is checked against its own).
        for _ in 0..3 {
            board
                .samples
                .push_back(Some(vec![sample(0.01), sample(0.01)]));
        }
        board
            .samples
            .push_back(Some(vec![sample(0.03), sample(0.03)]));
        board
            .samples
            .push_back(Some(vec![sample(0.01), sample(0.01)]));
        let cmds = [ValveCommand { u: 0.3 }, ValveCommand { u: -0.2 }];
        {
            let mut sup = ChannelSupervisor::new(&mut board, fingers());
            for tick in 0..3 {
                assert!(sup.sense(tick, tick as f64 * 1e-3).is_some());
                assert!(sup.actuate(tick, tick as f64 * 1e-3, &cmds));
            }
            assert!(sup.sense(3, 3e-3).is_none());
            assert!(!sup.actuate(3, 3e-3, &cmds));
            let f = sup.fault().expect("latched");
            assert_eq!(
                (f.channel, f.fault.tick, f.fault.kind),
                (Some(1), 3, ErrorKind::Limit)
            );
            assert!(
                f.fault
                    .message
                    .starts_with("channel 1 (right): position x = 0.03 m"),
                "{}",
                f.fault.message
            );
            // Latched: the next tick is safe too, although its sample is fine.
            assert!(sup.sense(4, 4e-3).is_some());
            assert!(!sup.actuate(4, 4e-3, &cmds));
        }
        let frames = sent(&board.wire);
        let run = [
            ChannelValve {
                duty_q15: to_q15(0.3),
                mode: ValveMode::Run,
            },
            ChannelValve {
                duty_q15: to_q15(-0.2),
                mode: ValveMode::Run,
            },
        ];
        let want: Vec<(u32, Vec<ChannelValve>)> = [0, 1, 2]
            .map(|k| (k, run.to_vec()))
            .into_iter()
            // Tick 3: the trip's frame and the tick's own command, both safe for both valves; tick 4; drop.
            .chain([3, 3, 4, u32::MAX].map(|k| (k, SAFE_BOTH.to_vec())))
            .collect();
        assert_eq!(frames, want);
    }

    #[test]
    fn a_nan_command_on_channel_0_puts_both_valves_safe_in_that_tick() {
        let mut board = Board::default();
        {
            let mut sup = ChannelSupervisor::new(&mut board, fingers());
            assert!(sup.actuate(0, 0.0, &[ValveCommand { u: 0.1 }, ValveCommand { u: 0.1 }]));
            assert!(!sup.actuate(
                1,
                1e-3,
                &[ValveCommand { u: f64::NAN }, ValveCommand { u: 0.5 }]
            ));
            let f = sup.fault().unwrap();
            assert_eq!((f.channel, f.fault.kind), (Some(0), ErrorKind::NotANumber));
            // One channel's samples missing from a frame is the board's fault, no channel's.
            sup.reset().unwrap();
            board_samples(&mut sup, vec![sample(0.01)]);
            assert!(sup.sense(2, 2e-3).is_none());
            assert_eq!(sup.fault().unwrap().channel, None);
        }
        let frames = sent(&board.wire);
        assert_eq!(frames[1], (1, SAFE_BOTH.to_vec()));
        assert_eq!(frames[2], (2, SAFE_BOTH.to_vec()));
    }

    fn board_samples(sup: &mut ChannelSupervisor<&mut Board>, s: Vec<SiSample>) {
        sup.rig.samples.push_back(Some(s));
    }

    #[test]
    fn one_channel_goes_out_as_the_version_1_valve_frame() {
        let m = valve_frame(7, &[ChannelCommand::Safe(SafeState::Hold)]).unwrap();
        assert_eq!(
            m,
            Message::Valve(crate::protocol::ValvePayload {
                tick: 7,
                duty_q15: 0,
                mode: ValveMode::SafeHold
            })
        );
        assert_eq!(valve_frame(7, &[]), None);
    }
}
