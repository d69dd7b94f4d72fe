//! Running a scene: for every controller it lists, the one loop on a fresh plant, recording a preallocated
//! trace, then the metrics of every window; the runs in parallel when nothing watches them.

mod host;
pub mod observe;
pub mod output;
pub mod result;
pub mod timing;
pub mod trace;

use pneuflex_control as control;

use crate::analysis::adaptation::{frozen_values, lyapunov_summary, pinned_parameters};
use crate::analysis::windows::compute_windows;
use crate::error::SceneError;
use crate::plants::Plant;
use crate::schema::plant::build_plant;
use crate::schema::{ControllerKind, FrozenValues, Scene};
pub use host::{
    RunPlan, simulate, simulate_observed, simulate_referenced, simulate_run, simulate_stoppable,
};
pub(crate) use host::{interned, interned_signals};
pub use observe::{Sink, Sinks};
pub use result::{LyapunovSummary, RunResult, WindowMetrics};
pub use timing::{TickTiming, time_ticks};

/// Runs every controller the scene lists, each on a fresh plant. `progress` receives the completed
/// fraction in [0, 1]. A diverged run is returned with `diverged` set; errors are only for bad input.
pub fn run_scene(
    scene: &Scene,
    progress: &mut dyn FnMut(f64),
) -> Result<Vec<RunResult>, SceneError> {
    run_scene_observed(scene, progress, &mut ())
}

