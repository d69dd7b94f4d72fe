//! Linearisation of the valve flow (eq. 12) and the transfer function of eqs. (16)-(17).
//!
//! eq. (16): `Y(s)/P_L(s) = b0 / (a3 s^3 + a2 s^2 + a1 s)` with
//! `b0 = S_a R T k (K_cb + K_ca r)`, `a3 = m V_a r`, `a2 = K_ca R T k m r + K_v V_a r`, `a1 = beta_n`.
//! eq. (17) writes it as `K_n / (s (s^2/w_n^2 + 2 xi_n s / w_n + 1))`. Dividing eq. (16) by a1:
//! `1/w_n^2 = a3/a1`, `2 xi_n / w_n = a2/a1`, `K_n = b0/a1`, hence
//! `w_n = sqrt(a1/a3)` and `xi_n = a2 / (2 sqrt(a1 a3))`.
//! The paper prints `xi_n = 1/2 a2 sqrt(beta_n/(m V_a r))` (a2 times w_n instead of divided by
//! `a1/w_n`), which has units of N^2 s/m^... and is not dimensionless; we use the derived form.
//!
//! `beta_n`: the paper prints `S_a^2 p_a k r + S_a^2 p_a k n + K_ca K_v R T k r`, which assumes the
//! initial force balance `S_a p_a = S_b p_b` (Section II.B). We use the general form
//! `beta_n = k (r S_a^2 p_a + S_b^2 p_b) + K_ca K_v R T k r`, which equals the printed one under that
//! assumption and stays right when atmosphere on the rod, gravity or a load shift the balance.
//! `a1 / a3 = (k p_a S_a^2 / V_a + k p_b S_b^2 / V_b)/m + ...` is the classic pneumatic-spring frequency.

use crate::mechanics::OneDofModel;

/// Transfer function of eqs. (16)-(17) from load pressure to position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TransferFunction {
    /// Gain K_n = b0 / a1, m/(Pa s).
    pub k_n: f64,
    /// Natural frequency omega_n = sqrt(a1/a3), rad/s.
    pub omega_n: f64,
    /// Damping ratio xi_n = a2 / (2 sqrt(a1 a3)), dimensionless.
    pub xi_n: f64,
    /// Denominator coefficients of eq. (16) in descending powers [a3, a2, a1, a0] (s^3..s^0), a0 = 0.
    pub den: [f64; 4],
    /// Numerator b0 of eq. (16), m^5/s.
    pub num: f64,
}

/// Physical parameters of eq. (16) at an operating point (SI).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TfParams {
    /// Cap-side piston area S_a, m^2.
    pub area_a: f64,
    /// Rod-side piston area S_b, m^2.
    pub area_b: f64,
    /// Chamber A volume at the operating point (incl. dead volume), m^3.
    pub volume_a: f64,
    /// Chamber B volume at the operating point (incl. dead volume), m^3.
    pub volume_b: f64,
    /// Chamber A pressure, Pa absolute.
    pub p_a: f64,
    /// Chamber B pressure, Pa absolute.
    pub p_b: f64,
    /// Gas temperature T, K.
    pub temperature_k: f64,
    /// Gas constant R, J/(kg K).
    pub gas_constant: f64,
    /// Polytropic exponent k.
    pub exponent: f64,
    /// Moving mass m, kg.
    pub mass_kg: f64,
    /// Viscous coefficient K_v, N s/m.
    pub viscous: f64,
    /// Flow-pressure coefficient of chamber A, K_ca = -d m_a/d p_a, kg/(s Pa).
    pub k_ca: f64,
    /// Flow-pressure coefficient of chamber B, K_cb = -d m_b/d p_b, kg/(s Pa).
    pub k_cb: f64,
}

impl TransferFunction {
    /// Eqs. (16)-(17) from physical parameters.
    pub fn from_params(p: &TfParams) -> Self {
        let r = p.volume_b / p.volume_a; // initial volume ratio r = V_b / V_a
        let rtk = p.gas_constant * p.temperature_k * p.exponent;
        let beta = p.exponent * (r * p.area_a * p.area_a * p.p_a + p.area_b * p.area_b * p.p_b)
            + p.k_ca * p.viscous * rtk * r;
        let a3 = p.mass_kg * p.volume_a * r; // eq. (16)
        let a2 = p.k_ca * rtk * p.mass_kg * r + p.viscous * p.volume_a * r; // eq. (16)
        let a1 = beta;
        let b0 = p.area_a * rtk * (p.k_cb + p.k_ca * r); // eq. (16)
        Self {
            k_n: b0 / a1,                        // eq. (17)
            omega_n: (a1 / a3).sqrt(),           // eq. (17)
            xi_n: a2 / (2.0 * (a1 * a3).sqrt()), // eq. (17), derived (printed form is wrong)
            den: [a3, a2, a1, 0.0],
            num: b0,
        }
    }
}

