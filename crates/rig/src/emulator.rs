//! The emulated rig: a plant run in real time behind a pseudo-terminal (or a given serial port), speaking the
//! I/O board's protocol, with fault injection. It is the firmware's behaviour in host code: stream samples at
//! the configured rate, apply valve commands, echo heartbeats, go to its safe state when the host falls silent.

use std::collections::VecDeque;
use std::fs::File;
use std::io::{Read, Write};
use std::os::fd::{AsRawFd, OwnedFd};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::clock::SimClock;
use crate::error::{ErrorKind, RigError};
use crate::plant::{EmulatedPlant, Environment, PlantSample, ValveDrive};
use crate::protocol::{
    AppliedPayload, DecodeEvent, Decoder, MAX_FRAME, Message, RESET_MAGIC, SamplePayload,
    ValveMode, encode, fault_code, from_q15, status,
};
use crate::rigfile::{Calibration, EmulatorConfig, InjectedFault};
use crate::serial::Link;

/// The master side of a pseudo-terminal pair; the slave is kept open so that reads never see a hang-up
/// before the host connects.
pub struct PtyLink {
    master: File,
    _slave: OwnedFd,
    /// Path of the slave device the host opens.
    pub path: PathBuf,
}

impl PtyLink {
    /// Opens a pty pair in raw mode with a non-blocking master.
    pub fn open() -> Result<Self, RigError> {
        use nix::fcntl::{FcntlArg, OFlag, fcntl};
        use nix::sys::termios::{SetArg, cfmakeraw, tcgetattr, tcsetattr};
        let io = |what: &str, e: nix::Error| RigError::new(ErrorKind::Io, format!("{what}: {e}"));
        let pty = nix::pty::openpty(None, None).map_err(|e| io("openpty", e))?;
        // Raw mode on the slave: no echo, no line editing, 8-bit clean.
        let mut t = tcgetattr(&pty.slave).map_err(|e| io("tcgetattr", e))?;
        cfmakeraw(&mut t);
        tcsetattr(&pty.slave, SetArg::TCSANOW, &t).map_err(|e| io("tcsetattr", e))?;
        let flags = fcntl(&pty.master, FcntlArg::F_GETFL).map_err(|e| io("fcntl", e))?;
        fcntl(
            &pty.master,
            FcntlArg::F_SETFL(OFlag::from_bits_truncate(flags) | OFlag::O_NONBLOCK),
        )
        .map_err(|e| io("fcntl", e))?;
        let path = std::fs::read_link(format!("/proc/self/fd/{}", pty.slave.as_raw_fd()))
            .map_err(|e| RigError::new(ErrorKind::Io, format!("pty path: {e}")))?;
        Ok(Self {
            master: File::from(pty.master),
            _slave: pty.slave,
            path,
        })
    }
}

impl Link for PtyLink {
    fn read_now(&mut self, buf: &mut [u8]) -> Result<usize, RigError> {
        match self.master.read(buf) {
            Ok(n) => Ok(n),
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => Ok(0),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => Ok(0),
            Err(e) => Err(RigError::new(ErrorKind::LinkLost, format!("pty read: {e}"))),
        }
    }

    fn write_all_bytes(&mut self, bytes: &[u8]) -> Result<(), RigError> {
        match self.master.write(bytes) {
            Ok(n) if n == bytes.len() => Ok(()),
            // A UART drops what does not fit; so does the emulated board.
            Ok(_) => Err(RigError::new(ErrorKind::Timeout, "pty buffer full")),
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                Err(RigError::new(ErrorKind::Timeout, "pty buffer full"))
            }
            Err(e) => Err(RigError::new(
                ErrorKind::LinkLost,
                format!("pty write: {e}"),
            )),
        }
    }
}

/// Records kept in each log vector at most (10 min at 1 kHz): a long `pneuflex rig emulate` must not grow
/// without bound.
pub const LOG_CAP: usize = 600_000;

/// One valve command as the emulated board received it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommandRecord {
    /// The host's tick number.
    pub tick: u32,
    /// Run or safe.
    pub mode: ValveMode,
    /// Duty, Q15.
    pub duty_q15: i16,
    /// Emulator experiment time when applied, s.
    pub t: f64,
}

