//! The double-acting cylinder with its valve, supply and exhaust: chamber mass and energy balance,
//! eqs. (2)-(10) of the paper, and the pneumatic force on the rod.
//!
//! Conventions: `x` is the piston extension from the cap end (the paper's `y`), m. Chamber A is the cap
//! side (its pressure extends the rod), chamber B the rod side. All pressures are absolute, Pa.
//!
//! Chamber model (per chamber, state p and T): with net mass inflow `M' = sum q_i` and enthalpy inflow
//! `H = sum q_i T_i` (T_i = upstream temperature: supply/atmosphere for inflow, the chamber for outflow),
//!
//! ```text
//! dp/dt = n / V (R H - p dV/dt)                          eq. (9)/(10) generalised
//! dT/dt = T / (p V) (V dp/dt + p dV/dt - R T M')         ideal gas, M = p V / (R T), eqs. (2)-(3)
//! ```
//!
//! `n` is the polytropic exponent: n = k = 1.4 is the adiabatic chamber of eqs. (5)-(7) (the default);
//! n = 1 an isothermal chamber. For a closed chamber the first line gives p V^n = const (eq. 5/6). The
//! second line is the mass balance of eq. (2) solved for T, so M = p V / (R T) changes exactly by the
//! port flows. Eq. (10) is the special case T_i = T_s for every flow and no dead volume.

use crate::flow::{ISO_T0_K, OrificeStep};
use crate::lanes::{Real, pick};
use crate::valve::{Openings, ValveModel};

/// Standard gravity, m/s^2.
pub const STANDARD_GRAVITY: f64 = 9.80665;
/// Specific gas constant of dry air, J/(kg K).
pub const R_AIR: f64 = 287.05;
/// Standard atmosphere, Pa absolute.
pub const P_ATM: f64 = 101_325.0;
/// Default gas temperature, K (20 degC).
pub const T_DEFAULT: f64 = 293.15;

/// Geometry of a double-acting single-rod cylinder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cylinder {
    /// Piston (bore) diameter, m.
    pub bore_m: f64,
    /// Rod diameter, m.
    pub rod_m: f64,
    /// Stroke length L, m.
    pub stroke_m: f64,
    /// Dead volume of chamber A at x = 0 (end cap, ports, tubing to the valve), m^3.
    pub dead_volume_a_m3: f64,
    /// Dead volume of chamber B at x = L, m^3.
    pub dead_volume_b_m3: f64,
}

impl Cylinder {
    /// Piston area on the cap side S_a, m^2.
    #[inline]
    pub fn area_a(&self) -> f64 {
        0.25 * core::f64::consts::PI * self.bore_m * self.bore_m
    }
    /// Annular piston area on the rod side S_b, m^2.
    #[inline]
    pub fn area_b(&self) -> f64 {
        self.area_a() - self.area_rod()
    }
    /// Rod cross-section, m^2 (the area on which the atmosphere pushes the rod back in).
    #[inline]
    pub fn area_rod(&self) -> f64 {
        0.25 * core::f64::consts::PI * self.rod_m * self.rod_m
    }
    /// Chamber volumes (V_a, V_b) at extension `x` (clamped to the stroke), m^3.
    #[inline]
    pub fn volumes(&self, x: f64) -> (f64, f64) {
        let x = x.clamp(0.0, self.stroke_m);
        (
            self.dead_volume_a_m3 + self.area_a() * x,
            self.dead_volume_b_m3 + self.area_b() * (self.stroke_m - x),
        )
    }
}

/// Thermodynamic properties of the working gas.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gas {
    /// Specific gas constant R, J/(kg K).
    pub gas_constant_j_per_kg_k: f64,
    /// Polytropic exponent n of the chamber process (1.4 = adiabatic air, 1.0 = isothermal).
    pub polytropic_exponent: f64,
}

impl Default for Gas {
    fn default() -> Self {
        Self {
            gas_constant_j_per_kg_k: R_AIR,
            polytropic_exponent: 1.4,
        }
    }
}

/// Supply and exhaust (atmosphere) conditions, absolute.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Supply {
    /// Supply pressure p_s, Pa absolute.
    pub supply_pressure_pa: f64,
    /// Supply temperature T_s, K.
    pub supply_temperature_k: f64,
    /// Atmospheric (exhaust) pressure, Pa absolute.
    pub atmosphere_pressure_pa: f64,
    /// Atmospheric temperature, K.
    pub atmosphere_temperature_k: f64,
}