/// Valve flow coefficients of eq. (12), linearised at an operating point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Linearisation {
    /// K_pa = d m_a / d X_v (flow into A per unit command), kg/s.
    pub k_pa: f64,
    /// K_pb = d m_b / d X_v (flow into B per unit command; negative: +u empties B), kg/s.
    pub k_pb: f64,
    /// K_ca = -d m_a / d p_a at the operating pressure, kg/(s Pa).
    pub k_ca: f64,
    /// K_cb = -d m_b / d p_b at the operating pressure, kg/(s Pa).
    pub k_cb: f64,
}

/// A steady operating point of the 1-DOF model: position, command and chamber pressures.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OperatingPoint {
    /// Piston extension, m.
    pub x: f64,
    /// Steady valve command u0 in [-1, 1] (mean spool / PWM duty mapping).
    pub u: f64,
    /// External force held, N along +x.
    pub f_ext: f64,
    /// Chamber A pressure, Pa absolute.
    pub p_a: f64,
    /// Chamber B pressure, Pa absolute.
    pub p_b: f64,
    /// Gas temperature (supply temperature), K.
    pub temperature_k: f64,
}

/// Why an operating point could not be found.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OperatingPointError {
    /// The valve has no flow at this command, so chamber pressures are not determined.
    #[error(
        "valve is closed at command u = {u}: chamber pressure is undetermined (give the proportional valve an underlap > 0)"
    )]
    ClosedValve {
        /// The command tried.
        u: f64,
    },
    /// Even full command cannot hold the flange against the load.
    #[error(
        "no valve command in [-1, 1] holds the flange at x = {x} m against f_ext = {f_ext} N (net force {f_lo} N at u = -1, {f_hi} N at u = +1)"
    )]
    Unreachable {
        /// Position, m.
        x: f64,
        /// External force, N.
        f_ext: f64,
        /// Net force at u = -1, N.
        f_lo: f64,
        /// Net force at u = +1, N.
        f_hi: f64,
    },
    /// The position is outside the stroke.
    #[error("operating position x = {x} m is outside the stroke [0, {stroke}] m")]
    OutsideStroke {
        /// Position, m.
        x: f64,
        /// Stroke, m.
        stroke: f64,
    },
}

impl OneDofModel {
    /// Steady chamber pressures (p_a, p_b) for a steady command `u`: where the period-mean net flow
    /// into each chamber vanishes, at supply temperature.
    pub fn steady_pressures(&self, u: f64) -> Result<(f64, f64), OperatingPointError> {
        let sp = &self.actuator.supply;
        let t = sp.supply_temperature_k;
        let lo = sp.atmosphere_pressure_pa;
        let hi = sp.supply_pressure_pa;
        let flow = |pa: f64, pb: f64| {
            self.actuator.mean_flows(
                &crate::actuator::ChamberState::with_temperature(pa, pb, t),
                u,
            )
        };
        let mid = 0.5 * (lo + hi);
        let (qa, qb) = flow(mid, mid);
        let (qa_lo, qb_lo) = flow(lo, lo);
        let (qa_hi, qb_hi) = flow(hi, hi);
        let closed_a = qa == 0.0 && qa_lo == 0.0 && qa_hi == 0.0;
        let closed_b = qb == 0.0 && qb_lo == 0.0 && qb_hi == 0.0;
        if closed_a || closed_b {
            return Err(OperatingPointError::ClosedValve { u });
        }
        // Net inflow decreases with chamber pressure: bisection on [p_atm, p_s].
        let root = |f: &dyn Fn(f64) -> f64| {
            let (mut a, mut b) = (lo, hi);
            for _ in 0..200 {
                let m = 0.5 * (a + b);
                if f(m) > 0.0 {
                    a = m;
                } else {
                    b = m;
                }
            }
            0.5 * (a + b)
        };
        let pa = root(&|p| flow(p, mid).0);
        let pb = root(&|p| flow(mid, p).1);
        Ok((pa, pb))
    }

