//! `pneuflex rig run --scene <scene with [[actuators]]> (--lockstep-truth SHEET | --port TTY)`: one run of a several-actuator
//! scene on a board of several channels (docs/rig.md, "Several actuators"), through the one loop and the one
//! pipeline every scene runs on: the scene's controllers, one per actuator, drive a [`BoardPlant`] whose
//! sensors are the board's samples and whose valves are the board's channels, behind the supervisor that
//! takes every valve safe in the tick any channel faults; the trace, `summary.json`, the claims and the
//! figures are the mechanism's own, as `pneuflex run` writes them.
//!
//! With `--lockstep-truth` the board is emulated in lockstep with a simulated clock: its plant is the scene's
//! own mechanism (its URDF, contacts and events) with SHEET hidden as every actuator's truth, its ADC noise
//! seeded by `--seed`. With `--port` the loop runs on the wall clock against a board of several channels on a
//! serial port: `rig emulate --scene` serves the same emulated board there ([`emulate`]).

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail};
use pneuflex_control::{Sensors, Signal, Telemetry, ValveCommand};
use pneuflex_files::OutputDir;
use pneuflex_files::output::{Manifest, Writer};
use pneuflex_rig::channel_board::{ChannelBoard, CoupledBoard, SerialChannels};
use pneuflex_rig::clock::{Clock, SimClock, WallClock};
use pneuflex_rig::emulator::{Emulator, EmulatorHandle, LockstepLink, MemLink};
use pneuflex_rig::plant::{CoupledPlant, Detached, PlantSample, ValveDrive};
use pneuflex_rig::protocol::ConfigPayload;
use pneuflex_rig::rigfile::{Channel, EmulatorConfig};
use pneuflex_rig::serial::Link;
use pneuflex_rig::supervisor::ChannelSupervisor;
use pneuflex_rig::{RigFile, session};
use pneuflex_scene::mechanism::{MechanismPlant, MechanismScene, plant::loop_events};
use pneuflex_scene::plants::{EventSpec, Plant, PlantError};
use pneuflex_scene::run::{RunPlan, simulate_run};

/// The emulated board's plant: the scene's mechanism, every actuator's valve a channel, its events at their
/// experiment time. Venting dumps an actuator's supply to atmosphere with its valve open (as the one-channel
/// emulator vents).
struct SceneMechanism {
    plant: MechanismPlant,
    events: Vec<EventSpec>,
    next_event: usize,
    /// Each channel's supply now (its sheet's, or atmosphere after an injected supply loss), Pa absolute.
    supply_pa: Vec<f64>,
    nominal_pa: Vec<f64>,
    atmosphere_pa: f64,
}

impl SceneMechanism {
    fn new(scene: &MechanismScene, atmosphere_pa: f64) -> anyhow::Result<Self> {
        let plant = MechanismPlant::new(scene)?;
        let nominal_pa = (0..scene.actuators.len())
            .map(|i| {
                plant.supply_pa(i).ok_or_else(|| {
                    anyhow!(
                        "actuators[{i}] ({}): its family has no supply port the emulated board can vent",
                        scene.actuators[i].name
                    )
                })
            })
            .collect::<anyhow::Result<Vec<f64>>>()?;
        let mut events = loop_events(scene);
        events.sort_by(|a, b| a.t_s().total_cmp(&b.t_s()));
        Ok(Self {
            plant,
            events,
            next_event: 0,
            supply_pa: nominal_pa.clone(),
            nominal_pa,
            atmosphere_pa,
        })
    }
}

impl CoupledPlant for SceneMechanism {
    fn channels(&self) -> usize {
        self.nominal_pa.len()
    }

    fn step(&mut self, t: f64, drives: &[ValveDrive], dt: f64) {
        // An event at the first period at or after its time, as the scene's loop applies it at its tick.
        while let Some(ev) = self.events.get(self.next_event)
            && ev.t_s() <= t + 0.5 * dt
        {
            // Checked when the scene loaded (the host's loop applies the same events to its own check).
            let _ = self.plant.apply(ev);
            self.next_event += 1;
        }
        for (i, d) in drives.iter().enumerate() {
            let (u, p) = match *d {
                ValveDrive::Run(u) => (u, self.supply_pa[i]),
                ValveDrive::Hold => (0.0, self.supply_pa[i]),
                ValveDrive::Vent => (1.0, self.atmosphere_pa),
            };
            self.plant.set_supply_pa(i, p);
            self.plant
                .actuate_actuator(i, ValveCommand::clamped(u), &Telemetry::default());
        }
        self.plant.advance(dt);
    }