/// State of the two chambers: absolute pressures and gas temperatures.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChamberState {
    /// Chamber A (cap side) pressure, Pa absolute.
    pub p_a: f64,
    /// Chamber B (rod side) pressure, Pa absolute.
    pub p_b: f64,
    /// Chamber A gas temperature, K.
    pub t_a: f64,
    /// Chamber B gas temperature, K.
    pub t_b: f64,
}

impl ChamberState {
    /// Chambers at pressures `p_a`, `p_b` (Pa absolute) and the default temperature 293.15 K.
    pub fn new(p_a: f64, p_b: f64) -> Self {
        Self::with_temperature(p_a, p_b, T_DEFAULT)
    }
    /// Chambers at pressures `p_a`, `p_b` (Pa absolute) and gas temperature `t_k` (K) in both.
    pub fn with_temperature(p_a: f64, p_b: f64, t_k: f64) -> Self {
        Self {
            p_a,
            p_b,
            t_a: t_k,
            t_b: t_k,
        }
    }
    #[inline]
    fn axpy(&self, h: f64, d: &Self) -> Self {
        Self {
            p_a: self.p_a + h * d.p_a,
            p_b: self.p_b + h * d.p_b,
            t_a: self.t_a + h * d.t_a,
            t_b: self.t_b + h * d.t_b,
        }
    }
}

/// Mass flows through the four valve paths, kg/s (positive in the direction of the name).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PortFlows {
    /// Supply -> A.
    pub p_a: f64,
    /// A -> exhaust.
    pub a_r: f64,
    /// Supply -> B.
    pub p_b: f64,
    /// B -> exhaust.
    pub b_r: f64,
}

impl PortFlows {
    /// Net mass flow into chamber A, kg/s.
    pub fn into_a(&self) -> f64 {
        self.p_a - self.a_r
    }
    /// Net mass flow into chamber B, kg/s.
    pub fn into_b(&self) -> f64 {
        self.p_b - self.b_r
    }
}

/// The pneumatic part of the actuator: cylinder, gas, valve, supply and exhaust.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Actuator {
    /// Cylinder geometry.
    pub cylinder: Cylinder,
    /// Gas properties and chamber process exponent.
    pub gas: Gas,
    /// The directional valve.
    pub valve: ValveModel,
    /// Supply and exhaust conditions.
    pub supply: Supply,
}

/// Lowest pressure the chamber equations evaluate, Pa (guards a diverging step, not a physical limit).
pub(crate) const P_FLOOR: f64 = 1.0;
/// Lowest temperature the chamber equations evaluate, K.
pub(crate) const T_FLOOR: f64 = 1.0;

impl Actuator {
    /// Net pneumatic force on the rod along +x, N: p_a S_a - p_b S_b - p_atm S_rod (eq. 1's F_1 with
    /// absolute pressures; the atmosphere acts on the rod's cross-section outside the cylinder).
    #[inline]
    pub fn piston_force(&self, s: &ChamberState) -> f64 {
        let c = &self.cylinder;
        s.p_a * c.area_a() - s.p_b * c.area_b() - self.supply.atmosphere_pressure_pa * c.area_rod()
    }

    /// Mass flows through the four valve paths for chamber state `s` and spool position `spool`.
    #[inline]
    pub fn port_flows(&self, s: &ChamberState, spool: f64) -> PortFlows {
        self.step_consts(spool).flows_enthalpy(s).0
    }

    /// Time derivatives of the chamber state (Pa/s, K/s) at extension `x`, velocity `x_dot` and spool
    /// position `spool`.
    #[inline]
    pub fn chamber_rates(&self, s: &ChamberState, x: f64, x_dot: f64, spool: f64) -> ChamberState {
        self.step_consts(spool).rates(s, x, x_dot)
    }

    /// The constants of the chamber equations for spool position `spool`, held over one step.
    #[inline]
    pub(crate) fn step_consts(&self, spool: f64) -> ChamberStep {
        self.consts_at(self.valve.openings(spool))
    }

