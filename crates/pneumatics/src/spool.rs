//! The valve's spool with delays and travel (issue 26), for a model with [`crate::SpoolDynamics`] or
//! [`crate::Lines`]; the paper's model keeps [`crate::ValveModel::segment`].
//!
//! The electrical signal e(t) is the command u (proportional valve) or, under PWM, +1 during
//! `[S_k, S_k + d_k T)` and -1 otherwise (S_k a period start, d_k the duty latched there from u). Each
//! change of e reaches the spool as a *move* after a delay D: on/off, the switching delay for an energising
//! edge and the release delay for a de-energising one; proportional, the dead time; plus the lines'
//! transport delay L/c for both. The spool then follows the move's target to first order,
//! `tau s' = target - s`, so `s(t) = target + (s_0 - target) exp(-(t - t_0)/tau)` (tau: the spool or
//! release time constant of the on/off valve, the response time of the proportional one; 0: a jump).
//! A move that arrives no later than one still pending overtakes it: a pulse shorter than the difference
//! of the two delays never reaches the spool, as on a solenoid that drops out before it pulled in.
//!
//! The paths open linearly with the spool ([`crate::ValveModel::openings`]): a 5/2 spool travelling from
//! -1 to +1 passes through a closed centre.

use crate::effects::Effects;
use crate::valve::{Pwm, ValveModel, ValveState, sanitize};

/// Delays and time constants of a valve's spool, s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Timing {
    /// PWM period of an on/off valve; `None` for a proportional valve.
    pwm_period: Option<f64>,
    /// Delay of a move towards +1 (on/off: energising; proportional: any), s.
    delay_on: f64,
    /// Delay of a move towards -1 (on/off: de-energising), s.
    delay_off: f64,
    /// Time constant of the travel towards a target > 0, s.
    tau_on: f64,
    /// Time constant of the travel towards a target <= 0, s.
    tau_off: f64,
}

impl Timing {
    /// The timing of `valve` with the model's spool dynamics and lines.
    pub(crate) fn of(valve: &ValveModel, e: &Effects) -> Self {
        let line = e.lines.map_or(0.0, |l| l.delay_s());
        let d = e.spool.unwrap_or_default();
        let [delay_on, delay_off, tau_on, tau_off] = valve.kind.spool_timing(&d);
        Self {
            pwm_period: valve.pwm_period_s(),
            delay_on: delay_on + line,
            delay_off: delay_off + line,
            tau_on,
            tau_off,
        }
    }
}

/// The spool over one piece of a step: `s(t) = target + (start - target) exp(-(t - t0) / tau)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SpoolLaw {
    t0: f64,
    start: f64,
    target: f64,
    tau: f64,
}

impl SpoolLaw {
    /// Whether the spool stands still over the piece.
    #[inline]
    pub(crate) fn is_held(&self) -> bool {
        self.tau <= 0.0 || self.start == self.target
    }

    /// The spool position at `t`.
    #[inline]
    pub(crate) fn at(&self, t: f64) -> f64 {
        if self.is_held() {
            self.target
        } else {
            self.target
                + (self.start - self.target) * crate::mechanics::decay((t - self.t0) / self.tau)
        }
    }
}

/// Advances the spool's schedule over `[t, t + dt]` under the command `u` (held) and returns the spool's
/// law from `t` and how far it holds: `None` for the whole step, `Some(t_e)` up to the next move's arrival
/// strictly inside the step, from where the caller asks again (as [`ValveModel::segment`]). The caller sets
/// `state.spool` to the law's value where its piece ends.
pub(crate) fn piece(
    timing: &Timing,
    state: &mut ValveState,
    u: f64,
    t: f64,
    dt: f64,
) -> (SpoolLaw, Option<f64>) {
    let u = sanitize(u);
    let t_end = t + dt;
    match timing.pwm_period {
        Some(period) => schedule_pwm(state, timing, period, u, t, t_end),
        None => schedule_command(state, timing, u, t),
    }
    state.moves.arrive(t);
    let target = state.moves.target;
    // Within 1e-12 of the full travel the spool is at its target (the exponential never gets there).
    if (state.spool - target).abs() <= 1e-12 {
        state.spool = target;
    }
    let law = SpoolLaw {
        t0: t,
        start: state.spool,
        target,
        tau: if target > 0.0 {
            timing.tau_on
        } else {
            timing.tau_off
        },
    };
    let edge = state.moves.next_arrival().filter(|&a| a < t_end);
    (law, edge)
}

