//! A mechanism scene's metrics per run, window and actuator, its claims, and the files they are written to.

use std::path::Path;

use serde::Serialize;

use super::schema::{MechanismScene, WindowSpec};
use crate::error::SceneError;
use crate::run::RunResult;

/// One actuator's force tracking in a window.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ActuatorMetrics {
    /// RMS of f_r − f_e, N (null when the window holds no sample).
    pub rms_force_error_n: f64,
    /// Largest |f_r − f_e|, N.
    pub max_abs_force_error_n: f64,
    /// Mean contact force, N.
    pub mean_force_n: f64,
}

/// A window of one run.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct WindowMetrics {
    /// The window's name.
    pub window: String,
    /// Per actuator, in scene order.
    pub actuators: Vec<(String, ActuatorMetrics)>,
    /// RMS over the window of the spread of the actuators' contact forces (largest − smallest), N: how
    /// unevenly the fingers of a gripper squeeze.
    pub force_imbalance_n: f64,
}

/// A run's summary.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct RunSummary {
    /// Run name.
    pub name: String,
    /// Its controller's kind (on every actuator).
    pub controller: crate::schema::ControllerKind,
    /// Why it stopped early, if it did.
    pub diverged: Option<String>,
    /// Why a signal cut it short, if one did.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub interrupted: Option<String>,
    /// Its windows.
    pub windows: Vec<WindowMetrics>,
}

/// A claim's verdict for one actuator (or the whole mechanism).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ClaimResult {
    /// The claim as written.
    pub statement: String,
    /// The actuator it was checked on (None for `force_imbalance_n`).
    pub actuator: Option<String>,
    /// The metric compared.
    pub metric: String,
    /// The better run's value.
    pub better_value: f64,
    /// The other run's value.
    pub than_value: f64,
    /// Whether the better run's value is lower by the claim's margin (the rule of every scene's claims,
    /// [`crate::analysis::claims::beats`]).
    pub holds: bool,
}

/// What `summary.json` holds.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct MechanismSummary {
    /// Scene name.
    pub scene: String,
    /// Scene description.
    pub description: String,
    /// The actuators' names.
    pub actuators: Vec<String>,
    /// Each run.
    pub runs: Vec<RunSummary>,
    /// Each claim, per actuator.
    pub claims: Vec<ClaimResult>,
}

/// One window's metrics of a run: per actuator, and the spread between them.
pub fn window_metrics(scene: &MechanismScene, run: &RunResult, w: &WindowSpec) -> WindowMetrics {
    let column = |name: &str| run.trace.column(name).unwrap_or_default();
    let t = column("t");
    // The one window rule of every scene kind: [t0, t1), the run's last sample included when t1 is its end.
    let (i0, i1) = if t.is_empty() {
        (0, 0)
    } else {
        crate::analysis::metrics::window_indices(t, w.t0_s, w.t1_s)
    };
    let inside: Vec<usize> = (i0..i1).collect();
    let forces: Vec<&[f64]> = scene
        .actuators
        .iter()
        .map(|a| column(&format!("{}.f_e", a.name)))
        .collect();
    let mut actuators = Vec::new();
    for (a, f_e) in scene.actuators.iter().zip(&forces) {
        let f_r = column(&format!("{}.f_ref", a.name));
        // No sample in the window (a run stopped before it): NaN, written as null.
        let n = inside.len() as f64;
        let err = |i: usize| f_r[i] - f_e[i];
        actuators.push((
            a.name.clone(),
            ActuatorMetrics {
                rms_force_error_n: (inside.iter().map(|&i| err(i).powi(2)).sum::<f64>() / n).sqrt(),
                max_abs_force_error_n: inside
                    .iter()
                    .map(|&i| err(i).abs())
                    .fold(f64::NAN, f64::max),
                mean_force_n: inside.iter().map(|&i| f_e[i]).sum::<f64>() / n,
            },
        ));
    }
    let spread = |i: usize| {
        let (lo, hi) = forces
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), f| {
                (lo.min(f[i]), hi.max(f[i]))
            });
        hi - lo
    };
    let force_imbalance_n =
        (inside.iter().map(|&i| spread(i).powi(2)).sum::<f64>() / inside.len() as f64).sqrt();
    WindowMetrics {
        window: w.name.clone(),
        actuators,
        force_imbalance_n,
    }
}

