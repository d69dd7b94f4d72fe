//! Several actuators on one board, both ends of the link (docs/protocol.md §6):
//! - [`ChannelBoard`], the emulated board: N one-channel [`Board`]s (each its own plant, environment, valve,
//!   ADC noise and injected faults: N independent 1-DOF plants) behind one link that speaks the N-channel
//!   frames. Each channel's board is the one-channel emulator, unchanged, fed through an in-memory link, so
//!   the channels behave exactly as the one-channel emulator does;
//! - [`SerialChannels`], the host driver: a [`ChannelRig`] that sends one Valves frame a tick and reads
//!   Samples frames, each channel converted to SI with its own calibration.

use std::sync::{Arc, Mutex};

use crate::emulator::{Board, EmulatorLog, MemLink};
use crate::error::{ErrorKind, RigError};
use crate::plant::{CoupledPlant, Detached, EmulatedPlant, ValveDrive};
use crate::protocol::{
    AppliedAllPayload, ChannelFaultPayload, ChannelSample, ChannelValve, ConfigPayload,
    DecodeEvent, Decoder, MAX_CHANNELS, MAX_FRAME, Message, SamplesPayload, ValvePayload, encode,
    fault_code, status,
};
use crate::rig::{Calibrated, RawSample, SiSample};
use crate::rigfile::Channel;
use crate::serial::Link;
use crate::supervisor::{ChannelCommand, ChannelRig, valve_frame};

/// Decodes every frame waiting on `link`.
fn drain<L: Link + ?Sized>(link: &mut L, decoder: &mut Decoder) -> Result<Vec<Message>, RigError> {
    let mut out = Vec::new();
    let mut rx = [0u8; 512];
    loop {
        let n = link.read_now(&mut rx)?;
        if n == 0 {
            return Ok(out);
        }
        decoder.feed(&rx[..n], |e| {
            if let DecodeEvent::Frame(f) = e {
                out.push(f.msg);
            }
        });
    }
}

fn send<L: Link + ?Sized>(link: &mut L, seq: &mut u8, msg: &Message) -> Result<(), RigError> {
    let mut buf = [0u8; MAX_FRAME];
    let n = encode(*seq, msg, &mut buf);
    *seq = seq.wrapping_add(1);
    link.write_all_bytes(&buf[..n])
}

/// One channel of a [`ChannelBoard`]: its one-channel board and the host end of the link to it.
struct Sub<P: EmulatedPlant> {
    board: Board<P, MemLink>,
    to_board: MemLink,
    decoder: Decoder,
    seq: u8,
    log: Arc<Mutex<EmulatorLog>>,
}

/// An emulated board with several channels (module docs).
pub struct ChannelBoard<P: EmulatedPlant, L: Link> {
    link: L,
    decoder: Decoder,
    tx_seq: u8,
    subs: Vec<Sub<P>>,
}

impl<P: EmulatedPlant, L: Link> ChannelBoard<P, L> {
    /// A board behind `link` whose channel i is `channels[i]` (an emulator and its log, as
    /// [`crate::emulator::Emulator::board`] makes them). `None` for no channels or more than
    /// [`MAX_CHANNELS`].
    pub fn new(
        link: L,
        channels: Vec<(crate::emulator::Emulator<P, MemLink>, MemLink)>,
    ) -> Option<Self>
    where
        P: 'static,
    {
        if channels.is_empty() || channels.len() > MAX_CHANNELS {
            return None;
        }
        let subs = channels
            .into_iter()
            .map(|(emulator, to_board)| {
                let log = Arc::new(Mutex::new(EmulatorLog::default()));
                Sub {
                    board: emulator.board(log.clone()),
                    to_board,
                    decoder: Decoder::new(),
                    seq: 0,
                    log,
                }
            })
            .collect();
        Some(Self {
            link,
            decoder: Decoder::new(),
            tx_seq: 0,
            subs,
        })
    }

    /// Channel `i`'s log (its valve commands as applied, its plant's truth).
    pub fn log(&self, i: usize) -> Option<EmulatorLog> {
        let l = self.subs.get(i)?.log.lock().ok()?;
        Some(l.clone())
    }

