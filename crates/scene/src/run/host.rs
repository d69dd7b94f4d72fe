//! The simulated host of the one loop (`pneuflex_control::tick::run_loop`): the scene's events at their tick,
//! the trace and the observers at every tick, the divergence and invariant checks, the plant's integration.

use pneuflex_control as control;
use pneuflex_control::{Controller, Setpoint};

use super::observe::Sink;
use super::result::RunResult;
use super::signal_name;
use super::trace::Trace;
use crate::error::SceneError;
use crate::plants::Plant;
use crate::schema::Scene;

/// Simulates run `index` of the scene with the given plant and controller (both at their initial state).
pub fn simulate<'p>(
    scene: &Scene,
    index: usize,
    plant: &mut (dyn Plant + 'p),
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
        &mut (),
    )
}

/// [`simulate`] with a sink called at every recorded tick.
pub fn simulate_observed<'p>(
    scene: &Scene,
    index: usize,
    plant: &mut (dyn Plant + 'p),
    controller: &mut dyn Controller,
    setpoints: &control::SetpointSchedule,
    progress: &mut dyn FnMut(f64),
    observer: &mut dyn Sink<dyn Plant + 'p>,
) -> Result<RunResult, SceneError> {
    simulate_stoppable(
        scene, index, plant, controller, setpoints, progress, observer, None,
    )
}

/// [`simulate_observed`] that a signal can stop: `stop` non-zero ends the run at the next tick, which comes
/// back with `interrupted` set (the rows simulated so far in its trace).
#[allow(clippy::too_many_arguments)]
pub fn simulate_stoppable<'p>(
    scene: &Scene,
    index: usize,
    plant: &mut (dyn Plant + 'p),
    controller: &mut dyn Controller,
    setpoints: &control::SetpointSchedule,
    progress: &mut dyn FnMut(f64),
    observer: &mut dyn Sink<dyn Plant + 'p>,
    stop: Option<&std::sync::atomic::AtomicUsize>,
) -> Result<RunResult, SceneError> {
    simulate_referenced(
        scene,
        index,
        plant,
        controller,
        &mut |_, t| setpoints.at(t),
        progress,
        observer,
        stop,
    )
}

/// [`simulate_stoppable`] toward `reference(0, t)` instead of the scene's setpoints (`pneuflex ros2`: a
/// reference a ROS 2 system commands).
#[allow(clippy::too_many_arguments)]
pub fn simulate_referenced<'p>(
    scene: &Scene,
    index: usize,
    plant: &mut (dyn Plant + 'p),
    controller: &mut dyn Controller,
    reference: &mut dyn FnMut(usize, f64) -> Setpoint,
    progress: &mut dyn FnMut(f64),
    observer: &mut dyn Sink<dyn Plant + 'p>,
    stop: Option<&std::sync::atomic::AtomicUsize>,
) -> Result<RunResult, SceneError> {
    let run = &scene.runs[index];
    let invalid = |key: &str, message: String| scene.invalid(key, message);
    let plan = RunPlan {
        name: &run.name,
        controller: run.controller,
        dt_s: scene.dt_s,
        n_steps: scene.n_steps(),
        events: &scene.events,
        divergence: &scene.divergence,
        invalid: &invalid,
    };
    simulate_run(
        &plan,
        plant,
        &mut [controller],
        reference,
        progress,
        observer,
        stop,
    )
}

/// What a run of the one loop takes from its scene, whatever the scene's kind (one actuator, or a
/// mechanism of several).
pub struct RunPlan<'a> {
    /// The run's name.
    pub name: &'a str,
    /// Its controller's kind (every actuator's).
    pub controller: crate::schema::ControllerKind,
    /// The control period, s.
    pub dt_s: f64,
    /// Ticks of the run (its trace has one more row).
    pub n_steps: usize,
    /// The events the plant applies, each at the first tick at or after its time.
    pub events: &'a [crate::schema::EventSpec],
    /// Each actuator's position and force limits.
    pub divergence: &'a crate::schema::DivergenceSpec,
    /// An error placed at a key of the scene file (`events[2]`).
    pub invalid: &'a dyn Fn(&str, String) -> SceneError,
}

