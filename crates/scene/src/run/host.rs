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
    let run = &scene.runs[index];
    let pwm_period_s = plant.pwm_period_s();
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
    observer.begin(&run.name, &declared, &*plant);
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
        pwm_period_s,
    })
}

/// A simulated plant around the controller: events at their tick, the trace and the observers at every
/// tick, the divergence and invariant checks, the integration ([`pneuflex_control::tick::run_loop`]).
struct SimulationHost<'a, 'p> {
    scene: &'a Scene,
    plant: &'a mut (dyn Plant + 'p),
    /// The scene's events by time, each with its index in the file (for messages).
    events: Vec<(usize, &'a crate::schema::EventSpec)>,
    next_event: usize,
    trace: Trace,
    observer: &'a mut dyn Sink<dyn Plant + 'p>,
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
        self.observer.row(row, &*self.plant);
        let lim = &self.scene.divergence;
        if let Some(reason) = lim.exceeded(t, row[index::X], row[index::F_E], row[index::X_R]) {
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
