//! The run loop: for every controller the scene lists, `sense → controller.update → actuate → advance(dt)`
//! on a fresh plant, recording a preallocated trace, then the metrics of every window.

use pneuflex_control as control;
use pneuflex_control::{Controller, Setpoint};
use serde::Serialize;

use crate::error::SceneError;
use crate::metrics::{self, EventResponse};
use crate::multibody::MultibodyPlant;
use crate::plant::{IdealLoop, LinearSpring, Plant};
use crate::pneumatic::OneDofPneumatic;
use crate::schema::{ControllerKind, ForcePiece, PlantSpec, RunSpec, Scene, WindowKind};
use crate::trace::{Row, Trace};

/// The outcome of one controller run: its trace, metrics, Lyapunov check and divergence state.
#[derive(Clone, Debug)]
pub struct RunResult {
    /// Run name from the scene.
    pub name: String,
    /// Controller kind.
    pub controller: ControllerKind,
    /// Recorded signals (up to the divergence point for a diverged run).
    pub trace: Trace,
    /// Metrics per window, in the scene's window order (empty for a diverged run).
    pub windows: Vec<WindowMetrics>,
    /// Lyapunov check of the adaptive law's error system (adaptive runs only).
    pub lyapunov: Option<LyapunovSummary>,
    /// Why the run was stopped, when it diverged.
    pub diverged: Option<String>,
    /// Why the run was cut short by the user (a signal), when it was.
    pub interrupted: Option<String>,
    /// What a reader of the results should know (e.g. an adaptive parameter pinned at its projection bound).
    pub warnings: Vec<String>,
}

impl RunResult {
    /// Whether the trace holds g, p, d.
    pub fn is_adaptive(&self) -> bool {
        self.controller == ControllerKind::Adaptive
    }

    /// The metrics of the window named `name`.
    pub fn window(&self, name: &str) -> Option<&WindowMetrics> {
        self.windows.iter().find(|w| w.name == name)
    }
}

/// Metrics of one window.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WindowMetrics {
    /// Window name.
    pub name: String,
    /// Window kind.
    pub kind: WindowKind,
    /// Window start, s.
    pub t0_s: f64,
    /// Window end, s.
    pub t1_s: f64,
    /// RMS of f_ref - f_e over the window, N.
    pub rms_force_error_n: f64,
    /// Sine windows: frequency of the reference, Hz.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frequency_hz: Option<f64>,
    /// Sine windows: phase lag of f_e behind f_ref, degrees (positive = lags).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub phase_lag_deg: Option<f64>,
    /// Sine windows: amplitude ratio |f_e| / |f_ref| of the fitted sines.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub amplitude_ratio: Option<f64>,
    /// Step windows: mean of f_ref - f_e, N.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub steady_state_error_n: Option<f64>,
    /// Event windows: peak force, overshoot, settling.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub event: Option<EventResponse>,
}

/// The Lyapunov check of Section III-D for an adaptive run (what summary.json reports).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct LyapunovSummary {
    /// Reference model damping a_m, 1/s.
    pub a_m: f64,
    /// Reference model stiffness b_m, 1/s².
    pub b_m: f64,
    /// Initial a_p = b_d / m_d (eq. (28) with d = 0), 1/s.
    pub a_p0: f64,
    /// Initial b_p = (k_d + k_e) / m_d (eq. (28) with p = 0), 1/s².
    pub b_p0: f64,
    /// Solution P of A_mᵀP + PA_m = -Q, row-major.
    pub p: [[f64; 2]; 2],
    /// Largest |entry| of A_mᵀP + PA_m + Q.
    pub residual: f64,
    /// V at t = 0.
    pub v0: f64,
    /// V at the end.
    pub v_end: f64,
    /// Largest one-step rise of V.
    pub max_delta_v: f64,
    /// Whether V never rose by more than 1e-9·V(0) in a step.
    pub non_increasing: bool,
}

