//! Reference generators (step, sine, ramp) and a fixed-capacity piecewise schedule of them.
//! Each segment is evaluated in its own local time τ = t - t_start, so the paper's
//! "10 + 2 sin(2π(t - 3))" is a sine segment starting at 3 s with zero phase.

use crate::error::{ParamError, finite, non_negative};
use crate::io::Setpoint;

/// One reference signal, evaluated at local time τ (s) since its segment started.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reference {
    /// Constant value.
    Constant {
        /// Value.
        value: f64,
    },
    /// `initial` before τ = t_step_s, `final_value` from then on.
    Step {
        /// Value before the step.
        initial: f64,
        /// Value at and after the step.
        final_value: f64,
        /// Local time of the step, s.
        t_step_s: f64,
    },
    /// bias + amplitude · sin(2π f τ + phase).
    Sine {
        /// Offset.
        bias: f64,
        /// Amplitude.
        amplitude: f64,
        /// Frequency, Hz.
        frequency_hz: f64,
        /// Phase at τ = 0, rad.
        phase_rad: f64,
    },
    /// start + slope · τ.
    Ramp {
        /// Value at τ = 0.
        start: f64,
        /// Rate of change, units per second.
        slope_per_s: f64,
    },
}

impl Reference {
    /// Value at local time `tau` (s).
    pub fn value(&self, tau: f64) -> f64 {
        match *self {
            Reference::Constant { value } => value,
            Reference::Step {
                initial,
                final_value,
                t_step_s,
            } => {
                if tau >= t_step_s {
                    final_value
                } else {
                    initial
                }
            }
            Reference::Sine {
                bias,
                amplitude,
                frequency_hz,
                phase_rad,
            } => {
                bias + amplitude
                    * libm::sin(core::f64::consts::TAU * frequency_hz * tau + phase_rad)
            }
            Reference::Ramp { start, slope_per_s } => start + slope_per_s * tau,
        }
    }

    /// Checks all fields finite, frequency and step time >= 0.
    pub fn validate(&self) -> Result<(), ParamError> {
        match *self {
            Reference::Constant { value } => finite("value", value),
            Reference::Step {
                initial,
                final_value,
                t_step_s,
            } => {
                finite("initial", initial)?;
                finite("final_value", final_value)?;
                non_negative("t_step_s", t_step_s)
            }
            Reference::Sine {
                bias,
                amplitude,
                frequency_hz,
                phase_rad,
            } => {
                finite("bias", bias)?;
                finite("amplitude", amplitude)?;
                non_negative("frequency_hz", frequency_hz)?;
                finite("phase_rad", phase_rad)
            }
            Reference::Ramp { start, slope_per_s } => {
                finite("start", start)?;
                finite("slope_per_s", slope_per_s)
            }
        }
    }
}

/// Default capacity of a [`Schedule`].
pub const SCHEDULE_CAPACITY: usize = 8;

/// Piecewise reference: segment i is active on [t_start_i, t_start_{i+1}); before the first
/// start the first segment is used at τ = 0. Fixed capacity `N`, no allocation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Schedule<const N: usize = SCHEDULE_CAPACITY> {
    starts: [f64; N],
    refs: [Reference; N],
    len: usize,
}

impl<const N: usize> Default for Schedule<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Schedule<N> {
    /// An empty schedule (evaluates to 0).
    pub const fn new() -> Self {
        Self {
            starts: [0.0; N],
            refs: [Reference::Constant { value: 0.0 }; N],
            len: 0,
        }
    }

    /// A schedule with a single segment active for all time.
    pub fn constant(reference: Reference) -> Self {
        let mut s = Self::new();
        // N >= 1 for any useful schedule; a zero-capacity schedule stays empty (evaluates to 0).
        let _ = s.push(0.0, reference);
        s
    }

    /// Appends a segment starting at `t_start_s` (strictly after the previous start).
    pub fn push(&mut self, t_start_s: f64, reference: Reference) -> Result<(), ParamError> {
        finite("t_start_s", t_start_s)?;
        reference.validate()?;
        if self.len >= N {
            return Err(ParamError::ScheduleFull { capacity: N });
        }
        if self.len > 0 && t_start_s <= self.starts[self.len - 1] {
            return Err(ParamError::ScheduleOrder {
                t_start: t_start_s,
                previous: self.starts[self.len - 1],
            });
        }
        self.starts[self.len] = t_start_s;
        self.refs[self.len] = reference;
        self.len += 1;
        Ok(())
    }

    /// Number of segments.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Segment `i`: its start time and reference (what a copy of the schedule is rebuilt from with
    /// [`Schedule::push`], e.g. on the embedded controller).
    pub fn segment(&self, i: usize) -> Option<(f64, Reference)> {
        (i < self.len).then(|| (self.starts[i], self.refs[i]))
    }

    /// Whether the schedule has no segments.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Index of the segment active at `t` (None when empty).
    pub fn active_segment(&self, t: f64) -> Option<usize> {
        if self.len == 0 {
            return None;
        }
        let mut i = 0;
        while i + 1 < self.len && t >= self.starts[i + 1] {
            i += 1;
        }
        Some(i)
    }

    /// Value at absolute time `t` (s).
    pub fn value(&self, t: f64) -> f64 {
        match self.active_segment(t) {
            None => 0.0,
            Some(i) => {
                let tau = t - self.starts[i];
                self.refs[i].value(if tau > 0.0 { tau } else { 0.0 })
            }
        }
    }
}

/// Force and desired-position schedules together: produces the [`Setpoint`] at time t.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SetpointSchedule<const N: usize = SCHEDULE_CAPACITY> {
    /// Reference force f_r, N.
    pub force_n: Schedule<N>,
    /// Desired position x_d, m.
    pub position_m: Schedule<N>,
}

impl<const N: usize> SetpointSchedule<N> {
    /// The setpoint at absolute time `t` (s).
    pub fn at(&self, t: f64) -> Setpoint {
        Setpoint {
            f_ref: self.force_n.value(t),
            x_d: self.position_m.value(t),
        }
    }
}

impl SetpointSchedule {
    /// The paper's Fig. 3 force schedule: 10 N step for 3 s, then 10 + 2 sin(2π(t - 3)) N;
    /// x_d constant at `x_d_m`.
    pub fn paper_fig3(x_d_m: f64) -> Result<Self, ParamError> {
        let mut force_n = Schedule::new();
        force_n.push(0.0, Reference::Constant { value: 10.0 })?;
        force_n.push(
            3.0,
            Reference::Sine {
                bias: 10.0,
                amplitude: 2.0,
                frequency_hz: 1.0,
                phase_rad: 0.0,
            },
        )?;
        let mut position_m = Schedule::new();
        position_m.push(0.0, Reference::Constant { value: x_d_m })?;
        Ok(Self {
            force_n,
            position_m,
        })
    }
}
