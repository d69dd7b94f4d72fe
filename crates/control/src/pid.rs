//! Inner position loop: PID on x_r - x with derivative on the (filtered) measurement,
//! output limits and anti-windup. Output is the valve command u.

use crate::error::{ParamError, non_negative, positive, within};

/// How the integrator is kept from winding up while the output saturates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AntiWindup {
    /// Conditional integration: the integrator is frozen while the output is saturated and the
    /// error would drive it further into saturation.
    Clamping,
    /// Back-calculation: the integrator is pulled back by (u_sat - u_unsat) / tracking_time_s.
    BackCalculation {
        /// Tracking time constant T_t, s (> 0; a common choice is sqrt(T_i T_d) or T_i / 2).
        tracking_time_s: f64,
    },
}

/// PID gains and limits. Error in m, output is the normalised valve command.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(from = "crate::pid::PidFile", into = "crate::pid::PidFile")
)]
pub struct PidParams {
    /// Proportional gain, 1/m (valve command per metre of position error).
    pub kp_per_m: f64,
    /// Integral gain, 1/(m·s).
    pub ki_per_m_s: f64,
    /// Derivative gain on the measured position, s/m (valve command per m/s).
    pub kd_s_per_m: f64,
    /// Time constant of the first-order low-pass on the derivative, s (0 = unfiltered).
    pub derivative_filter_s: f64,
    /// Lower output limit (valve command).
    pub u_min: f64,
    /// Upper output limit (valve command).
    pub u_max: f64,
    /// Anti-windup scheme.
    pub anti_windup: AntiWindup,
}

impl Default for PidParams {
    /// A starting point for a small double-acting cylinder on a proportional valve: full valve
    /// opening at 5 mm error, mild integral and velocity damping, 2 ms derivative filter,
    /// limits [-1, 1], clamping. Plants with a known valve retune these in their scene file.
    fn default() -> Self {
        Self {
            kp_per_m: 200.0,
            ki_per_m_s: 50.0,
            kd_s_per_m: 2.0,
            derivative_filter_s: 0.002,
            u_min: -1.0,
            u_max: 1.0,
            anti_windup: AntiWindup::Clamping,
        }
    }
}

/// Largest proportional gain, 1/m: 1 µm of error saturates the command.
pub const MAX_KP_PER_M: f64 = 1.0e6;
/// Largest integral gain, 1/(m s): 1 µm held for 1 ms saturates the command.
pub const MAX_KI_PER_M_S: f64 = 1.0e9;
/// Largest derivative gain, s/m: 1 mm/s saturates the command.
pub const MAX_KD_S_PER_M: f64 = 1.0e3;

impl PidParams {
    /// Checks gains in [0, their largest meaningful value], finite limits with u_min < u_max, and a positive
    /// tracking time.
    pub fn validate(&self) -> Result<(), ParamError> {
        // The command is normalised to [-1, 1]: past these gains a 1 µm position error (the finest position
        // sensor), 1 µm held for a 1 ms tick, or a 1 mm/s speed alone drives the valve from closed to fully
        // open, so the loop is an on/off switch, not a gain (the shipped scenes use 10-200 /m).
        for (name, gain, max) in [
            ("kp_per_m", self.kp_per_m, MAX_KP_PER_M),
            ("ki_per_m_s", self.ki_per_m_s, MAX_KI_PER_M_S),
            ("kd_s_per_m", self.kd_s_per_m, MAX_KD_S_PER_M),
        ] {
            non_negative(name, gain)?;
            within(name, gain, 0.0, max)?;
        }
        non_negative("derivative_filter_s", self.derivative_filter_s)?;
        // The valve command is normalised to [-1, 1] (ValveCommand).
        within("u_min", self.u_min, -1.0, 1.0)?;
        within("u_max", self.u_max, -1.0, 1.0)?;
        if self.u_min >= self.u_max {
            return Err(ParamError::BadLimits {
                u_min: self.u_min,
                u_max: self.u_max,
            });
        }
        if let AntiWindup::BackCalculation { tracking_time_s } = self.anti_windup {
            positive("tracking_time_s", tracking_time_s)?;
        }
        Ok(())
    }
}

/// PID state: integrator, filtered measurement derivative, last measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pid {
    params: PidParams,
    integral: f64,
    v_filt: f64,
    x_prev: f64,
    primed: bool,
    saturated: bool,
}

impl Pid {
    /// A PID at rest; parameters are validated.
    pub fn new(params: PidParams) -> Result<Self, ParamError> {
        params.validate()?;
        Ok(Self {
            params,
            integral: 0.0,
            v_filt: 0.0,
            x_prev: 0.0,
            primed: false,
            saturated: false,
        })
    }

    /// The PID's parameters.
    pub fn params(&self) -> &PidParams {
        &self.params
    }

    /// One control period: reference `r` and measurement `y` (m) to a limited command.
    /// The derivative acts on -y only, so a step in `r` gives no derivative kick.
    pub fn update(&mut self, r: f64, y: f64, dt: f64) -> f64 {
        let p = &self.params;
        let err = r - y;
        // Derivative on the measurement: backward difference, then a first-order low-pass
        // discretised by backward Euler (stable for any dt).
        let raw = if self.primed && dt > 0.0 {
            (y - self.x_prev) / dt
        } else {
            0.0
        };
        self.x_prev = y;
        self.primed = true;
        let alpha = if dt > 0.0 {
            dt / (p.derivative_filter_s + dt)
        } else {
            0.0
        };
        self.v_filt += alpha * (raw - self.v_filt);

        let unsat = p.kp_per_m * err + self.integral - p.kd_s_per_m * self.v_filt;
        let u = unsat.clamp(p.u_min, p.u_max);
        self.saturated = u != unsat;
        // Integrate after computing the output (the integral state feeds the next period).
        match p.anti_windup {
            AntiWindup::Clamping => {
                let pushes_out = (unsat > p.u_max && err > 0.0) || (unsat < p.u_min && err < 0.0);
                if !pushes_out {
                    self.integral += p.ki_per_m_s * err * dt;
                }
            }
            AntiWindup::BackCalculation { tracking_time_s } => {
                self.integral += (p.ki_per_m_s * err + (u - unsat) / tracking_time_s) * dt;
            }
        }
        // The integral term alone never needs to exceed the output range.
        self.integral = self.integral.clamp(p.u_min, p.u_max);
        if u.is_nan() { 0.0 } else { u }
    }

    /// Integrator state (already multiplied by k_i), valve-command units.
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// Filtered measured velocity used by the derivative term, m/s.
    pub fn velocity_estimate(&self) -> f64 {
        self.v_filt
    }

    /// Whether the last output was clamped at a limit.
    pub fn saturated(&self) -> bool {
        self.saturated
    }

    /// Back to rest (integrator and derivative filter cleared).
    pub fn reset(&mut self) {
        self.integral = 0.0;
        self.v_filt = 0.0;
        self.x_prev = 0.0;
        self.primed = false;
        self.saturated = false;
    }
}

/// `PidParams` as scene files write it (`serde` feature): the anti-windup scheme as an optional
/// `tracking_time_s` (absent = clamping) and defaults for every key the paper leaves open. Unknown keys are
/// rejected. Kept here, beside the params, so the file form depends on `PidParams` and not the other way round.
#[cfg(feature = "serde")]
mod file_form {
    use serde::{Deserialize, Serialize};

    use super::{AntiWindup, PidParams};

    fn one() -> f64 {
        1.0
    }
    fn minus_one() -> f64 {
        -1.0
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
}

#[cfg(feature = "serde")]
pub use file_form::PidFile;