/// Builds the plant a scene describes, at its initial state.
pub fn build_plant(scene: &Scene) -> Result<Box<dyn Plant>, SceneError> {
    let env = LinearSpring {
        stiffness_n_per_m: scene.environment.stiffness_n_per_m,
        x_e_m: scene.environment.x_e_m,
    };
    match &scene.plant {
        PlantSpec::Ideal {
            omega_rad_per_s,
            zeta,
            x0_m,
        } => Ok(Box::new(IdealLoop::new(
            *omega_rad_per_s,
            *zeta,
            *x0_m,
            env,
        ))),
        PlantSpec::Pneumatic { .. } => Ok(Box::new(OneDofPneumatic::from_scene(scene, env)?)),
        PlantSpec::Multibody(_) => Ok(Box::new(MultibodyPlant::from_scene(scene)?)),
        PlantSpec::Linear { .. } => Ok(Box::new(crate::linear::LinearPlant::from_scene(
            scene, env,
        )?)),
    }
}

/// The force/position setpoint schedule of the scene, in the control crate's fixed-capacity form.
pub fn build_setpoints(scene: &Scene) -> Result<control::SetpointSchedule, SceneError> {
    let mut sp = control::SetpointSchedule::default();
    for (i, piece) in scene.reference.force.iter().enumerate() {
        let r = match *piece {
            ForcePiece::Step { value_n, .. } => control::Reference::Constant { value: value_n },
            ForcePiece::Sine {
                bias_n,
                amplitude_n,
                frequency_hz,
                phase_rad,
                ..
            } => control::Reference::Sine {
                bias: bias_n,
                amplitude: amplitude_n,
                frequency_hz,
                phase_rad,
            },
            ForcePiece::Ramp {
                value0_n,
                slope_n_per_s,
                ..
            } => control::Reference::Ramp {
                start: value0_n,
                slope_per_s: slope_n_per_s,
            },
        };
        sp.force_n
            .push(piece.start_s(), r)
            .map_err(|e| scene.invalid(&format!("reference.force[{i}]"), e.to_string()))?;
    }
    sp.position_m
        .push(
            0.0,
            control::Reference::Constant {
                value: scene.reference.x_d_m,
            },
        )
        .map_err(|e| scene.invalid("reference.x_d_m", e.to_string()))?;
    Ok(sp)
}

/// Builds the controller of run `index` of the scene; an error names the key of the run it is about.
pub fn build_controller(
    scene: &Scene,
    index: usize,
) -> Result<Box<dyn Controller + Send + Sync>, SceneError> {
    scene.runs[index]
        .build()
        .map_err(|e| scene.invalid(&format!("runs[{index}].{}", e.key), e.message))
}

/// Runs every controller the scene lists, each on a fresh plant. `progress` receives the completed
/// fraction in [0, 1]. A diverged run is returned with `diverged` set; errors are only for bad input.
pub fn run_scene(
    scene: &Scene,
    progress: &mut dyn FnMut(f64),
) -> Result<Vec<RunResult>, SceneError> {
    run_scene_observed(scene, progress, &mut NoObserver)
}

/// Watches runs tick by tick without changing them (a viewer, a live plot). Called after each tick's
/// sample is recorded, with the plant in the state that sample was read from.
pub trait StepObserver {
    /// A run starts; the plant is at its initial state.
    fn begin_run(&mut self, _run: &crate::schema::RunSpec, _plant: &dyn Plant) {}
    /// The run's columns as their producers declare them (the loop's, the controller's, the plant's),
    /// before its first tick.
    fn columns(&mut self, _columns: &[pneuflex_control::Signal]) {}
    /// One control tick was recorded.
    fn on_step(&mut self, _row: &Row, _plant: &dyn Plant) {}
    /// A run ended (its metrics are not computed yet).
    fn end_run(&mut self, _result: &RunResult) {}
    /// Whether this observer watches anything. One that does not (every method a no-op) lets the runs of
    /// a scene execute in parallel; one that does sees them one after another, in the scene's order.
    fn watches(&self) -> bool {
        true
    }
}

/// The observer that watches nothing.
pub struct NoObserver;

impl StepObserver for NoObserver {
    fn watches(&self) -> bool {
        false
    }
}

/// A [`pneuflex_control::RowObserver`] — the row watcher the rig's loop takes too — as a [`StepObserver`]
/// of the simulation: the same observer watches a simulated run and a run on the real rig.
pub struct Rows<'a>(pub &'a mut dyn pneuflex_control::RowObserver);