    /// The constants of the chamber equations with the valve's paths open by `o`.
    #[inline]
    pub(crate) fn consts_at(&self, o: Openings) -> ChamberStep {
        let c = &self.cylinder;
        let sp = &self.supply;
        // One set of ISO 6358 constants per path (all equal to the valve's unless the sheet gives paths).
        let v = &self.valve;
        let (or_pa, or_ar, or_pb, or_br) = (
            OrificeStep::new(&v.path(0)),
            OrificeStep::new(&v.path(1)),
            OrificeStep::new(&v.path(2)),
            OrificeStep::new(&v.path(3)),
        );
        ChamberStep {
            area_a: c.area_a(),
            area_b: c.area_b(),
            atm_rod_force: sp.atmosphere_pressure_pa * c.area_rod(),
            stroke: c.stroke_m,
            dead_a: c.dead_volume_a_m3,
            dead_b: c.dead_volume_b_m3,
            n: self.gas.polytropic_exponent,
            r: self.gas.gas_constant_j_per_kg_k,
            k_pa: or_pa.gain(o.p_a),
            k_ar: or_ar.gain(o.a_r),
            k_pb: or_pb.gain(o.p_b),
            k_br: or_br.gain(o.b_r),
            or_pa,
            or_ar,
            or_pb,
            or_br,
            ps: sp.supply_pressure_pa,
            ts: sp.supply_temperature_k,
            t0_over_ts: ISO_T0_K / sp.supply_temperature_k,
            pr: sp.atmosphere_pressure_pa,
            tr: sp.atmosphere_temperature_k,
            t0_over_tr: ISO_T0_K / sp.atmosphere_temperature_k,
        }
    }

    /// Advances the chambers by `dt` with classic RK4, the piston moving as `x + x_dot * tau` inside the
    /// step and the spool held. Allocation-free; callers may substep.
    pub fn step_chambers(&self, s: &mut ChamberState, x: f64, x_dot: f64, spool: f64, dt: f64) {
        self.step_consts(spool).step(s, x, x_dot, dt);
    }

    /// Gas masses (M_a, M_b) in the chambers at extension `x`, kg (ideal gas, M = p V / (R T)).
    pub fn chamber_masses(&self, s: &ChamberState, x: f64) -> (f64, f64) {
        let (va, vb) = self.cylinder.volumes(x);
        let r = self.gas.gas_constant_j_per_kg_k;
        (s.p_a * va / (r * s.t_a), s.p_b * vb / (r * s.t_b))
    }

    /// Period-averaged net mass flows (into A, into B), kg/s, for a steady command `u` at chamber state
    /// `s`: the spool position itself for a proportional valve, the duty-weighted mean of the two
    /// positions for a PWM-driven on/off valve.
    pub fn mean_flows(&self, s: &ChamberState, u: f64) -> (f64, f64) {
        let (w, hi, lo) = self.valve.averaging(u);
        let f_hi = self.port_flows(s, hi);
        if w >= 1.0 {
            return (f_hi.into_a(), f_hi.into_b());
        }
        let f_lo = self.port_flows(s, lo);
        (
            w * f_hi.into_a() + (1.0 - w) * f_lo.into_a(),
            w * f_hi.into_b() + (1.0 - w) * f_lo.into_b(),
        )
    }
}

/// The chamber equations with everything that is constant over one step (geometry, gas, the valve
/// openings of the held spool, supply and exhaust, the orifice constants) evaluated once, so that each
/// RK4 stage only does the state-dependent work.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ChamberStep {
    /// S_a, m^2.
    pub(crate) area_a: f64,
    /// S_b, m^2.
    pub(crate) area_b: f64,
    /// p_atm S_rod, N.
    atm_rod_force: f64,
    /// Stroke L, m.
    pub(crate) stroke: f64,
    /// Dead volume of A, m^3.
    pub(crate) dead_a: f64,
    /// Dead volume of B, m^3.
    pub(crate) dead_b: f64,
    /// Polytropic exponent n.
    pub(crate) n: f64,
    /// Gas constant R, J/(kg K).
    pub(crate) r: f64,
    /// ISO 6358 constants of the paths P->A, A->R, P->B, B->R.
    pub(crate) or_pa: OrificeStep,
    pub(crate) or_ar: OrificeStep,
    pub(crate) or_pb: OrificeStep,
    pub(crate) or_br: OrificeStep,
    /// Gains (opening C rho0) of the paths P->A, A->R, P->B, B->R, kg/(s Pa).
    pub(crate) k_pa: f64,
    pub(crate) k_ar: f64,
    pub(crate) k_pb: f64,
    pub(crate) k_br: f64,
    /// Supply pressure (Pa), temperature (K) and T0 / T_s.
    pub(crate) ps: f64,
    pub(crate) ts: f64,
    t0_over_ts: f64,
    /// Exhaust pressure (Pa), temperature (K) and T0 / T_atm.
    pub(crate) pr: f64,
    pub(crate) tr: f64,
    t0_over_tr: f64,
}

