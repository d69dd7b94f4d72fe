//! Runs a mechanism scene through the one loop: per run, a controller per actuator on a fresh
//! [`MechanismPlant`], driven by the simulation host every scene kind runs on (events at their tick, the
//! trace and the sinks every tick, each actuator's divergence limits and the plant's invariants).

use std::sync::atomic::AtomicUsize;

use pneuflex_control::Setpoint;

use super::plant::{MechanismPlant, loop_events};
use super::schema::MechanismScene;
use crate::error::SceneError;
use crate::plants::Plant;
use crate::run::{RunPlan, RunResult, Sink, simulate_run};

/// Runs every run of the scene; `progress` gets the fraction done; a non-zero `stop` (a signal's number)
/// ends the run in progress at the next tick, marked interrupted, and starts no other. Each run's trace is
/// `t`, then per actuator `<name>.<signal>`: the loop's signals, its controller's own, then the plant's
/// `x_dot` and `force` of each actuator.
pub fn run_all(
    scene: &MechanismScene,
    progress: &mut dyn FnMut(f64),
    stop: Option<&AtomicUsize>,
    observer: &mut dyn Sink<dyn Plant>,
) -> Result<Vec<RunResult>, SceneError> {
    let mut out = Vec::with_capacity(scene.runs.len());
    let n = scene.runs.len() as f64;
    for r in 0..scene.runs.len() {
        let run = run_one(
            scene,
            r,
            &mut |_, _, scheduled| scheduled,
            &mut |f| progress((r as f64 + f) / n),
            observer,
            stop,
        )?;
        let stopped = run.interrupted.is_some();
        out.push(run);
        if stopped {
            break;
        }
    }
    progress(1.0);
    Ok(out)
}

/// Run `r` of the scene on a fresh plant, actuator `i`'s setpoint at `t` being `reference(i, t, scheduled)`
/// with `scheduled` the scene's own (`pneuflex ros2` replaces it with a commanded one); the sink's `end` is
/// called when it ends.
pub fn run_one(
    scene: &MechanismScene,
    r: usize,
    reference: &mut dyn FnMut(usize, f64, Setpoint) -> Setpoint,
    progress: &mut dyn FnMut(f64),
    observer: &mut dyn Sink<dyn Plant>,
    stop: Option<&AtomicUsize>,
) -> Result<RunResult, SceneError> {
    let events = loop_events(scene);
    let invalid = |key: &str, message: String| scene.invalid(key, message);
    let spec = &scene.runs[r];
    let mut plant = MechanismPlant::new(scene)?;
    let mut controllers = scene.run_controllers(r)?;
    let schedules = plant.schedules().to_vec();
    let mut each: Vec<&mut dyn pneuflex_control::Controller> = controllers
        .iter_mut()
        .map(|c| &mut **c as &mut dyn pneuflex_control::Controller)
        .collect();
    let plan = RunPlan {
        name: &spec.name,
        controller: spec.controller,
        dt_s: scene.dt_s,
        n_steps: scene.n_steps(),
        events: &events,
        divergence: &scene.divergence,
        invalid: &invalid,
    };
    let run = simulate_run(
        &plan,
        &mut plant,
        &mut each,
        &mut |i, t| reference(i, t, schedules[i].at(t)),
        progress,
        observer,
        stop,
    )?;
    observer.end(run.diverged.as_deref().or(run.interrupted.as_deref()));
    Ok(run)
}