impl StepObserver for Rows<'_> {
    fn columns(&mut self, columns: &[pneuflex_control::Signal]) {
        self.0.begin(columns);
    }
    fn on_step(&mut self, row: &Row, _plant: &dyn Plant) {
        self.0.row(row.values);
    }
    fn end_run(&mut self, _result: &RunResult) {
        self.0.end();
    }
}

/// Any number of observers watching the same runs (Rerun, a live plot, a progress display …), each
/// called in order.
#[derive(Default)]
pub struct Observers<'a>(pub Vec<&'a mut dyn StepObserver>);

impl StepObserver for Observers<'_> {
    fn begin_run(&mut self, run: &crate::schema::RunSpec, plant: &dyn Plant) {
        for o in &mut self.0 {
            o.begin_run(run, plant);
        }
    }
    fn columns(&mut self, columns: &[pneuflex_control::Signal]) {
        for o in &mut self.0 {
            o.columns(columns);
        }
    }
    fn on_step(&mut self, row: &Row, plant: &dyn Plant) {
        for o in &mut self.0 {
            o.on_step(row, plant);
        }
    }
    fn end_run(&mut self, result: &RunResult) {
        for o in &mut self.0 {
            o.end_run(result);
        }
    }
    fn watches(&self) -> bool {
        self.0.iter().any(|o| o.watches())
    }
}

/// [`run_scene`] with an observer called at every tick of every run.
pub fn run_scene_observed(
    scene: &Scene,
    progress: &mut dyn FnMut(f64),
    observer: &mut dyn StepObserver,
) -> Result<Vec<RunResult>, SceneError> {
    run_scene_with(scene, &RunOptions::default(), progress, observer)
}

/// How a scene is run: the limits it must stay within, a flag a signal handler sets to stop it, and who
/// is told when a run's trace is complete.
#[derive(Clone, Copy, Default)]
pub struct RunOptions<'a> {
    /// Refuse scenes beyond these before anything runs.
    pub limits: crate::schema::Limits,
    /// Non-zero stops the current run at the next tick (the value is the signal number, e.g. 2 = SIGINT);
    /// later runs are not started.
    pub stop: Option<&'a std::sync::atomic::AtomicUsize>,
    /// Called once per run that ran, as soon as its trace, window metrics and warnings are final (its
    /// Lyapunov check may still be under way), on the thread that ran it, in any order: `pneuflex run`
    /// writes the run's trace there while the other runs are still simulating.
    pub on_run: Option<&'a (dyn Fn(&RunResult) + Sync)>,
}

impl std::fmt::Debug for RunOptions<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RunOptions")
            .field("limits", &self.limits)
            .field("stop", &self.stop)
            .field("on_run", &self.on_run.map(|_| "Fn(&RunResult)"))
            .finish()
    }
}

/// The conventional name of a signal number, for messages.
pub fn signal_name(signal: usize) -> String {
    match signal {
        1 => "SIGHUP".into(),
        2 => "SIGINT".into(),
        15 => "SIGTERM".into(),
        n => format!("signal {n}"),
    }
}

/// [`run_scene_observed`] with limits and a stop flag. Runs stopped by the flag come back with
/// `interrupted` set; runs not started are absent (the runs started are always the first ones, in order).
///
/// When the observer watches nothing ([`StepObserver::watches`]) and there are several runs and cores,
/// the runs execute in parallel (rayon's pool), each on its own plant from [`build_plant`]; the results
/// are the same, bit for bit, as one after another. A stop flag then stops every run in progress and no
/// further run starts.
pub fn run_scene_with(
    scene: &Scene,
    opts: &RunOptions<'_>,
    progress: &mut dyn FnMut(f64),
    observer: &mut dyn StepObserver,
) -> Result<Vec<RunResult>, SceneError> {
    scene.validate()?;
    scene.check_budget(&opts.limits)?;
    let setpoints = build_setpoints(scene)?;
    let parallel = !observer.watches()
        && scene.runs.len() > 1
        && rayon::current_num_threads() > 1
        // A pool thread must not block on the progress channel below.
        && rayon::current_thread_index().is_none();
    if parallel {
        return run_parallel(scene, opts, &setpoints, progress);
    }
    let mut plant = build_plant(scene)?;
    let pwm_period = pwm_period_s(scene);
    let n_runs = scene.runs.len();
    let mut out = Vec::with_capacity(n_runs);
    for i in 0..n_runs {
        if stopped(opts) {
            break;
        }
        let mut controller = build_controller(scene, i)?;
        plant.reset();
        let mut sub = |f: f64| progress((i as f64 + f) / n_runs as f64);
        observer.begin_run(&scene.runs[i], plant.as_ref());
        let mut r = simulate_loop(
            scene,
            i,
            plant.as_mut(),
            controller.as_mut(),
            &setpoints,
            &mut sub,
            observer,
            opts.stop,
        )?;
        observer.end_run(&r);
        finish_run(scene, i, &mut r, pwm_period);
        if let Some(f) = opts.on_run {
            f(&r);
        }
        out.push(r);
    }
    progress(1.0);
    Ok(out)
}

