//! `[environment]`: the linear-spring environment the flange pushes against, eq. (21).

use serde::{Deserialize, Serialize};

use super::Scene;
use crate::error::SceneError;
use crate::origin::Check;

/// A linear-spring environment, eq. (21): f_e = k_e (x - x_e) while x > x_e, 0 otherwise.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentSpec {
    /// Environment stiffness k_e, N/m.
    pub stiffness_n_per_m: f64,
    /// Position of the environment surface x_e along the flange axis, m.
    #[serde(default)]
    pub x_e_m: f64,
}

/// Checks `[environment]`.
pub(crate) fn validate(scene: &Scene, v: &Check<'_>) -> Result<(), SceneError> {
    v.non_negative(
        "environment.stiffness_n_per_m",
        scene.environment.stiffness_n_per_m,
    )?;
    v.finite("environment.x_e_m", scene.environment.x_e_m)?;
    Ok(())
}
