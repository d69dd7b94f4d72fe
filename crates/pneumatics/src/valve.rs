//! Directional control valves: a proportional 5/3 valve and the rig's 5/2 on/off solenoid valve under PWM.
//!
//! Both are described by a normalised spool position `s` in [-1, 1] and four flow paths
//! (P = supply, R = exhaust): P->A and B->R open for `s > 0`, P->B and A->R open for `s < 0`.
//! The command `u` in [-1, 1] follows the lead's convention: +1 = supply to A, B to exhaust (extend).

use crate::effects::SpoolDynamics;
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

impl ValveKind {
    /// The kind's name in a sheet (`valve.kind`) and its own parameters under the sheet's keys.
    pub fn sheet_keys(&self) -> (&'static str, Vec<(&'static str, f64)>) {
        match *self {
            ValveKind::Proportional { response_time_s } => {
                ("proportional", vec![("response_time_s", response_time_s)])
            }
            ValveKind::OnOffPwm {
                pwm_frequency_hz,
                switching_delay_s,
            } => (
                "on_off_pwm",
                vec![
                    ("pwm_frequency_hz", pwm_frequency_hz),
                    ("switching_delay_s", switching_delay_s),
                ],
            ),
        }
    }

    /// The period of the PWM carrier, s, for a valve switched by PWM; None for one that follows the
    /// command.
    pub fn pwm_period_s(&self) -> Option<f64> {
        match *self {
            ValveKind::OnOffPwm {
                pwm_frequency_hz, ..
            } => Some(1.0 / pwm_frequency_hz),
            ValveKind::Proportional { .. } => None,
        }
    }

    /// The spool's delays and time constants with the model's spool dynamics ([`crate::SpoolDynamics`],
    /// before the lines' delay), s: `[delay on, delay off, tau on, tau off]` ("on" a move towards +1).
    pub(crate) fn spool_timing(&self, d: &SpoolDynamics) -> [f64; 4] {
        match *self {
            ValveKind::OnOffPwm {
                switching_delay_s, ..
            } => [
                switching_delay_s,
                d.release_delay_s.unwrap_or(switching_delay_s),
                d.spool_time_constant_s,
                d.release_time_constant_s.unwrap_or(d.spool_time_constant_s),
            ],
            ValveKind::Proportional { response_time_s } => [
                d.dead_time_s,
                d.dead_time_s,
                response_time_s,
                response_time_s,
            ],
        }
    }
}

/// The four flow paths of a 5-port valve, in the order of [`ValveModel::paths`].
pub const PATHS: [&str; 4] = ["supply_a", "a_exhaust", "supply_b", "b_exhaust"];

/// A 5-port directional valve: flow restriction, centre underlap and spool dynamics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ValveModel {
    /// ISO 6358 characteristics of one fully open path.
    pub orifice: Orifice,
    /// Per-path ISO 6358 characteristics where a path differs from `orifice` (supply -> A, A -> exhaust,
    /// supply -> B, B -> exhaust, as [`PATHS`]); `None`: `orifice`. A real valve's metering edges are not
    /// identical, and identification can tell them apart (docs/identification.md).
    pub paths: [Option<Orifice>; 4],
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
    pub(crate) started: bool,
    /// Time of the first PWM period start, s.
    pub(crate) t0: f64,
    /// Index of the current PWM period.
    pub(crate) period: u64,
    /// Duty latched for the current period.
    pub(crate) duty: f64,
    /// Duty latched for the previous period (edges delayed into the current one).
    pub(crate) prev_duty: f64,
    /// The spool's pending moves when the model has spool dynamics or lines ([`crate::spool`]).
    pub(crate) moves: crate::moves::PendingMoves,
}

impl ValveState {
    /// How many numbers [`ValveState::to_array`] writes.
    pub const LEN: usize = 6;

    /// A valve state resting at spool position `spool` (clamped to [-1, 1]).
    pub fn at_spool(spool: f64) -> Self {
        Self {
            spool: sanitize(spool),
            ..Self::default()
        }
    }

    /// The state as numbers, for a host that keeps it in its own buffer of f64 (MuJoCo's `plugin_state`):
    /// spool, PWM clock started (0 or 1), first period start (s), period index, latched duty, previous duty.
    /// [`ValveState::from_array`] gives it back bit for bit (a period index is exact up to 2^53).
    pub fn to_array(&self) -> [f64; Self::LEN] {
        [
            self.spool,
            if self.started { 1.0 } else { 0.0 },
            self.t0,
            self.period as f64,
            self.duty,
            self.prev_duty,
        ]
    }