fn stopped(opts: &RunOptions<'_>) -> bool {
    opts.stop
        .is_some_and(|f| f.load(std::sync::atomic::Ordering::Relaxed) != 0)
}

/// A simulated run's metrics, Lyapunov check and warnings.
fn finish_run(scene: &Scene, i: usize, r: &mut RunResult, pwm_period: Option<f64>) {
    finish_metrics(scene, i, r, pwm_period);
    if r.controller == ControllerKind::Adaptive {
        r.lyapunov = lyapunov_summary(scene, &scene.runs[i]);
    }
}

/// A simulated run's window metrics and warnings (what needs its trace).
fn finish_metrics(scene: &Scene, i: usize, r: &mut RunResult, pwm_period: Option<f64>) {
    if r.diverged.is_none() && r.interrupted.is_none() {
        r.windows = compute_windows_with(scene, &r.trace, pwm_period);
    }
    r.warnings = pinned_parameters(&scene.runs[i], &r.trace);
}

/// The runs of a scene on the pool's threads: each worker takes the next run in the scene's order (so the
/// runs started are a prefix), builds its plant and controller, simulates and computes its metrics. The
/// calling thread makes the Lyapunov checks of the adaptive runs (they need the scene, not the trace; 2 ms
/// each on paper-fig7) while the workers simulate, where it would only wait for their messages: taken after
/// the runs, a check held back the outputs that wait for this function. A run stopped by a signal is still
/// checked, as in the sequential path. The calling thread reports progress from what the workers send. The
/// first error in run order is returned.
fn run_parallel(
    scene: &Scene,
    opts: &RunOptions<'_>,
    setpoints: &control::SetpointSchedule,
    progress: &mut dyn FnMut(f64),
) -> Result<Vec<RunResult>, SceneError> {
    use std::sync::Mutex;
    use std::sync::atomic::{AtomicUsize, Ordering};
    let n_runs = scene.runs.len();
    let pwm_period = pwm_period_s(scene);
    let next = AtomicUsize::new(0);
    let slots: Vec<Mutex<Option<Result<RunResult, SceneError>>>> =
        (0..n_runs).map(|_| Mutex::new(None)).collect();
    let workers = n_runs.min(rayon::current_num_threads());
    let (tx, rx) = std::sync::mpsc::channel::<(usize, f64)>();
    let lyapunov = rayon::in_place_scope(|s| {
        for _ in 0..workers {
            let tx = tx.clone();
            let (next, slots) = (&next, &slots);
            s.spawn(move |_| {
                loop {
                    if stopped(opts) {
                        break;
                    }
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= n_runs {
                        break;
                    }
                    let run = || -> Result<RunResult, SceneError> {
                        let mut plant = build_plant(scene)?;
                        let mut controller = build_controller(scene, i)?;
                        // Progress in steps of 1 % of the run (each message wakes the caller).
                        let mut sent = 0.0;
                        let mut sub = |f: f64| {
                            if f - sent >= 0.01 || (f >= 1.0 && sent < 1.0) {
                                sent = f;
                                let _ = tx.send((i, f));
                            }
                        };
                        let mut r = simulate_loop(
                            scene,
                            i,
                            plant.as_mut(),
                            controller.as_mut(),
                            setpoints,
                            &mut sub,
                            &mut NoObserver,
                            opts.stop,
                        )?;
                        finish_metrics(scene, i, &mut r, pwm_period);
                        if let Some(f) = opts.on_run {
                            f(&r);
                        }
                        Ok(r)
                    };
                    let r = run();
                    let failed = r.is_err();
                    *slots[i].lock().unwrap_or_else(|e| e.into_inner()) = Some(r);
                    if failed {
                        // Later runs would be discarded: start none.
                        next.fetch_max(n_runs, Ordering::Relaxed);
                    }
                }
            });
        }
        drop(tx);
        let lyapunov: Vec<Option<LyapunovSummary>> = (0..n_runs)
            .map(|i| {
                (scene.runs[i].controller == ControllerKind::Adaptive)
                    .then(|| lyapunov_summary(scene, &scene.runs[i]))
                    .flatten()
            })
            .collect();
        let mut done = vec![0.0; n_runs];
        let mut total = 0.0;
        for (i, f) in rx {
            total += f - done[i];
            done[i] = f;
            progress(total / n_runs as f64);
        }
        lyapunov
    });
    progress(1.0);
    let mut out = Vec::with_capacity(n_runs);
    for (slot, lyap) in slots.into_iter().zip(lyapunov) {
        match slot.into_inner().unwrap_or_else(|e| e.into_inner()) {
            Some(r) => {
                let mut r = r?;
                r.lyapunov = lyap;
                out.push(r);
            }
            None => break,
        }
    }
    Ok(out)
}