    fn sample(&self, i: usize) -> PlantSample {
        let s = self.plant.sense_actuator(i);
        PlantSample {
            x: s.x,
            x_dot: s.x_dot,
            p_a: s.p_a,
            p_b: s.p_b,
            supply_pa: self.supply_pa[i],
        }
    }

    fn load_n(&self, i: usize) -> f64 {
        self.plant.sense_actuator(i).f_e
    }

    fn set_supply_pa(&mut self, i: usize, p: f64) {
        self.supply_pa[i] = p;
    }

    fn restart(&mut self) {
        self.plant.reset();
        self.next_event = 0;
        self.supply_pa.clone_from(&self.nominal_pa);
    }
}

/// The board as the one loop's plant: each actuator sensed from its channel's newest sample, every channel's
/// command sent in one frame when the loop advances, the supervisor in charge. The scene's events are the
/// board's own (its plant's), so the host applies none.
struct BoardPlant<L: Link, K: Clock> {
    supervisor: ChannelSupervisor<SerialChannels<L>>,
    clock: K,
    /// The clock's time at tick 0, s: tick k's deadline is `t0 + k dt`.
    t0: f64,
    dt: f64,
    /// Consecutive ticks without a new sample, and how many make a fault (the rig file's
    /// `watchdog.timeout_ms`).
    stale: u64,
    stale_limit: u64,
    names: Vec<String>,
    signals: &'static [Signal],
    latest: Vec<Sensors>,
    board_t: f64,
    commands: Vec<ValveCommand>,
    tick: u64,
    /// Ticks on which no sample came (the previous one was used).
    missed: u64,
}

impl<L: Link, K: Clock> BoardPlant<L, K> {
    /// Reads the newest samples at the clock's time; whether any came (a fault the supervisor latched is
    /// its own: [`Plant::check_invariants`] ends the run on it).
    fn read(&mut self) -> bool {
        let now = self.clock.now();
        match self.supervisor.sense(self.tick, now) {
            Some(s) => {
                self.stale = 0;
                for (l, s) in self.latest.iter_mut().zip(&s) {
                    *l = s.sensors;
                }
                self.board_t = s.first().map_or(f64::NAN, |s| s.board_time_s);
                true
            }
            None => {
                if self.supervisor.fault().is_none() {
                    self.missed += 1;
                    self.stale += 1;
                    if self.stale > self.stale_limit {
                        let e = pneuflex_rig::RigError::new(
                            pneuflex_rig::ErrorKind::Timeout,
                            format!("no sample from the board for {} ticks", self.stale),
                        );
                        self.supervisor.trip(self.tick, now, None, e);
                    }
                }
                false
            }
        }
    }
}

impl<L: Link, K: Clock> Plant for BoardPlant<L, K> {
    fn sense(&self) -> Sensors {
        self.latest[0]
    }

    fn actuate(&mut self, command: ValveCommand, _telemetry: &Telemetry) {
        self.commands[0] = command;
    }

    fn actuator_names(&self) -> &[String] {
        &self.names
    }

    fn sense_actuator(&self, i: usize) -> Sensors {
        self.latest[i]
    }

    fn actuate_actuator(&mut self, i: usize, command: ValveCommand, _telemetry: &Telemetry) {
        self.commands[i] = command;
    }

    fn advance(&mut self, _dt: f64) {
        let now = self.clock.now();
        self.supervisor.actuate(self.tick, now, &self.commands);
        self.tick += 1;
        // The next tick's deadline on the clock (the wall clock paces a real board; the simulated one steps a
        // lockstep board to it).
        self.clock.wait_until(self.t0 + self.tick as f64 * self.dt);
        self.read();
    }

    /// The board's plant has the events (a real part stiffens by itself): the host applies none.
    fn apply(&mut self, _event: &EventSpec) -> Result<(), PlantError> {
        Ok(())
    }

    fn reset(&mut self) {}