/// The plant's truth at one sample, for tests and plots.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TruthRecord {
    /// Experiment time, s.
    pub t: f64,
    /// Position, m.
    pub x: f64,
    /// Contact force, N.
    pub f_e: f64,
}

/// What the emulator did, shared with whoever started it.
#[derive(Clone, Debug, Default)]
pub struct EmulatorLog {
    /// Every valve command applied, in order.
    pub commands: Vec<CommandRecord>,
    /// The plant's truth per sample period after the run started.
    pub truth: Vec<TruthRecord>,
    /// Samples sent.
    pub samples_sent: u64,
    /// Frames that did not fit in the output buffer.
    pub tx_dropped: u64,
    /// Times the board's own watchdog tripped.
    pub board_watchdog_trips: u64,
    /// Why the emulator stopped, if it stopped by itself.
    pub ended: Option<String>,
    /// Runs started: Config frames received (each one restarts the plant, see [`Board::step`]).
    pub runs: u64,
    /// Where each run starts in `truth` (the index of its first record), one per run.
    pub run_starts: Vec<usize>,
}

/// Runs `board` in the calling thread, one step per sample period of the wall clock, until `stop` is set or
/// the board stops. The board's clock is its own sample tick, k periods, as a board's timer is: when this
/// thread is descheduled it catches up, and its late samples read like a slow link, each stamped with the
/// time its physics reached (what an exact replay needs: docs/protocol.md, 0x07).
pub fn run_real_time<B: Stepped + ?Sized>(board: &mut B, stop: &AtomicBool) {
    let period_s = board.period_s();
    let period = Duration::from_secs_f64(period_s);
    let start = Instant::now();
    let mut k: u64 = 0;
    while !stop.load(Ordering::Relaxed) {
        let deadline = start + period.mul_f64(k as f64);
        let now = Instant::now();
        if deadline > now {
            std::thread::sleep(deadline - now);
        }
        let board_time = k as f64 * period_s;
        k += 1;
        if !board.step_period(board_time) {
            break;
        }
    }
}

/// A running emulator.
pub struct EmulatorHandle {
    /// The pty path for the host (`None` when serving a given port).
    pub path: Option<PathBuf>,
    stop: Arc<AtomicBool>,
    log: Arc<Mutex<EmulatorLog>>,
    thread: Option<JoinHandle<()>>,
}

impl EmulatorHandle {
    /// Runs `board` on its own thread in real time ([`run_real_time`]) until stopped; `log` is the board's
    /// (the first channel's, for a board of several), `path` the pty the host opens.
    pub fn spawn<B: Stepped + 'static>(
        mut board: B,
        path: Option<PathBuf>,
        log: Arc<Mutex<EmulatorLog>>,
    ) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let s = stop.clone();
        let thread = std::thread::Builder::new()
            .name("pneuflex-emulator".into())
            .spawn(move || run_real_time(&mut board, &s))
            .ok();
        Self {
            path,
            stop,
            log,
            thread,
        }
    }

    /// A snapshot of the log.
    pub fn log(&self) -> EmulatorLog {
        self.log.lock().map(|l| l.clone()).unwrap_or_default()
    }

    /// Runs started so far (host connections), without copying the log.
    pub fn runs(&self) -> u64 {
        self.log.lock().map_or(0, |l| l.runs)
    }

    /// Whether the emulator thread has finished.
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(|t| t.is_finished())
    }

    /// Stops the emulator and returns its log.
    pub fn stop(mut self) -> EmulatorLog {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        self.log()
    }
}

impl Drop for EmulatorHandle {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A tiny deterministic noise source (xorshift64*).
struct Noise(u64);

impl Noise {
    /// The noise of `seed` (xorshift needs an odd, non-zero state).
    fn seeded(seed: u64) -> Self {
        Self(seed.wrapping_mul(2).wrapping_add(0x9E37_79B9_7F4A_7C15) | 1)
    }