/// What feeds the chambers over a step, with its constants evaluated: the chamber equations' rates and the
/// piston force, for the 1-DOF model's RK4 ([`ChamberStep`]: the valve at a held spool;
/// [`crate::regulator::RegulatedStep`]: a pressure regulator in front of each chamber).
pub(crate) trait Chambers {
    /// Net pneumatic force on the rod along +x, N.
    fn piston_force(&self, s: &ChamberState) -> f64;
    /// Time derivatives of the chamber state (Pa/s, K/s) at extension `x` and velocity `x_dot`.
    fn rates(&self, s: &ChamberState, x: f64, x_dot: f64) -> ChamberState;
}

impl Chambers for ChamberStep {
    #[inline(always)]
    fn piston_force(&self, s: &ChamberState) -> f64 {
        ChamberStep::piston_force(self, s)
    }
    #[inline(always)]
    fn rates(&self, s: &ChamberState, x: f64, x_dot: f64) -> ChamberState {
        ChamberStep::rates(self, s, x, x_dot)
    }
}

impl ChamberStep {
    /// [`Actuator::step_chambers`] with these constants (the spool's).
    #[inline]
    pub(crate) fn step(&self, s: &mut ChamberState, x: f64, x_dot: f64, dt: f64) {
        let cs = self;
        let h = 0.5 * dt;
        let k1 = cs.rates(s, x, x_dot);
        let k2 = cs.rates(&s.axpy(h, &k1), x + x_dot * h, x_dot);
        let k3 = cs.rates(&s.axpy(h, &k2), x + x_dot * h, x_dot);
        let k4 = cs.rates(&s.axpy(dt, &k3), x + x_dot * dt, x_dot);
        let w = dt / 6.0;
        s.p_a += w * (k1.p_a + 2.0 * k2.p_a + 2.0 * k3.p_a + k4.p_a);
        s.p_b += w * (k1.p_b + 2.0 * k2.p_b + 2.0 * k3.p_b + k4.p_b);
        s.t_a += w * (k1.t_a + 2.0 * k2.t_a + 2.0 * k3.t_a + k4.t_a);
        s.t_b += w * (k1.t_b + 2.0 * k2.t_b + 2.0 * k3.t_b + k4.t_b);
    }

    /// Net pneumatic force on the rod along +x, N (same as [`Actuator::piston_force`]).
    #[inline(always)]
    pub(crate) fn piston_force(&self, s: &ChamberState) -> f64 {
        self.force_of(s.p_a, s.p_b)
    }

    /// [`Self::piston_force`] at chamber pressures `p_a`, `p_b` (a plant's, or a pack of plants').
    #[inline(always)]
    pub(crate) fn force_of<R: Real>(&self, p_a: R, p_b: R) -> R {
        p_a * R::splat(self.area_a) - p_b * R::splat(self.area_b) - R::splat(self.atm_rod_force)
    }

    /// Signed flow supply -> chamber (kg/s) through a path of gain `k` and its enthalpy carrier
    /// q T_upstream (kg K/s), eq. (11); the chamber is at `p`, `t` (floored). The direction picks the
    /// upstream node, and one flow is formed ([`crate::lanes`]).
    #[inline(always)]
    pub(crate) fn supply_path<R: Real>(&self, or: &OrificeStep, k: R, p: R, t: R) -> (R, R) {
        let ps = R::splat(self.ps);
        let [q, h] = pick!(R; R::splat(0.0).lt(k) =>
            {
                let filling = p.le(ps);
                if R::ONE {
                    pick!(R; filling => {
                        let q = or.flow(k, R::splat(self.t0_over_ts), ps, p);
                        [q, q * R::splat(self.ts)]
                    }, {
                        let q = or.flow(k, R::splat(ISO_T0_K) / t, p, ps);
                        [-q, -q * t]
                    })
                } else {
                // T0 / T_u, p_u, p_d.
                let [t0_tu, p_u, p_d] = pick!(R; filling =>
                    [R::splat(self.t0_over_ts), ps, p],
                    [R::splat(ISO_T0_K) / t, p, ps]
                );
                let q = or.flow(k, t0_tu, p_u, p_d);
                pick!(R; filling => [q, q * R::splat(self.ts)], [-q, -q * t])
                }
            },
            [R::splat(0.0); 2]
        );
        (q, h)
    }

