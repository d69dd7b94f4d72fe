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
    /// The value is outside its admissible interval.
    #[error("parameter `{name}` must be in [{min}, {max}], got {value}")]
    OutOfRange {
        /// Parameter name as in the struct field.
        name: &'static str,
        /// Offending value.
        value: f64,
        /// Lower bound.
        min: f64,
        /// Upper bound.
        max: f64,
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

impl ParamError {
    /// The parameter (struct field, = file key) the error is about, when it is about one.
    pub fn field(&self) -> Option<&'static str> {
        match self {
            ParamError::NotFinite { name, .. }
            | ParamError::Negative { name, .. }
            | ParamError::NotPositive { name, .. }
            | ParamError::OutOfRange { name, .. } => Some(name),
            ParamError::BadLimits { .. } => Some("u_max"),
            _ => None,
        }
    }

    /// What is wrong, without the parameter's name (for messages that name the key themselves).
    pub fn reason(&self) -> alloc_free::Reason<'_> {
        alloc_free::Reason(self)
    }
}

/// Display of [`ParamError::reason`] without allocation (no_std).
pub mod alloc_free {
    use super::ParamError;

    /// The reason of a parameter error, displayed without the parameter's name.
    pub struct Reason<'a>(pub(crate) &'a ParamError);

    impl core::fmt::Display for Reason<'_> {
        fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
            match *self.0 {
                ParamError::NotFinite { value, .. } => {
                    write!(f, "must be a finite number, got {value}")
                }
                ParamError::Negative { value, .. } => write!(f, "must be >= 0, got {value}"),
                ParamError::NotPositive { value, .. } => write!(f, "must be > 0, got {value}"),
                ParamError::OutOfRange {
                    value, min, max, ..
                } => write!(f, "must be in [{min}, {max}], got {value}"),
                ParamError::BadLimits { u_min, u_max } => write!(
                    f,
                    "need u_min < u_max, got u_min = {u_min}, u_max = {u_max}"
                ),
                ref other => write!(f, "{other}"),
            }
        }
    }
}

/// Checks that `value` is finite and within [min, max].
pub(crate) fn within(name: &'static str, value: f64, min: f64, max: f64) -> Result<(), ParamError> {
    finite(name, value)?;
    if (min..=max).contains(&value) {
        Ok(())
    } else {
        Err(ParamError::OutOfRange {
            name,
            value,
            min,
            max,
        })
    }
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
