//! A run recorded outside the simulation (on the rig, by `rig run`; a log given to `compare`) judged as the
//! scene's run: the same windows, metrics, Lyapunov check and warnings as a simulated run, from the same
//! code, so its `summary.json` and figures read as `run`'s do.

use super::adaptation::{lyapunov_summary, pinned_parameters};
use super::windows::compute_windows;
use crate::run::RunResult;
use crate::run::trace::Trace;
use crate::schema::{ControllerKind, Scene};

/// Run `index` of `scene` (a scene reduced by [`Scene::one_run`] or [`Scene::some_runs`] to the runs
/// recorded and the time they ran) as `trace` recorded it. `ended` is why the recording ended early (a rig fault): the run is then
/// treated as a diverged simulation is — its trace kept, no window metrics. `pwm_period_s` is the
/// valve's PWM period of the scene's plant (the event metrics average over it).
pub fn recorded_run(
    scene: &Scene,
    index: usize,
    name: &str,
    trace: Trace,
    ended: Option<String>,
    pwm_period_s: Option<f64>,
) -> RunResult {
    let run = &scene.runs[index];
    let windows = if ended.is_none() {
        compute_windows(scene, &trace, pwm_period_s)
    } else {
        Vec::new()
    };
    let warnings = pinned_parameters(run, &trace);
    RunResult {
        name: name.to_string(),
        controller: run.controller,
        windows,
        lyapunov: if run.controller == ControllerKind::Adaptive {
            lyapunov_summary(scene, run)
        } else {
            None
        },
        diverged: ended,
        interrupted: None,
        warnings,
        pwm_period_s,
        trace,
    }
}
