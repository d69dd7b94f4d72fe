//! The paper's claims as a table the tool produces: for each `[[claims]]` of a scene, the two runs' values
//! of the metric and whether the claim holds (summary.json `claims`, printed by `run`).

use serde::Serialize;

use crate::run::result::{RunResult, WindowMetrics};
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
    /// On settling times: the verdict flips when the settling band is drawn 5 % narrower or wider
    /// (`EventResponse::settling_time_range_s`), with both runs' ranges. Such a verdict is not one to lean on.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fragile: Option<String>,
}

/// The metrics a claim (and a comparison) can name.
pub const METRICS: [&str; 8] = [
    "rms_force_error_n",
    "phase_lag_deg",
    "steady_state_error_n",
    "peak_force_n",
    "jump_n",
    "recovery_overshoot_n",
    "recovery_overshoot_pct",
    "settling_time_s",
];

/// The value of `metric` in a window (settling time None when not settled; None when the window's kind
/// does not have it).
pub fn value(w: &WindowMetrics, metric: &str) -> Option<f64> {
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
    let why_not = verdict(c, b, t);
    // A settling-time verdict is checked again with both runs' settling times at the probed bands.
    let range = |run: &str| {
        lookup(results, run, &c.window)
            .and_then(|w| w.event.as_ref())
            .map(|e| e.settling_time_range_s)
    };
    let fragile = match (settling, range(&c.better), range(&c.than)) {
        (true, Some(rb), Some(rt))
            if (0..2).any(|k| verdict(c, rb[k], rt[k]).is_none() != why_not.is_none()) =>
        {
            let show = |r: [Option<f64>; 2]| {
                let s =
                    |v: Option<f64>| v.map_or("not settled".to_string(), |v| format!("{v:.3} s"));
                format!("{}–{}", s(r[0]), s(r[1]))
            };
            Some(format!(
                "the verdict flips with the settling band {:.0} % narrower or wider ({} {}, {} {})",
                100.0 * crate::analysis::metrics::SETTLING_BAND_PROBE,
                c.better,
                show(rb),
                c.than,
                show(rt)
            ))
        }
        _ => None,
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
        fragile,
    }
}

/// Why the claim does not hold for the better run's value `b` and the other's `t` (None: it holds).
fn verdict(c: &ClaimSpec, b: Option<f64>, t: Option<f64>) -> Option<String> {
    let settling = c.metric == "settling_time_s";
    match (b, t) {
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
    }
}

/// Every claim of the scene checked against its results.
pub fn check_all(scene: &Scene, results: &[RunResult]) -> Vec<ClaimResult> {
    scene.claims.iter().map(|c| check(c, results)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::metrics::{Steady, event_response};
    use crate::schema::{ControllerKind, WindowKind};

    /// A run whose only window, `change`, is the event response of f_e = 10 + e(t) on a 10 N reference.
    fn run(name: &str, e: impl Fn(f64) -> f64) -> RunResult {
        let t: Vec<f64> = (0..=4000).map(|k| k as f64 * 1e-3).collect();
        let f_ref = vec![10.0; t.len()];
        let f_e: Vec<f64> = t.iter().map(|&ti| 10.0 + e(ti)).collect();
        RunResult {
            name: name.into(),
            controller: ControllerKind::Impedance,
            trace: crate::run::trace::Trace::with_capacity(0, Vec::new()),
            windows: vec![WindowMetrics {
                name: "change".into(),
                kind: WindowKind::Event,
                t0_s: 0.0,
                t1_s: 4.0,
                rms_force_error_n: 0.0,
                frequency_hz: None,
                phase_lag_deg: None,
                amplitude_ratio: None,
                steady_state_error_n: None,
                event: event_response(&t, &f_ref, &f_e, Steady::Constant, None),
            }],
            lyapunov: None,
            diverged: None,
            interrupted: None,
            warnings: Vec::new(),
            pwm_period_s: None,
        }
    }

    fn claim(better: &str, than: &str) -> ClaimSpec {
        ClaimSpec {
            statement: format!("{better} settles faster"),
            window: "change".into(),
            metric: "settling_time_s".into(),
            better: better.into(),
            than: than.into(),
            margin_pct: 2.0,
        }
    }

    #[test]
    fn a_settling_verdict_that_flips_with_the_band_is_called_fragile() {
        // `edge`: a damped oscillation whose 5th extremum (w t = 5π - atan(a/w), 1.551 s) is 2 % above the
        // 0.2 N band, so it settles just after it with the nominal band, and ~0.1 s after the 4th (1.237 s)
        // with a 5 % wider one. `smooth`: 5 e^{-2.2 t}, which reaches the band at ln(25)/2.2 = 1.463 s (the
        // wider one at 1.441 s), between the two.
        let (a, w) = (2.0_f64, 10.0_f64);
        let shape = move |t: f64| (-a * t).exp() * (w * t).cos();
        let t5 = (5.0 * std::f64::consts::PI - (a / w).atan()) / w;
        let amp = 1.02 * 0.2 / shape(t5).abs();
        let results = [
            run("edge", move |t| amp * shape(t)),
            run("smooth", |t| 5.0 * (-2.2 * t).exp()),
        ];
        let c = check(&claim("edge", "smooth"), &results);
        assert!(!c.holds, "{c:?}");
        let why = c.fragile.expect("the verdict flips with the wider band");
        assert!(why.contains("edge") && why.contains("smooth"), "{why}");
        // The smooth run against a slower smooth one: the same verdict at every band, nothing to flag.
        let results = [
            run("smooth", |t| 5.0 * (-2.2 * t).exp()),
            run("slow", |t| 5.0 * (-1.1 * t).exp()),
        ];
        let c = check(&claim("smooth", "slow"), &results);
        assert!(c.holds && c.fragile.is_none(), "{c:?}");
    }
}
