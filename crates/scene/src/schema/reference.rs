//! `[reference]`: the force reference schedule and the desired position.

use serde::{Deserialize, Serialize};

use super::Scene;
use crate::error::SceneError;
use crate::origin::Check;

/// Force reference schedule and desired position.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ReferenceSpec {
    /// Desired (free-space) position x_d, m (constant).
    #[serde(default)]
    pub x_d_m: f64,
    /// Pieces of the force reference f_r; each holds from its start time until the next piece starts.
    pub force: Vec<ForcePiece>,
}

/// One piece of the force reference schedule.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum ForcePiece {
    /// Constant force from `start_s` on.
    Step {
        /// Start time, s.
        start_s: f64,
        /// Force, N.
        value_n: f64,
    },
    /// bias + amplitude · sin(2π f (t - start) + phase).
    Sine {
        /// Start time, s.
        start_s: f64,
        /// Bias, N.
        bias_n: f64,
        /// Amplitude, N.
        amplitude_n: f64,
        /// Frequency, Hz.
        frequency_hz: f64,
        /// Phase at the start time, rad.
        #[serde(default)]
        phase_rad: f64,
    },
    /// value0 + slope · (t - start).
    Ramp {
        /// Start time, s.
        start_s: f64,
        /// Force at the start time, N.
        value0_n: f64,
        /// Slope, N/s.
        slope_n_per_s: f64,
    },
}

impl ReferenceSpec {
    /// The sine piece that covers the whole interval [t0, t1], if any.
    pub fn sine_in(&self, t0: f64, t1: f64) -> Option<ForcePiece> {
        let pieces = &self.force;
        for (i, p) in pieces.iter().enumerate() {
            let end = pieces.get(i + 1).map_or(f64::INFINITY, ForcePiece::start_s);
            if matches!(p, ForcePiece::Sine { .. }) && p.start_s() <= t0 && t1 <= end {
                return Some(*p);
            }
        }
        None
    }
}

impl ForcePiece {
    /// Start time of the piece, s.
    pub fn start_s(&self) -> f64 {
        match *self {
            ForcePiece::Step { start_s, .. }
            | ForcePiece::Sine { start_s, .. }
            | ForcePiece::Ramp { start_s, .. } => start_s,
        }
    }
}

/// Checks `[reference]`: its pieces in time order, each one's numbers.
pub(crate) fn validate(scene: &Scene, v: &Check<'_>) -> Result<(), SceneError> {
    v.finite("reference.x_d_m", scene.reference.x_d_m)?;
    if scene.reference.force.is_empty() {
        return Err(v.err("reference.force", "needs at least one piece".into()));
    }
    if scene.reference.force.len() > pneuflex_control::reference::SCHEDULE_CAPACITY {
        return Err(v.err(
            "reference.force",
            format!(
                "at most {} pieces, got {}",
                pneuflex_control::reference::SCHEDULE_CAPACITY,
                scene.reference.force.len()
            ),
        ));
    }
    let mut prev = f64::NEG_INFINITY;
    for (i, piece) in scene.reference.force.iter().enumerate() {
        let at = |k: &str| format!("reference.force[{i}].{k}");
        v.non_negative(&at("start_s"), piece.start_s())?;
        if piece.start_s() <= prev {
            return Err(v.err(
                &at("start_s"),
                format!(
                    "pieces must start in increasing time order, got {} after {prev}",
                    piece.start_s()
                ),
            ));
        }
        prev = piece.start_s();
        match *piece {
            ForcePiece::Step { value_n, .. } => v.finite(&at("value_n"), value_n)?,
            ForcePiece::Sine {
                bias_n,
                amplitude_n,
                frequency_hz,
                phase_rad,
                ..
            } => {
                v.finite(&at("bias_n"), bias_n)?;
                v.non_negative(&at("amplitude_n"), amplitude_n)?;
                v.positive(&at("frequency_hz"), frequency_hz)?;
                v.finite(&at("phase_rad"), phase_rad)?;
            }
            ForcePiece::Ramp {
                value0_n,
                slope_n_per_s,
                ..
            } => {
                v.finite(&at("value0_n"), value0_n)?;
                v.finite(&at("slope_n_per_s"), slope_n_per_s)?;
            }
        }
    }
    Ok(())
}

impl ForcePiece {
    /// The piece as the control crate's reference (from its start time on).
    pub fn reference(&self) -> pneuflex_control::Reference {
        use pneuflex_control::Reference;
        match *self {
            ForcePiece::Step { value_n, .. } => Reference::Constant { value: value_n },
            ForcePiece::Sine {
                bias_n,
                amplitude_n,
                frequency_hz,
                phase_rad,
                ..
            } => Reference::Sine {
                bias: bias_n,
                amplitude: amplitude_n,
                frequency_hz,
                phase_rad,
            },
            ForcePiece::Ramp {
                value0_n,
                slope_n_per_s,
                ..
            } => Reference::Ramp {
                start: value0_n,
                slope_per_s: slope_n_per_s,
            },
        }
    }
}

impl Scene {
    /// The force/position setpoint schedule of the reference, in the control crate's fixed-capacity form.
    pub fn setpoints(&self) -> Result<pneuflex_control::SetpointSchedule, SceneError> {
        use pneuflex_control::Reference;
        let mut sp = pneuflex_control::SetpointSchedule::default();
        for (i, piece) in self.reference.force.iter().enumerate() {
            let r = piece.reference();
            sp.force_n
                .push(piece.start_s(), r)
                .map_err(|e| self.invalid(&format!("reference.force[{i}]"), e.to_string()))?;
        }
        sp.position_m
            .push(
                0.0,
                Reference::Constant {
                    value: self.reference.x_d_m,
                },
            )
            .map_err(|e| self.invalid("reference.x_d_m", e.to_string()))?;
        Ok(sp)
    }
}
