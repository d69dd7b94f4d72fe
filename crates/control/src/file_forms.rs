//! The controller parameters as scene files write them (optional `serde` feature, still `no_std`).
//!
//! The parameter structs of this crate are the file format: `ImpedanceParams` as it is, `PidParams` and
//! `AdaptiveParams` through the flat forms below, whose only differences are file conventions — the
//! anti-windup scheme as an optional `tracking_time_s`, projection bounds as optional keys (absent = off,
//! +inf inside), and defaults for every key the paper leaves open. Unknown keys are rejected.

use serde::{Deserialize, Serialize};

use crate::adaptive::{AdaptiveParams, LambdaDSign, Sigma1Sign, VelocitySource};
use crate::pid::{AntiWindup, PidParams};

fn one() -> f64 {
    1.0
}
fn minus_one() -> f64 {
    -1.0
}
fn half_newton() -> f64 {
    0.5
}
fn default_derivative_filter() -> f64 {
    0.002
}

/// `[runs.inner]`: the inner position loop (PID on x_r - x, derivative on the measurement).
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PidFile {
    /// Proportional gain, 1/m.
    pub kp_per_m: f64,
    /// Integral gain, 1/(m·s).
    #[serde(default)]
    pub ki_per_m_s: f64,
    /// Derivative gain on the measured position, s/m.
    #[serde(default)]
    pub kd_s_per_m: f64,
    /// Low-pass time constant of the derivative, s (0 = unfiltered).
    #[serde(default = "default_derivative_filter")]
    pub derivative_filter_s: f64,
    /// Lower valve-command limit, in [-1, 1].
    #[serde(default = "minus_one")]
    pub u_min: f64,
    /// Upper valve-command limit, in [-1, 1].
    #[serde(default = "one")]
    pub u_max: f64,
    /// Back-calculation tracking time, s; absent = conditional integration (clamping).
    #[serde(default)]
    pub tracking_time_s: Option<f64>,
}

impl From<PidFile> for PidParams {
    fn from(f: PidFile) -> Self {
        Self {
            kp_per_m: f.kp_per_m,
            ki_per_m_s: f.ki_per_m_s,
            kd_s_per_m: f.kd_s_per_m,
            derivative_filter_s: f.derivative_filter_s,
            u_min: f.u_min,
            u_max: f.u_max,
            anti_windup: match f.tracking_time_s {
                None => AntiWindup::Clamping,
                Some(tracking_time_s) => AntiWindup::BackCalculation { tracking_time_s },
            },
        }
    }
}

impl From<PidParams> for PidFile {
    fn from(p: PidParams) -> Self {
        Self {
            kp_per_m: p.kp_per_m,
            ki_per_m_s: p.ki_per_m_s,
            kd_s_per_m: p.kd_s_per_m,
            derivative_filter_s: p.derivative_filter_s,
            u_min: p.u_min,
            u_max: p.u_max,
            tracking_time_s: match p.anti_windup {
                AntiWindup::Clamping => None,
                AntiWindup::BackCalculation { tracking_time_s } => Some(tracking_time_s),
            },
        }
    }
}

/// `[runs.adaptive]`: gains of the σ-modified adaptive law, eq. (35), and the units they are read in.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct AdaptiveFile {
    /// Force unit the gains are read in, N.
    #[serde(default = "one")]
    pub force_unit_n: f64,
    /// Position unit the gains are read in, m.
    #[serde(default = "one")]
    pub position_unit_m: f64,
    /// Sign of λ_d inside χ.
    #[serde(default = "from_edot")]
    pub lambda_d_sign: LambdaDSign,
    /// Sign of the σ_1 term.
    #[serde(default = "leakage")]
    pub sigma1_sign: Sigma1Sign,
    /// λ_p.
    pub lambda_p: f64,
    /// λ_d.
    pub lambda_d: f64,
    /// μ_1.
    pub mu1: f64,
    /// μ_2.
    pub mu2: f64,
    /// μ_3.
    pub mu3: f64,
    /// σ_1, 1/s.
    pub sigma1: f64,
    /// σ_2, 1/s.
    pub sigma2: f64,
    /// σ_3, 1/s.
    pub sigma3: f64,
    /// Adapt only while in contact.
    #[serde(default)]
    pub adapt_in_contact_only: bool,
    /// Contact force above which the flange counts as in contact, N.
    #[serde(default = "half_newton")]
    pub contact_threshold_n: f64,
    /// Velocity used for ẋ in eqs. (35)/(36).
    #[serde(default = "measured")]
    pub velocity_source: VelocitySource,
    /// Projection bound |g| <= g_max_m, m (absent = unbounded).
    #[serde(default)]
    pub g_max_m: Option<f64>,
    /// Projection bound 0 <= p <= p_max_m_per_n, m/N (absent = unbounded).
    #[serde(default)]
    pub p_max_m_per_n: Option<f64>,
    /// Projection bound -d_max_s <= d <= 0, s (absent = unbounded).
    #[serde(default)]
    pub d_max_s: Option<f64>,
}

fn from_edot() -> LambdaDSign {
    LambdaDSign::FromEdot
}
fn leakage() -> Sigma1Sign {
    Sigma1Sign::Leakage
}
fn measured() -> VelocitySource {
    VelocitySource::Measured
}

/// Absent = off = +inf inside the law.
fn bound(b: Option<f64>) -> f64 {
    b.unwrap_or(f64::INFINITY)
}

fn optional(b: f64) -> Option<f64> {
    (b != f64::INFINITY).then_some(b)
}

impl From<AdaptiveFile> for AdaptiveParams {
    fn from(f: AdaptiveFile) -> Self {
        Self {
            lambda_p: f.lambda_p,
            lambda_d: f.lambda_d,
            mu1: f.mu1,
            mu2: f.mu2,
            mu3: f.mu3,
            sigma1: f.sigma1,
            sigma2: f.sigma2,
            sigma3: f.sigma3,
            force_unit_n: f.force_unit_n,
            position_unit_m: f.position_unit_m,
            lambda_d_sign: f.lambda_d_sign,
            sigma1_sign: f.sigma1_sign,
            adapt_in_contact_only: f.adapt_in_contact_only,
            contact_threshold_n: f.contact_threshold_n,
            velocity_source: f.velocity_source,
            g_max_m: bound(f.g_max_m),
            p_max_m_per_n: bound(f.p_max_m_per_n),
            d_max_s: bound(f.d_max_s),
        }
    }
}

impl From<AdaptiveParams> for AdaptiveFile {
    fn from(a: AdaptiveParams) -> Self {
        Self {
            force_unit_n: a.force_unit_n,
            position_unit_m: a.position_unit_m,
            lambda_d_sign: a.lambda_d_sign,
            sigma1_sign: a.sigma1_sign,
            lambda_p: a.lambda_p,
            lambda_d: a.lambda_d,
            mu1: a.mu1,
            mu2: a.mu2,
            mu3: a.mu3,
            sigma1: a.sigma1,
            sigma2: a.sigma2,
            sigma3: a.sigma3,
            adapt_in_contact_only: a.adapt_in_contact_only,
            contact_threshold_n: a.contact_threshold_n,
            velocity_source: a.velocity_source,
            g_max_m: optional(a.g_max_m),
            p_max_m_per_n: optional(a.p_max_m_per_n),
            d_max_s: optional(a.d_max_s),
        }
    }
}
