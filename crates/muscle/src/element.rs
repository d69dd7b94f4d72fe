//! The muscle as a force element between two anchors, stepped by a host that gives it the anchors'
//! distance over each of its steps: the engine's mechanism (pneuflex-multibody's `ActuatorFamily`) and the
//! MuJoCo plugin `pneuflex.muscle` (crates/mujoco-plugin) run this one implementation, as both run
//! `pneuflex_pneumatics::PneumaticForceElement` for the cylinder.
//!
//! Over a step of dt from length L moving at rate L', the element integrates its chamber (M9, M10) and
//! valve or regulator in `substeps` RK4 substeps with the length moving at the step's rate (split at a PWM
//! valve's spool edges) and returns the mean tension (M5, M7, M8), by the trapezoid over each piece.

use pneuflex_pneumatics::ValveState;

use crate::chamber::{ChamberState, MuscleChamber, Port};
use crate::plant::Feed;

/// The McKibben muscle as a force element: its chamber, its feed, the gas, the valve's state, the command
/// held and the element's clock (which drives a PWM valve's periods).
#[derive(Debug, Clone)]
pub struct MuscleForceElement {
    /// Muscle, gas and supply.
    pub chamber: MuscleChamber,
    /// Valve or regulator.
    pub feed: Feed,
    /// Gas in the muscle.
    pub gas: ChamberState,
    /// The valve's spool and PWM state (unused with a regulator).
    pub valve: ValveState,
    /// The command u in [-1, 1] held until changed.
    command: f64,
    substeps: u32,
    time_s: f64,
}

impl MuscleForceElement {
    /// How many numbers [`MuscleForceElement::state`] writes: p, T, the valve's state and the clock.
    pub const STATE_LEN: usize = 3 + ValveState::LEN;

    /// A muscle at gas state `gas`, its valve at rest at spool 0, `substeps` (0 is 1) per step.
    pub fn new(chamber: MuscleChamber, feed: Feed, gas: ChamberState, substeps: u32) -> Self {
        Self {
            chamber,
            feed,
            gas,
            valve: ValveState::default(),
            command: 0.0,
            substeps: substeps.max(1),
            time_s: 0.0,
        }
    }

    /// Sets the command held from the next step on: the valve command u in [-1, 1] (clamped; NaN is 0),
    /// or for a regulator the set pressure from atmosphere (u = -1) to supply (u = +1), linearly.
    pub fn set_command(&mut self, u: f64) {
        self.command = if u.is_nan() { 0.0 } else { u.clamp(-1.0, 1.0) };
    }

    /// The command held, in [-1, 1].
    pub fn command(&self) -> f64 {
        self.command
    }

    /// The fully contracted length L_min = L0 (1 - eps_max) (M6): the mount's retracted length, m.
    pub fn contracted_length_m(&self) -> f64 {
        let b = &self.chamber.muscle.braid;
        b.rest_length_m * (1.0 - b.max_contraction())
    }

    /// The mount's stroke L0 - L_min from full contraction to the rest length, m.
    pub fn stroke_m(&self) -> f64 {
        self.chamber.muscle.braid.rest_length_m - self.contracted_length_m()
    }

    /// What feeds the chamber under the command: the 3/2 valve at `spool`, or the regulator set from
    /// atmosphere (u = -1) to supply (u = +1), linearly.
    fn port(&self, spool: f64) -> Port {
        match self.feed {
            Feed::Closed => Port::Closed,
            Feed::Valve(valve) => Port::Valve { valve, spool },
            Feed::Regulator { time_constant_s } => {
                let s = &self.chamber.supply;
                Port::Regulator {
                    time_constant_s,
                    set_pressure_pa: s.atmosphere_pressure_pa
                        + 0.5
                            * (self.command + 1.0)
                            * (s.supply_pressure_pa - s.atmosphere_pressure_pa),
                }
            }
        }
    }