/// Simulates run `index` of the scene with the given plant and controller (both at their initial state).
pub fn simulate(
    scene: &Scene,
    index: usize,
    plant: &mut dyn Plant,
    controller: &mut dyn Controller,
    setpoints: &control::SetpointSchedule,
    progress: &mut dyn FnMut(f64),
) -> Result<RunResult, SceneError> {
    simulate_observed(
        scene,
        index,
        plant,
        controller,
        setpoints,
        progress,
        &mut NoObserver,
    )
}

/// [`simulate`] with an observer called at every recorded tick.
pub fn simulate_observed(
    scene: &Scene,
    index: usize,
    plant: &mut dyn Plant,
    controller: &mut dyn Controller,
    setpoints: &control::SetpointSchedule,
    progress: &mut dyn FnMut(f64),
    observer: &mut dyn StepObserver,
) -> Result<RunResult, SceneError> {
    simulate_loop(
        scene, index, plant, controller, setpoints, progress, observer, None,
    )
}

/// [`simulate_observed`] that a signal can stop: `stop` non-zero ends the run at the next tick, which comes
/// back with `interrupted` set (the rows simulated so far in its trace).
#[allow(clippy::too_many_arguments)]
pub fn simulate_stoppable(
    scene: &Scene,
    index: usize,
    plant: &mut dyn Plant,
    controller: &mut dyn Controller,
    setpoints: &control::SetpointSchedule,
    progress: &mut dyn FnMut(f64),
    observer: &mut dyn StepObserver,
    stop: Option<&std::sync::atomic::AtomicUsize>,
) -> Result<RunResult, SceneError> {
    simulate_loop(
        scene, index, plant, controller, setpoints, progress, observer, stop,
    )
}