    fn next(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform integer in [-a, a].
    fn counts(&mut self, a: u16) -> i64 {
        if a == 0 {
            return 0;
        }
        (self.next() % (2 * u64::from(a) + 1)) as i64 - i64::from(a)
    }
}

fn add_noise(c: u16, n: i64, full: u16) -> u16 {
    (i64::from(c) + n).clamp(0, i64::from(full)) as u16
}

/// The emulated board and plant.
pub struct Emulator<P: EmulatedPlant, L: Link> {
    plant: P,
    link: Option<L>,
    cal: Calibration,
    cfg: EmulatorConfig,
    env: Environment,
}

impl<P: EmulatedPlant + 'static, L: Link + 'static> Emulator<P, L> {
    /// An emulator of `plant` behind `link`, with the rig's calibration (inverted to make counts).
    pub fn new(plant: P, link: L, cal: Calibration, cfg: EmulatorConfig) -> Self {
        // No spring: a board whose plant is a mechanism (its contacts are the environment); a one-actuator
        // emulator without one is refused where it is made (`session::emulated_plant`).
        let env = cfg
            .environment
            .as_ref()
            .map_or(Environment::NONE, Environment::from_config);
        Self {
            plant,
            link: Some(link),
            cal,
            cfg,
            env,
        }
    }

    /// Runs the emulator on its own thread, in real time, until stopped.
    pub fn spawn(self, path: Option<PathBuf>) -> EmulatorHandle {
        let log = Arc::new(Mutex::new(EmulatorLog::default()));
        EmulatorHandle::spawn(self.board(log.clone()), path, log)
    }

    /// Runs in the calling thread in real time ([`run_real_time`]) until `stop` is set or the link closes.
    pub fn run(self, stop: &AtomicBool, log: Arc<Mutex<EmulatorLog>>) {
        run_real_time(&mut self.board(log), stop);
    }

    /// The board, to be stepped by the caller.
    pub fn board(self, log: Arc<Mutex<EmulatorLog>>) -> Board<P, L> {
        let period_s = 1.0 / self.cfg.sample_rate_hz;
        let substeps = (period_s / self.cfg.plant_dt_s).round().max(1.0) as usize;
        let noise = Noise::seeded(self.cfg.seed);
        Board {
            plant: self.plant,
            link: self.link,
            cal: self.cal,
            cfg: self.cfg,
            env: self.env,
            log,
            period_s,
            substeps,
            h: period_s / substeps as f64,
            noise,
            decoder: Decoder::new(),
            tx_seq: 0,
            drive_mode: ValveMode::SafeVent,
            duty_q15: 0,
            last_tick: 0,
            safe_mode: ValveMode::SafeVent,
            board_wd_s: None,
            last_host_msg_s: 0.0,
            board_fault: false,
            wd_tripped: false,
            run_start_s: None,
            frozen: None,
            supply_lost: false,
            pending: Vec::with_capacity(8),
            echoes: Vec::with_capacity(8),
            finished: false,
            delay_line: VecDeque::new(),
        }
    }
}

/// One period's state between [`Board::begin`] and [`Board::end_period`].
pub(crate) struct Period {
    /// Experiment time at the period's start, s (0 before the run starts).
    t_now: f64,
    /// A heartbeat echo and a watchdog fault to send.
    replies: [Option<Message>; 2],
    stalled: bool,
    dropping: bool,
    corrupt: bool,
    stuck: bool,
}

impl Period {
    /// Experiment time at the period's start, s.
    pub(crate) fn t_now(&self) -> f64 {
        self.t_now
    }
}

/// The firmware's state: one [`Board::step`] per sample period at board time `now` (s since power-up).
/// Time is passed in, so the same board runs in real time ([`Emulator::spawn`]) or in lockstep with a
/// simulated clock ([`lockstep`]).
pub struct Board<P: EmulatedPlant, L: Link> {
    plant: P,
    link: Option<L>,
    cal: Calibration,
    cfg: EmulatorConfig,
    env: Environment,
    log: Arc<Mutex<EmulatorLog>>,
    period_s: f64,
    substeps: usize,
    h: f64,
    noise: Noise,
    decoder: Decoder,
    tx_seq: u8,
    drive_mode: ValveMode,
    duty_q15: i16,
    last_tick: u32,
    safe_mode: ValveMode,
    board_wd_s: Option<f64>,
    last_host_msg_s: f64,
    board_fault: bool,
    wd_tripped: bool,
    run_start_s: Option<f64>,
    frozen: Option<SamplePayload>,
    supply_lost: bool,
    pending: Vec<Message>,
    /// Applied echoes of this period, sent before its Sample.
    echoes: Vec<Message>,
    finished: bool,
    /// Run commands on their way to the valve (`transport_delay_s`, whole sample periods).
    delay_line: VecDeque<ValveDrive>,
}

impl<P: EmulatedPlant, L: Link> Board<P, L> {
    /// The sample period, s.
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    fn end(&mut self, why: String) {
        self.finished = true;
        if let Ok(mut l) = self.log.lock() {
            l.ended = Some(why);
        }
    }

