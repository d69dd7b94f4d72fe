//! Parameter errors: every check names the parameter and what was expected.

/// A controller parameter that is non-finite, negative or otherwise out of range.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum ParamError {
    /// The value is NaN or infinite.
    #[error("parameter `{name}` must be finite, got {value}")]
    NotFinite {
        /// Parameter name as in the struct field.
        name: &'static str,
        /// Offending value.
        value: f64,
    },
    /// The value is negative where only values >= 0 make sense.
    #[error("parameter `{name}` must be >= 0, got {value}")]
    Negative {
        /// Parameter name as in the struct field.
        name: &'static str,
        /// Offending value.
        value: f64,
    },
    /// The value must be strictly positive (masses, unit scales, periods).
    #[error("parameter `{name}` must be > 0, got {value}")]
    NotPositive {
        /// Parameter name as in the struct field.
        name: &'static str,
        /// Offending value.
        value: f64,
    },
    /// Output limits with min >= max.
    #[error("output limits must satisfy u_min < u_max, got u_min = {u_min}, u_max = {u_max}")]
    BadLimits {
        /// Lower output limit.
        u_min: f64,
        /// Upper output limit.
        u_max: f64,
    },
    /// The reference model of the Lyapunov check is not Hurwitz (needs a_m > 0, b_m > 0).
    #[error(
        "reference model must be stable: need a_m > 0 and b_m > 0, got a_m = {a_m}, b_m = {b_m}"
    )]
    UnstableReferenceModel {
        /// Reference-model damping coefficient a_m.
        a_m: f64,
        /// Reference-model stiffness coefficient b_m.
        b_m: f64,
    },
    /// Q of the Lyapunov equation is not symmetric positive definite.
    #[error("Q must be symmetric positive definite")]
    QNotPositiveDefinite,
    /// A reference schedule has more segments than its fixed capacity.
    #[error("reference schedule is full (capacity {capacity})")]
    ScheduleFull {
        /// Fixed capacity of the schedule.
        capacity: usize,
    },
    /// Schedule segments must be added in strictly increasing start time.
    #[error("schedule segment start {t_start} s is not after the previous start {previous} s")]
    ScheduleOrder {
        /// Start time of the rejected segment, s.
        t_start: f64,
        /// Start time of the previous segment, s.
        previous: f64,
    },
}

/// Checks that `value` is finite.
pub(crate) fn finite(name: &'static str, value: f64) -> Result<(), ParamError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(ParamError::NotFinite { name, value })
    }
}

/// Checks that `value` is finite and >= 0.
pub(crate) fn non_negative(name: &'static str, value: f64) -> Result<(), ParamError> {
    finite(name, value)?;
    if value >= 0.0 {
        Ok(())
    } else {
        Err(ParamError::Negative { name, value })
    }
}

/// Checks that `value` is finite and > 0.
pub(crate) fn positive(name: &'static str, value: f64) -> Result<(), ParamError> {
    finite(name, value)?;
    if value > 0.0 {
        Ok(())
    } else {
        Err(ParamError::NotPositive { name, value })
    }
}