/// The summary of `runs` (those that ran).
pub fn summarise(scene: &MechanismScene, runs: &[RunResult]) -> MechanismSummary {
    let summaries: Vec<RunSummary> = runs
        .iter()
        .map(|r| RunSummary {
            name: r.name.clone(),
            controller: r.controller,
            diverged: r.diverged.clone(),
            interrupted: r.interrupted.clone(),
            windows: scene
                .metrics
                .iter()
                .map(|w| window_metrics(scene, r, w))
                .collect(),
        })
        .collect();
    let mut claims = Vec::new();
    let window = |run: &str, w: &str| {
        summaries
            .iter()
            .find(|s| s.name == run && s.diverged.is_none())
            .and_then(|s| s.windows.iter().find(|m| m.window == w))
    };
    for c in &scene.claims {
        let (Some(better), Some(than)) = (window(&c.better, &c.window), window(&c.than, &c.window))
        else {
            continue;
        };
        let mut push = |actuator: Option<String>, b: f64, t: f64| {
            claims.push(ClaimResult {
                statement: c.statement.clone(),
                actuator,
                metric: c.metric.clone(),
                better_value: b,
                than_value: t,
                holds: crate::analysis::claims::beats(b, t, c.margin_pct),
            })
        };
        if c.metric == "force_imbalance_n" {
            push(None, better.force_imbalance_n, than.force_imbalance_n);
            continue;
        }
        for ((name, mb), (_, mt)) in better.actuators.iter().zip(&than.actuators) {
            if c.actuator.as_ref().is_some_and(|a| a != name) {
                continue;
            }
            let pick = |m: &ActuatorMetrics| match c.metric.as_str() {
                "rms_force_error_n" => m.rms_force_error_n,
                _ => m.max_abs_force_error_n,
            };
            push(Some(name.clone()), pick(mb), pick(mt));
        }
    }
    MechanismSummary {
        scene: scene.name.clone(),
        description: scene.description.clone(),
        actuators: scene.actuators.iter().map(|a| a.name.clone()).collect(),
        runs: summaries,
        claims,
    }
}

fn write_err(path: &Path) -> impl Fn(std::io::Error) -> SceneError + '_ {
    move |os_error| SceneError::Write {
        path: path.to_path_buf(),
        os_error,
    }
}

/// Writes every run's trace (`<dir>/<run>/trace.csv`, or `trace.diverged.csv` / `trace.interrupted.csv`
/// for a run cut short) and `<dir>/summary.json`.
pub fn write(dir: &Path, summary: &MechanismSummary, runs: &[RunResult]) -> Result<(), SceneError> {
    for r in runs {
        // The one trace writer and file name of every scene kind.
        crate::run::output::write_trace(dir, r)?;
    }
    let path = dir.join("summary.json");
    let text = serde_json::to_string_pretty(summary).expect("plain data");
    std::fs::write(&path, text + "\n").map_err(write_err(&path))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run of the gripper's two fingers, f_ref = 10 N, whose force error is `err(t)` on both fingers.
    fn run(scene: &MechanismScene, name: &str, err: impl Fn(f64) -> f64) -> RunResult {
        use crate::run::trace::{Column, Trace};
        let column = |n: String| Column {
            name: n,
            unit: "N".into(),
            group: "force".into(),
        };
        let mut columns = vec![column("t".into())];
        for a in &scene.actuators {
            columns.push(column(format!("{}.f_ref", a.name)));
            columns.push(column(format!("{}.f_e", a.name)));
        }
        let mut trace = Trace::with_capacity(scene.n_steps() + 1, columns);
        for k in 0..=scene.n_steps() {
            let t = k as f64 * scene.dt_s;
            let mut row = vec![t];
            for _ in &scene.actuators {
                row.extend([10.0, 10.0 - err(t)]);
            }
            trace.push(&row);
        }
        RunResult {
            name: name.into(),
            controller: crate::schema::ControllerKind::Impedance,
            trace,
            windows: Vec::new(),
            lyapunov: None,
            diverged: None,
            interrupted: None,
            warnings: Vec::new(),
            pwm_period_s: None,
        }
    }

    fn gripper() -> MechanismScene {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/gripper.toml");
        MechanismScene::load(&path).unwrap()
    }

    #[test]
    fn a_window_holds_t0_to_t1_without_t1_as_in_every_scene() {
        let scene = gripper();
        // 1 N of error from the sine_foam window's end (5 s) on: none of it inside [3, 5).
        let r = run(
            &scene,
            "impedance",
            |t| if t >= 5.0 - 1e-9 { 1.0 } else { 0.0 },
        );
        let s = summarise(&scene, &[r]);
        let foam = s.runs[0]
            .windows
            .iter()
            .find(|w| w.window == "sine_foam")
            .unwrap();
        assert_eq!(foam.actuators[0].1.rms_force_error_n, 0.0);
        assert_eq!(foam.actuators[0].1.max_abs_force_error_n, 0.0);
        // The run's last window ends at its end: its last sample counts.
        let rubber = s.runs[0]
            .windows
            .iter()
            .find(|w| w.window == "sine_rubber")
            .unwrap();
        assert_eq!(rubber.actuators[0].1.rms_force_error_n, 1.0);
    }

    #[test]
    fn a_claim_holds_only_past_its_margin_as_in_every_scene() {
        let mut scene = gripper();
        // adaptive 0.99 N RMS against impedance's 1.00 N: 1 % better.
        let runs = [
            run(&scene, "impedance", |_| 1.0),
            run(&scene, "adaptive", |_| 0.99),
        ];
        let holds = |scene: &MechanismScene| {
            summarise(scene, &runs)
                .claims
                .iter()
                .map(|c| c.holds)
                .collect::<Vec<_>>()
        };
        assert_eq!(
            holds(&scene),
            [false; 4],
            "1 % is within the default 2 % margin"
        );
        for c in &mut scene.claims {
            c.margin_pct = 0.5;
        }
        assert_eq!(holds(&scene), [true; 4]);
    }
}
