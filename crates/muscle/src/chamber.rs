//! The muscle's chamber: the mass and energy balance of the paper's eqs. (2)-(10) with a volume that depends
//! on the muscle's length, fed by a 3/2 valve (ISO 6358 flow, eq. (11)) or by a pressure regulator.
//!
//! State: absolute pressure p and gas temperature T. With net mass inflow M' and enthalpy inflow
//! H = sum q_i T_i (T_i the upstream temperature: the supply's for inflow, the chamber's for outflow), as
//! `pneuflex_pneumatics::Actuator` does for each of the cylinder's chambers:
//!
//! ```text
//! dp/dt = n / V (R H - p dV/dt)                        eq. (9)/(10), V = V(L) of (M2)       (M9)
//! dT/dt = T / p (dp/dt + (p dV/dt - R T M') / V)       mass balance, M = p V / (R T), eq. (2) (M10)
//! ```
//!
//! n = 1.4 is the adiabatic chamber of eqs. (5)-(6) (a closed chamber keeps p V^n), n = 1 the isothermal
//! one. (M10) makes M = p V / (R T) change exactly by the port flows.

use pneuflex_pneumatics::{Gas, Supply, ValveModel};

use crate::braid::Muscle;

/// Lowest pressure (Pa) and temperature (K) the equations evaluate: guards a diverging step, not a limit.
const P_FLOOR: f64 = 1.0;
const T_FLOOR: f64 = 1.0;

/// Pressure and temperature of the gas in the muscle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChamberState {
    /// Absolute pressure p, Pa.
    pub pressure_pa: f64,
    /// Gas temperature T, K.
    pub temperature_k: f64,
}

/// What feeds the chamber while it is integrated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Port {
    /// Nothing: a closed chamber.
    Closed,
    /// A 3/2 valve at spool position `spool` in [-1, 1]: the supply reaches the muscle through the valve's
    /// `supply_a` path (open for spool > 0), the muscle empties to the exhaust through `a_exhaust` (open for
    /// spool < 0); a 5/3 or 5/2 valve sheet with its B port plugged is such a valve.
    Valve {
        /// The valve: its supply_a and a_exhaust paths and underlap.
        valve: ValveModel,
        /// Spool position held over the step.
        spool: f64,
    },
    /// A pressure regulator in front of the muscle: the chamber pressure follows the set pressure (clamped
    /// to [atmosphere, supply]) with a first-order lag, `dp/dt = (p_set - p) / tau` (M11), the regulator
    /// passing whatever flow that takes (no flow limit).
    Regulator {
        /// Time constant tau of the regulated pressure, s (> 0).
        time_constant_s: f64,
        /// Set pressure p_set, Pa absolute.
        set_pressure_pa: f64,
    },
}

/// Time derivatives of the chamber state and the net mass inflow that produced them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChamberRates {
    /// dp/dt, Pa/s.
    pub pressure_pa_per_s: f64,
    /// dT/dt, K/s.
    pub temperature_k_per_s: f64,
    /// Net mass flow into the muscle M', kg/s.
    pub mass_flow_kg_per_s: f64,
}

/// The muscle with its gas and its supply: everything the chamber equations need.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MuscleChamber {
    /// The muscle.
    pub muscle: Muscle,
    /// Gas constant and the chamber's polytropic exponent n.
    pub gas: Gas,
    /// Supply and exhaust (atmosphere) conditions.
    pub supply: Supply,
}

impl MuscleChamber {
    /// Gauge pressure p - p_atm, Pa.
    pub fn gauge_pa(&self, s: &ChamberState) -> f64 {
        s.pressure_pa - self.supply.atmosphere_pressure_pa
    }

    /// The muscle's tension at chamber state `s`, length `length_m` and lengthening rate `length_rate`, N.
    pub fn tension(&self, s: &ChamberState, length_m: f64, length_rate: f64) -> f64 {
        self.muscle.tension(self.gauge_pa(s), length_m, length_rate)
    }

    /// Gas mass in the muscle M = p V / (R T), kg.
    pub fn gas_mass_kg(&self, s: &ChamberState, length_m: f64) -> f64 {
        let (v, _) = self.muscle.chamber_volume(length_m, 0.0);
        s.pressure_pa * v / (self.gas.gas_constant_j_per_kg_k * s.temperature_k)
    }

    /// Net mass inflow M' (kg/s) and enthalpy carrier H = sum q_i T_i (kg K/s) through `port` with the
    /// gas at `p`, `t` in volume `v` changing at `dv`.
    fn port_flow(&self, port: &Port, p: f64, t: f64, v: f64, dv: f64) -> (f64, f64) {
        let sp = &self.supply;
        match *port {
            Port::Closed => (0.0, 0.0),
            Port::Valve { valve, spool } => {
                let o = valve.openings(spool);
                // eq. (11) on each path; mass_flow's second value is q T_upstream.
                let (q_in, h_in) = valve.path(0).mass_flow(
                    o.p_a,
                    sp.supply_pressure_pa,
                    sp.supply_temperature_k,
                    p,
                    t,
                );
                let (q_out, h_out) = valve.path(1).mass_flow(
                    o.a_r,
                    p,
                    t,
                    sp.atmosphere_pressure_pa,
                    sp.atmosphere_temperature_k,
                );
                (q_in - q_out, h_in - h_out)
            }
            Port::Regulator {
                time_constant_s,
                set_pressure_pa,
            } => {
                let p_set = set_pressure_pa.clamp(sp.atmosphere_pressure_pa, sp.supply_pressure_pa);
                let dp = (p_set - p) / time_constant_s;
                // (M9) solved for the inflow that makes dp/dt the regulator's (M11):
                // R T_in M' = V dp/dt / n + p dV/dt, T_in the supply's when filling, the gas's when venting.
                let demand = v * dp / self.gas.polytropic_exponent + p * dv;
                let t_in = if demand > 0.0 {
                    sp.supply_temperature_k
                } else {
                    t
                };
                let q = demand / (self.gas.gas_constant_j_per_kg_k * t_in);
                (q, q * t_in)
            }
        }
    }

    /// Time derivatives of the chamber state (M9, M10) at length `length_m`, lengthening rate
    /// `length_rate` (m/s), fed through `port`.
    pub fn rates(
        &self,
        s: &ChamberState,
        length_m: f64,
        length_rate: f64,
        port: &Port,
    ) -> ChamberRates {
        let p = s.pressure_pa.max(P_FLOOR);
        let t = s.temperature_k.max(T_FLOOR);
        let (v, dv) = self.muscle.chamber_volume(length_m, length_rate);
        let (q, h) = self.port_flow(port, p, t, v, dv);
        let (n, r) = (
            self.gas.polytropic_exponent,
            self.gas.gas_constant_j_per_kg_k,
        );
        let dp = n / v * (r * h - p * dv);
        let dt = t / p * (dp + (p * dv - r * t * q) / v);
        ChamberRates {
            pressure_pa_per_s: dp,
            temperature_k_per_s: dt,
            mass_flow_kg_per_s: q,
        }
    }
}