    /// One sample period at board time `now`: the host's frames to every channel (a Valves frame's slot i
    /// to channel i as a Valve; Config, Heartbeat and Reset to all), every channel's period, and their
    /// answers as one frame each: Samples, AppliedAll, one Heartbeat echo, one board Fault. Returns false
    /// once the link or a channel has stopped.
    pub fn step(&mut self, now: f64) -> Result<bool, RigError> {
        self.step_with(now, |subs, now| {
            subs.iter_mut().all(|sub| sub.board.step(now))
        })
    }

    /// [`Self::step`] with the channels' periods run by `periods` (each channel's own plant, or one mechanism
    /// under every channel's valve); false from it: a channel has stopped.
    fn step_with(
        &mut self,
        now: f64,
        periods: impl FnOnce(&mut [Sub<P>], f64) -> bool,
    ) -> Result<bool, RigError> {
        for msg in drain(&mut self.link, &mut self.decoder)? {
            match msg {
                Message::Valves(v) if usize::from(v.n) == self.subs.len() => {
                    for (sub, c) in self.subs.iter_mut().zip(v.channels()) {
                        let one = Message::Valve(ValvePayload {
                            tick: v.tick,
                            duty_q15: c.duty_q15,
                            mode: c.mode,
                        });
                        send(&mut sub.to_board, &mut sub.seq, &one)?;
                    }
                }
                Message::Config(_) | Message::Heartbeat(_) | Message::Reset(_) => {
                    for sub in &mut self.subs {
                        send(&mut sub.to_board, &mut sub.seq, &msg)?;
                    }
                }
                // A Valves frame for another number of channels, or a one-channel Valve: not this board's.
                _ => {}
            }
        }
        if !periods(&mut self.subs, now) {
            return Ok(false);
        }
        let mut out: Vec<Vec<Message>> = Vec::with_capacity(self.subs.len());
        for sub in &mut self.subs {
            out.push(drain(&mut sub.to_board, &mut sub.decoder)?);
        }
        let n = self.subs.len();
        let pick = |i: usize, f: fn(&Message) -> bool| -> Vec<Message> {
            out[i].iter().copied().filter(&f).collect()
        };
        let mut frames = Vec::new();
        // Every channel hears the same host, so its echoes and its watchdog agree: channel 0's stand for all.
        frames.extend(pick(0, |m| matches!(m, Message::Heartbeat(_))));
        for m in pick(0, |m| matches!(m, Message::Fault { .. })) {
            if let Message::Fault { code, detail } = m {
                frames.push(if code == fault_code::HOST_SILENT {
                    m
                } else {
                    Message::ChannelFault(ChannelFaultPayload {
                        channel: 0,
                        code,
                        detail,
                    })
                });
            }
        }
        let per_channel = |f: fn(&Message) -> bool| (0..n).map(|i| pick(i, f)).collect::<Vec<_>>();
        let applied = per_channel(|m| matches!(m, Message::Applied(_)));
        for k in 0..applied[0].len() {
            let mut ch = [ChannelValve::default(); MAX_CHANNELS];
            let mut first = None;
            for (i, a) in applied.iter().enumerate() {
                if let Some(Message::Applied(a)) = a.get(k) {
                    ch[i] = ChannelValve {
                        duty_q15: a.duty_q15,
                        mode: a.mode,
                    };
                    first.get_or_insert(*a);
                }
            }
            if let Some(a) =
                first.and_then(|a| AppliedAllPayload::new(a.board_time_us, a.tick, &ch[..n]))
            {
                frames.push(Message::AppliedAll(a));
            }
        }
        let samples = per_channel(|m| matches!(m, Message::Sample(_)));
        if let Some(Some(Message::Sample(s0))) = samples.first().map(|s| s.last()) {
            let mut ch = [ChannelSample::default(); MAX_CHANNELS];
            let mut complete = true;
            for (i, s) in samples.iter().enumerate() {
                match s.last() {
                    Some(Message::Sample(s)) => ch[i] = ChannelSample::from(s),
                    _ => complete = false,
                }
            }
            if complete
                && let Some(p) = SamplesPayload::new(s0.board_time_us, s0.last_cmd_tick, &ch[..n])
            {
                frames.push(Message::Samples(p));
            }
        }
        for m in &frames {
            match send(&mut self.link, &mut self.tx_seq, m) {
                Ok(()) => {}
                Err(e) if e.kind() == ErrorKind::Timeout => {}
                Err(e) => return Err(e),
            }
        }
        Ok(true)
    }
}