    /// A fault the supervisor latched (every valve already safe) ends the run here.
    fn check_invariants(&self) -> Result<(), PlantError> {
        match self.supervisor.fault() {
            Some(f) => Err(PlantError::invariant(format!(
                "rig fault: {}: {} (tick {}); every valve was put in its safe state in that tick",
                f.fault.kind, f.fault.message, f.fault.tick
            ))),
            None => Ok(()),
        }
    }

    fn signals(&self) -> &'static [Signal] {
        self.signals
    }

    fn record(&self, out: &mut [f64]) {
        if let Some(o) = out.last_mut() {
            *o = self.board_t;
        }
    }
}

/// The board's own column: the time stamp of the samples the tick used.
const BOARD_SIGNALS: [Signal; 1] = [Signal::new(
    "board_t",
    "s",
    "time",
    "board time of the samples the tick used (the board's clock)",
)];

/// The rig file's channels matched to the scene's actuators, by name and in order.
fn channels_for(
    rig: &RigFile,
    rig_file: &Path,
    scene: &MechanismScene,
) -> anyhow::Result<Vec<Channel>> {
    let channels = rig.channels();
    let actuators: Vec<&str> = scene.actuators.iter().map(|a| a.name.as_str()).collect();
    let named: Vec<&str> = channels.iter().map(|c| c.name.as_str()).collect();
    if named != actuators {
        bail!(
            "{}: [[channel]] names {:?} differ from the scene's actuators {:?} ({}): a board of several \
             actuators has one [[channel]] per actuator, in the scene's order (docs/rig.md)",
            rig_file.display(),
            named,
            actuators,
            scene.source.display()
        );
    }
    Ok(channels)
}

/// The emulated board of `scene`: its mechanism with `truths[i]` hidden as actuator i's, one channel per
/// actuator with the rig file's calibration, answering on `link`.
fn coupled_board<L: Link>(
    rig: &RigFile,
    rig_file: &Path,
    scene: &MechanismScene,
    truths: &[PathBuf],
    seed: u64,
    channels: &[Channel],
    link: L,
) -> anyhow::Result<CoupledBoard<L>> {
    let mut hidden = scene.clone();
    for (a, t) in hidden.actuators.iter_mut().zip(truths) {
        a.sheet = std::path::absolute(t)?;
    }
    hidden.check_sheets()?;
    let plant = SceneMechanism::new(&hidden, channels[0].cal.atmosphere_pa)?;
    // A board channel samples two chamber pressures (docs/protocol.md §6); a muscle has one.
    if let Some(i) =
        (0..scene.actuators.len()).find(|&i| plant.plant.sense_actuator(i).p_a.is_nan())
    {
        bail!(
            "{}: actuators[{i}] ({}) is a muscle: a board channel samples a cylinder's two chambers, a muscle's \
             one pressure is not in the protocol's Samples yet",
            scene.source.display(),
            scene.actuators[i].name
        );
    }
    let e = rig.emulator.as_ref();
    let mut subs = Vec::with_capacity(channels.len());
    for (i, ch) in channels.iter().enumerate() {
        let cfg = EmulatorConfig {
            sample_rate_hz: rig.rt.rate_hz,
            plant_dt_s: 1.0 / rig.rt.rate_hz,
            actuator: None,
            x0_m: 0.0,
            adc_noise_counts: e.map_or(1, |e| e.adc_noise_counts),
            // Each channel's ADC its own noise.
            seed: seed.wrapping_add(i as u64),
            supply_pa: plant.nominal_pa[i],
            transport_delay_s: e.map_or(0.0, |e| e.transport_delay_s),
            environment: None,
            faults: e.map(|e| e.faults.clone()).unwrap_or_default(),
        };
        let (to_board, board_end) = MemLink::pair();
        subs.push((
            Emulator::new(Detached::default(), board_end, ch.cal, cfg),
            to_board,
        ));
    }
    ChannelBoard::coupled(link, Box::new(plant), subs).ok_or_else(|| {
        anyhow!(
            "{}: {} channels: a board carries 1..={}",
            rig_file.display(),
            channels.len(),
            pneuflex_rig::protocol::MAX_CHANNELS
        )
    })
}

