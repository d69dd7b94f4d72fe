//! Directional control valves: a proportional 5/3 valve and the rig's 5/2 on/off solenoid valve under PWM.
//!
//! Both are described by a normalised spool position `s` in [-1, 1] and four flow paths
//! (P = supply, R = exhaust): P->A and B->R open for `s > 0`, P->B and A->R open for `s < 0`.
//! The command `u` in [-1, 1] follows the lead's convention: +1 = supply to A, B to exhaust (extend).

use crate::flow::Orifice;

/// Relative openings of the four paths of a 5-port valve, each in [0, 1].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Openings {
    /// Supply P -> chamber A.
    pub p_a: f64,
    /// Chamber A -> exhaust R.
    pub a_r: f64,
    /// Supply P -> chamber B.
    pub p_b: f64,
    /// Chamber B -> exhaust R.
    pub b_r: f64,
}

/// How the spool moves in response to the command.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ValveKind {
    /// Proportional 5/3 valve: the spool follows `u` with a first-order lag.
    Proportional {
        /// First-order spool time constant, s (0 = ideal, spool = u).
        response_time_s: f64,
    },
    /// Two-position five-way (5/2) single-solenoid valve switched by PWM.
    ///
    /// The continuous command maps to duty `d = (1 + u) / 2` of the energised position (+1); the
    /// de-energised spring position is -1 (supply to B, A to exhaust). The duty is latched at the start of
    /// every PWM period and each edge reaches the spool `switching_delay_s` later.
    OnOffPwm {
        /// PWM carrier frequency, Hz.
        pwm_frequency_hz: f64,
        /// Delay between the electrical edge and the spool changing position, s (< one PWM period).
        switching_delay_s: f64,
    },
}

/// A 5-port directional valve: flow restriction, centre underlap and spool dynamics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ValveModel {
    /// ISO 6358 characteristics of one fully open path.
    pub orifice: Orifice,
    /// Underlap as a fraction of full spool travel (proportional valve): at `s = 0` every path is open by
    /// this fraction, which gives the centre leakage and hence K_c of eq. (12). 0 for a 5/2 valve.
    pub underlap: f64,
    /// Spool dynamics.
    pub kind: ValveKind,
}

/// Internal state of a valve (spool position and PWM bookkeeping). Start from `ValveState::default()`
/// or [`ValveState::at_spool`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ValveState {
    /// Current spool position in [-1, 1].
    pub spool: f64,
    /// Whether the PWM period clock has been started.
    started: bool,
    /// Time of the first PWM period start, s.
    t0: f64,
    /// Index of the current PWM period.
    period: u64,
    /// Duty latched for the current period.
    duty: f64,
    /// Duty latched for the previous period (edges delayed into the current one).
    prev_duty: f64,
}

impl ValveState {
    /// A valve state resting at spool position `spool` (clamped to [-1, 1]).
    pub fn at_spool(spool: f64) -> Self {
        Self {
            spool: sanitize(spool),
            ..Self::default()
        }
    }
}

/// Clamps a command to [-1, 1]; NaN becomes 0 (never an open valve by accident).
#[inline]
fn sanitize(u: f64) -> f64 {
    if u.is_nan() { 0.0 } else { u.clamp(-1.0, 1.0) }
}

impl ValveModel {
    /// Path openings for spool position `s` (underlapped spool: a path opens from `s = -underlap`).
    #[inline]
    pub fn openings(&self, s: f64) -> Openings {
        let e = self.underlap;
        let scale = 1.0 / (1.0 + e);
        let pos = ((s + e) * scale).clamp(0.0, 1.0);
        let neg = ((-s + e) * scale).clamp(0.0, 1.0);
        Openings {
            p_a: pos,
            b_r: pos,
            p_b: neg,
            a_r: neg,
        }
    }

    /// Advances the valve over `[t, t + dt]` under command `u` and returns the spool position to hold
    /// during that step (zero-order hold; for PWM the spool is sampled at mid-step, so `dt` must be much
    /// shorter than the PWM period to resolve the duty).
    pub fn spool(&self, state: &mut ValveState, u: f64, t: f64, dt: f64) -> f64 {
        let u = sanitize(u);
        match self.kind {
            ValveKind::Proportional { response_time_s } => {
                if response_time_s > 0.0 {
                    // Exact discretisation of tau s' = u - s over one step.
                    let a = 1.0 - (-dt / response_time_s).exp();
                    state.spool += (u - state.spool) * a;
                } else {
                    state.spool = u;
                }
            }
            ValveKind::OnOffPwm {
                pwm_frequency_hz,
                switching_delay_s,
            } => {
                let period = 1.0 / pwm_frequency_hz;
                let duty = 0.5 * (1.0 + u);
                if !state.started {
                    state.started = true;
                    state.t0 = t;
                    state.period = 0;
                    state.duty = duty;
                    // Before the first period the coil was off: spring position.
                    state.prev_duty = 0.0;
                }
                // Period index floor((t - t0) / T) for t >= t0, 0 before; the cast truncates, which
                // is the floor for positive values (and avoids a libm call on baseline x86-64).
                let k = (t - state.t0) / period;
                let k = if k > 0.0 { k as u64 } else { 0 };
                if k > state.period {
                    state.prev_duty = if k == state.period + 1 {
                        state.duty
                    } else {
                        duty
                    };
                    state.duty = duty;
                    state.period = k;
                }
                let start = state.t0 + state.period as f64 * period;
                let ts = t + 0.5 * dt - switching_delay_s;
                let (phase, d) = if ts >= start {
                    (ts - start, state.duty)
                } else {
                    (ts - (start - period), state.prev_duty)
                };
                state.spool = if phase >= 0.0 && phase < d * period {
                    1.0
                } else {
                    -1.0
                };
            }
        }
        state.spool
    }

    /// The duty-cycle (PWM) or spool (proportional) weights used to average the flows of a steady
    /// command `u`: returns `(w, s_hi, s_lo)` so that mean flow = w q(s_hi) + (1 - w) q(s_lo).
    pub fn averaging(&self, u: f64) -> (f64, f64, f64) {
        let u = sanitize(u);
        match self.kind {
            ValveKind::Proportional { .. } => (1.0, u, u),
            ValveKind::OnOffPwm { .. } => (0.5 * (1.0 + u), 1.0, -1.0),
        }
    }
}