impl<L: Link> ChannelBoard<Detached, L> {
    /// A board whose channels drive one mechanism, `plant` (a gripper's fingers on one part): channel i's
    /// board is `channels[i]` as in [`Self::new`], with a [`Detached`] plant. `None` for no channels, more
    /// than [`MAX_CHANNELS`], or a plant of another number of channels.
    pub fn coupled(
        link: L,
        plant: Box<dyn CoupledPlant>,
        channels: Vec<(crate::emulator::Emulator<Detached, MemLink>, MemLink)>,
    ) -> Option<CoupledBoard<L>> {
        if plant.channels() != channels.len() {
            return None;
        }
        let board = Self::new(link, channels)?;
        let drives = vec![ValveDrive::Vent; plant.channels()];
        Some(CoupledBoard {
            board,
            plant,
            drives,
        })
    }
}

/// A board of several channels on one mechanism ([`ChannelBoard::coupled`]). Each period every channel's
/// board takes in the host's frames and its faults, then the mechanism advances under every channel's valve
/// at once, then each channel samples its own actuator and answers: the order of a one-channel board's
/// period, with the channels' physics joined.
pub struct CoupledBoard<L: Link> {
    board: ChannelBoard<Detached, L>,
    plant: Box<dyn CoupledPlant>,
    drives: Vec<ValveDrive>,
}

impl<L: Link> CoupledBoard<L> {
    /// Channel `i`'s log (its valve commands as applied, its actuator's truth).
    pub fn log(&self, i: usize) -> Option<EmulatorLog> {
        self.board.log(i)
    }

    /// Channel `i`'s log itself, shared (for a handle that watches the board run).
    pub fn log_handle(&self, i: usize) -> Option<Arc<Mutex<EmulatorLog>>> {
        self.board.subs.get(i).map(|s| s.log.clone())
    }

    /// One sample period at board time `now` (see [`ChannelBoard::step`]).
    pub fn step(&mut self, now: f64) -> Result<bool, RigError> {
        let (plant, drives) = (&mut self.plant, &mut self.drives);
        self.board.step_with(now, |subs, now| {
            coupled_period(subs, plant.as_mut(), drives, now)
        })
    }
}

/// One period of the channels of a [`CoupledBoard`]: false once a channel has stopped.
fn coupled_period(
    subs: &mut [Sub<Detached>],
    plant: &mut dyn CoupledPlant,
    drives: &mut [ValveDrive],
    now: f64,
) -> bool {
    let mut periods = Vec::with_capacity(subs.len());
    for sub in subs.iter_mut() {
        match sub.board.begin(now) {
            Some(p) => periods.push(p),
            None => return false,
        }
    }
    // What the channels' boards asked of the plant: a new run (every channel hears the same Config), then a
    // channel's supply lost.
    let mut restart = false;
    for sub in subs.iter_mut() {
        restart |= std::mem::take(&mut sub.board.plant_mut().restart_asked);
    }
    if restart {
        plant.restart();
    }
    for (i, sub) in subs.iter_mut().enumerate() {
        if let Some(p) = sub.board.plant_mut().supply_asked.take() {
            plant.set_supply_pa(i, p);
        }
        drives[i] = sub.board.valve_drive();
    }
    // Every channel hears the same first Run: channel 0's clock stands for all.
    let (h, substeps) = subs[0].board.substep();
    if subs[0].board.running() {
        let t0 = periods[0].t_now();
        for k in 0..substeps {
            plant.step(t0 + k as f64 * h, drives, h);
        }
    }
    for (i, (sub, period)) in subs.iter_mut().zip(&periods).enumerate() {
        let ps = plant.sample(i);
        sub.board.plant_mut().state = ps;
        if !sub.board.end_period(now, period, &ps, plant.load_n(i)) {
            return false;
        }
    }
    true
}

impl<L: Link> crate::emulator::Stepped for CoupledBoard<L> {
    fn period_s(&self) -> f64 {
        self.board.subs[0].board.period_s()
    }