/// A declared name that lives as long as the program: the prefixed column names of a plant of several
/// actuators (`left.f_e`), which the sinks receive as [`pneuflex_control::Signal`]s. Each distinct name is
/// kept once, so a sweep of many runs does not grow memory.
pub(crate) fn interned(name: String) -> &'static str {
    use std::collections::HashSet;
    use std::sync::{Mutex, OnceLock};
    static NAMES: OnceLock<Mutex<HashSet<&'static str>>> = OnceLock::new();
    let mut names = NAMES
        .get_or_init(Default::default)
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    if let Some(&n) = names.get(name.as_str()) {
        return n;
    }
    let n: &'static str = Box::leak(name.into_boxed_str());
    names.insert(n);
    n
}

/// [`interned`] for a whole declaration list (a plant's signals), kept once per distinct list of names.
pub(crate) fn interned_signals(
    signals: Vec<pneuflex_control::Signal>,
) -> &'static [pneuflex_control::Signal] {
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};
    type Lists = HashMap<Vec<&'static str>, &'static [pneuflex_control::Signal]>;
    static LISTS: OnceLock<Mutex<Lists>> = OnceLock::new();
    let key: Vec<&'static str> = signals.iter().map(|s| s.name).collect();
    let mut lists = LISTS
        .get_or_init(Default::default)
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    lists
        .entry(key)
        .or_insert_with(|| Box::leak(signals.into_boxed_slice()))
}

/// One run of the one loop: `controllers[i]` drives the plant's actuator `i` toward `reference(i, t)`.
/// The row is `t`, then each actuator's block (the loop's signals but `t`, then its controller's own; named
/// `<actuator>.<signal>` when the plant has several), then the plant's own signals.
pub fn simulate_run<'p>(
    plan: &RunPlan<'_>,
    plant: &mut (dyn Plant + 'p),
    controllers: &mut [&mut dyn Controller],
    reference: &mut dyn FnMut(usize, f64) -> Setpoint,
    progress: &mut dyn FnMut(f64),
    observer: &mut dyn Sink<dyn Plant + 'p>,
    stop: Option<&std::sync::atomic::AtomicUsize>,
) -> Result<RunResult, SceneError> {
    use pneuflex_control::signal::index;
    use pneuflex_control::{LOOP_SIGNALS, Signal};
    let pwm_period_s = plant.pwm_period_s();
    let dt = plan.dt_s;
    let n = plan.n_steps;
    let names: Vec<String> = plant.actuator_names().to_vec();
    assert!(
        names.is_empty() && controllers.len() == 1 || names.len() == controllers.len(),
        "a controller per actuator"
    );
    // Event order by time, keeping each event's index in the file for messages.
    let mut events: Vec<(usize, &crate::schema::EventSpec)> =
        plan.events.iter().enumerate().collect();
    events.sort_by(|a, b| a.1.t_s().total_cmp(&b.1.t_s()));
    // The row: t, each actuator's block, the plant's signals, as each declares them.
    let prefixed = |i: usize, s: &Signal| -> Signal {
        match names.get(i) {
            Some(a) => Signal {
                name: interned(format!("{a}.{}", s.name)),
                ..*s
            },
            None => *s,
        }
    };
    let mut declared: Vec<Signal> = vec![LOOP_SIGNALS[index::T]];
    let mut limits = Vec::with_capacity(controllers.len());
    for (i, c) in controllers.iter().enumerate() {
        let at = declared.len() - 1;
        limits.push(ActuatorColumns {
            name: names.get(i).cloned(),
            x: at + index::X,
            f_e: at + index::F_E,
            x_r: at + index::X_R,
        });
        declared.extend(
            LOOP_SIGNALS[1..]
                .iter()
                .chain(c.signals())
                .map(|s| prefixed(i, s)),
        );
    }
    declared.extend(plant.signals().iter().copied());
    let columns: Vec<super::trace::Column> = declared.iter().map(Into::into).collect();
    observer.begin(plan.name, &declared, &*plant);
    let mut values = vec![0.0; columns.len()];
    let mut host = SimulationHost {
        plan,
        plant,
        events,
        next_event: 0,
        trace: Trace::with_capacity(n + 1, columns),
        observer,
        actuators: limits,
        last_step: n as u64,
        report_every: (n / 200).max(1) as u64,
        progress,
        stop,
        diverged: None,
        interrupted: None,
    };
    pneuflex_control::tick::run_loops(&mut host, controllers, reference, dt, &mut values)?;
    let SimulationHost {
        trace,
        diverged,
        interrupted,
        progress,
        ..
    } = host;
    progress(1.0);
    Ok(RunResult {
        name: plan.name.to_string(),
        controller: plan.controller,
        trace,
        windows: Vec::new(),
        lyapunov: None,
        diverged,
        interrupted,
        warnings: Vec::new(),
        pwm_period_s,
    })
}