    /// The inverse of [`ValveState::to_array`]; `None` for numbers it never writes (a spool or duty outside
    /// [-1, 1] / [0, 1], a flag other than 0 or 1, a time that is not finite, a period index that is not a
    /// whole number in [0, 2^53]), so that a corrupted buffer is refused rather than run.
    pub fn from_array(a: &[f64; Self::LEN]) -> Option<Self> {
        let [spool, started, t0, period, duty, prev_duty] = *a;
        let started = match started {
            0.0 => false,
            1.0 => true,
            _ => return None,
        };
        let whole = (0.0..=9_007_199_254_740_992.0).contains(&period) && period.fract() == 0.0;
        let unit = |d: f64| (0.0..=1.0).contains(&d);
        if !((-1.0..=1.0).contains(&spool)
            && t0.is_finite()
            && whole
            && unit(duty)
            && unit(prev_duty))
        {
            return None;
        }
        Some(Self {
            spool,
            started,
            t0,
            period: period as u64,
            duty,
            prev_duty,
            // A host that keeps the state as numbers runs sheets without spool dynamics or lines (the
            // force element refuses those): no moves are ever pending.
            moves: Default::default(),
        })
    }
}

/// Clamps a command to [-1, 1]; NaN becomes 0 (never an open valve by accident).
#[inline]
pub(crate) fn sanitize(u: f64) -> f64 {
    if u.is_nan() { 0.0 } else { u.clamp(-1.0, 1.0) }
}

impl ValveModel {
    /// The period of the PWM carrier, s, for an on/off valve switched by PWM; None for a proportional valve.
    pub fn pwm_period_s(&self) -> Option<f64> {
        self.kind.pwm_period_s()
    }

    /// The ISO 6358 characteristics of path `i` (as [`PATHS`]).
    #[inline]
    pub fn path(&self, i: usize) -> Orifice {
        self.paths[i].unwrap_or(self.orifice)
    }

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
    /// shorter than the PWM period to resolve the duty, and an edge inside the step is not located: the
    /// integrators use [`ValveModel::segment`], which is this for the proportional valve).
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

    /// Advances the valve from `t` over at most `dt` under command `u` (held) and returns the spool
    /// position and how far it holds: `(spool, None)` for the whole of `[t, t + dt]`, `(spool, Some(t_e))`
    /// up to the spool edge at the absolute time `t_e`, strictly inside `(t, t + dt)`. An integrator calls it
    /// again from `t_e` (with the rest of its step) and integrates each piece with its spool held, so every
    /// PWM edge, delayed by `switching_delay_s`, falls on a piece boundary: the results converge with the
    /// step instead of sampling the spool once per step ([`ValveModel::spool`]).
    ///
    /// For the proportional valve this is [`ValveModel::spool`] over `dt` and never an edge. Under PWM the
    /// duty of each period is latched from `u` at the period start (a start inside `[t, t + dt)` latches the
    /// `u` of this call: the caller holds `u` over its step). Allocation-free; `t` must not go backwards.
    pub fn segment(&self, state: &mut ValveState, u: f64, t: f64, dt: f64) -> (f64, Option<f64>) {
        let ValveKind::OnOffPwm {
            pwm_frequency_hz,
            switching_delay_s,
        } = self.kind
        else {
            return (self.spool(state, u, t, dt), None);
        };
        let pwm = Pwm {
            period: 1.0 / pwm_frequency_hz,
            delay: switching_delay_s,
        };
        let duty = 0.5 * (1.0 + sanitize(u));
        pwm.latch(state, duty, t);
        let s0 = pwm.spool_at(state, t);
        state.spool = s0;
        let t_end = t + dt;
        let mut tau = t;
        loop {
            // Inside the current period [start_k, start_k+1) the spool can change at the previous
            // period's delayed falling edge, this period's delayed rising edge and its falling edge.
            let next_start = pwm.start(state, state.period + 1);
            let lim = next_start.min(t_end);
            for c in [pwm.fall_prev(state), pwm.rise(state), pwm.fall(state)] {
                if c > tau && c < lim && pwm.spool_at(state, c) != s0 {
                    return (s0, Some(c));
                }
            }
            // A period start within `snap` of the step's end belongs to the next call (see `Pwm::snap`).
            if next_start >= t_end - pwm.snap() {
                return (s0, None);
            }
            // The next period starts inside the step: latch its duty from this call's command.
            state.prev_duty = state.duty;
            state.duty = duty;
            state.period += 1;
            tau = next_start;
            if pwm.spool_at(state, tau) != s0 {
                return (s0, Some(tau));
            }
        }
    }

