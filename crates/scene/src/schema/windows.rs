//! `[[metrics]]`: the named time windows over which metrics are computed.

use serde::{Deserialize, Serialize};

use super::Scene;
use crate::error::SceneError;
use crate::origin::Check;

/// What a metric window measures.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum WindowKind {
    /// A sine reference: RMS error and phase lag of f_e behind f_ref.
    Sine,
    /// A step (constant) reference: RMS error and steady-state error.
    Step,
    /// After an event: peak force, recovery overshoot, 2% settling time.
    Event,
}

/// A named time window for metrics.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MetricWindow {
    /// Window name (a key in summary.json).
    pub name: String,
    /// Window start, s (for `event`: the event time).
    pub t0_s: f64,
    /// Window end, s.
    pub t1_s: f64,
    /// What to measure.
    pub kind: WindowKind,
}

/// Checks `[[metrics]]`: unique names, windows inside the scene, a sine piece under a sine window.
pub(crate) fn validate(scene: &Scene, v: &Check<'_>) -> Result<(), SceneError> {
    for (i, w) in scene.metrics.iter().enumerate() {
        let at = |k: &str| format!("metrics[{i}].{k}");
        if w.name.trim().is_empty() {
            return Err(v.err(&at("name"), "must not be empty".into()));
        }
        if scene.metrics[..i].iter().any(|o| o.name == w.name) {
            return Err(v.err(&at("name"), format!("duplicate window name {:?}", w.name)));
        }
        v.non_negative(&at("t0_s"), w.t0_s)?;
        v.finite(&at("t1_s"), w.t1_s)?;
        if w.t1_s <= w.t0_s || w.t1_s > scene.duration_s + 0.5 * scene.dt_s {
            return Err(v.err(
                &at("t1_s"),
                format!(
                    "must satisfy t0_s < t1_s <= duration_s ({}), got t0_s = {}, t1_s = {}",
                    scene.duration_s, w.t0_s, w.t1_s
                ),
            ));
        }
        if w.kind == WindowKind::Sine && scene.reference.sine_in(w.t0_s, w.t1_s).is_none() {
            return Err(v.err(
                &at("kind"),
                format!(
                    "\"sine\" needs one sine reference piece covering [{}, {}] s",
                    w.t0_s, w.t1_s
                ),
            ));
        }
    }
    Ok(())
}
