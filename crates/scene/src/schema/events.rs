//! `[[events]]`: timed changes of the scene (stiffness, a swap of the environment, the incline).

use serde::{Deserialize, Serialize};

use super::Scene;
use super::check::Check;
use crate::error::SceneError;

/// A timed change of the scene, applied at the first control tick at or after `t_s`.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum EventSpec {
    /// The environment stiffness k_e becomes a new value (on the multibody plant: one material's mount).
    Stiffness {
        /// Time of the event, s.
        t_s: f64,
        /// New stiffness, N/m.
        stiffness_n_per_m: f64,
        /// Multibody plant only: the material to change; absent = the one facing the flange.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        material: Option<String>,
        /// Multibody plant only: new mount damping, N·s/m; absent = unchanged.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        damping_n_s_per_m: Option<f64>,
    },
    /// Multibody plant only: the carriage brings another material in front of the flange (Fig. 7):
    /// it retreats beyond the flange's reach, slides across and comes back, over `duration_s`.
    SwapEnvironment {
        /// Time the carriage starts moving, s.
        t_s: f64,
        /// Material that faces the flange afterwards.
        to: String,
        /// Duration of the whole carriage move, s.
        duration_s: f64,
    },
    /// The incline alpha of the actuator axis changes (gravity aids extension by m g sin(alpha)).
    Alpha {
        /// Time of the event, s.
        t_s: f64,
        /// New incline below horizontal, degrees, in [-90, 90].
        alpha_deg: f64,
    },
}

impl EventSpec {
    /// Time of the event, s.
    pub fn t_s(&self) -> f64 {
        match *self {
            EventSpec::Stiffness { t_s, .. }
            | EventSpec::SwapEnvironment { t_s, .. }
            | EventSpec::Alpha { t_s, .. } => t_s,
        }
    }

    /// The event's `kind` as written in the scene file.
    pub fn kind(&self) -> &'static str {
        match self {
            EventSpec::Stiffness { .. } => "stiffness",
            EventSpec::SwapEnvironment { .. } => "swap_environment",
            EventSpec::Alpha { .. } => "alpha",
        }
    }
}

/// Checks `[[events]]`: inside the scene, and possible on its plant.
pub(crate) fn validate(scene: &Scene, v: &Check<'_>) -> Result<(), SceneError> {
    for (i, ev) in scene.events.iter().enumerate() {
        let at = |k: &str| format!("events[{i}].{k}");
        v.non_negative(&at("t_s"), ev.t_s())?;
        if ev.t_s() > scene.duration_s + 0.5 * scene.dt_s {
            return Err(v.err(
                &at("t_s"),
                format!(
                    "the event would never happen: t_s = {} is after the end of the scene (duration_s = {})",
                    ev.t_s(),
                    scene.duration_s
                ),
            ));
        }
        let mb = scene.plant.multibody();
        match ev {
            EventSpec::Stiffness {
                stiffness_n_per_m,
                material,
                damping_n_s_per_m,
                ..
            } => {
                v.non_negative(&at("stiffness_n_per_m"), *stiffness_n_per_m)?;
                if let Some(c) = damping_n_s_per_m {
                    v.non_negative(&at("damping_n_s_per_m"), *c)?;
                }
                match mb {
                    Some(mb) => {
                        // The mount is a spring: zero stiffness has no rest position.
                        v.positive(&at("stiffness_n_per_m"), *stiffness_n_per_m)?;
                        if let Some(name) = material {
                            super::plant::known_material(v, &at("material"), mb, name)?;
                        }
                    }
                    None => {
                        if material.is_some() || damping_n_s_per_m.is_some() {
                            return Err(v.err(
                                &at("material"),
                                "`material` and `damping_n_s_per_m` need plant.kind = \"multibody\"".into(),
                            ));
                        }
                    }
                }
            }
            EventSpec::SwapEnvironment { to, duration_s, .. } => {
                let Some(mb) = mb else {
                    return Err(v.err(
                        &at("kind"),
                        "\"swap_environment\" needs plant.kind = \"multibody\": the 1-DOF plants have one linear-spring environment and no carriage".into(),
                    ));
                };
                super::plant::known_material(v, &at("to"), mb, to)?;
                v.positive(&at("duration_s"), *duration_s)?;
                if ev.t_s() + duration_s > scene.duration_s + 0.5 * scene.dt_s {
                    return Err(v.err(
                        &at("duration_s"),
                        format!(
                            "the swap must end within the scene: t_s + duration_s = {} > duration_s = {}",
                            ev.t_s() + duration_s,
                            scene.duration_s
                        ),
                    ));
                }
            }
            EventSpec::Alpha { alpha_deg, .. } => {
                v.within(&at("alpha_deg"), *alpha_deg, -90.0, 90.0)?;
                if !scene.plant.has_gravity() {
                    return Err(v.err(
                        &at("kind"),
                        "\"alpha\" has no effect on plant.kind = \"ideal\" or \"linear\" (no gravity in those models)".into(),
                    ));
                }
            }
        }
    }
    Ok(())
}