    /// Signed flow chamber -> exhaust (kg/s) and its enthalpy carrier (kg K/s), eq. (11).
    #[inline(always)]
    pub(crate) fn exhaust_path<R: Real>(&self, or: &OrificeStep, k: R, p: R, t: R) -> (R, R) {
        let pr = R::splat(self.pr);
        let [q, h] = pick!(R; R::splat(0.0).lt(k) =>
            {
                let venting = pr.le(p);
                if R::ONE {
                    pick!(R; venting => {
                        let q = or.flow(k, R::splat(ISO_T0_K) / t, p, pr);
                        [q, q * t]
                    }, {
                        let q = or.flow(k, R::splat(self.t0_over_tr), pr, p);
                        [-q, -q * R::splat(self.tr)]
                    })
                } else {
                let [t0_tu, p_u, p_d] = pick!(R; venting =>
                    [R::splat(ISO_T0_K) / t, p, pr],
                    [R::splat(self.t0_over_tr), pr, p]
                );
                let q = or.flow(k, t0_tu, p_u, p_d);
                pick!(R; venting => [q, q * t], [-q, -q * R::splat(self.tr)])
                }
            },
            [R::splat(0.0); 2]
        );
        (q, h)
    }

    /// Flows and enthalpy carriers (q T_upstream) into A and B.
    #[inline(always)]
    pub(crate) fn flows_enthalpy(&self, s: &ChamberState) -> (PortFlows, (f64, f64)) {
        let [pa, pb, ta, tb] = floored([s.p_a, s.p_b, s.t_a, s.t_b]);
        let gains = [self.k_pa, self.k_ar, self.k_pb, self.k_br];
        let (pf, h) = self.flows_of(gains, [pa, pb, ta, tb]);
        (
            PortFlows {
                p_a: pf[0],
                a_r: pf[1],
                p_b: pf[2],
                b_r: pf[3],
            },
            h,
        )
    }

    /// The four paths' flows (P->A, A->R, P->B, B->R) and the enthalpy carriers into A and B, with the
    /// paths' `gains` at the floored chamber state `[p_a, p_b, t_a, t_b]`.
    #[inline(always)]
    fn flows_of<R: Real>(&self, gains: [R; 4], [pa, pb, ta, tb]: [R; 4]) -> ([R; 4], (R, R)) {
        let (q_pa, h_pa) = self.supply_path(&self.or_pa, gains[0], pa, ta);
        let (q_ar, h_ar) = self.exhaust_path(&self.or_ar, gains[1], pa, ta);
        let (q_pb, h_pb) = self.supply_path(&self.or_pb, gains[2], pb, tb);
        let (q_br, h_br) = self.exhaust_path(&self.or_br, gains[3], pb, tb);
        ([q_pa, q_ar, q_pb, q_br], (h_pa - h_ar, h_pb - h_br))
    }

    /// Chamber volumes and their rates (V_a, V_b, V_a', V_b') at extension `x` and velocity `x_dot`, m^3 and
    /// m^3/s: `V_a = V_a0 + S_a x`, `V_b = V_b0 + S_b (L - x)`, x clamped to the stroke.
    #[inline(always)]
    pub(crate) fn volumes<R: Real>(&self, x: R, x_dot: R) -> (R, R, R, R) {
        let (zero, stroke) = (R::splat(0.0), R::splat(self.stroke));
        let (area_a, area_b) = (R::splat(self.area_a), R::splat(self.area_b));
        let xc = x.clamp(0.0, self.stroke);
        let va = R::splat(self.dead_a) + area_a * xc;
        let vb = R::splat(self.dead_b) + area_b * (stroke - xc);
        // Outside the stroke the piston rests on a stop: the volumes do not change.
        let inside = R::or(
            R::or(
                R::and(zero.lt(x), x.lt(stroke)),
                R::and(x.le(zero), zero.lt(x_dot)),
            ),
            R::and(stroke.le(x), x_dot.lt(zero)),
        );
        let v = R::select(inside, x_dot, zero);
        (va, vb, area_a * v, -area_b * v)
    }