    /// One sample period at board time `now`: receive, board watchdog, physics, sample, transmit.
    /// Returns false once the board has stopped (link closed or failed).
    pub fn step(&mut self, now: f64) -> bool {
        let Some(period) = self.begin(now) else {
            return false;
        };
        let drive = self.valve_drive();
        if self.running() {
            for i in 0..self.substeps {
                let ts = period.t_now + i as f64 * self.h;
                let x = self.plant.sample().x;
                let f_e = self.env.force(ts, x);
                // f_ext on the flange = -f_e.
                self.plant.step(drive, -f_e, self.h);
            }
        }
        let ps = self.plant.sample();
        let f_e = self.env.force(period.t_now, ps.x);
        self.end_period(now, &period, &ps, f_e)
    }

    /// The board's part of a period before the physics: injected faults, the host's frames, the board's
    /// watchdog. `None` once the board has stopped. A board of several channels on one mechanism
    /// ([`crate::channel_board::ChannelBoard::coupled`]) runs this on every channel, then the mechanism under
    /// every channel's [`Self::valve_drive`], then [`Self::end_period`] on every channel.
    pub(crate) fn begin(&mut self, now: f64) -> Option<Period> {
        if self.finished {
            return None;
        }
        // Experiment time runs from the first Run command.
        let t = self.run_start_s.map(|s| now - s);
        let active = |f: &InjectedFault| -> bool {
            let Some(t) = t else { return false };
            match *f {
                InjectedFault::Stall { at_s, for_s } => t >= at_s && t < at_s + for_s,
                InjectedFault::DropFrames { at_s }
                | InjectedFault::CorruptCrc { at_s }
                | InjectedFault::StuckSensor { at_s }
                | InjectedFault::SupplyLoss { at_s }
                | InjectedFault::CloseLink { at_s } => t >= at_s,
            }
        };
        let faults = &self.cfg.faults;
        let any = |pred: fn(&InjectedFault) -> bool| faults.iter().any(|f| pred(f) && active(f));
        let stalled = any(|f| matches!(f, InjectedFault::Stall { .. }));
        let dropping = any(|f| matches!(f, InjectedFault::DropFrames { .. }));
        let corrupt = any(|f| matches!(f, InjectedFault::CorruptCrc { .. }));
        let stuck = any(|f| matches!(f, InjectedFault::StuckSensor { .. }));
        let close = any(|f| matches!(f, InjectedFault::CloseLink { .. }));
        if !self.supply_lost && any(|f| matches!(f, InjectedFault::SupplyLoss { .. })) {
            self.supply_lost = true;
            self.plant.set_supply_pa(self.cal.atmosphere_pa);
        }
        if close && self.link.is_some() {
            self.link = None;
            self.end("link closed by fault injection".into());
            return None;
        }

        if !stalled && !self.receive() {
            return None;
        }
        let mut replies: [Option<Message>; 2] = [None, None];
        if stalled {
            // A stalled firmware runs nothing, its watchdog included; the host's silence is not its doing.
            self.last_host_msg_s = now;
        }
        for msg in std::mem::take(&mut self.pending) {
            self.last_host_msg_s = now;
            if let Some(reply) = self.handle(msg, now) {
                replies[0] = Some(reply);
            }
        }
        if !stalled {
            replies[1] = self.board_watchdog(now);
        }
        Some(Period {
            t_now: t.unwrap_or(0.0),
            replies,
            stalled,
            dropping,
            corrupt,
            stuck,
        })
    }