/// Proportional valve: a change of the command is a move after the dead time (and the lines' delay).
fn schedule_command(state: &mut ValveState, timing: &Timing, u: f64, t: f64) {
    let m = &mut state.moves;
    if !m.started {
        // As if the command had rested at the spool's position.
        m.begin(state.spool, state.spool);
    }
    if u != m.electrical {
        m.push(t + timing.delay_on, u);
        m.electrical = u;
    }
}

/// On/off valve under PWM: every period that starts before the step's end (less the PWM clock's snap,
/// [`Pwm::snap`]) latches its duty from `u` and schedules its edges.
fn schedule_pwm(state: &mut ValveState, timing: &Timing, period: f64, u: f64, t: f64, t_end: f64) {
    let pwm = Pwm { period, delay: 0.0 };
    let duty = 0.5 * (1.0 + u);
    if !state.started || !state.moves.started {
        state.started = true;
        state.t0 = t;
        state.period = 0;
        state.duty = duty;
        state.prev_duty = 0.0;
        // Before the first period the coil was off: the spring position.
        state.moves.begin(-1.0, -1.0);
        open_period(state, timing, &pwm, duty);
    }
    while pwm.start(state, state.period + 1) < t_end - pwm.snap() {
        state.period += 1;
        state.prev_duty = state.duty;
        state.duty = duty;
        open_period(state, timing, &pwm, duty);
    }
}