    /// Time derivatives of the chamber state (Pa/s, K/s) at extension `x` and velocity `x_dot`.
    #[inline(always)]
    pub(crate) fn rates(&self, s: &ChamberState, x: f64, x_dot: f64) -> ChamberState {
        let gains = [self.k_pa, self.k_ar, self.k_pb, self.k_br];
        let [p_a, p_b, t_a, t_b] = self.rates_of(gains, [s.p_a, s.p_b, s.t_a, s.t_b], x, x_dot);
        ChamberState { p_a, p_b, t_a, t_b }
    }

    /// [`Self::rates`] with the paths' `gains` (P->A, A->R, P->B, B->R) at the chamber state
    /// `[p_a, p_b, t_a, t_b]`: one plant's, or a pack of plants' that share every other constant.
    #[inline(always)]
    pub(crate) fn rates_of<R: Real>(&self, gains: [R; 4], s: [R; 4], x: R, x_dot: R) -> [R; 4] {
        let (va, vb, dva, dvb) = self.volumes(x, x_dot);
        let [pa, pb, ta, tb] = floored(s);
        let (q, (ha, hb)) = self.flows_of(gains, [pa, pb, ta, tb]);
        let (into_a, into_b) = (q[0] - q[1], q[2] - q[3]);
        let (n, r) = (R::splat(self.n), R::splat(self.r));
        let one = R::splat(1.0);
        let (inv_va, inv_vb) = (one / va, one / vb);
        // eq. (9)/(10): dp/dt = n R H / V - n p V'/V (H = enthalpy inflow / c_p, upstream temperatures).
        let dpa = n * inv_va * (r * ha - pa * dva);
        let dpb = n * inv_vb * (r * hb - pb * dvb);
        // eqs. (2)-(3): M = pV/(RT), dM/dt = net inflow  =>  dT/dt = T (p'/p + V'/V - R T M'/(p V)),
        // written with one division by p: dT/dt = (T/p) (p' + (p V' - R T M') / V).
        let dta = ta / pa * (dpa + inv_va * (pa * dva - r * ta * into_a));
        let dtb = tb / pb * (dpb + inv_vb * (pb * dvb - r * tb * into_b));
        [dpa, dpb, dta, dtb]
    }
}

