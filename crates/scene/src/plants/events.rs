//! The timed changes a plant applies (`[[events]]` of the scene file: stiffness, a swap of the environment,
//! the incline). The scene checks them against itself and its plant (`schema/events.rs`).

use serde::{Deserialize, Serialize};

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