#[allow(clippy::too_many_arguments)]
fn simulate_loop(
    scene: &Scene,
    index: usize,
    plant: &mut dyn Plant,
    controller: &mut dyn Controller,
    setpoints: &control::SetpointSchedule,
    progress: &mut dyn FnMut(f64),
    observer: &mut dyn StepObserver,
    stop: Option<&std::sync::atomic::AtomicUsize>,
) -> Result<RunResult, SceneError> {
    let run = &scene.runs[index];
    let dt = scene.dt_s;
    let n = scene.n_steps();
    // Event order by time, keeping each event's index in the file for messages.
    let mut events: Vec<(usize, &crate::schema::EventSpec)> =
        scene.events.iter().enumerate().collect();
    events.sort_by(|a, b| a.1.t_s().total_cmp(&b.1.t_s()));
    // The row: the loop's signals, then the controller's and the plant's, as each declares them.
    let (c_sig, p_sig) = (controller.signals(), plant.signals());
    let columns = Trace::loop_columns(&[c_sig, p_sig]);
    let declared: Vec<pneuflex_control::Signal> = pneuflex_control::LOOP_SIGNALS
        .iter()
        .chain(c_sig)
        .chain(p_sig)
        .copied()
        .collect();
    observer.columns(&declared);
    let mut values = vec![0.0; columns.len()];
    let mut host = SimulationHost {
        scene,
        plant,
        events,
        next_event: 0,
        trace: Trace::with_capacity(n + 1, columns),
        observer,
        last_step: n as u64,
        report_every: (n / 200).max(1) as u64,
        progress,
        stop,
        diverged: None,
        interrupted: None,
    };
    let mut reference = |t: f64| -> Setpoint { setpoints.at(t) };
    pneuflex_control::tick::run_loop(&mut host, controller, &mut reference, dt, &mut values)?;
    let SimulationHost {
        trace,
        diverged,
        interrupted,
        progress,
        ..
    } = host;
    progress(1.0);
    Ok(RunResult {
        name: run.name.clone(),
        controller: run.controller,
        trace,
        windows: Vec::new(),
        lyapunov: None,
        diverged,
        interrupted,
        warnings: Vec::new(),
    })
}

/// A simulated plant around the controller: events at their tick, the trace and the observers at every
/// tick, the divergence and invariant checks, the integration ([`pneuflex_control::tick::run_loop`]).
struct SimulationHost<'a> {
    scene: &'a Scene,
    plant: &'a mut dyn Plant,
    /// The scene's events by time, each with its index in the file (for messages).
    events: Vec<(usize, &'a crate::schema::EventSpec)>,
    next_event: usize,
    trace: Trace,
    observer: &'a mut dyn StepObserver,
    /// The tick at the run's end (the trace has `last_step + 1` rows).
    last_step: u64,
    report_every: u64,
    progress: &'a mut dyn FnMut(f64),
    stop: Option<&'a std::sync::atomic::AtomicUsize>,
    diverged: Option<String>,
    interrupted: Option<String>,
}

impl pneuflex_control::tick::LoopHost for SimulationHost<'_> {
    type Error = SceneError;

    fn begin_tick(&mut self, _k: u64, t: f64) -> Result<pneuflex_control::tick::Flow, SceneError> {
        // Events apply at the first tick at or after their time (half a tick of tolerance for rounding).
        let half = 0.5 * self.scene.dt_s;
        while let Some(&(index, ev)) = self.events.get(self.next_event)
            && ev.t_s() <= t + half
        {
            self.plant.apply(ev).map_err(|m| {
                self.scene
                    .invalid(&format!("events[{index}]"), m.to_string())
            })?;
            self.next_event += 1;
        }
        Ok(pneuflex_control::tick::Flow::Continue)
    }

    fn sense(&mut self, _k: u64, _t: f64) -> Option<control::Sensors> {
        Some(self.plant.sense())
    }

    fn record(&mut self, row: &mut [f64]) {
        self.plant.record(row);
    }

    fn actuate(
        &mut self,
        _k: u64,
        _t: f64,
        command: &control::ValveCommand,
        telemetry: &control::Telemetry,
    ) -> f64 {
        self.plant.actuate(*command, telemetry);
        command.u
    }

    fn end_tick(
        &mut self,
        k: u64,
        t: f64,
        row: &mut [f64],
    ) -> Result<pneuflex_control::tick::Flow, SceneError> {
        use pneuflex_control::signal::index;
        use pneuflex_control::tick::Flow;
        self.trace.push(row);
        self.observer.on_step(
            &Row {
                columns: self.trace.columns(),
                values: row,
            },
            &*self.plant,
        );
        let lim = &self.scene.divergence;
        if let Some(reason) = divergence(t, row[index::X], row[index::F_E], row[index::X_R], lim) {
            self.diverged = Some(reason);
            return Ok(Flow::Stop);
        }
        // Physical invariants (chamber pressures, temperatures, the stroke): a finite but impossible
        // state is a divergence too.
        if let Err(v) = self.plant.check_invariants() {
            self.diverged = Some(format!("{v} at t = {t:.4} s"));
            return Ok(Flow::Stop);
        }
        if k == self.last_step {
            return Ok(Flow::Stop);
        }
        if let Some(sig) = self
            .stop
            .map(|f| f.load(std::sync::atomic::Ordering::Relaxed))
            .filter(|&s| s != 0)
        {
            self.interrupted = Some(format!("{} at t = {t:.4} s", signal_name(sig)));
            return Ok(Flow::Stop);
        }
        if k.is_multiple_of(self.report_every) {
            (self.progress)(k as f64 / self.last_step as f64);
        }
        Ok(Flow::Continue)
    }

    fn advance(&mut self, dt: f64) {
        self.plant.advance(dt);
    }
}