/// The edges of the current period: energised from its start if the duty is above 0, de-energised at
/// `d T` if the duty is below 1; each a move after its delay.
fn open_period(state: &mut ValveState, timing: &Timing, pwm: &Pwm, duty: f64) {
    let start = pwm.start(state, state.period);
    let level = if duty > 0.0 { 1.0 } else { -1.0 };
    let m = &mut state.moves;
    if level != m.electrical {
        let delay = if level > 0.0 {
            timing.delay_on
        } else {
            timing.delay_off
        };
        m.push(start + delay, level);
        m.electrical = level;
    }
    if duty > 0.0 && duty < 1.0 {
        m.push(start + timing.delay_off + duty * pwm.period, -1.0);
        m.electrical = -1.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::{Lines, SpoolDynamics};
    use crate::flow::Orifice;
    use crate::valve::ValveKind;

    fn pwm_valve(delay: f64) -> ValveModel {
        ValveModel {
            orifice: Orifice {
                sonic_conductance_m3_per_s_pa: 5e-9,
                critical_pressure_ratio: 0.3,
            },
            paths: [None; 4],
            underlap: 0.0,
            kind: ValveKind::OnOffPwm {
                pwm_frequency_hz: 40.0,
                switching_delay_s: delay,
            },
        }
    }

    /// The spool position at each of `times` (increasing), driven by `u` from t = 0 in steps of `dt`, with
    /// each step split at the moves as an integrator splits it.
    fn trajectory(timing: &Timing, u: impl Fn(f64) -> f64, dt: f64, times: &[f64]) -> Vec<f64> {
        let mut st = ValveState::at_spool(-1.0);
        let mut out = Vec::new();
        let mut t = 0.0;
        let mut next = times.iter().copied().peekable();
        while next.peek().is_some() {
            let (mut tau, t_end) = (t, t + dt);
            loop {
                let (law, edge) = piece(timing, &mut st, u(t), tau, t_end - tau);
                let end = edge.unwrap_or(t_end);
                while let Some(&w) = next.peek() {
                    if w >= tau && w < end {
                        out.push(law.at(w));
                        next.next();
                    } else {
                        break;
                    }
                }
                st.spool = law.at(end);
                match edge {
                    Some(e) => tau = e,
                    None => break,
                }
            }
            t = t_end;
        }
        out
    }

    /// On/off valve at 50 % duty, 5 ms pull-in and 2 ms drop-out delay, 1 ms / 3 ms spool travel: the spool
    /// starts to move exactly at each delayed edge and follows `1 - 2 exp(-t'/tau_on)` after a pull-in and
    /// `-1 + (s_1 + 1) exp(-t'/tau_off)` after a drop-out (closed forms of tau s' = target - s).
    #[test]
    fn pwm_spool_follows_the_delayed_first_order_law() {
        let e = Effects {
            spool: Some(SpoolDynamics {
                release_delay_s: Some(0.002),
                spool_time_constant_s: 0.001,
                release_time_constant_s: Some(0.003),
                dead_time_s: 0.0,
            }),
            ..Effects::default()
        };
        let timing = Timing::of(&pwm_valve(0.005), &e);
        // Pull-in at 5 ms, drop-out command at 12.5 ms reaches the spool at 14.5 ms.
        let times = [
            0.004, 0.0049, 0.0051, 0.006, 0.008, 0.0144, 0.0146, 0.016, 0.02,
        ];
        let got = trajectory(&timing, |_| 0.0, 1e-4, &times);
        let rise = |t: f64| 1.0 - 2.0 * (-(t - 0.005) / 0.001).exp();
        let s1 = rise(0.0145);
        for (&t, &s) in times.iter().zip(&got) {
            let want = if t < 0.005 {
                -1.0
            } else if t < 0.0145 {
                rise(t)
            } else {
                -1.0 + (s1 + 1.0) * (-(t - 0.0145) / 0.003).exp()
            };
            assert!((s - want).abs() < 1e-9, "t {t}: {s} vs {want}");
        }
    }

    /// A pulse shorter than the pull-in delay minus the drop-out delay never reaches the spool.
    #[test]
    fn a_pulse_shorter_than_the_delay_difference_is_swallowed() {
        let e = Effects {
            spool: Some(SpoolDynamics {
                release_delay_s: Some(0.001),
                ..SpoolDynamics::default()
            }),
            ..Effects::default()
        };
        let timing = Timing::of(&pwm_valve(0.008), &e);
        // Duty 0.2 -> 5 ms pulse, drop-out arrives at 6 ms < pull-in at 8 ms: nothing moves.
        let times: Vec<f64> = (0..49).map(|i| 0.001 * i as f64 + 0.0005).collect();
        let got = trajectory(&timing, |_| -0.6, 1e-4, &times);
        assert!(got.iter().all(|&s| s == -1.0), "{got:?}");
        // Duty 0.5 -> 12.5 ms pulse: on from 8 ms to 13.5 ms of each period.
        let got = trajectory(&timing, |_| 0.0, 1e-4, &times);
        for (&t, &s) in times.iter().zip(&got) {
            let ph = t % 0.025;
            let want = if (0.008..0.0135).contains(&ph) {
                1.0
            } else {
                -1.0
            };
            assert_eq!(s, want, "t {t}");
        }
    }

    /// Proportional valve: a command step at t = 0 moves the spool from 2 ms of dead time plus the lines'
    /// 1 m / 250 m/s = 4 ms on as `u (1 - exp(-(t - 6 ms) / tau))`.
    #[test]
    fn proportional_dead_time_and_line_delay() {
        let mut v = pwm_valve(0.0);
        v.kind = ValveKind::Proportional {
            response_time_s: 0.004,
        };
        let e = Effects {
            spool: Some(SpoolDynamics {
                dead_time_s: 0.002,
                ..SpoolDynamics::default()
            }),
            lines: Some(Lines {
                volume_m3: 1e-6,
                orifice: v.orifice,
                length_m: 1.0,
                speed_of_sound_m_per_s: 250.0,
            }),
            ..Effects::default()
        };
        let timing = Timing::of(&v, &e);
        let mut st = ValveState::at_spool(0.0);
        let (dt, mut t) = (1e-4, 0.0);
        let mut checked = 0;
        while t < 0.03 {
            let (law, edge) = piece(&timing, &mut st, 0.7, t, dt);
            let mut tau = t;
            let mut law = law;
            if let Some(e) = edge {
                assert!((e - 0.006).abs() < 1e-12, "move at {e}");
                st.spool = law.at(e);
                tau = e;
                law = piece(&timing, &mut st, 0.7, e, t + dt - e).0;
            }
            let mid = 0.5 * (tau + t + dt);
            let want = if mid < 0.006 {
                0.0
            } else {
                0.7 * (1.0 - (-(mid - 0.006) / 0.004).exp())
            };
            assert!((law.at(mid) - want).abs() < 1e-9, "t {mid}");
            st.spool = law.at(t + dt);
            t += dt;
            checked += 1;
        }
        assert!(checked >= 299);
    }
}