/// Where an actuator's position, force and reference position sit in the row, and its name when the
/// plant has several (a divergence names it).
struct ActuatorColumns {
    name: Option<String>,
    x: usize,
    f_e: usize,
    x_r: usize,
}

/// A simulated plant around the controller: events at their tick, the trace and the observers at every
/// tick, the divergence and invariant checks, the integration ([`pneuflex_control::tick::run_loop`]).
struct SimulationHost<'a, 'p> {
    plan: &'a RunPlan<'a>,
    plant: &'a mut (dyn Plant + 'p),
    /// The scene's events by time, each with its index in the file (for messages).
    events: Vec<(usize, &'a crate::schema::EventSpec)>,
    next_event: usize,
    trace: Trace,
    observer: &'a mut dyn Sink<dyn Plant + 'p>,
    /// Each actuator's columns the divergence checks read.
    actuators: Vec<ActuatorColumns>,
    /// The tick at the run's end (the trace has `last_step + 1` rows).
    last_step: u64,
    report_every: u64,
    progress: &'a mut dyn FnMut(f64),
    stop: Option<&'a std::sync::atomic::AtomicUsize>,
    diverged: Option<String>,
    interrupted: Option<String>,
}

impl pneuflex_control::tick::LoopHost for SimulationHost<'_, '_> {
    type Error = SceneError;

    fn begin_tick(&mut self, _k: u64, t: f64) -> Result<pneuflex_control::tick::Flow, SceneError> {
        // Events apply at the first tick at or after their time (half a tick of tolerance for rounding).
        let half = 0.5 * self.plan.dt_s;
        while let Some(&(index, ev)) = self.events.get(self.next_event)
            && ev.t_s() <= t + half
        {
            self.plant
                .apply(ev)
                .map_err(|m| (self.plan.invalid)(&format!("events[{index}]"), m.to_string()))?;
            self.next_event += 1;
        }
        Ok(pneuflex_control::tick::Flow::Continue)
    }

    fn sense(&mut self, _k: u64, _t: f64, actuator: usize) -> Option<control::Sensors> {
        Some(self.plant.sense_actuator(actuator))
    }

    fn record(&mut self, row: &mut [f64]) {
        self.plant.record(row);
    }

    fn actuate(
        &mut self,
        _k: u64,
        _t: f64,
        actuator: usize,
        command: &control::ValveCommand,
        telemetry: &control::Telemetry,
    ) -> f64 {
        self.plant.actuate_actuator(actuator, *command, telemetry);
        command.u
    }

    fn end_tick(
        &mut self,
        k: u64,
        t: f64,
        row: &mut [f64],
    ) -> Result<pneuflex_control::tick::Flow, SceneError> {
        use pneuflex_control::tick::Flow;
        self.trace.push(row);
        self.observer.row(row, &*self.plant);
        let lim = self.plan.divergence;
        for a in &self.actuators {
            if let Some(reason) = lim.exceeded(t, row[a.x], row[a.f_e], row[a.x_r]) {
                self.diverged = Some(match &a.name {
                    Some(name) => format!("{name}: {reason}"),
                    None => reason,
                });
                return Ok(Flow::Stop);
            }
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