    /// A link error stops the board, as a failed link stops a one-channel board.
    fn step_period(&mut self, now: f64) -> bool {
        self.step(now).unwrap_or(false)
    }
}

/// The host driver of a board with several channels (module docs).
pub struct SerialChannels<L: Link> {
    link: L,
    decoder: Decoder,
    tx_seq: u8,
    cals: Vec<Calibrated<()>>,
    newest: Option<SamplesPayload>,
    board_fault: Option<String>,
    /// Samples frames received.
    pub samples: u64,
}

impl<L: Link> SerialChannels<L> {
    /// A driver of `channels` (the rig file's, in order) behind `link`; `velocity_cutoff_hz` as
    /// `loop.velocity_cutoff_hz`.
    pub fn new(link: L, channels: &[Channel], velocity_cutoff_hz: f64) -> Self {
        Self {
            link,
            decoder: Decoder::new(),
            tx_seq: 0,
            cals: channels
                .iter()
                .map(|c| Calibrated::new((), c.cal, velocity_cutoff_hz))
                .collect(),
            newest: None,
            board_fault: None,
            samples: 0,
        }
    }

    /// Sends the board its configuration (the board's own safe state is channel 0's: every channel's valve
    /// goes safe together, each to the state its one-channel board was configured with).
    pub fn configure(&mut self, cfg: ConfigPayload) -> Result<(), RigError> {
        send(&mut self.link, &mut self.tx_seq, &Message::Config(cfg))
    }

    fn pump(&mut self) -> Result<(), RigError> {
        for m in drain(&mut self.link, &mut self.decoder)? {
            match m {
                Message::Samples(s) => {
                    self.samples += 1;
                    if s.channels()
                        .iter()
                        .any(|c| c.status & status::BOARD_FAULT != 0)
                    {
                        self.board_fault
                            .get_or_insert_with(|| "the board reports a latched fault".into());
                    }
                    self.newest = Some(s);
                }
                Message::Fault { code, detail } => {
                    self.board_fault.get_or_insert_with(|| {
                        format!("board fault 0x{code:02X} (detail {detail})")
                    });
                }
                Message::ChannelFault(f) => {
                    self.board_fault.get_or_insert_with(|| {
                        format!(
                            "channel {} fault 0x{:02X} (detail {})",
                            f.channel, f.code, f.detail
                        )
                    });
                }
                _ => {}
            }
        }
        Ok(())
    }
}

impl<L: Link> ChannelRig for SerialChannels<L> {
    fn read(&mut self, now_s: f64) -> Result<Option<Vec<SiSample>>, RigError> {
        self.pump()?;
        if let Some(m) = &self.board_fault {
            return Err(RigError::new(ErrorKind::BoardFault, m.clone()));
        }
        let Some(s) = self.newest.take() else {
            return Ok(None);
        };
        if s.channels().len() != self.cals.len() {
            return Err(RigError::new(
                ErrorKind::BoardFault,
                format!(
                    "the board sent {} channels, the rig file has {}",
                    s.channels().len(),
                    self.cals.len()
                ),
            ));
        }
        let board_time_s = f64::from(s.board_time_us) * 1e-6;
        Ok(Some(
            self.cals
                .iter_mut()
                .enumerate()
                .map(|(i, cal)| {
                    let raw = s.sample(i).unwrap_or_default();
                    cal.convert(&RawSample {
                        host_time_s: now_s,
                        board_time_s,
                        raw,
                    })
                })
                .collect(),
        ))
    }

    fn write(&mut self, tick: u32, cmds: &[ChannelCommand]) -> Result<(), RigError> {
        let msg = valve_frame(tick, cmds).ok_or_else(|| {
            RigError::new(
                ErrorKind::Io,
                format!(
                    "{} channels: a frame carries 1..={MAX_CHANNELS}",
                    cmds.len()
                ),
            )
        })?;
        send(&mut self.link, &mut self.tx_seq, &msg)
    }

    fn reset(&mut self) -> Result<(), RigError> {
        self.board_fault = None;
        send(
            &mut self.link,
            &mut self.tx_seq,
            &Message::Reset(crate::protocol::RESET_MAGIC),
        )
    }
}