/// [`run_scene`] with an observer called at every tick of every run.
pub fn run_scene_observed(
    scene: &Scene,
    progress: &mut dyn FnMut(f64),
    observer: &mut dyn Sink<dyn Plant>,
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
/// When the sink watches nothing ([`Sink::watches`]) and there are several runs and cores,
/// the runs execute in parallel (rayon's pool), each on its own plant from [`build_plant`]; the results
/// are the same, bit for bit, as one after another. A stop flag then stops every run in progress and no
/// further run starts.
pub fn run_scene_with(
    scene: &Scene,
    opts: &RunOptions<'_>,
    progress: &mut dyn FnMut(f64),
    observer: &mut dyn Sink<dyn Plant>,
) -> Result<Vec<RunResult>, SceneError> {
    scene.validate()?;
    scene.check_budget(&opts.limits)?;
    let setpoints = scene.setpoints()?;
    let n_runs = scene.runs.len();
    // Two phases: the adapting runs, then the frozen runs (always last), which hold values the first
    // phase's traces give.
    let n_adapting = scene
        .runs
        .iter()
        .position(|r| r.frozen.is_some())
        .unwrap_or(n_runs);
    let share =
        |lo: usize, hi: usize| move |f: f64| (lo as f64 + f * (hi - lo) as f64) / n_runs as f64;
    let first = share(0, n_adapting);
    let adapting = Phase {
        scene,
        opts,
        setpoints: &setpoints,
        first: 0,
        held: &vec![Ok(None); n_adapting],
    };
    let mut out = run_phase(&adapting, &mut |f| progress(first(f)), observer)?;
    if n_adapting < n_runs && out.len() == n_adapting && !stopped(opts) {
        let frozen: Vec<Held> = scene.runs[n_adapting..]
            .iter()
            .map(|run| {
                let f = run.frozen.as_ref().ok_or("not frozen")?;
                let source = out.iter().find(|r| r.name == f.run).ok_or("no source")?;
                frozen_values(run, source).map(Some)
            })
            .collect();
        let second = share(n_adapting, n_runs);
        let frozen = Phase {
            scene,
            opts,
            setpoints: &setpoints,
            first: n_adapting,
            held: &frozen,
        };
        let mut later = run_phase(&frozen, &mut |f| progress(second(f)), observer)?;
        out.append(&mut later);
    }
    progress(1.0);
    Ok(out)
}

/// What run `first + k` of a phase holds: `Ok(None)` for an adapting run, the values of a frozen run, or
/// why a frozen run is not simulated (its source did not finish): it comes back with an empty trace and
/// that reason as its divergence.
type Held = Result<Option<FrozenValues>, String>;

/// One phase of a scene's runs: runs `first..first + held.len()`, run `first + k` holding `held[k]`.
struct Phase<'a, 'o> {
    scene: &'a Scene,
    opts: &'a RunOptions<'o>,
    setpoints: &'a control::SetpointSchedule,
    first: usize,
    held: &'a [Held],
}

impl Phase<'_, '_> {
    /// What run `first + k` holds; or, for a frozen run with nothing to hold, its result (already
    /// given to `on_run`, like every run's).
    fn held(&self, k: usize) -> Result<Option<FrozenValues>, Box<RunResult>> {
        match &self.held[k] {
            Ok(held) => Ok(*held),
            Err(why) => {
                let r = not_simulated(self.scene, self.first + k, why);
                if let Some(f) = self.opts.on_run {
                    f(&r);
                }
                Err(Box::new(r))
            }
        }
    }
}

/// Runs a phase, one run after another or in parallel.
fn run_phase(
    phase: &Phase<'_, '_>,
    progress: &mut dyn FnMut(f64),
    observer: &mut dyn Sink<dyn Plant>,
) -> Result<Vec<RunResult>, SceneError> {
    let (scene, opts, setpoints, first) = (phase.scene, phase.opts, phase.setpoints, phase.first);
    let n_runs = phase.held.len();
    if n_runs == 0 {
        return Ok(Vec::new());
    }
    let parallel = !observer.watches()
        && n_runs > 1
        && rayon::current_num_threads() > 1
        // A pool thread must not block on the progress channel below.
        && rayon::current_thread_index().is_none();
    if parallel {
        return run_parallel(phase, progress);
    }
    let mut plant = build_plant(scene)?;
    let mut out = Vec::with_capacity(n_runs);
    for k in 0..n_runs {
        if stopped(opts) {
            break;
        }
        let i = first + k;
        let held = match phase.held(k) {
            Ok(held) => held,
            Err(not_run) => {
                out.push(*not_run);
                continue;
            }
        };
        let mut controller = scene.run_controller(i, held)?;
        plant.reset();
        let mut sub = |f: f64| progress((k as f64 + f) / n_runs as f64);
        let mut r = host::simulate_stoppable(
            scene,
            i,
            plant.as_mut(),
            controller.as_mut(),
            setpoints,
            &mut sub,
            observer,
            opts.stop,
        )?;
        observer.end(r.diverged.as_deref().or(r.interrupted.as_deref()));
        finish_run(scene, i, &mut r);
        if let Some(f) = opts.on_run {
            f(&r);
        }
        out.push(r);
    }
    Ok(out)
}

/// A frozen run whose source gave nothing to hold: no trace, no metrics, and `why` as its divergence.
fn not_simulated(scene: &Scene, i: usize, why: &str) -> RunResult {
    let run = &scene.runs[i];
    // The loop's columns and the controller's (the plant's are left out: no plant was built).
    let signals = scene
        .run_controller(i, Some(FrozenValues::default()))
        .map_or(&[][..], |c| c.signals());
    RunResult {
        name: run.name.clone(),
        controller: run.controller,
        trace: trace::Trace::with_capacity(0, trace::Trace::loop_columns(&[signals])),
        windows: Vec::new(),
        lyapunov: None,
        diverged: Some(why.to_string()),
        interrupted: None,
        warnings: Vec::new(),
        pwm_period_s: None,
    }
}

fn stopped(opts: &RunOptions<'_>) -> bool {
    opts.stop
        .is_some_and(|f| f.load(std::sync::atomic::Ordering::Relaxed) != 0)
}

/// A simulated run's metrics, Lyapunov check and warnings.
fn finish_run(scene: &Scene, i: usize, r: &mut RunResult) {
    finish_metrics(scene, i, r);
    if adapts(scene, i) {
        r.lyapunov = lyapunov_summary(scene, &scene.runs[i]);
    }
}

/// Whether run `i`'s law adapts (an adaptive run that is not frozen): what the Lyapunov check is about.
fn adapts(scene: &Scene, i: usize) -> bool {
    scene.runs[i].controller == ControllerKind::Adaptive && scene.runs[i].frozen.is_none()
}

/// A simulated run's window metrics and warnings (what needs its trace).
fn finish_metrics(scene: &Scene, i: usize, r: &mut RunResult) {
    if r.diverged.is_none() && r.interrupted.is_none() {
        r.windows = compute_windows(scene, &r.trace, r.pwm_period_s);
    }
    r.warnings = pinned_parameters(&scene.runs[i], &r.trace);
}

/// The fraction of a phase done, from each run's own fraction as the workers send them.
struct ProgressSum {
    done: Vec<f64>,
    total: f64,
}

impl ProgressSum {
    fn new(n_runs: usize) -> Self {
        ProgressSum {
            done: vec![0.0; n_runs],
            total: 0.0,
        }
    }

    /// Run `k` is `f` done: the phase's fraction, never above 1. The increments arrive in any order, so
    /// their rounded sum can pass 1 by an ulp, and a bar would then step back at the final 1.0.
    fn report(&mut self, k: usize, f: f64) -> f64 {
        self.total += f - self.done[k];
        self.done[k] = f;
        (self.total / self.done.len() as f64).min(1.0)
    }
}

/// The runs of a scene on the pool's threads: each worker takes the next run in the scene's order (so the
/// runs started are a prefix), builds its plant and controller, simulates and computes its metrics. The
/// calling thread makes the Lyapunov checks of the adaptive runs (they need the scene, not the trace; 2 ms
/// each on paper-fig7) while the workers simulate, where it would only wait for their messages: taken after
/// the runs, a check held back the outputs that wait for this function. A run stopped by a signal is still
/// checked, as in the sequential path. The calling thread reports progress from what the workers send. The
/// first error in run order is returned.
fn run_parallel(
    phase: &Phase<'_, '_>,
    progress: &mut dyn FnMut(f64),
) -> Result<Vec<RunResult>, SceneError> {
    use std::sync::Mutex;
    use std::sync::atomic::{AtomicUsize, Ordering};
    let (scene, opts, setpoints, first) = (phase.scene, phase.opts, phase.setpoints, phase.first);
    let n_runs = phase.held.len();
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
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    if k >= n_runs {
                        break;
                    }
                    let i = first + k;
                    let run = || -> Result<RunResult, SceneError> {
                        let held = match phase.held(k) {
                            Ok(held) => held,
                            Err(not_run) => return Ok(*not_run),
                        };
                        let mut plant = build_plant(scene)?;
                        let mut controller = scene.run_controller(i, held)?;
                        // Progress in steps of 1 % of the run (each message wakes the caller).
                        let mut sent = 0.0;
                        let mut sub = |f: f64| {
                            if f - sent >= 0.01 || (f >= 1.0 && sent < 1.0) {
                                sent = f;
                                let _ = tx.send((k, f));
                            }
                        };
                        let mut r = host::simulate_stoppable(
                            scene,
                            i,
                            plant.as_mut(),
                            controller.as_mut(),
                            setpoints,
                            &mut sub,
                            &mut (),
                            opts.stop,
                        )?;
                        finish_metrics(scene, i, &mut r);
                        if let Some(f) = opts.on_run {
                            f(&r);
                        }
                        Ok(r)
                    };
                    let r = run();
                    let failed = r.is_err();
                    *slots[k].lock().unwrap_or_else(|e| e.into_inner()) = Some(r);
                    if failed {
                        // Later runs would be discarded: start none.
                        next.fetch_max(n_runs, Ordering::Relaxed);
                    }
                }
            });
        }
        drop(tx);
        let lyapunov: Vec<Option<LyapunovSummary>> = (first..first + n_runs)
            .map(|i| {
                adapts(scene, i)
                    .then(|| lyapunov_summary(scene, &scene.runs[i]))
                    .flatten()
            })
            .collect();
        let mut sum = ProgressSum::new(n_runs);
        for (k, f) in rx {
            progress(sum.report(k, f));
        }
        lyapunov
    });
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

#[cfg(test)]
mod tests {
    use super::ProgressSum;

    /// Two runs reporting in turn, each in steps of 0.015 (as rounded floats, the way a run's 1 % steps
    /// land): the unclamped sum reaches 1 + 4e-15 before both runs end. The phase's fraction never
    /// passes 1, never falls, and ends at 1.
    #[test]
    fn a_phase_fraction_from_interleaved_runs_rises_to_exactly_one() {
        let mut steps = Vec::new();
        let mut f: f64 = 0.0;
        while f < 1.0 {
            f = (f + 0.015).min(1.0);
            steps.push(f);
        }
        let mut sum = ProgressSum::new(2);
        let mut seen = Vec::new();
        for &f in &steps {
            for k in 0..2 {
                seen.push(sum.report(k, f));
            }
        }
        assert!(seen.iter().all(|&p| p <= 1.0), "{seen:?}");
        assert!(seen.windows(2).all(|w| w[0] <= w[1]), "{seen:?}");
        assert_eq!(seen.last(), Some(&1.0));
    }
}