/// The chamber state `[p_a, p_b, t_a, t_b]` floored for the equations.
#[inline(always)]
fn floored<R: Real>([pa, pb, ta, tb]: [R; 4]) -> [R; 4] {
    let (p, t) = (R::splat(P_FLOOR), R::splat(T_FLOOR));
    [pa.max(p), pb.max(p), ta.max(t), tb.max(t)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::Orifice;
    use crate::valve::ValveKind;

    fn act(underlap: f64, b: f64) -> Actuator {
        Actuator {
            cylinder: Cylinder {
                bore_m: 0.016,
                rod_m: 0.005,
                stroke_m: 0.05,
                dead_volume_a_m3: 3.5e-6,
                dead_volume_b_m3: 3.5e-6,
            },
            gas: Gas::default(),
            valve: ValveModel {
                orifice: Orifice {
                    sonic_conductance_m3_per_s_pa: 5.0e-9,
                    critical_pressure_ratio: b,
                },
                paths: [None; 4],
                underlap,
                kind: ValveKind::Proportional {
                    response_time_s: 0.0,
                },
            },
            supply: Supply {
                supply_pressure_pa: 6.0e5,
                supply_temperature_k: 300.0,
                atmosphere_pressure_pa: P_ATM,
                atmosphere_temperature_k: 290.0,
            },
        }
    }

    /// The per-step evaluation (one square root per path, no pressure-ratio division) gives the same
    /// flows and chamber rates as the textbook form: `Orifice::mass_flow` per path (ISO 6358 with
    /// phi(p_d / p_u), eq. 11) and dT/dt = T (p'/p + V'/V - R T M'/(p V)) (eqs. 2-3, 9-10), to rounding,
    /// in every flow regime (choked, subsonic, laminar, reverse) and for both flow directions; with one
    /// orifice for all paths and with each path its own (`ValveModel::paths`: C and b differ per path).
    #[test]
    fn step_constants_match_reference_equations() {
        let pressures = [
            5.0e4, 1.0e5, P_ATM, 1.0135e5, 1.5e5, 3.0e5, 5.99e5, 5.9999e5, 6.0e5, 6.5e5,
        ];
        let mut checked = 0;
        for (b, per_path) in [(0.0, false), (0.3, false), (0.528, false), (0.3, true)] {
            for underlap in [0.0, 0.05] {
                let mut a = act(underlap, b);
                if per_path {
                    for (i, (c, bi)) in [(3e-9, 0.1), (4e-9, 0.45), (2.5e-9, 0.3), (4.5e-9, 0.528)]
                        .into_iter()
                        .enumerate()
                    {
                        a.valve.paths[i] = Some(Orifice {
                            sonic_conductance_m3_per_s_pa: c,
                            critical_pressure_ratio: bi,
                        });
                    }
                }
                let or: [Orifice; 4] = std::array::from_fn(|i| a.valve.path(i));
                let (ps, ts) = (a.supply.supply_pressure_pa, a.supply.supply_temperature_k);
                let (pr, tr) = (
                    a.supply.atmosphere_pressure_pa,
                    a.supply.atmosphere_temperature_k,
                );
                for spool in [-1.0, -0.3, 0.0, 0.02, 0.7, 1.0] {
                    let o = a.valve.openings(spool);
                    for &pa in &pressures {
                        for &pb in &pressures {
                            let s = ChamberState {
                                p_a: pa,
                                p_b: pb,
                                t_a: 250.0,
                                t_b: 340.0,
                            };
                            let (ta, tb) = (s.t_a, s.t_b);
                            let (q_pa, h_pa) = or[0].mass_flow(o.p_a, ps, ts, pa, ta);
                            let (q_ar, h_ar) = or[1].mass_flow(o.a_r, pa, ta, pr, tr);
                            let (q_pb, h_pb) = or[2].mass_flow(o.p_b, ps, ts, pb, tb);
                            let (q_br, h_br) = or[3].mass_flow(o.b_r, pb, tb, pr, tr);
                            let f = a.port_flows(&s, spool);
                            let scale = 1e-12 * (5.0e-9 * 1.185 * 6.5e5);
                            for (got, want) in
                                [(f.p_a, q_pa), (f.a_r, q_ar), (f.p_b, q_pb), (f.b_r, q_br)]
                            {
                                assert!(
                                    (got - want).abs() <= scale,
                                    "b {b}, spool {spool}, p_a {pa}, p_b {pb}: {got} vs {want}"
                                );
                            }
                            // Chamber rates from the reference flows, moving piston.
                            let (x, xd) = (0.02, 0.3);
                            let (va, vb) = a.cylinder.volumes(x);
                            let dva = a.cylinder.area_a() * xd;
                            let dvb = -a.cylinder.area_b() * xd;
                            let (n, r) = (a.gas.polytropic_exponent, a.gas.gas_constant_j_per_kg_k);
                            let dpa = n / va * (r * (h_pa - h_ar) - pa * dva);
                            let dpb = n / vb * (r * (h_pb - h_br) - pb * dvb);
                            let dta =
                                ta * (dpa / pa + dva / va - r * ta * (q_pa - q_ar) / (pa * va));
                            let dtb =
                                tb * (dpb / pb + dvb / vb - r * tb * (q_pb - q_br) / (pb * vb));
                            let k = a.chamber_rates(&s, x, xd, spool);
                            for (got, want, unit) in [
                                (k.p_a, dpa, 1e-3),
                                (k.p_b, dpb, 1e-3),
                                (k.t_a, dta, 1e-6),
                                (k.t_b, dtb, 1e-6),
                            ] {
                                assert!(
                                    (got - want).abs() <= 1e-11 * want.abs() + unit,
                                    "b {b}, spool {spool}, p_a {pa}, p_b {pb}: {got} vs {want}"
                                );
                            }
                            checked += 1;
                        }
                    }
                }
            }
        }
        assert_eq!(checked, 4 * 2 * 6 * 10 * 10);
    }

    /// The rod force of the per-step constants is the public `piston_force`.
    #[test]
    fn step_force_matches_piston_force() {
        let a = act(0.0, 0.3);
        let s = ChamberState::new(4.2e5, 1.7e5);
        let f = a.step_consts(0.0).piston_force(&s);
        assert!((f - a.piston_force(&s)).abs() <= 1e-12 * f.abs());
    }
}