    /// Whether a run is under way (the plant moves only then; before the first Run command it rests).
    pub(crate) fn running(&self) -> bool {
        self.run_start_s.is_some()
    }

    /// The plant's integration step within a period, s, and the steps per period.
    pub(crate) fn substep(&self) -> (f64, usize) {
        (self.h, self.substeps)
    }

    /// The board's plant (a channel of a coupled board holds a [`crate::plant::Detached`] one).
    pub(crate) fn plant_mut(&mut self) -> &mut P {
        &mut self.plant
    }

    /// The board's part of a period after the physics: the truth logged, the sample with its noise, the
    /// frames sent (none while stalled). False once the link is gone or failed.
    pub(crate) fn end_period(
        &mut self,
        now: f64,
        period: &Period,
        ps: &PlantSample,
        f_e: f64,
    ) -> bool {
        if self.running()
            && let Ok(mut l) = self.log.lock()
            && l.truth.len() < LOG_CAP
        {
            l.truth.push(TruthRecord {
                t: period.t_now,
                x: ps.x,
                f_e,
            });
        }
        let sample = self.sample_payload(now, ps, f_e, period.stuck);
        if period.stalled {
            return true;
        }
        self.transmit(&period.replies, sample, period.dropping, period.corrupt)
    }

    /// Reads what the host sent into `pending`; false once the link failed (the board has stopped).
    fn receive(&mut self) -> bool {
        if let Some(link) = self.link.as_mut() {
            let mut rx = [0u8; 512];
            loop {
                match link.read_now(&mut rx) {
                    Ok(0) => break,
                    Ok(n) => {
                        let pending = &mut self.pending;
                        self.decoder.feed(&rx[..n], |ev| {
                            if let DecodeEvent::Frame(f) = ev {
                                pending.push(f.msg);
                            }
                        })
                    }
                    Err(e) => {
                        self.end(e.to_string());
                        return false;
                    }
                }
            }
        }
        true
    }

    /// Acts on one message from the host; a heartbeat is answered (the reply returned).
    fn handle(&mut self, msg: Message, now: f64) -> Option<Message> {
        match msg {
            Message::Valve(v) => {
                if self.run_start_s.is_none() && v.mode == ValveMode::Run {
                    self.run_start_s = Some(now);
                }
                // A latched board fault keeps the valve safe until Reset.
                if !self.board_fault {
                    self.drive_mode = v.mode;
                    self.duty_q15 = v.duty_q15;
                }
                self.last_tick = v.tick;
                // The echo of what the valve now does, by the samples' clock (docs/protocol.md, 0x07).
                self.echoes.push(Message::Applied(AppliedPayload {
                    board_time_us: board_time_us(now),
                    tick: v.tick,
                    duty_q15: self.duty_q15,
                    mode: self.drive_mode,
                }));
                if let Ok(mut l) = self.log.lock()
                    && l.commands.len() < LOG_CAP
                {
                    l.commands.push(CommandRecord {
                        tick: v.tick,
                        mode: self.drive_mode,
                        duty_q15: self.duty_q15,
                        t: self.run_start_s.map_or(0.0, |s| now - s),
                    });
                }
            }
            Message::Heartbeat(c) => return Some(Message::Heartbeat(c)),
            Message::Config(c) => {
                // A host connecting configures the board first (docs/protocol.md, handshake): a new run.
                self.new_run();
                self.safe_mode = c.safe_mode;
                self.board_wd_s = (c.watchdog_ms > 0).then(|| f64::from(c.watchdog_ms) * 1e-3);
            }
            Message::Reset(m) if m == RESET_MAGIC => {
                self.board_fault = false;
                self.wd_tripped = false;
            }
            _ => {}
        }
        None
    }

