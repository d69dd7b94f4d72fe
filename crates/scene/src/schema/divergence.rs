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

impl DivergenceSpec {
    /// Why a tick's state is a divergence, if it is: a non-finite position, force or reference position,
    /// or one beyond these thresholds. Every scene kind's loop asks this of every actuator at every tick.
    pub fn exceeded(&self, t: f64, x: f64, f_e: f64, x_r: f64) -> Option<String> {
        if !x.is_finite() || !f_e.is_finite() || !x_r.is_finite() {
            return Some(format!(
                "non-finite state at t = {t:.4} s (x = {x}, f_e = {f_e}, x_r = {x_r})"
            ));
        }
        if x.abs() > self.max_abs_position_m {
            return Some(format!(
                "|x| = {} m exceeds divergence.max_abs_position_m = {} at t = {t:.4} s",
                crate::error::readable(x.abs(), 4),
                self.max_abs_position_m
            ));
        }
        if x_r.abs() > self.max_abs_position_m {
            return Some(format!(
                "|x_r| = {} m exceeds divergence.max_abs_position_m = {} at t = {t:.4} s",
                crate::error::readable(x_r.abs(), 4),
                self.max_abs_position_m
            ));
        }
        if f_e.abs() > self.max_abs_force_n {
            return Some(format!(
                "|f_e| = {} N exceeds divergence.max_abs_force_n = {} at t = {t:.4} s",
                crate::error::readable(f_e.abs(), 1),
                self.max_abs_force_n
            ));
        }
        None
    }
}

/// Checks `[divergence]`.
pub(crate) fn validate(scene: &Scene, v: &Check<'_>) -> Result<(), SceneError> {
    let d = &scene.divergence;
    v.positive("divergence.max_abs_position_m", d.max_abs_position_m)?;
    v.positive("divergence.max_abs_force_n", d.max_abs_force_n)?;
    Ok(())
}
