//! `pneuflex rig run --scene <scene with [[actuators]]> --lockstep-truth SHEET`: one run of a several-actuator
//! scene on a board of several channels (docs/rig.md, "Several actuators"), through the one loop and the one
//! pipeline every scene runs on: the scene's controllers, one per actuator, drive a [`BoardPlant`] whose
//! sensors are the board's samples and whose valves are the board's channels, behind the supervisor that
//! takes every valve safe in the tick any channel faults; the trace, `summary.json`, the claims and the
//! figures are the mechanism's own, as `pneuflex run` writes them.
//!
//! The board is emulated in lockstep with a simulated clock: its plant is the scene's own mechanism (its
//! URDF, contacts and events) with SHEET hidden as every actuator's truth, its ADC noise seeded by `--seed`.
//! A real board of several channels runs the same host side once the firmware drives N valves (issue 43).

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail};
use pneuflex_control::{Sensors, Signal, Telemetry, ValveCommand};
use pneuflex_files::OutputDir;
use pneuflex_files::output::{Manifest, Writer};
use pneuflex_rig::channel_board::{ChannelBoard, CoupledBoard, SerialChannels};
use pneuflex_rig::clock::{Clock, SimClock};
use pneuflex_rig::emulator::{Emulator, LockstepLink, MemLink};
use pneuflex_rig::plant::{CoupledPlant, Detached, PlantSample, ValveDrive};
use pneuflex_rig::protocol::ConfigPayload;
use pneuflex_rig::rigfile::{Channel, EmulatorConfig};
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

type Driver = SerialChannels<LockstepLink<CoupledBoard<MemLink>>>;

/// The board as the one loop's plant: each actuator sensed from its channel's newest sample, every channel's
/// command sent in one frame when the loop advances, the supervisor in charge. The scene's events are the
/// board's own (its plant's), so the host applies none.
struct BoardPlant {
    supervisor: ChannelSupervisor<Driver>,
    clock: SimClock,
    names: Vec<String>,
    signals: &'static [Signal],
    latest: Vec<Sensors>,
    board_t: f64,
    commands: Vec<ValveCommand>,
    tick: u64,
    /// Ticks on which no sample came (the previous one was used).
    missed: u64,
}

impl BoardPlant {
    /// Reads the newest samples at the clock's time; whether any came (a fault the supervisor latched is
    /// its own: [`Plant::check_invariants`] ends the run on it).
    fn read(&mut self) -> bool {
        let now = self.clock.now();
        match self.supervisor.sense(self.tick, now) {
            Some(s) => {
                for (l, s) in self.latest.iter_mut().zip(&s) {
                    *l = s.sensors;
                }
                self.board_t = s.first().map_or(f64::NAN, |s| s.board_time_s);
                true
            }
            None => {
                self.missed += u64::from(self.supervisor.fault().is_none());
                false
            }
        }
    }
}

impl Plant for BoardPlant {
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

    fn advance(&mut self, dt: f64) {
        let now = self.clock.now();
        self.supervisor.actuate(self.tick, now, &self.commands);
        self.tick += 1;
        self.clock.wait_until(now + dt);
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

/// The coupled board of `scene` (`truths[i]` hidden as actuator i's) behind a lockstep link, and the clock it
/// steps with.
fn emulated_board(
    rig: &RigFile,
    rig_file: &Path,
    scene: &MechanismScene,
    truths: &[PathBuf],
    seed: u64,
    channels: &[Channel],
) -> anyhow::Result<(LockstepLink<CoupledBoard<MemLink>>, SimClock)> {
    let mut hidden = scene.clone();
    for (a, t) in hidden.actuators.iter_mut().zip(truths) {
        a.sheet = std::path::absolute(t)?;
    }
    hidden.check_sheets()?;
    let plant = SceneMechanism::new(&hidden, channels[0].cal.atmosphere_pa)?;
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
    let (host, board_end) = MemLink::pair();
    let board = ChannelBoard::coupled(board_end, Box::new(plant), subs).ok_or_else(|| {
        anyhow!(
            "{}: {} channels: a board carries 1..={}",
            rig_file.display(),
            channels.len(),
            pneuflex_rig::protocol::MAX_CHANNELS
        )
    })?;
    let clock = SimClock::new();
    Ok((LockstepLink::new(board, host, clock.clone()), clock))
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
    let Some((truth, seed)) = lockstep else {
        bail!(
            "{}: a scene with several actuators runs on a board of several channels in lockstep \
             (--lockstep-truth SHEET) so far; a real board needs the firmware's N controllers (issue 43){}",
            scene_path.display(),
            port.map(|p| format!("; --port {p} is not taken yet"))
                .unwrap_or_default()
        );
    };
    let rig = RigFile::load(rig_file)?;
    let mut scene = MechanismScene::load(scene_path)?;
    // Each actuator's hidden truth: --lockstep-truth's, or its own --truth NAME=SHEET.
    let mut hidden: Vec<PathBuf> = vec![truth.to_path_buf(); scene.actuators.len()];
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
        hidden[i] = PathBuf::from(sheet);
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

    let (link, mut clock) = emulated_board(&rig, rig_file, &scene, &hidden, seed, &channels)?;
    let mut driver = SerialChannels::new(link, &channels, rig.rt.velocity_cutoff_hz);
    driver.configure(ConfigPayload {
        sample_period_us: (1e6 / rig.rt.rate_hz).round() as u32,
        watchdog_ms: rig.watchdog.board_watchdog_ms,
        safe_mode: channels[0].safe_state.mode(),
    })?;
    let names: Vec<String> = channels.iter().map(|c| c.name.clone()).collect();
    let channel_names = names.clone();
    let mut plant = BoardPlant {
        supervisor: ChannelSupervisor::new(driver, channels.clone()),
        clock: clock.clone(),
        signals: &BOARD_SIGNALS,
        latest: vec![Sensors::default(); names.len()],
        board_t: f64::NAN,
        commands: vec![ValveCommand { u: 0.0 }; names.len()],
        names,
        tick: 0,
        missed: 0,
    };
    // The first samples before the first tick (the handshake's timeout on the board's clock).
    let timeout_s = (rig.link.handshake_timeout_ms as f64 * 1e-3).max(0.1);
    let period = 1.0 / rig.rt.rate_hz;
    let mut first = false;
    while !first && clock.now() < timeout_s && plant.supervisor.fault().is_none() {
        let t = clock.now() + period;
        clock.wait_until(t);
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
            "{}: no samples from the emulated board within {timeout_s} s",
            rig_file.display()
        );
    }
    let events = loop_events(&scene);
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
    let bar = super::progress::Progress::new(false, format!("rig run {} (lockstep)", scene.name));
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
    let missed = plant.missed;
    drop(plant);
    let runs = vec![result];
    let summary = pneuflex_scene::mechanism::summarise(&scene, &runs);
    pneuflex_scene::mechanism::write(stage.path(), &summary, &runs)?;
    super::mechanism::write_figures(stage.path(), &scene, &runs, figures)?;
    if mcap {
        // Into the staged directory: committed with the trace.
        super::bag::write_runs(stage.path(), &runs, &channel_names)?;
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
    outln!(
        "{}: run {} on the emulated board of {} channels (lockstep, hidden truths {}); outputs in {}",
        scene.name,
        r.name,
        channels.len(),
        channels
            .iter()
            .zip(&hidden)
            .map(|(c, t)| format!("{}={}", c.name, t.display()))
            .collect::<Vec<_>>()
            .join(", "),
        dest.display()
    );
    super::fail_on_divergence(
        std::iter::once((r.name.as_str(), r.diverged.as_deref())),
        &dest,
    )
}