    /// A new run starts from the scene's initial state, whatever ran before: the plant as it was made (position,
    /// chambers, supply), experiment time (stiffness change, injected faults) from the next first Run command,
    /// the valve as at power-up, the sensor noise from its seed. A latched board fault stays until Reset
    /// (docs/protocol.md); the board's clock runs on.
    fn new_run(&mut self) {
        self.plant.restart();
        self.run_start_s = None;
        self.supply_lost = false;
        self.frozen = None;
        self.delay_line.clear();
        self.drive_mode = ValveMode::SafeVent;
        self.duty_q15 = 0;
        self.last_tick = 0;
        self.noise = Noise::seeded(self.cfg.seed);
        if let Ok(mut l) = self.log.lock() {
            l.runs += 1;
            let at = l.truth.len();
            l.run_starts.push(at);
        }
    }

    /// The board's own watchdog: a silent host (or a stalled board, once it wakes) -> safe state, and the
    /// fault to report.
    fn board_watchdog(&mut self, now: f64) -> Option<Message> {
        if let Some(wd) = self.board_wd_s
            && self.run_start_s.is_some()
            && !self.board_fault
            && now - self.last_host_msg_s > wd
        {
            self.board_fault = true;
            self.wd_tripped = true;
            self.drive_mode = self.safe_mode;
            self.duty_q15 = 0;
            if let Ok(mut l) = self.log.lock() {
                l.board_watchdog_trips += 1;
            }
            return Some(Message::Fault {
                code: fault_code::HOST_SILENT,
                detail: (wd * 1e3).round().min(f64::from(u16::MAX)) as u16,
            });
        }
        None
    }

    /// What the valve does this period: the latest command, a run command after the transport delay (a safe
    /// state at once).
    pub(crate) fn valve_drive(&mut self) -> ValveDrive {
        let drive = match self.drive_mode {
            ValveMode::Run => ValveDrive::Run(from_q15(self.duty_q15)),
            ValveMode::SafeVent => ValveDrive::Vent,
            ValveMode::SafeHold => ValveDrive::Hold,
        };
        // Transport delay: a run command reaches the valve `transport_delay_s` later (until the first one
        // arrives the valve keeps its power-up state, vented). A safe state is the board's own: at once.
        let delay_periods = (self.cfg.transport_delay_s / self.period_s).round() as usize;
        match drive {
            ValveDrive::Run(_) if delay_periods > 0 && self.run_start_s.is_some() => {
                self.delay_line.push_back(drive);
                if self.delay_line.len() > delay_periods {
                    self.delay_line.pop_front().unwrap_or(ValveDrive::Vent)
                } else {
                    ValveDrive::Vent
                }
            }
            ValveDrive::Run(_) => drive,
            _ => {
                self.delay_line.clear();
                drive
            }
        }
    }

    /// The sample the board sends: the plant's state in counts with the ADC's noise (frozen by a stuck
    /// sensor fault), and the board's status.
    fn sample_payload(
        &mut self,
        now: f64,
        ps: &PlantSample,
        f_e: f64,
        stuck: bool,
    ) -> SamplePayload {
        let full = |c: &crate::rigfile::LinearChannel| c.full_scale() as u16;
        let c = &self.cal;
        let noise = &mut self.noise;
        let (ch1, chb) = c.pressure_counts(ps.p_a, ps.p_b);
        let ch1_full = match c.channel_a {
            crate::rigfile::ChannelA::Chamber(ch) | crate::rigfile::ChannelA::Differential(ch) => {
                full(&ch)
            }
        };
        let a = self.cfg.adc_noise_counts;
        let mut sample = SamplePayload {
            board_time_us: board_time_us(now),
            last_cmd_tick: self.last_tick,
            position: add_noise(c.position.from_si(ps.x), noise.counts(a), full(&c.position)),
            p_a: add_noise(ch1, noise.counts(a), ch1_full),
            p_b: add_noise(chb, noise.counts(a), full(&c.pressure_b)),
            p_supply: add_noise(
                c.supply.from_si(ps.supply_pa - c.atmosphere_pa),
                noise.counts(a),
                full(&c.supply),
            ),
            load: c.load_from_si(f_e) + noise.counts(a) as i32,
            duty_q15: self.duty_q15,
            status: 0,
        };
        if stuck {
            let f = *self.frozen.get_or_insert(sample);
            sample.position = f.position;
            sample.p_a = f.p_a;
            sample.p_b = f.p_b;
            sample.p_supply = f.p_supply;
            sample.load = f.load;
        }
        sample.status = match self.drive_mode {
            ValveMode::Run => 0,
            ValveMode::SafeVent => status::SAFE,
            ValveMode::SafeHold => status::SAFE | status::SAFE_HOLD,
        } | if self.board_fault {
            status::BOARD_FAULT
        } else {
            0
        } | if self.wd_tripped { status::WATCHDOG } else { 0 };
        sample
    }