    /// One RK4 step of the gas over `h` from length `l` moving at `l_dot`, the port held.
    fn rk4(&mut self, l: f64, l_dot: f64, h: f64, port: &Port) {
        let c = &self.chamber;
        let d = |g: &ChamberState, l: f64| {
            let r = c.rates(g, l, l_dot, port);
            (r.pressure_pa_per_s, r.temperature_k_per_s)
        };
        let at = |g: &ChamberState, k: (f64, f64), s: f64| ChamberState {
            pressure_pa: g.pressure_pa + s * k.0,
            temperature_k: g.temperature_k + s * k.1,
        };
        let g = self.gas;
        let k1 = d(&g, l);
        let k2 = d(&at(&g, k1, 0.5 * h), l + 0.5 * h * l_dot);
        let k3 = d(&at(&g, k2, 0.5 * h), l + 0.5 * h * l_dot);
        let k4 = d(&at(&g, k3, h), l + h * l_dot);
        self.gas = ChamberState {
            pressure_pa: g.pressure_pa + h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0),
            temperature_k: g.temperature_k + h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1),
        };
    }

    /// Advances the chamber by `dt` (s) while the muscle's length goes from `length_m` at `rate` (m/s),
    /// and returns the mean tension over the step, N (trapezoid over each piece).
    pub fn step_length(&mut self, length_m: f64, rate: f64, dt: f64) -> f64 {
        let h = dt / f64::from(self.substeps);
        let mut t_sum = 0.0;
        for i in 0..self.substeps {
            let (t_sub, t_end) = (self.time_s, self.time_s + h);
            let (mut tau, mut rest) = (t_sub, h);
            loop {
                let (spool, edge) = match self.feed {
                    Feed::Valve(v) => v.segment(&mut self.valve, self.command, tau, rest),
                    _ => (0.0, None),
                };
                let len = edge.map_or(rest, |e| (e - tau).min(rest));
                let l = length_m + rate * (h * f64::from(i) + (tau - t_sub));
                let f0 = self.chamber.tension(&self.gas, l, rate);
                let port = self.port(spool);
                self.rk4(l, rate, len, &port);
                let f1 = self.chamber.tension(&self.gas, l + rate * len, rate);
                t_sum += 0.5 * (f0 + f1) * (len / h);
                match edge {
                    Some(e) if e < t_end => {
                        tau = e;
                        rest = t_end - e;
                    }
                    _ => break,
                }
            }
            self.time_s += h;
        }
        t_sum / f64::from(self.substeps)
    }

    /// The muscle's tension at rest at length `length_m` and the gas now, N (M5, M8).
    pub fn static_tension(&self, length_m: f64) -> f64 {
        self.chamber.tension(&self.gas, length_m, 0.0)
    }

    /// The evolving state as numbers, for a host's buffer (MuJoCo's plugin_state): p (Pa absolute),
    /// T (K), the valve's [`ValveState::to_array`], the element's clock (s).
    pub fn state(&self) -> [f64; Self::STATE_LEN] {
        let mut s = [0.0; Self::STATE_LEN];
        s[0] = self.gas.pressure_pa;
        s[1] = self.gas.temperature_k;
        s[2..2 + ValveState::LEN].copy_from_slice(&self.valve.to_array());
        s[Self::STATE_LEN - 1] = self.time_s;
        s
    }

    /// Restores [`MuscleForceElement::state`]'s numbers; `false` (nothing changed) when they are not a
    /// state the element can be in (a pressure or temperature not finite and positive, a bad valve state,
    /// a clock not finite).
    pub fn set_state(&mut self, s: &[f64; Self::STATE_LEN]) -> bool {
        let mut va = [0.0; ValveState::LEN];
        va.copy_from_slice(&s[2..2 + ValveState::LEN]);
        let Some(valve) = ValveState::from_array(&va) else {
            return false;
        };
        if !(s[..2].iter().all(|v| v.is_finite() && *v > 0.0) && s[Self::STATE_LEN - 1].is_finite())
        {
            return false;
        }
        self.gas = ChamberState {
            pressure_pa: s[0],
            temperature_k: s[1],
        };
        self.valve = valve;
        self.time_s = s[Self::STATE_LEN - 1];
        true
    }
}
