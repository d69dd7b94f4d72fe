//! A small plant to test the muscle on: a muscle anchored to a wall pulls a mass that a spring (and an
//! optional constant pull, a hanging weight) draws away from the wall; chamber, valve or regulator and the
//! mass integrated together with classic RK4.
//!
//! ```text
//! m L'' = k_s (L_s - L) + F_pull - c L' - T(p, L, L')                                     (M12)
//! ```
//!
//! L is the muscle's length (the mass's distance from the wall), T the tension (M5, M7, M8), L_s the length
//! at which the spring is relaxed.

use pneuflex_pneumatics::{ValveModel, ValveState};

use crate::chamber::{ChamberState, MuscleChamber, Port};

/// What the muscle pulls: mass, spring, damper and a constant pull away from the wall.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Load {
    /// Moving mass m, kg (> 0).
    pub mass_kg: f64,
    /// Spring rate k_s, N/m.
    pub spring_n_per_m: f64,
    /// Muscle length L_s at which the spring is relaxed, m.
    pub spring_free_length_m: f64,
    /// Viscous damping c of the mass's guide, N s/m.
    pub damping_n_s_per_m: f64,
    /// Constant force drawing the mass away from the wall F_pull (a hanging weight m g), N.
    pub pull_n: f64,
}

impl Load {
    /// Force of the load on the mass away from the wall at length `length_m` and velocity
    /// `velocity_m_per_s`, N: k_s (L_s - L) + F_pull - c L' (M12 without the muscle).
    pub fn force(&self, length_m: f64, velocity_m_per_s: f64) -> f64 {
        self.spring_n_per_m * (self.spring_free_length_m - length_m) + self.pull_n
            - self.damping_n_s_per_m * velocity_m_per_s
    }
}

/// What feeds the muscle in the plant, with its own state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Feed {
    /// A closed muscle (no valve).
    Closed,
    /// A 3/2 valve (see [`Port::Valve`]); the command is the valve command u in [-1, 1], +1 filling.
    Valve(ValveModel),
    /// A pressure regulator (see [`Port::Regulator`]); the command is the set pressure, Pa absolute.
    Regulator {
        /// Time constant of the regulated pressure, s (> 0).
        time_constant_s: f64,
    },
}

/// State of the plant: the mass's motion, the gas, and the gas mass that came in through the port.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantState {
    /// Muscle length L (mass's distance from the wall), m.
    pub length_m: f64,
    /// L', m/s.
    pub velocity_m_per_s: f64,
    /// Gas in the muscle.
    pub chamber: ChamberState,
    /// Integral of the net mass inflow since the start, kg: the mass balance's check (M10).
    pub inflow_kg: f64,
}

impl PlantState {
    fn axpy(&self, h: f64, d: &Self) -> Self {
        Self {
            length_m: self.length_m + h * d.length_m,
            velocity_m_per_s: self.velocity_m_per_s + h * d.velocity_m_per_s,
            chamber: ChamberState {
                pressure_pa: self.chamber.pressure_pa + h * d.chamber.pressure_pa,
                temperature_k: self.chamber.temperature_k + h * d.chamber.temperature_k,
            },
            inflow_kg: self.inflow_kg + h * d.inflow_kg,
        }
    }
}

/// The muscle, its feed and its load.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MusclePlant {
    /// Muscle, gas and supply.
    pub chamber: MuscleChamber,
    /// The load the muscle pulls.
    pub load: Load,
    /// Valve, regulator or nothing.
    pub feed: Feed,
    /// The valve's spool and PWM state (unused without a valve).
    pub valve_state: ValveState,
    /// The plant's clock, s (drives a PWM valve's periods).
    pub time_s: f64,
}

impl MusclePlant {
    /// A plant at time 0, a valve's spool at rest at 0.
    pub fn new(chamber: MuscleChamber, load: Load, feed: Feed) -> Self {
        Self {
            chamber,
            load,
            feed,
            valve_state: ValveState::default(),
            time_s: 0.0,
        }
    }

    /// The longest step RK4 keeps stable against the braid friction, s: near rest the tanh of (M7) is a
    /// damper c = (F_c + c_p p) / v_s on the mass, an eigenvalue -c / m, and RK4 is stable on the real axis
    /// for h |lambda| < 2.785; taken at the supply pressure. (The chamber's and the spring's time scales
    /// are usually longer; a PWM valve's edges split the step anyway.)
    pub fn friction_step_limit_s(&self) -> f64 {
        let f = &self.chamber.muscle.friction;
        let p = self.chamber.supply.supply_pressure_pa - self.chamber.supply.atmosphere_pressure_pa;
        let damping = (f.coulomb_n + f.coulomb_n_per_pa * p) / f.smooth_velocity_m_per_s;
        if damping > 0.0 {
            2.785 * self.load.mass_kg / damping
        } else {
            f64::INFINITY
        }
    }

    /// Time derivative of the plant's state with the port held.
    fn derivative(&self, x: &PlantState, port: &Port) -> PlantState {
        let (l, v) = (x.length_m, x.velocity_m_per_s);
        let r = self.chamber.rates(&x.chamber, l, v, port);
        let tension = self.chamber.tension(&x.chamber, l, v);
        PlantState {
            length_m: v,
            velocity_m_per_s: (self.load.force(l, v) - tension) / self.load.mass_kg,
            chamber: ChamberState {
                pressure_pa: r.pressure_pa_per_s,
                temperature_k: r.temperature_k_per_s,
            },
            inflow_kg: r.mass_flow_kg_per_s,
        }
    }

    /// One classic RK4 step of `dt` with the port held.
    fn rk4(&self, x: &mut PlantState, port: &Port, dt: f64) {
        let h = 0.5 * dt;
        let k1 = self.derivative(x, port);
        let k2 = self.derivative(&x.axpy(h, &k1), port);
        let k3 = self.derivative(&x.axpy(h, &k2), port);
        let k4 = self.derivative(&x.axpy(dt, &k3), port);
        // k1 + 2 k2 + 2 k3 + k4
        let sum = k1.axpy(2.0, &k2).axpy(2.0, &k3).axpy(1.0, &k4);
        *x = x.axpy(dt / 6.0, &sum);
    }

    /// Advances the plant by `dt` (s) under `command` (the valve command u in [-1, 1], or the regulator's
    /// set pressure in Pa absolute; ignored when closed), held over the step. A PWM valve's spool edges
    /// split the step (`ValveModel::segment`), so each piece is integrated with its spool held.
    pub fn step(&mut self, x: &mut PlantState, command: f64, dt: f64) {
        match self.feed {
            Feed::Closed => self.rk4(x, &Port::Closed, dt),
            Feed::Regulator { time_constant_s } => self.rk4(
                x,
                &Port::Regulator {
                    time_constant_s,
                    set_pressure_pa: command,
                },
                dt,
            ),
            Feed::Valve(valve) => {
                let (mut t, t_end) = (self.time_s, self.time_s + dt);
                loop {
                    let (spool, edge) = valve.segment(&mut self.valve_state, command, t, t_end - t);
                    let end = edge.unwrap_or(t_end);
                    self.rk4(x, &Port::Valve { valve, spool }, end - t);
                    if end >= t_end {
                        break;
                    }
                    t = end;
                }
            }
        }
        self.time_s += dt;
    }
}