    /// Sends the replies, the valve echoes and the sample (unless frames are dropped); false once the link
    /// is gone or failed.
    fn transmit(
        &mut self,
        replies: &[Option<Message>; 2],
        sample: SamplePayload,
        dropping: bool,
        corrupt: bool,
    ) -> bool {
        let Some(link) = self.link.as_mut() else {
            self.finished = true;
            return false;
        };
        let mut tx = [0u8; MAX_FRAME];
        let mut dropped = 0;
        let mut sent = 0;
        let echoes = std::mem::take(&mut self.echoes);
        let out = replies
            .iter()
            .flatten()
            .chain(&echoes)
            .copied()
            .chain((!dropping).then_some(Message::Sample(sample)));
        for msg in out {
            let n = encode(self.tx_seq, &msg, &mut tx);
            self.tx_seq = self.tx_seq.wrapping_add(1);
            if corrupt {
                tx[n - 1] ^= 0x5A;
            }
            match link.write_all_bytes(&tx[..n]) {
                Ok(()) => sent += u64::from(matches!(msg, Message::Sample(_))),
                Err(e) if e.kind() == ErrorKind::Timeout => dropped += 1,
                Err(e) => {
                    self.end(e.to_string());
                    return false;
                }
            }
        }
        self.echoes = echoes;
        self.echoes.clear();
        if let Ok(mut l) = self.log.lock() {
            l.samples_sent += sent;
            l.tx_dropped += dropped;
        }
        true
    }
}

/// Board time `now` (s) as the protocol's µs field (it wraps after ~71 min).
fn board_time_us(now: f64) -> u32 {
    ((now * 1e6).round() as u64 & 0xFFFF_FFFF) as u32
}

/// One direction of an in-memory byte pipe.
#[derive(Debug, Default)]
struct Pipe {
    to_board: VecDeque<u8>,
    to_host: VecDeque<u8>,
    host_closed: bool,
    board_closed: bool,
}

/// Bytes each direction of a [`MemLink`] holds before writes fail like a full UART buffer.
pub const MEM_LINK_CAPACITY: usize = 16 * 1024;

/// One end of an in-memory link (board end or host end). Dropping an end is a hang-up for the other.
#[derive(Debug)]
pub struct MemLink {
    pipe: Arc<Mutex<Pipe>>,
    board_end: bool,
}

impl MemLink {
    /// A connected pair: (host end, board end).
    pub fn pair() -> (MemLink, MemLink) {
        let pipe = Arc::new(Mutex::new(Pipe::default()));
        (
            MemLink {
                pipe: pipe.clone(),
                board_end: false,
            },
            MemLink {
                pipe,
                board_end: true,
            },
        )
    }
}

impl MemLink {
    /// Under the pipe's lock: the queue this end reads, the one it writes, and whether the other end hung up.
    fn queues<T>(
        &self,
        f: impl FnOnce(&mut VecDeque<u8>, &mut VecDeque<u8>, bool) -> Result<T, RigError>,
    ) -> Result<T, RigError> {
        let mut guard = self
            .pipe
            .lock()
            .map_err(|_| RigError::new(ErrorKind::LinkLost, "link poisoned"))?;
        let p = &mut *guard;
        if self.board_end {
            f(&mut p.to_board, &mut p.to_host, p.host_closed)
        } else {
            f(&mut p.to_host, &mut p.to_board, p.board_closed)
        }
    }
}

impl Link for MemLink {
    fn read_now(&mut self, buf: &mut [u8]) -> Result<usize, RigError> {
        self.queues(|q, _, peer_closed| {
            if q.is_empty() {
                return if peer_closed {
                    Err(RigError::new(ErrorKind::LinkLost, "the other end hung up"))
                } else {
                    Ok(0)
                };
            }
            let n = buf.len().min(q.len());
            for (dst, src) in buf.iter_mut().zip(q.drain(..n)) {
                *dst = src;
            }
            Ok(n)
        })
    }

