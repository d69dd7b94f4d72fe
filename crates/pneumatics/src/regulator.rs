//! A pressure regulator in front of each chamber, in place of the directional valve: the command is the two
//! chambers' pressure set-points (Pa absolute) instead of a valve command.
//!
//! Each regulator is a first-order pressure loop whose flow is limited by the valve's ISO 6358 paths fully
//! open (the regulator fills from the supply through the path supply -> chamber and vents to the exhaust
//! through the path chamber -> exhaust, eq. (11)). For one chamber at pressure p, temperature T and volume V
//! (changing at V'), with the set-point p_set clamped to [p_atm, p_s]:
//!
//! ```text
//! dp*/dt = (p_set - p) / tau                              the regulator's first-order law            (R1)
//! R T_in q* = V dp*/dt / n + p V'                         eq. (9) solved for the inflow giving (R1)   (R2)
//!     T_in = T_s when filling (q* > 0), T when venting
//! q = min(q*, q_fill)    filling, q_fill  = eq. (11) from the supply through the supply path, open
//! q = max(q*, -q_vent)   venting, q_vent  = eq. (11) to the exhaust through the exhaust path, open    (R3)
//! ```
//!
//! and the chamber follows eqs. (9)-(10) with the net inflow M' = q and the enthalpy carrier H = q T_in, as
//! under the valve ([`crate::actuator`]). While the flow is within its limit, (R2) makes dp/dt = (p_set - p)/tau
//! exactly: a closed chamber reaches p_set as p_set + (p0 - p_set) e^(-t/tau). A step the flow cannot follow
//! is limited by the valve's conductance: filling a closed chamber while the path is choked (p <= b p_s), q is
//! C rho0 p_s sqrt(T0/T_s) and p rises as the ramp n R T_s q / V. The regulator cannot fill above the supply
//! or vent below the atmosphere (its flow limits vanish there), nor fill from above the supply. A NaN set-point
//! passes no flow (the chamber is closed). The regulator has no state of its own: the chamber pressure is its
//! output. Tested in tests/regulator.rs (the step response and the choked ramp in closed form).

use crate::actuator::{Actuator, ChamberState, ChamberStep, Chambers, P_FLOOR, T_FLOOR};
use crate::flow::OrificeStep;
use crate::valve::Openings;

/// A first-order pressure regulator in front of each chamber (the flow limit is the actuator's valve's).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PressureRegulator {
    /// Time constant tau of (R1), s.
    pub time_constant_s: f64,
}

impl PressureRegulator {
    /// The time constants taken, s: regulators settle in milliseconds to seconds (the muscle sheet's
    /// `[regulator] time_constant_s` bounds).
    pub const TIME_CONSTANT_S: (f64, f64) = (1e-5, 10.0);

    /// A regulator of time constant `time_constant_s`, or why it is refused (not finite, outside
    /// [`Self::TIME_CONSTANT_S`]).
    pub fn new(time_constant_s: f64) -> Result<Self, String> {
        let (lo, hi) = Self::TIME_CONSTANT_S;
        if !(lo..=hi).contains(&time_constant_s) {
            return Err(format!(
                "the regulator's time constant must be in [{lo:e}, {hi}] s, got {time_constant_s}"
            ));
        }
        Ok(Self { time_constant_s })
    }
}

/// The chamber equations under the two regulators, with everything constant over a step evaluated once: the
/// geometry, the gas and the valve's paths fully open (their flow limits), the set-points.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RegulatedStep {
    /// The chamber constants with every path of the valve fully open.
    c: ChamberStep,
    /// 1 / (n tau), 1/s.
    inv_n_tau: f64,
    /// Set-points of A and B, clamped to [p_atm, p_s]; NaN: no flow.
    set_a: f64,
    set_b: f64,
}

impl RegulatedStep {
    pub(crate) fn new(a: &Actuator, reg: &PressureRegulator, set_a: f64, set_b: f64) -> Self {
        let c = a.consts_at(Openings {
            p_a: 1.0,
            a_r: 1.0,
            p_b: 1.0,
            b_r: 1.0,
        });
        let clamp = |p: f64| {
            if p.is_nan() { p } else { p.clamp(c.pr, c.ps) }
        };
        Self {
            inv_n_tau: 1.0 / (c.n * reg.time_constant_s),
            set_a: clamp(set_a),
            set_b: clamp(set_b),
            c,
        }
    }

    /// The flow into one chamber and its enthalpy carrier (kg/s, kg K/s), (R1)-(R3), the chamber at `p`, `t`
    /// (floored), volume `v` changing at `dv`, fed from `supply` and vented through `exhaust` (a path's
    /// constants and its gain, fully open).
    #[inline(always)]
    fn port(
        &self,
        set: f64,
        (p, t, v, dv): (f64, f64, f64, f64),
        supply: (&OrificeStep, f64),
        exhaust: (&OrificeStep, f64),
    ) -> (f64, f64) {
        if set.is_nan() {
            return (0.0, 0.0);
        }
        let c = &self.c;
        // (R2): R T_in q*.
        let demand = v * (set - p) * self.inv_n_tau + p * dv;
        if demand > 0.0 {
            // (R3): no more than the supply path passes (nothing from a supply below the chamber).
            let q_fill = c.supply_path(supply.0, supply.1, p, t).0.max(0.0);
            let q = (demand / (c.r * c.ts)).min(q_fill);
            (q, q * c.ts)
        } else {
            let q_vent = c.exhaust_path(exhaust.0, exhaust.1, p, t).0.max(0.0);
            let q = (-demand / (c.r * t)).min(q_vent);
            (-q, -q * t)
        }
    }