fn divergence(
    t: f64,
    x: f64,
    f_e: f64,
    x_r: f64,
    lim: &crate::schema::DivergenceSpec,
) -> Option<String> {
    if !x.is_finite() || !f_e.is_finite() || !x_r.is_finite() {
        return Some(format!(
            "non-finite state at t = {t:.4} s (x = {x}, f_e = {f_e}, x_r = {x_r})"
        ));
    }
    if x.abs() > lim.max_abs_position_m {
        return Some(format!(
            "|x| = {:.4} m exceeds divergence.max_abs_position_m = {} at t = {t:.4} s",
            x.abs(),
            lim.max_abs_position_m
        ));
    }
    if x_r.abs() > lim.max_abs_position_m {
        return Some(format!(
            "|x_r| = {:.4} m exceeds divergence.max_abs_position_m = {} at t = {t:.4} s",
            x_r.abs(),
            lim.max_abs_position_m
        ));
    }
    if f_e.abs() > lim.max_abs_force_n {
        return Some(format!(
            "|f_e| = {:.1} N exceeds divergence.max_abs_force_n = {} at t = {t:.4} s",
            f_e.abs(),
            lim.max_abs_force_n
        ));
    }
    None
}

/// Warnings for adaptive parameters that sat at their projection bound for most of the run: then the bound,
/// not the adaptive law, set them (issue: a silently pinned parameter).
pub fn pinned_parameters(run: &RunSpec, tr: &Trace) -> Vec<String> {
    let Some(a) = run.adaptive else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for (name, key, bound) in [
        ("p", "p_max_m_per_n", a.p_max_m_per_n),
        ("d", "d_max_s", a.d_max_s),
    ] {
        let Some(col) = tr.column(name).filter(|c| !c.is_empty()) else {
            continue;
        };
        if !(bound.is_finite() && bound > 0.0) {
            continue;
        }
        let at = col
            .iter()
            .filter(|v| (v.abs() - bound).abs() <= 1e-9 * bound)
            .count();
        let frac = at as f64 / col.len() as f64;
        if frac > 0.5 {
            out.push(format!(
                "run `{}`: the adaptive {name} sat at its projection bound {key} = {bound} for {:.0} % of the \
                 run: the bound, not the adaptive law, set it (widen the bound or retune; docs/control.md)",
                run.name,
                100.0 * frac
            ));
        }
    }
    out
}

/// The PWM period of the scene's valve, s, when it is an on/off valve under PWM (the period its force and
/// pressures are averaged over for the event metrics and the figures); None for a continuous valve or a
/// plant without one.
pub fn pwm_period_s(scene: &Scene) -> Option<f64> {
    let sheet = match &scene.plant {
        PlantSpec::Ideal { .. } | PlantSpec::Linear { .. } => return None,
        PlantSpec::Pneumatic { actuator, .. } => scene.resolve(actuator),
        PlantSpec::Multibody(mb) => scene.resolve(&mb.actuator),
    };
    match scene.load_sheet(&sheet).ok()?.valve.valve.kind {
        pneuflex_pneumatics::ValveKind::OnOffPwm {
            pwm_frequency_hz, ..
        } => Some(1.0 / pwm_frequency_hz),
        pneuflex_pneumatics::ValveKind::Proportional { .. } => None,
    }
}

/// The metrics of every window of the scene on a trace.
pub fn compute_windows(scene: &Scene, tr: &Trace) -> Vec<WindowMetrics> {
    compute_windows_with(scene, tr, pwm_period_s(scene))
}