/// `rig run` on a several-actuator scene (module docs).
#[allow(clippy::too_many_arguments)]
pub fn run(
    rig_file: &Path,
    port: Option<&str>,
    lockstep: Option<(&Path, u64)>,
    truths: &[String],
    scene_path: &Path,
    run_name: Option<&str>,
    duration_s: Option<f64>,
    out: Option<&Path>,
    figures: pneuflex_viz::Format,
    mcap: bool,
) -> anyhow::Result<()> {
    let rig = RigFile::load(rig_file)?;
    let mut scene = MechanismScene::load(scene_path)?;
    // In lockstep, each actuator's hidden truth: --lockstep-truth's, or its own --truth NAME=SHEET (a real
    // board hides its own).
    let mut hidden: Vec<PathBuf> = match lockstep {
        Some((truth, _)) => vec![truth.to_path_buf(); scene.actuators.len()],
        None => Vec::new(),
    };
    for t in truths {
        let Some((name, sheet)) = t.split_once('=') else {
            bail!(
                "--truth {t}: expected NAME=SHEET (an actuator of {} and its truth)",
                scene_path.display()
            );
        };
        let Some(i) = scene.actuators.iter().position(|a| a.name == name) else {
            bail!(
                "--truth {t}: `{name}` is not an actuator of {} (its actuators: {})",
                scene_path.display(),
                scene
                    .actuators
                    .iter()
                    .map(|a| a.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        };
        if let Some(h) = hidden.get_mut(i) {
            *h = PathBuf::from(sheet);
        }
    }
    session::check_scene_rate(scene.dt_s, scene_path, &rig, rig_file)?;
    let channels = channels_for(&rig, rig_file, &scene)?;
    let index = match run_name {
        None => 0,
        Some(name) => scene
            .runs
            .iter()
            .position(|r| r.name == name)
            .ok_or_else(|| {
                anyhow!(
                    "{}: no run named '{name}' (runs: {})",
                    scene_path.display(),
                    scene
                        .runs
                        .iter()
                        .map(|r| r.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            })?,
    };
    if let Some(d) = duration_s {
        pneuflex_rig::rtloop::check_duration(d)
            .map_err(|e| anyhow!("--duration: {}", e.message))?;
        scene.duration_s = d;
    }
    // The one run: the summary, claims and figures are of the run recorded.
    let run = scene.runs[index].clone();
    let mut controllers = scene.run_controllers(index)?;
    let schedules = MechanismPlant::new(&scene)?.schedules().to_vec();
    scene.runs = vec![run];
    let dest = match out {
        Some(d) => d.to_path_buf(),
        // A recording is never replaced: a second one goes beside the first (`<scene>-2`, ...).
        None => pneuflex_files::output::fresh_destination(
            &Path::new("out").join("rig").join(&scene.name),
        ),
    };
    let inputs = scene.input_files();
    let protect: Vec<&Path> = [scene_path, rig_file]
        .into_iter()
        .chain(hidden.iter().map(PathBuf::as_path))
        .chain(inputs.iter().map(|(_, p)| p.as_path()))
        .collect();
    let stage = OutputDir::create(&dest, &protect, Writer::recording("rig run"))?;

    let (result, missed) = on_board(
        &rig,
        rig_file,
        port,
        lockstep.map(|(_, seed)| seed),
        &hidden,
        &scene,
        &channels,
        &mut controllers,
        &schedules,
    )?;
    let runs = vec![result];
    let summary = pneuflex_scene::mechanism::summarise(&scene, &runs);
    pneuflex_scene::mechanism::write(stage.path(), &summary, &runs)?;
    super::mechanism::write_figures(stage.path(), &scene, &runs, figures)?;
    if mcap {
        // Into the staged directory: committed with the trace.
        let names: Vec<String> = channels.iter().map(|c| c.name.clone()).collect();
        super::bag::write_runs(stage.path(), &runs, &names)?;
    }
    let digests: Vec<pneuflex_files::InputDigest> = [("rig", rig_file.to_path_buf())]
        .into_iter()
        .chain(hidden.iter().map(|p| ("truth", p.clone())))
        .chain(inputs.iter().cloned())
        .filter_map(|(role, p)| pneuflex_files::InputDigest::of_file(&p, role).ok())
        .collect();
    let manifest = Manifest::new("rig run", env!("CARGO_PKG_VERSION"), digests);
    let dest: PathBuf = stage.commit(manifest)?;
    let r = &runs[0];
    if missed > 0 {
        errln!("note: {missed} ticks had no new sample and used the previous one");
    }
    let board = if hidden.is_empty() {
        format!("the board on {}", port.unwrap_or(&rig.link.port))
    } else {
        format!(
            "the emulated board (lockstep, hidden truths {})",
            channels
                .iter()
                .zip(&hidden)
                .map(|(c, t)| format!("{}={}", c.name, t.display()))
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    outln!(
        "{}: run {} on {board}, {} channels; outputs in {}",
        scene.name,
        r.name,
        channels.len(),
        dest.display()
    );
    super::fail_on_divergence(
        std::iter::once((r.name.as_str(), r.diverged.as_deref())),
        &dest,
    )
}

/// Connects to the board behind `link` (its configuration, its first samples within the handshake timeout on
/// `clock`), runs the scene's one run through the one loop on it, and parks every valve: the run, and the ticks
/// that had no new sample.
#[allow(clippy::too_many_arguments)]
fn record<L: Link, K: Clock>(
    rig: &RigFile,
    rig_file: &Path,
    channels: &[Channel],
    scene: &MechanismScene,
    controllers: &mut [Box<dyn pneuflex_control::Controller + Send + Sync>],
    schedules: &[pneuflex_control::SetpointSchedule],
    link: L,
    clock: K,
) -> anyhow::Result<(pneuflex_scene::RunResult, u64)> {
    let mut driver = SerialChannels::new(link, channels, rig.rt.velocity_cutoff_hz);
    driver.configure(ConfigPayload {
        sample_period_us: (1e6 / rig.rt.rate_hz).round() as u32,
        watchdog_ms: rig.watchdog.board_watchdog_ms,
        safe_mode: channels[0].safe_state.mode(),
    })?;
    let names: Vec<String> = channels.iter().map(|c| c.name.clone()).collect();
    let dt = scene.dt_s;
    let mut plant = BoardPlant {
        supervisor: ChannelSupervisor::new(driver, channels.to_vec()),
        t0: 0.0,
        dt,
        stale: 0,
        stale_limit: ((rig.watchdog.timeout_ms * 1e-3 / dt).ceil() as u64).max(1),
        clock,
        signals: &BOARD_SIGNALS,
        latest: vec![Sensors::default(); names.len()],
        board_t: f64::NAN,
        commands: vec![ValveCommand { u: 0.0 }; names.len()],
        names,
        tick: 0,
        missed: 0,
    };
    // The first samples before the first tick, within the handshake's timeout.
    let timeout_s = (rig.link.handshake_timeout_ms as f64 * 1e-3).max(0.1);
    let start = plant.clock.now();
    let mut first = false;
    while !first && plant.clock.now() - start < timeout_s && plant.supervisor.fault().is_none() {
        let t = plant.clock.now() + dt;
        plant.clock.wait_until(t);
        plant.stale = 0;
        first = plant.read();
    }
    plant.missed = 0;
    if let Some(f) = plant.supervisor.fault() {
        bail!(
            "{}: the board faulted before the run: {}",
            rig_file.display(),
            f.fault.message
        );
    }
    if !first {
        bail!(
            "{}: no samples from the board within {timeout_s} s (link.handshake_timeout_ms)",
            rig_file.display()
        );
    }
    plant.t0 = plant.clock.now();
    let events = loop_events(scene);
    let invalid = |key: &str, message: String| scene.invalid(key, message);
    let plan = RunPlan {
        name: &scene.runs[0].name,
        controller: scene.runs[0].controller,
        dt_s: scene.dt_s,
        n_steps: scene.n_steps(),
        events: &events,
        divergence: &scene.divergence,
        invalid: &invalid,
    };
    let stop = super::stop_flag()?;
    let bar = super::progress::Progress::new(false, format!("rig run {}", scene.name));
    let mut each: Vec<&mut dyn pneuflex_control::Controller> = controllers
        .iter_mut()
        .map(|c| &mut **c as &mut dyn pneuflex_control::Controller)
        .collect();
    let result = simulate_run(
        &plan,
        &mut plant,
        &mut each,
        &mut |i, t| schedules[i].at(t),
        &mut |f| bar.set(f),
        &mut (),
        Some(&stop),
    )?;
    bar.finish();
    // The normal end: every valve safe.
    let _ = plant.supervisor.park(plant.tick);
    Ok((result, plant.missed))
}

/// `rig emulate --scene <scene with [[actuators]]>`: the scene's mechanism as the board's plant, one channel per
/// actuator, in real time behind a new pseudo-terminal (or `port`), until Ctrl-C or `duration_s`; `hidden.truth`
/// replaces every actuator's sheet, `hidden.seed` the ADC noise's seed. Each host connection starts a run from
/// the scene's initial state.
pub fn emulate(
    rig_file: &Path,
    scene_path: &Path,
    port: Option<&str>,
    duration_s: Option<f64>,
    hidden: &super::emulated::Hidden,
) -> anyhow::Result<()> {
    let rig = RigFile::load(rig_file)?;
    let text = pneuflex_files::read_text(scene_path, pneuflex_files::InputKind::Scene)?;
    if !MechanismScene::is_mechanism(&text) {
        bail!(
            "--scene {}: a scene of one actuator; its emulator is the rig file's [emulator] table (no --scene)",
            scene_path.display()
        );
    }
    if hidden.delay_s.is_some() {
        bail!(
            "--delay: the board of a scene of several actuators applies its commands in the period they come"
        );
    }
    let scene = MechanismScene::load(scene_path)?;
    session::check_scene_rate(scene.dt_s, scene_path, &rig, rig_file)?;
    let channels = channels_for(&rig, rig_file, &scene)?;
    let truths: Vec<PathBuf> = hidden
        .truth
        .iter()
        .flat_map(|t| std::iter::repeat_n(t.clone(), scene.actuators.len()))
        .collect();
    let seed = hidden
        .seed
        .or(rig.emulator.as_ref().map(|e| e.seed))
        .unwrap_or(1);
    let handle = match port {
        Some(p) => {
            let (link, _) = pneuflex_rig::serial::open(&rig, rig_file, Some(p))?;
            let board = coupled_board(&rig, rig_file, &scene, &truths, seed, &channels, link)?;
            let log = board
                .log_handle(0)
                .ok_or_else(|| anyhow!("{}: no channels", rig_file.display()))?;
            EmulatorHandle::spawn(board, None, log)
        }
        None => {
            let link = pneuflex_rig::emulator::PtyLink::open()?;
            let path = link.path.clone();
            let board = coupled_board(&rig, rig_file, &scene, &truths, seed, &channels, link)?;
            let log = board
                .log_handle(0)
                .ok_or_else(|| anyhow!("{}: no channels", rig_file.display()))?;
            EmulatorHandle::spawn(board, Some(path), log)
        }
    };
    super::emulated::serve(handle, &rig.name, port, duration_s)
}

/// [`record`] on the board: the emulated one in lockstep (`lockstep_seed`, `hidden` its truths), else the
/// one on the serial port (`port`, or the rig file's `link.port`) on the wall clock.
#[allow(clippy::too_many_arguments)]
fn on_board(
    rig: &RigFile,
    rig_file: &Path,
    port: Option<&str>,
    lockstep_seed: Option<u64>,
    hidden: &[PathBuf],
    scene: &MechanismScene,
    channels: &[Channel],
    controllers: &mut [Box<dyn pneuflex_control::Controller + Send + Sync>],
    schedules: &[pneuflex_control::SetpointSchedule],
) -> anyhow::Result<(pneuflex_scene::RunResult, u64)> {
    match lockstep_seed {
        Some(seed) => {
            let (host, board_end) = MemLink::pair();
            let board = coupled_board(rig, rig_file, scene, hidden, seed, channels, board_end)?;
            let clock = SimClock::new();
            let link = LockstepLink::new(board, host, clock.clone());
            record(
                rig,
                rig_file,
                channels,
                scene,
                controllers,
                schedules,
                link,
                clock,
            )
        }
        None => {
            let (link, _) = pneuflex_rig::serial::open(rig, rig_file, port)?;
            let clock = WallClock::new(std::time::Duration::from_micros(rig.rt.spin_us));
            record(
                rig,
                rig_file,
                channels,
                scene,
                controllers,
                schedules,
                link,
                clock,
            )
        }
    }
}

/// `rig excite --scene <scene with [[actuators]]>`: every actuator's own excitation (`a`, its signal seeded
/// with `a.seed` + its index, centred within its channel's position limits) at once on the board of as many
/// channels, through the one loop; the recording is `<out>/excite/trace.csv` with each actuator's columns, for
/// `identify --channel NAME`. In lockstep with `a.lockstep_truth` hidden as every actuator's truth, else on
/// the port.
pub fn excite(
    rig_file: &Path,
    port: Option<&str>,
    scene_path: &Path,
    a: &super::excitation::ExciteArgs,
    out: Option<&Path>,
) -> anyhow::Result<()> {
    pneuflex_rig::rtloop::check_duration(a.duration_s)
        .map_err(|e| anyhow!("--duration: {}", e.message))?;
    let rig = RigFile::load(rig_file)?;
    let text = pneuflex_files::read_text(scene_path, pneuflex_files::InputKind::Scene)?;
    if !MechanismScene::is_mechanism(&text) {
        bail!(
            "--scene {}: a scene of one actuator; rig excite takes the rig file's one channel without --scene",
            scene_path.display()
        );
    }
    let mut scene = MechanismScene::load(scene_path)?;
    session::check_scene_rate(scene.dt_s, scene_path, &rig, rig_file)?;
    let channels = channels_for(&rig, rig_file, &scene)?;
    let mut controllers: Vec<Box<dyn pneuflex_control::Controller + Send + Sync>> = Vec::new();
    for (i, ch) in channels.iter().enumerate() {
        let e = super::excitation::excitation(
            a,
            a.seed.wrapping_add(i as u64),
            ch.limits.position_m,
            rig_file,
            &format!("channel[{i}] ({}) position limits", ch.name),
        )?;
        controllers.push(Box::new(pneuflex_identify::excite::Exciter::new(e)));
    }
    // No reference: the excitation is the command.
    let schedules = vec![pneuflex_control::SetpointSchedule::default(); channels.len()];
    scene.duration_s = a.duration_s;
    let mut run = scene.runs[0].clone();
    run.name = "excite".into();
    scene.runs = vec![run];
    let hidden: Vec<PathBuf> = a
        .lockstep_truth
        .iter()
        .flat_map(|t| std::iter::repeat_n(t.clone(), channels.len()))
        .collect();
    let dest = match out {
        Some(d) => d.to_path_buf(),
        None => pneuflex_files::output::fresh_destination(
            &Path::new("out").join("rig").join("excite").join(&a.signal),
        ),
    };
    let inputs = scene.input_files();
    let protect: Vec<&Path> = [scene_path, rig_file]
        .into_iter()
        .chain(hidden.iter().map(PathBuf::as_path))
        .chain(inputs.iter().map(|(_, p)| p.as_path()))
        .collect();
    let stage = OutputDir::create(
        &dest,
        &protect,
        Writer::recording(pneuflex_rig::record::EXCITE),
    )?;
    let (result, missed) = on_board(
        &rig,
        rig_file,
        port,
        a.lockstep_truth.as_ref().map(|_| a.seed),
        &hidden,
        &scene,
        &channels,
        &mut controllers,
        &schedules,
    )?;
    pneuflex_scene::write_trace(stage.path(), &result)?;
    if a.mcap {
        let names: Vec<String> = channels.iter().map(|c| c.name.clone()).collect();
        super::bag::write_runs(stage.path(), std::slice::from_ref(&result), &names)?;
    }
    let digests: Vec<pneuflex_files::InputDigest> = [("rig", rig_file.to_path_buf())]
        .into_iter()
        .chain(hidden.iter().map(|p| ("truth", p.clone())))
        .chain(inputs.iter().cloned())
        .filter_map(|(role, p)| pneuflex_files::InputDigest::of_file(&p, role).ok())
        .collect();
    let dest = stage.commit(Manifest::new(
        pneuflex_rig::record::EXCITE,
        env!("CARGO_PKG_VERSION"),
        digests,
    ))?;
    if missed > 0 {
        errln!("note: {missed} ticks had no new sample and used the previous one");
    }
    outln!(
        "{}: {} excitation of {} channels ({}); trace: {}",
        scene.name,
        a.signal,
        channels.len(),
        channels
            .iter()
            .map(|c| c.name.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        dest.join("excite")
            .join(pneuflex_scene::run::output::trace_file_name(&result))
            .display()
    );
    super::fail_on_divergence(
        std::iter::once(("excite", result.diverged.as_deref())),
        &dest,
    )
}