    /// How long the spool holds after a call of [`Self::segment`] that started at `tau`: a later call
    /// from `t` over `dt` with `t + dt < until` and `t + snap < latch` would change no state and return
    /// `(state.spool, None)` whatever its command (no period starts, so no duty is latched, and no edge
    /// lies before `until`), so a caller may skip it. An on/off valve holds until its next spool edge or
    /// period start; a proportional valve follows its command at every step and never holds.
    pub fn hold(&self, state: &ValveState, tau: f64) -> SpoolHold {
        let ValveKind::OnOffPwm {
            pwm_frequency_hz,
            switching_delay_s,
        } = self.kind
        else {
            return SpoolHold::NONE;
        };
        if !state.started {
            return SpoolHold::NONE;
        }
        let pwm = Pwm {
            period: 1.0 / pwm_frequency_hz,
            delay: switching_delay_s,
        };
        let next_start = pwm.start(state, state.period + 1);
        let mut until = next_start - pwm.snap();
        // The spool is piecewise constant between these candidates (`segment`'s), so the first that
        // changes it ends the hold.
        for c in [pwm.fall_prev(state), pwm.rise(state), pwm.fall(state)] {
            if c > tau && c < until && pwm.spool_at(state, c) != state.spool {
                until = c;
            }
        }
        SpoolHold {
            until,
            next_start,
            snap: pwm.snap(),
        }
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

/// How long a valve's spool holds without a call of [`ValveModel::segment`] ([`ValveModel::hold`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpoolHold {
    /// A call ending before this time (s) would find no edge.
    until: f64,
    /// The next period start (s) and the snap before it (`Pwm::snap`): a call from `t` with
    /// `t + snap < next_start` latches nothing.
    next_start: f64,
    snap: f64,
}

impl SpoolHold {
    /// No hold: every step calls [`ValveModel::segment`].
    pub const NONE: Self = Self {
        until: f64::NEG_INFINITY,
        next_start: f64::NEG_INFINITY,
        snap: 0.0,
    };

    /// Whether a call of [`ValveModel::segment`] from `t` over `dt` may be skipped.
    #[inline]
    pub fn covers(&self, t: f64, dt: f64) -> bool {
        t + dt < self.until && t + self.snap < self.next_start
    }
}

/// The PWM clock of an on/off valve: period and switching delay, and the edge times of the latched
/// periods. Every time is computed by one expression (`start`, `rise`, `fall`, `fall_prev`), so an edge
/// returned by [`ValveModel::segment`] compares equal to itself when the next piece starts there.
pub(crate) struct Pwm {
    /// PWM period T, s.
    pub(crate) period: f64,
    /// Switching delay, s (< T).
    pub(crate) delay: f64,
}

impl Pwm {
    /// How close (s) a period start may lie after a call's time `t` and still count as started at `t`:
    /// 1e-7 of the period. The callers' clocks accumulate their steps (`t += dt`), so a period start meant
    /// to coincide with a control tick lands a rounding error before or after it; without the snap the duty
    /// would be latched from the previous tick's command or the new one's at random, and results would not
    /// converge with the step. With it, a period start at a step boundary latches the new step's command.
    #[inline]
    pub(crate) fn snap(&self) -> f64 {
        1e-7 * self.period
    }

    /// Start of period `k`, s.
    #[inline]
    pub(crate) fn start(&self, st: &ValveState, k: u64) -> f64 {
        st.t0 + k as f64 * self.period
    }

    /// The delayed rising edge of the current period (the energised position from here on if duty > 0).
    #[inline]
    fn rise(&self, st: &ValveState) -> f64 {
        self.start(st, st.period) + self.delay
    }

    /// The delayed falling edge of the current period (back to the spring position).
    #[inline]
    fn fall(&self, st: &ValveState) -> f64 {
        self.rise(st) + st.duty * self.period
    }

    /// The delayed falling edge of the previous period (before the first period: the coil was off).
    #[inline]
    fn fall_prev(&self, st: &ValveState) -> f64 {
        self.start(st, st.period) - self.period + self.delay + st.prev_duty * self.period
    }

    /// Starts the clock on the first call, and moves it to the period containing `t` (the largest k with
    /// start(k) <= t + snap), latching `duty` for a new period.
    fn latch(&self, st: &mut ValveState, duty: f64, t: f64) {
        if !st.started {
            st.started = true;
            st.t0 = t;
            st.period = 0;
            st.duty = duty;
            // Before the first period the coil was off: spring position.
            st.prev_duty = 0.0;
        }
        let t = t + self.snap();
        // A first guess of the period, settled below by the exact comparisons against start(k) (so any
        // guess gives the same k): the current period while `t` lies within the next two (a step is
        // shorter than a period; this skips a division at every step), else floor((t - t0) / T) (the cast
        // truncates: the floor for positive values, without a libm call).
        let mut k = if self.start(st, st.period + 2) > t {
            st.period
        } else {
            let k = (t - st.t0) / self.period;
            if k > 0.0 { k as u64 } else { 0 }
        };
        while self.start(st, k + 1) <= t {
            k += 1;
        }
        while k > 0 && self.start(st, k) > t {
            k -= 1;
        }
        if k > st.period {
            st.prev_duty = if k == st.period + 1 { st.duty } else { duty };
            st.duty = duty;
            st.period = k;
        }
    }

    /// The spool just after `tau` (right-continuous), for `tau` in the current period [start_k - snap,
    /// start_k+1).
    #[inline]
    fn spool_at(&self, st: &ValveState, tau: f64) -> f64 {
        let on = if tau >= self.rise(st) {
            tau < self.fall(st)
        } else {
            tau < self.fall_prev(st)
        };
        if on { 1.0 } else { -1.0 }
    }
}
