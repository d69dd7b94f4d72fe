//! The product's control tick, timed: run `index` of a scene through the one loop and its simulation host
//! (events, trace, sinks, divergence and invariant checks, the plant's integration) — what `pneuflex run`
//! executes — with a clock read at two ticks. The benches, `examples/tick_rate.rs` and Python's
//! `bench_scene_ticks` time this, not a loop of their own.

use std::time::{Duration, Instant};

use pneuflex_control::signal::index;
use pneuflex_control::{Signal, Sink};

use crate::error::SceneError;
use crate::schema::Scene;
use crate::schema::plant::build_plant;

/// What [`time_ticks`] measured.
#[derive(Clone, Debug, PartialEq)]
pub struct TickTiming {
    /// Wall time of the timed ticks.
    pub wall: Duration,
    /// Number of timed ticks.
    pub ticks: u64,
    /// Mean contact force over the timed ticks, N (a check that the loop did what the scene does).
    pub mean_f_e_n: f64,
    /// The last timed tick's row (`LOOP_SIGNALS`, then the controller's and the plant's own).
    pub last_row: Vec<f64>,
}

/// Reads the clock when the tick `settle` ends and when the tick `settle + ticks` ends.
struct Stopwatch {
    settle: u64,
    ticks: u64,
    k: u64,
    start: Option<Instant>,
    end: Option<Instant>,
    sum_f_e: f64,
    last_row: Vec<f64>,
}

impl<W: ?Sized> Sink<W> for Stopwatch {
    fn begin(&mut self, _run: &str, _columns: &[Signal], _world: &W) {
        self.k = 0;
    }

    fn row(&mut self, values: &[f64], _world: &W) {
        let k = self.k;
        self.k += 1;
        if k == self.settle {
            self.start = Some(Instant::now());
        } else if k > self.settle && k <= self.settle + self.ticks {
            self.sum_f_e += values[index::F_E];
            if k == self.settle + self.ticks {
                self.end = Some(Instant::now());
                self.last_row = values.to_vec();
            }
        }
    }
}

/// Times `ticks` ticks of run `index` after `settle_s` of untimed ticks (steady contact, say), on a
/// fresh plant of the scene; the scene's duration is set to cover them.
pub fn time_ticks(
    scene: &Scene,
    index: usize,
    ticks: u64,
    settle_s: f64,
) -> Result<TickTiming, SceneError> {
    if index >= scene.runs.len() {
        return Err(scene.invalid(
            "runs",
            format!("no run {index}: the scene has {}", scene.runs.len()),
        ));
    }
    let dt = scene.dt_s;
    let settle = (settle_s.max(0.0) / dt).round() as u64;
    let ticks = ticks.max(1);
    let mut timed = scene.clone();
    // Ticks 0..=settle+ticks: the last one ends the run.
    timed.duration_s = (settle + ticks) as f64 * dt;
    let setpoints = timed.setpoints()?;
    let mut plant = build_plant(&timed)?;
    let mut controller = timed.controller(index)?;
    let mut watch = Stopwatch {
        settle,
        ticks,
        k: 0,
        start: None,
        end: None,
        sum_f_e: 0.0,
        last_row: Vec::new(),
    };
    let r = super::simulate_observed(
        &timed,
        index,
        plant.as_mut(),
        controller.as_mut(),
        &setpoints,
        &mut |_| {},
        &mut watch,
    )?;
    if let Some(why) = r.diverged {
        return Err(timed.invalid(
            &format!("runs[{index}]"),
            format!("diverged while timed: {why}"),
        ));
    }
    let (Some(start), Some(end)) = (watch.start, watch.end) else {
        return Err(timed.invalid(
            "duration_s",
            format!(
                "the run ended after {} ticks, before the {} timed ones",
                watch.k,
                settle + ticks
            ),
        ));
    };
    Ok(TickTiming {
        wall: end - start,
        ticks,
        mean_f_e_n: watch.sum_f_e / ticks as f64,
        last_row: watch.last_row,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_timed_ticks_are_the_runs_own() {
        // Before the first event the timed loop is the scene's run: its last row is the trace's row.
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paper-fig3.toml");
        let scene = Scene::load(&path).unwrap();
        let runs = crate::run_scene(&scene, &mut |_| {}).unwrap();
        for (i, r) in runs.iter().enumerate() {
            if scene.runs[i].frozen.is_some() {
                // Its values come from the whole scene's run: timed alone, it has none to hold.
                let e = time_ticks(&scene, i, 300, 0.2).unwrap_err().to_string();
                assert!(e.contains("frozen"), "{e}");
                continue;
            }
            let t = time_ticks(&scene, i, 300, 0.2).unwrap();
            assert_eq!(t.ticks, 300);
            let k = 200 + 300;
            assert_eq!(t.last_row[index::T], r.trace.t()[k]);
            assert_eq!(t.last_row[index::F_E], r.trace.f_e()[k], "run {}", r.name);
            assert_eq!(t.last_row[index::X], r.trace.column("x").unwrap()[k]);
            let mean = r.trace.f_e()[201..=k].iter().sum::<f64>() / 300.0;
            assert!((t.mean_f_e_n - mean).abs() <= 1e-12 * mean.abs().max(1.0));
        }
        assert!(time_ticks(&scene, 9, 10, 0.0).is_err());
    }
}
