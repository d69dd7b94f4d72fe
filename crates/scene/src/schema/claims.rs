//! `[[claims]]`: what the scene claims, one run better than another on a metric of a window.

use serde::{Deserialize, Serialize};

use super::Scene;
use super::windows::WindowKind;
use crate::error::SceneError;
use crate::origin::Check;

/// A claim: run `better` has a lower `metric` than run `than` over window `window` (every metric here is
/// better when lower; a run that did not settle has an infinite settling time).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ClaimSpec {
    /// The claim in words, as the paper makes it.
    pub statement: String,
    /// Metric window the claim is read on.
    pub window: String,
    /// Which metric: one of [`CLAIM_METRICS`].
    pub metric: String,
    /// The run claimed to be better.
    pub better: String,
    /// The run it is compared with.
    pub than: String,
    /// Smallest difference that counts, % of the larger value (default 2: a single run of the PWM loop moves
    /// its metrics by about that much under a halved step or a 1 µm change of x0; closer is too close to
    /// call, and the claim does not hold).
    #[serde(default = "two_percent")]
    pub margin_pct: f64,
}

fn two_percent() -> f64 {
    2.0
}

/// Metrics a claim can compare, with the window kinds that have them.
pub const CLAIM_METRICS: [(&str, &[WindowKind]); 8] = [
    (
        "rms_force_error_n",
        &[WindowKind::Sine, WindowKind::Step, WindowKind::Event],
    ),
    ("phase_lag_deg", &[WindowKind::Sine]),
    ("steady_state_error_n", &[WindowKind::Step]),
    ("peak_force_n", &[WindowKind::Event]),
    ("jump_n", &[WindowKind::Event]),
    ("recovery_overshoot_n", &[WindowKind::Event]),
    ("recovery_overshoot_pct", &[WindowKind::Event]),
    ("settling_time_s", &[WindowKind::Event]),
];

/// Checks `[[claims]]`: the window, the metric (measured on that window's kind) and both runs exist.
pub(crate) fn validate(scene: &Scene, v: &Check<'_>) -> Result<(), SceneError> {
    for (i, c) in scene.claims.iter().enumerate() {
        let at = |k: &str| format!("claims[{i}].{k}");
        let Some(w) = scene.metrics.iter().find(|w| w.name == c.window) else {
            return Err(v.err(
                &at("window"),
                format!("no metric window named {:?}", c.window),
            ));
        };
        match CLAIM_METRICS.iter().find(|(m, _)| *m == c.metric) {
            None => {
                let known: Vec<&str> = CLAIM_METRICS.iter().map(|(m, _)| *m).collect();
                return Err(v.err(
                    &at("metric"),
                    format!("unknown metric {:?}, expected one of {known:?}", c.metric),
                ));
            }
            Some((_, kinds)) if !kinds.contains(&w.kind) => {
                return Err(v.err(
                    &at("metric"),
                    format!("{:?} is not measured on a {:?} window", c.metric, w.kind),
                ));
            }
            Some(_) => {}
        }
        v.non_negative(&at("margin_pct"), c.margin_pct)?;
        for (k, run) in [("better", &c.better), ("than", &c.than)] {
            if !scene.runs.iter().any(|r| &r.name == run) {
                return Err(v.err(&at(k), format!("no run named {run:?}")));
            }
        }
    }
    Ok(())
}
