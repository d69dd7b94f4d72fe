//! The emulated rig: a plant run in real time behind a pseudo-terminal (or a given serial port), speaking the
//! I/O board's protocol, with fault injection. It is the firmware's behaviour in host code: stream samples at
//! the configured rate, apply valve commands, echo heartbeats, go to its safe state when the host falls silent.

use std::fs::File;
use std::io::{Read, Write};
use std::os::fd::{AsRawFd, OwnedFd};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::error::{ErrorKind, RigError};
use crate::plant::{EmulatedPlant, Environment, ValveDrive};
use crate::protocol::{
    DecodeEvent, Decoder, MAX_FRAME, Message, RESET_MAGIC, SamplePayload, ValveMode, encode,
    fault_code, from_q15, status,
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
    /// A snapshot of the log.
    pub fn log(&self) -> EmulatorLog {
        self.log.lock().map(|l| l.clone()).unwrap_or_default()
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
        let env = Environment::from_config(&cfg.environment);
        Self {
            plant,
            link: Some(link),
            cal,
            cfg,
            env,
        }
    }

    /// Runs the emulator on its own thread until stopped.
    pub fn spawn(self, path: Option<PathBuf>) -> EmulatorHandle {
        let stop = Arc::new(AtomicBool::new(false));
        let log = Arc::new(Mutex::new(EmulatorLog::default()));
        let (s, l) = (stop.clone(), log.clone());
        let thread = std::thread::Builder::new()
            .name("pneuflex-emulator".into())
            .spawn(move || self.run(&s, &l))
            .ok();
        EmulatorHandle {
            path,
            stop,
            log,
            thread,
        }
    }

    /// Runs in the calling thread until `stop` is set or the link closes.
    pub fn run(mut self, stop: &AtomicBool, log: &Mutex<EmulatorLog>) {
        let period_s = 1.0 / self.cfg.sample_rate_hz;
        let period = Duration::from_secs_f64(period_s);
        let substeps = (period_s / self.cfg.plant_dt_s).round().max(1.0) as usize;
        let h = period_s / substeps as f64;
        let full = |c: &crate::rigfile::LinearChannel| c.full_scale() as u16;
        let mut noise = Noise(
            self.cfg
                .seed
                .wrapping_mul(2)
                .wrapping_add(0x9E37_79B9_7F4A_7C15)
                | 1,
        );
        let mut decoder = Decoder::new();
        let mut rx = [0u8; 512];
        let mut tx = [0u8; MAX_FRAME];
        let mut tx_seq: u8 = 0;
        let mut drive_mode = ValveMode::SafeVent;
        let mut duty_q15: i16 = 0;
        let mut last_tick: u32 = 0;
        let mut safe_mode = ValveMode::SafeVent;
        let mut board_wd: Option<Duration> = None;
        let mut last_host_msg = Instant::now();
        let mut board_fault = false;
        let mut wd_tripped = false;
        let mut run_start: Option<Instant> = None;
        let mut frozen: Option<SamplePayload> = None;
        let mut supply_lost = false;
        let start = Instant::now();
        let mut k: u64 = 0;
        let mut pending: Vec<(Message, bool)> = Vec::with_capacity(8);
        while !stop.load(Ordering::Relaxed) {
            let deadline = start + period.mul_f64(k as f64);
            let now = Instant::now();
            if deadline > now {
                std::thread::sleep(deadline - now);
            }
            k += 1;
            // Experiment time runs from the first Run command.
            let t = run_start.map(|s| (Instant::now() - s).as_secs_f64());
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
            let stalled = faults
                .iter()
                .any(|f| matches!(f, InjectedFault::Stall { .. }) && active(f));
            let dropping = faults
                .iter()
                .any(|f| matches!(f, InjectedFault::DropFrames { .. }) && active(f));
            let corrupt = faults
                .iter()
                .any(|f| matches!(f, InjectedFault::CorruptCrc { .. }) && active(f));
            let stuck = faults
                .iter()
                .any(|f| matches!(f, InjectedFault::StuckSensor { .. }) && active(f));
            let close = faults
                .iter()
                .any(|f| matches!(f, InjectedFault::CloseLink { .. }) && active(f));
            if !supply_lost
                && faults
                    .iter()
                    .any(|f| matches!(f, InjectedFault::SupplyLoss { .. }) && active(f))
            {
                supply_lost = true;
                self.plant.set_supply_pa(self.cal.atmosphere_pa);
            }
            if close && self.link.is_some() {
                self.link = None;
                if let Ok(mut l) = log.lock() {
                    l.ended = Some("link closed by fault injection".into());
                }
                break;
            }

            // Receive.
            if !stalled && let Some(link) = self.link.as_mut() {
                loop {
                    match link.read_now(&mut rx) {
                        Ok(0) => break,
                        Ok(n) => decoder.feed(&rx[..n], |ev| {
                            if let DecodeEvent::Frame(f) = ev {
                                pending.push((f.msg, true));
                            }
                        }),
                        Err(e) => {
                            if let Ok(mut l) = log.lock() {
                                l.ended = Some(e.to_string());
                            }
                            return;
                        }
                    }
                }
            }
            let mut replies: [Option<Message>; 2] = [None, None];
            if stalled {
                // A stalled firmware runs nothing, its watchdog included; the host's silence is not its doing.
                last_host_msg = Instant::now();
            }
            for (msg, _) in pending.drain(..) {
                last_host_msg = Instant::now();
                match msg {
                    Message::Valve(v) => {
                        if run_start.is_none() && v.mode == ValveMode::Run {
                            run_start = Some(Instant::now());
                        }
                        // A latched board fault keeps the valve safe until Reset.
                        if !board_fault {
                            drive_mode = v.mode;
                            duty_q15 = v.duty_q15;
                        }
                        last_tick = v.tick;
                        if let Ok(mut l) = log.lock()
                            && l.commands.len() < LOG_CAP
                        {
                            l.commands.push(CommandRecord {
                                tick: v.tick,
                                mode: drive_mode,
                                duty_q15,
                                t: t.unwrap_or(0.0),
                            });
                        }
                    }
                    Message::Heartbeat(c) => replies[0] = Some(Message::Heartbeat(c)),
                    Message::Config(c) => {
                        safe_mode = c.safe_mode;
                        board_wd = (c.watchdog_ms > 0)
                            .then(|| Duration::from_millis(u64::from(c.watchdog_ms)));
                    }
                    Message::Reset(m) if m == RESET_MAGIC => {
                        board_fault = false;
                        wd_tripped = false;
                    }
                    _ => {}
                }
            }
            // The board's own watchdog: a silent host (or a stalled board, once it wakes) -> safe state.
            if let Some(wd) = board_wd.filter(|_| !stalled)
                && run_start.is_some()
                && !board_fault
                && last_host_msg.elapsed() > wd
            {
                board_fault = true;
                wd_tripped = true;
                drive_mode = safe_mode;
                duty_q15 = 0;
                replies[1] = Some(Message::Fault {
                    code: fault_code::HOST_SILENT,
                    detail: wd.as_millis().min(u128::from(u16::MAX)) as u16,
                });
                if let Ok(mut l) = log.lock() {
                    l.board_watchdog_trips += 1;
                }
            }

            // Physics (never stalls). Before the run starts the plant rests.
            let drive = match drive_mode {
                ValveMode::Run => ValveDrive::Run(from_q15(duty_q15)),
                ValveMode::SafeVent => ValveDrive::Vent,
                ValveMode::SafeHold => ValveDrive::Hold,
            };
            let t_now = t.unwrap_or(0.0);
            if run_start.is_some() {
                for i in 0..substeps {
                    let ts = t_now + i as f64 * h;
                    let x = self.plant.sample().x;
                    let f_e = self.env.force(ts, x);
                    // f_ext on the flange = -f_e.
                    self.plant.step(drive, -f_e, h);
                }
            }
            let ps = self.plant.sample();
            let f_e = self.env.force(t_now, ps.x);
            if run_start.is_some()
                && let Ok(mut l) = log.lock()
                && l.truth.len() < LOG_CAP
            {
                l.truth.push(TruthRecord {
                    t: t_now,
                    x: ps.x,
                    f_e,
                });
            }

            // Sample.
            let c = &self.cal;
            let (ch1, chb) = c.pressure_counts(ps.p_a, ps.p_b);
            let ch1_full = match c.channel_a {
                crate::rigfile::ChannelA::Chamber(ch)
                | crate::rigfile::ChannelA::Differential(ch) => full(&ch),
            };
            let a = self.cfg.adc_noise_counts;
            let mut sample = SamplePayload {
                board_time_us: (start.elapsed().as_micros() & 0xFFFF_FFFF) as u32,
                last_cmd_tick: last_tick,
                position: add_noise(c.position.from_si(ps.x), noise.counts(a), full(&c.position)),
                p_a: add_noise(ch1, noise.counts(a), ch1_full),
                p_b: add_noise(chb, noise.counts(a), full(&c.pressure_b)),
                p_supply: add_noise(
                    c.supply.from_si(ps.supply_pa - c.atmosphere_pa),
                    noise.counts(a),
                    full(&c.supply),
                ),
                load: c.load_from_si(f_e) + noise.counts(a) as i32,
                duty_q15,
                status: 0,
            };
            if stuck {
                let f = *frozen.get_or_insert(sample);
                sample.position = f.position;
                sample.p_a = f.p_a;
                sample.p_b = f.p_b;
                sample.p_supply = f.p_supply;
                sample.load = f.load;
            }
            sample.status = match drive_mode {
                ValveMode::Run => 0,
                ValveMode::SafeVent => status::SAFE,
                ValveMode::SafeHold => status::SAFE | status::SAFE_HOLD,
            } | if board_fault { status::BOARD_FAULT } else { 0 }
                | if wd_tripped { status::WATCHDOG } else { 0 };

            // Transmit.
            if stalled {
                continue;
            }
            let Some(link) = self.link.as_mut() else {
                break;
            };
            let mut dropped = 0;
            let mut sent = 0;
            let out = replies
                .iter()
                .flatten()
                .copied()
                .chain((!dropping).then_some(Message::Sample(sample)));
            for msg in out {
                let n = encode(tx_seq, &msg, &mut tx);
                tx_seq = tx_seq.wrapping_add(1);
                if corrupt {
                    tx[n - 1] ^= 0x5A;
                }
                match link.write_all_bytes(&tx[..n]) {
                    Ok(()) => sent += u64::from(matches!(msg, Message::Sample(_))),
                    Err(e) if e.kind() == ErrorKind::Timeout => dropped += 1,
                    Err(e) => {
                        if let Ok(mut l) = log.lock() {
                            l.ended = Some(e.to_string());
                        }
                        return;
                    }
                }
            }
            if let Ok(mut l) = log.lock() {
                l.samples_sent += sent;
                l.tx_dropped += dropped;
            }
        }
    }
}