/// [`compute_windows`] with the PWM period already known (None: no averaging).
pub fn compute_windows_with(
    scene: &Scene,
    tr: &Trace,
    pwm_period_s: Option<f64>,
) -> Vec<WindowMetrics> {
    scene
        .metrics
        .iter()
        .map(|w| {
            let (i0, i1) = metrics::window_indices(tr.t(), w.t0_s, w.t1_s);
            let (t, r, f) = (&tr.t()[i0..i1], &tr.f_ref()[i0..i1], &tr.f_e()[i0..i1]);
            let mut m = WindowMetrics {
                name: w.name.clone(),
                kind: w.kind,
                t0_s: w.t0_s,
                t1_s: w.t1_s,
                rms_force_error_n: metrics::rms_error(r, f),
                frequency_hz: None,
                phase_lag_deg: None,
                amplitude_ratio: None,
                steady_state_error_n: None,
                event: None,
            };
            match w.kind {
                WindowKind::Sine => {
                    if let Some(ForcePiece::Sine { frequency_hz, .. }) =
                        scene.sine_in(w.t0_s, w.t1_s)
                    {
                        let om = std::f64::consts::TAU * frequency_hz;
                        m.frequency_hz = Some(frequency_hz);
                        m.phase_lag_deg = metrics::phase_lag_deg(t, r, f, frequency_hz);
                        if let (Some((ar, _, _)), Some((af, _, _))) =
                            (metrics::fit_sine(t, r, om), metrics::fit_sine(t, f, om))
                        {
                            m.amplitude_ratio = Some(af / ar);
                        }
                    }
                }
                WindowKind::Step => m.steady_state_error_n = Some(metrics::mean_error(r, f)),
                WindowKind::Event => {
                    // The steady state the response is measured against: the sine the window ends on,
                    // repeated, or the constant reference's mean error.
                    let steady = match scene.sine_in(w.t1_s - 1e-9, w.t1_s) {
                        Some(ForcePiece::Sine { frequency_hz, .. }) => {
                            metrics::Steady::Periodic(frequency_hz)
                        }
                        _ => metrics::Steady::Constant,
                    };
                    m.event = metrics::event_response(t, r, f, steady, pwm_period_s);
                }
            }
            m
        })
        .collect()
}

/// The Lyapunov check (Section III-D) for an adaptive run: the control crate's reference model and Q,
/// started from the run's impedance loop at the scene's initial stiffness (eq. (28) with p = d = g = 0)
/// and the initial force error e(0) = f_r(0).
pub fn lyapunov_summary(scene: &Scene, run: &RunSpec) -> Option<LyapunovSummary> {
    let mut params = control::LyapunovCheckParams::default();
    let imp = &run.impedance;
    let k_e = scene.environment.stiffness_n_per_m;
    let a_p0 = imp.b_d_ns_per_m / imp.m_d_kg; // eq. (28), d = 0
    let b_p0 = (imp.k_d_n_per_m + k_e) / imp.m_d_kg; // eq. (28), p = 0
    let e0 = build_setpoints(scene).ok()?.at(0.0).f_ref;
    // eq. (28) with g = 0, x_e measured from x_d (eq. (27)'s x_e - x_d; eq. (28) drops x_d).
    let x_rel = scene.environment.x_e_m - scene.reference.x_d_m;
    let w_p0 =
        imp.k_d_n_per_m * k_e / imp.m_d_kg * (if k_e > 0.0 { e0 / k_e } else { 0.0 } + x_rel);
    params.initial = control::MracState {
        e: e0,
        e_dot: 0.0,
        e_m: e0,
        e_m_dot: 0.0,
        a_p: a_p0,
        b_p: b_p0,
        w_p: w_p0,
    };
    let r = control::lyapunov_check(&params).ok()?;
    Some(LyapunovSummary {
        a_m: params.a_m,
        b_m: params.b_m,
        a_p0,
        b_p0,
        p: r.p,
        residual: r.residual,
        v0: r.v0,
        v_end: r.v_end,
        max_delta_v: r.max_delta_v,
        non_increasing: r.non_increasing(1e-9),
    })
}