    /// The operating point at extension `x` holding external force `f_ext`: the steady command u0 whose
    /// steady chamber pressures balance eq. (1) with x' = x'' = 0 (friction zero at rest).
    pub fn operating_point(
        &self,
        x: f64,
        f_ext: f64,
    ) -> Result<OperatingPoint, OperatingPointError> {
        let stroke = self.actuator.cylinder.stroke_m;
        if !(x > 0.0 && x < stroke) {
            return Err(OperatingPointError::OutsideStroke { x, stroke });
        }
        let t = self.actuator.supply.supply_temperature_k;
        let net = |u: f64| -> Result<(f64, f64, f64), OperatingPointError> {
            let (pa, pb) = self.steady_pressures(u)?;
            let c = crate::actuator::ChamberState::with_temperature(pa, pb, t);
            Ok((self.drive_force(&c, f_ext), pa, pb))
        };
        let (f_lo, _, _) = net(-1.0)?;
        let (f_hi, _, _) = net(1.0)?;
        if f_lo > 0.0 || f_hi < 0.0 {
            return Err(OperatingPointError::Unreachable {
                x,
                f_ext,
                f_lo,
                f_hi,
            });
        }
        let (mut a, mut b) = (-1.0, 1.0);
        for _ in 0..80 {
            let m = 0.5 * (a + b);
            if net(m)?.0 < 0.0 {
                a = m;
            } else {
                b = m;
            }
        }
        let u = 0.5 * (a + b);
        let (_, p_a, p_b) = net(u)?;
        Ok(OperatingPoint {
            x,
            u,
            f_ext,
            p_a,
            p_b,
            temperature_k: t,
        })
    }

    /// Coefficients of eq. (12) at an operating point, by central differences of the (period-mean) ISO
    /// 6358 flows. K_c is evaluated at the operating pressures (the paper's "at p = 0" is a typo: the
    /// derivative at zero absolute pressure is not the operating slope).
    pub fn linearise(&self, op: &OperatingPoint) -> Linearisation {
        use crate::actuator::ChamberState;
        let t = op.temperature_k;
        let q = |pa: f64, pb: f64, u: f64| {
            self.actuator
                .mean_flows(&ChamberState::with_temperature(pa, pb, t), u)
        };
        let hp = 1e-4 * (op.p_a.min(op.p_b));
        let hu = 1e-6;
        let (u_lo, u_hi) = ((op.u - hu).max(-1.0), (op.u + hu).min(1.0));
        let (qa_uh, qb_uh) = q(op.p_a, op.p_b, u_hi);
        let (qa_ul, qb_ul) = q(op.p_a, op.p_b, u_lo);
        let k_ca = -(q(op.p_a + hp, op.p_b, op.u).0 - q(op.p_a - hp, op.p_b, op.u).0) / (2.0 * hp);
        let k_cb = -(q(op.p_a, op.p_b + hp, op.u).1 - q(op.p_a, op.p_b - hp, op.u).1) / (2.0 * hp);
        Linearisation {
            k_pa: (qa_uh - qa_ul) / (u_hi - u_lo),
            k_pb: (qb_uh - qb_ul) / (u_hi - u_lo),
            k_ca,
            k_cb,
        }
    }

    /// Physical parameters of eq. (16) at an operating point (gas at supply temperature).
    pub fn tf_params(&self, op: &OperatingPoint) -> TfParams {
        let a = &self.actuator;
        let (va, vb) = a.cylinder.volumes(op.x);
        let lin = self.linearise(op);
        TfParams {
            area_a: a.cylinder.area_a(),
            area_b: a.cylinder.area_b(),
            volume_a: va,
            volume_b: vb,
            p_a: op.p_a,
            p_b: op.p_b,
            temperature_k: op.temperature_k,
            gas_constant: a.gas.gas_constant_j_per_kg_k,
            exponent: a.gas.polytropic_exponent,
            mass_kg: self.mechanics.moving_mass_kg,
            viscous: self.mechanics.viscous_n_s_per_m,
            k_ca: lin.k_ca,
            k_cb: lin.k_cb,
        }
    }

    /// Transfer function of eqs. (16)-(17) at an operating point.
    pub fn transfer_function(&self, op: &OperatingPoint) -> TransferFunction {
        TransferFunction::from_params(&self.tf_params(op))
    }

    /// Transfer function at mid-stroke, holding no external load (the paper's "piston near the middle").
    pub fn transfer_function_mid_stroke(
        &self,
    ) -> Result<(OperatingPoint, TransferFunction), OperatingPointError> {
        let op = self.operating_point(0.5 * self.actuator.cylinder.stroke_m, 0.0)?;
        Ok((op, self.transfer_function(&op)))
    }
}
