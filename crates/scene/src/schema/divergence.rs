//! `[divergence]`: the thresholds that stop a run as diverged.

use serde::{Deserialize, Serialize};

use super::Scene;
use crate::error::SceneError;
use crate::origin::Check;

/// Thresholds that stop a run as diverged.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DivergenceSpec {
    /// Largest admissible |x|, m.
    #[serde(default = "default_max_position")]
    pub max_abs_position_m: f64,
    /// Largest admissible |f_e|, N.
    #[serde(default = "default_max_force")]
    pub max_abs_force_n: f64,
}

fn default_max_position() -> f64 {
    10.0
}

fn default_max_force() -> f64 {
    1.0e5
}

impl Default for DivergenceSpec {
    fn default() -> Self {
        Self {
            max_abs_position_m: default_max_position(),
            max_abs_force_n: default_max_force(),
        }
    }
}

/// Checks `[divergence]`.
pub(crate) fn validate(scene: &Scene, v: &Check<'_>) -> Result<(), SceneError> {
    let d = &scene.divergence;
    v.positive("divergence.max_abs_position_m", d.max_abs_position_m)?;
    v.positive("divergence.max_abs_force_n", d.max_abs_force_n)?;
    Ok(())
}