    /// Net mass flows into A and B (kg/s) and their enthalpy carriers (kg K/s) at extension `x`, velocity
    /// `x_dot`.
    #[inline(always)]
    pub(crate) fn flows(&self, s: &ChamberState, x: f64, x_dot: f64) -> ((f64, f64), (f64, f64)) {
        let c = &self.c;
        let (va, vb, dva, dvb) = c.volumes(x, x_dot);
        let pa = s.p_a.max(P_FLOOR);
        let pb = s.p_b.max(P_FLOOR);
        let ta = s.t_a.max(T_FLOOR);
        let tb = s.t_b.max(T_FLOOR);
        let (qa, ha) = self.port(
            self.set_a,
            (pa, ta, va, dva),
            (&c.or_pa, c.k_pa),
            (&c.or_ar, c.k_ar),
        );
        let (qb, hb) = self.port(
            self.set_b,
            (pb, tb, vb, dvb),
            (&c.or_pb, c.k_pb),
            (&c.or_br, c.k_br),
        );
        ((qa, qb), (ha, hb))
    }
}

impl Chambers for RegulatedStep {
    #[inline(always)]
    fn piston_force(&self, s: &ChamberState) -> f64 {
        self.c.piston_force(s)
    }

    /// Eqs. (9)-(10) with the regulators' flows, as [`ChamberStep::rates`] with the valve's.
    #[inline(always)]
    fn rates(&self, s: &ChamberState, x: f64, x_dot: f64) -> ChamberState {
        let c = &self.c;
        let (va, vb, dva, dvb) = c.volumes(x, x_dot);
        let ((qa, qb), (ha, hb)) = self.flows(s, x, x_dot);
        let (n, r) = (c.n, c.r);
        let pa = s.p_a.max(P_FLOOR);
        let pb = s.p_b.max(P_FLOOR);
        let ta = s.t_a.max(T_FLOOR);
        let tb = s.t_b.max(T_FLOOR);
        let (inv_va, inv_vb) = (1.0 / va, 1.0 / vb);
        let dpa = n * inv_va * (r * ha - pa * dva);
        let dpb = n * inv_vb * (r * hb - pb * dvb);
        let dta = ta / pa * (dpa + inv_va * (pa * dva - r * ta * qa));
        let dtb = tb / pb * (dpb + inv_vb * (pb * dvb - r * tb * qb));
        ChamberState {
            p_a: dpa,
            p_b: dpb,
            t_a: dta,
            t_b: dtb,
        }
    }
}

/// One classic RK4 step of the chambers under `k` with the piston moving as x + x_dot tau.
#[inline]
pub(crate) fn rk4_chambers(k: &impl Chambers, s: &mut ChamberState, x: f64, x_dot: f64, dt: f64) {
    let h = 0.5 * dt;
    let at = |d: &ChamberState, w: f64| ChamberState {
        p_a: s.p_a + w * d.p_a,
        p_b: s.p_b + w * d.p_b,
        t_a: s.t_a + w * d.t_a,
        t_b: s.t_b + w * d.t_b,
    };
    let k1 = k.rates(s, x, x_dot);
    let k2 = k.rates(&at(&k1, h), x + x_dot * h, x_dot);
    let k3 = k.rates(&at(&k2, h), x + x_dot * h, x_dot);
    let k4 = k.rates(&at(&k3, dt), x + x_dot * dt, x_dot);
    let w = dt / 6.0;
    s.p_a += w * (k1.p_a + 2.0 * k2.p_a + 2.0 * k3.p_a + k4.p_a);
    s.p_b += w * (k1.p_b + 2.0 * k2.p_b + 2.0 * k3.p_b + k4.p_b);
    s.t_a += w * (k1.t_a + 2.0 * k2.t_a + 2.0 * k3.t_a + k4.t_a);
    s.t_b += w * (k1.t_b + 2.0 * k2.t_b + 2.0 * k3.t_b + k4.t_b);
}

impl Actuator {
    /// Time derivatives of the chamber state (Pa/s, K/s) at extension `x`, velocity `x_dot`, with the
    /// regulators `reg` in front of the chambers at set-points `set_pa` (A, B; Pa absolute): (R1)-(R3) and
    /// eqs. (9)-(10).
    pub fn regulated_rates(
        &self,
        reg: &PressureRegulator,
        set_pa: (f64, f64),
        s: &ChamberState,
        x: f64,
        x_dot: f64,
    ) -> ChamberState {
        RegulatedStep::new(self, reg, set_pa.0, set_pa.1).rates(s, x, x_dot)
    }

    /// Net mass flows into A and B (kg/s) the regulators pass at chamber state `s` (R1)-(R3).
    pub fn regulated_flows(
        &self,
        reg: &PressureRegulator,
        set_pa: (f64, f64),
        s: &ChamberState,
        x: f64,
        x_dot: f64,
    ) -> (f64, f64) {
        RegulatedStep::new(self, reg, set_pa.0, set_pa.1)
            .flows(s, x, x_dot)
            .0
    }

    /// Advances the chambers by `dt` with classic RK4 behind the regulators at set-points `set_pa`, the piston
    /// moving as `x + x_dot * tau` inside the step ([`Actuator::step_chambers`] with the regulators).
    pub fn step_chambers_regulated(
        &self,
        reg: &PressureRegulator,
        set_pa: (f64, f64),
        s: &mut ChamberState,
        x: f64,
        x_dot: f64,
        dt: f64,
    ) {
        rk4_chambers(
            &RegulatedStep::new(self, reg, set_pa.0, set_pa.1),
            s,
            x,
            x_dot,
            dt,
        );
    }
}