    fn write_all_bytes(&mut self, bytes: &[u8]) -> Result<(), RigError> {
        self.queues(|_, q, peer_closed| {
            if peer_closed {
                return Err(RigError::new(ErrorKind::LinkLost, "the other end hung up"));
            }
            if q.len() + bytes.len() > MEM_LINK_CAPACITY {
                return Err(RigError::new(ErrorKind::Timeout, "link buffer full"));
            }
            q.extend(bytes.iter().copied());
            Ok(())
        })
    }
}

impl Drop for MemLink {
    fn drop(&mut self) {
        if let Ok(mut p) = self.pipe.lock() {
            if self.board_end {
                p.board_closed = true;
            } else {
                p.host_closed = true;
            }
        }
    }
}

/// A board a simulated clock steps, one call per sample period: the one-channel [`Board`], or a board of
/// several channels ([`crate::channel_board`]).
pub trait Stepped: Send {
    /// The sample period, s.
    fn period_s(&self) -> f64;
    /// One sample period at board time `now`; false once the board has stopped.
    fn step_period(&mut self, now: f64) -> bool;
}

impl<P: EmulatedPlant, L: Link> Stepped for Board<P, L> {
    fn period_s(&self) -> f64 {
        self.period_s
    }

    fn step_period(&mut self, now: f64) -> bool {
        self.step(now)
    }
}

/// The host end of a link to a board stepped in lockstep with a [`SimClock`]: every read first runs
/// the board's sample periods up to the clock's time (board time = clock time). Deterministic: no threads,
/// no wall clock.
pub struct LockstepLink<B: Stepped> {
    host: MemLink,
    board: B,
    clock: SimClock,
    /// Board steps done; step k runs at k · period.
    steps: u64,
    period_ns: u64,
}

impl<B: Stepped> LockstepLink<B> {
    /// `board`, whose link's other end is `host`, stepped with `clock`.
    pub fn new(board: B, host: MemLink, clock: SimClock) -> Self {
        let period_ns = ((board.period_s() * 1e9).round() as u64).max(1);
        Self {
            host,
            board,
            clock,
            steps: 0,
            period_ns,
        }
    }

    /// The board.
    pub fn board(&self) -> &B {
        &self.board
    }

    fn advance(&mut self) {
        let now = self.clock.now_ns();
        while self.steps * self.period_ns <= now {
            let t = (self.steps * self.period_ns) as f64 * 1e-9;
            self.steps += 1;
            if !self.board.step_period(t) {
                break;
            }
        }
    }
}

impl<B: Stepped> Drop for LockstepLink<B> {
    /// One more board period, so that the board takes in the last frames sent (the final safe command).
    fn drop(&mut self) {
        let t = (self.steps * self.period_ns) as f64 * 1e-9;
        self.board.step_period(t);
    }
}

impl<B: Stepped> Link for LockstepLink<B> {
    fn read_now(&mut self, buf: &mut [u8]) -> Result<usize, RigError> {
        self.advance();
        self.host.read_now(buf)
    }

    fn write_all_bytes(&mut self, bytes: &[u8]) -> Result<(), RigError> {
        self.host.write_all_bytes(bytes)
    }
}

/// The emulated board on an in-memory link, stepped in lockstep with `clock`; returns the host end and the
/// board's log.
pub fn lockstep<P: EmulatedPlant + 'static>(
    plant: P,
    cal: Calibration,
    cfg: EmulatorConfig,
    clock: SimClock,
) -> (LockstepLink<Board<P, MemLink>>, Arc<Mutex<EmulatorLog>>) {
    let (host, board_end) = MemLink::pair();
    let log = Arc::new(Mutex::new(EmulatorLog::default()));
    let board = Emulator::new(plant, board_end, cal, cfg).board(log.clone());
    (LockstepLink::new(board, host, clock), log)
}
