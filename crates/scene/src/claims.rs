//! The paper's claims as a table the tool produces: for each `[[claims]]` of a scene, the two runs' values
//! of the metric and whether the claim holds (summary.json `claims`, printed by `run`).

use serde::Serialize;

use crate::runner::{RunResult, WindowMetrics};
use crate::schema::{ClaimSpec, Scene};

/// One claim checked on a scene's results.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ClaimResult {
    /// The claim in words.
    pub statement: String,
    /// Window and metric it is read on.
    pub window: String,
    /// The metric (lower is better).
    pub metric: String,
    /// The run claimed better, and its value (None: missing, diverged or not settled).
    pub better: String,
    /// Its value.
    pub better_value: Option<f64>,
    /// The run compared with.
    pub than: String,
    /// Its value.
    pub than_value: Option<f64>,
    /// Whether the claim holds on these results.
    pub holds: bool,
    /// Why it does not hold, when it does not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub why_not: Option<String>,
}

/// The value of `metric` in a window (settling time None when not settled).
fn value(w: &WindowMetrics, metric: &str) -> Option<f64> {
    let e = w.event.as_ref();
    match metric {
        "rms_force_error_n" => Some(w.rms_force_error_n),
        "phase_lag_deg" => w.phase_lag_deg,
        "steady_state_error_n" => w.steady_state_error_n.map(f64::abs),
        "peak_force_n" => e.map(|e| e.peak_force_n),
        "jump_n" => e.map(|e| e.jump_n),
        "recovery_overshoot_n" => e.map(|e| e.recovery_overshoot_n),
        "recovery_overshoot_pct" => e.map(|e| e.recovery_overshoot_pct),
        "settling_time_s" => e.and_then(|e| e.settling_time_s),
        _ => None,
    }
}

fn lookup<'a>(results: &'a [RunResult], run: &str, window: &str) -> Option<&'a WindowMetrics> {
    results.iter().find(|r| r.name == run)?.window(window)
}

/// Checks one claim against a scene's results: it holds when the better run's value is lower by at least
/// the claim's margin.
pub fn check(c: &ClaimSpec, results: &[RunResult]) -> ClaimResult {
    let get = |run: &str| lookup(results, run, &c.window).and_then(|w| value(w, &c.metric));
    let (b, t) = (get(&c.better), get(&c.than));
    let settling = c.metric == "settling_time_s";
    let why_not = match (b, t) {
        (Some(b), Some(t)) if b < t && t - b >= 0.01 * c.margin_pct * b.abs().max(t.abs()) => None,
        (Some(b), Some(t)) if b < t => Some(format!(
            "too close to call: {} {b:.4} is below {} {t:.4} by {:.2} %, less than the {} % margin",
            c.better,
            c.than,
            100.0 * (t - b) / b.abs().max(t.abs()),
            c.margin_pct
        )),
        (Some(b), Some(t)) => Some(format!(
            "{} {b:.4} is not below {} {t:.4}",
            c.better, c.than
        )),
        // Not settling is an infinite settling time: a settled run beats one that did not settle.
        (Some(_), None) if settling => None,
        (None, _) if settling => Some(format!("{} did not settle", c.better)),
        _ => Some("a value is missing (a run diverged or did not reach the window)".into()),
    };
    ClaimResult {
        statement: c.statement.clone(),
        window: c.window.clone(),
        metric: c.metric.clone(),
        better: c.better.clone(),
        better_value: b,
        than: c.than.clone(),
        than_value: t,
        holds: why_not.is_none(),
        why_not,
    }
}

/// Every claim of the scene checked against its results.
pub fn check_all(scene: &Scene, results: &[RunResult]) -> Vec<ClaimResult> {
    scene.claims.iter().map(|c| check(c, results)).collect()
}
