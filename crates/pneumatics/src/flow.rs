//! ISO 6358 mass flow through a pneumatic restriction (valve path), eq. (11) of the paper.
//!
//! The paper writes the flow as `m_dot = q X_v psi(p_u, p_d)` (eq. 11) without giving psi; we use the
//! ISO 6358-1 model with sonic conductance `C` and critical pressure ratio `b`:
//!
//! ```text
//! q_m = C rho0 p_u sqrt(T0 / T_u) * phi(r),   r = p_d / p_u
//! phi = 1                                   r <= b        (choked)
//! phi = sqrt(1 - ((r - b) / (1 - b))^2)     b < r <= r_l  (subsonic)
//! phi = phi(r_l) (1 - r) / (1 - r_l)        r_l < r <= 1  (laminar, ISO 6358-3)
//! ```
//!
//! The laminar tail (r_l = 0.999) removes the infinite slope of the elliptic law at equal pressures,
//! which would make the chamber equations infinitely stiff at rest.

use crate::lanes::{Real, pick};

/// ISO 8778 reference temperature for sonic conductance, K.
pub const ISO_T0_K: f64 = 293.15;
/// ISO 8778 reference density of air, kg/m^3.
pub const ISO_RHO0_KG_M3: f64 = 1.185;
/// Pressure ratio above which the flow is treated as laminar (linear in the pressure drop).
pub const LAMINAR_RATIO: f64 = 0.999;

/// A restriction characterised by ISO 6358 sonic conductance and critical pressure ratio.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orifice {
    /// Sonic conductance C at full opening, m^3/(s Pa) (1 dm^3/(s bar) = 1e-8 m^3/(s Pa)).
    pub sonic_conductance_m3_per_s_pa: f64,
    /// Critical pressure ratio b, dimensionless, 0 <= b < 1.
    pub critical_pressure_ratio: f64,
}

impl Orifice {
    /// The ISO 6358 flow function phi(r) for a downstream/upstream pressure ratio `r` in [0, 1].
    #[inline]
    pub fn phi(&self, r: f64) -> f64 {
        let b = self.critical_pressure_ratio;
        if r <= b {
            1.0
        } else if r <= LAMINAR_RATIO {
            let z = (r - b) / (1.0 - b);
            (1.0 - z * z).max(0.0).sqrt()
        } else {
            let z = (LAMINAR_RATIO - b) / (1.0 - b);
            let phi_l = (1.0 - z * z).max(0.0).sqrt();
            phi_l * (1.0 - r).max(0.0) / (1.0 - LAMINAR_RATIO)
        }
    }

    /// Signed mass flow from node 1 to node 2, kg/s, at relative opening `opening` in [0, 1].
    ///
    /// Positive when gas flows 1 -> 2. The upstream node (the one at higher pressure) sets the
    /// temperature; the second value returned is `q * T_upstream` (kg K/s), the enthalpy carrier used by
    /// the chamber energy balance.
    #[inline]
    pub fn mass_flow(&self, opening: f64, p1: f64, t1: f64, p2: f64, t2: f64) -> (f64, f64) {
        if opening <= 0.0 {
            return (0.0, 0.0);
        }
        let k = opening * self.sonic_conductance_m3_per_s_pa * ISO_RHO0_KG_M3;
        if p1 >= p2 {
            if p1 <= 0.0 {
                return (0.0, 0.0);
            }
            let q = k * p1 * (ISO_T0_K / t1).sqrt() * self.phi(p2 / p1);
            (q, q * t1)
        } else {
            let q = k * p2 * (ISO_T0_K / t2).sqrt() * self.phi(p1 / p2);
            (-q, -q * t2)
        }
    }
}

/// The state-independent part of eq. (11) for one orifice, computed once per integration step so the
/// RK4 stages of the chamber equations do no divisions by `1 - b` and take one square root per open path.
#[derive(Clone, Copy, Debug)]
pub(crate) struct OrificeStep {
    /// C rho0, kg/(s Pa) at full opening.
    c_rho0: f64,
    /// Critical pressure ratio b.
    b: f64,
    /// 1 / (1 - b).
    inv_one_minus_b: f64,
    /// The laminar tail's `(p_u phi)^2 / (p_u - p_d)^2 = phi(r_l)^2 / (1 - r_l)^2`, formed once so that no
    /// stage divides for it.
    laminar_gain: f64,
}

impl OrificeStep {
    /// Step constants of orifice `o`.
    #[inline(always)]
    pub(crate) fn new(o: &Orifice) -> Self {
        let b = o.critical_pressure_ratio;
        Self {
            c_rho0: o.sonic_conductance_m3_per_s_pa * ISO_RHO0_KG_M3,
            b,
            inv_one_minus_b: 1.0 / (1.0 - b),
            laminar_gain: {
                let z = (LAMINAR_RATIO - b) / (1.0 - b);
                (1.0 - z * z).max(0.0) / ((1.0 - LAMINAR_RATIO) * (1.0 - LAMINAR_RATIO))
            },
        }
    }

    /// Flow gain `opening C rho0` of a path at relative opening `opening` (0 when shut), kg/(s Pa).
    #[inline(always)]
    pub(crate) fn gain(&self, opening: f64) -> f64 {
        if opening > 0.0 {
            opening * self.c_rho0
        } else {
            0.0
        }
    }

    /// `(p_u phi(p_d / p_u))^2`, Pa^2, for `p_u >= p_d > 0`, without dividing by `p_u`: the subsonic
    /// branch of eq. (11) multiplied out, `p_u^2 (1 - z^2) = (p_u - w)(p_u + w)` with
    /// `w = (p_d - b p_u) / (1 - b) = p_u z`. One plant computes the regime it is in; a pack of plants
    /// forms the three and blends them ([`crate::lanes`]).
    #[inline(always)]
    pub(crate) fn p_phi_sq<R: Real>(&self, p_u: R, p_d: R) -> R {
        let b_p_u = R::splat(self.b) * p_u;
        let [q] = pick!(R; p_d.le(b_p_u) =>
            // Choked: phi = 1.
            [p_u * p_u],
            pick!(R; p_d.le(R::splat(LAMINAR_RATIO) * p_u) =>
                {
                    let w = (p_d - b_p_u) * R::splat(self.inv_one_minus_b);
                    [((p_u - w) * (p_u + w)).max(R::splat(0.0))]
                },
                {
                    // Laminar tail: p_u phi = phi(r_l) (p_u - p_d) / (1 - r_l).
                    let dp = (p_u - p_d).max(R::splat(0.0));
                    [R::splat(self.laminar_gain) * dp * dp]
                }
            )
        );
        q
    }

    /// Mass flow `q` (kg/s) from an upstream node at `p_u` to a downstream node at `p_d <= p_u` through a
    /// path of gain `k` (from [`Self::gain`]), with `t0_over_tu = T0 / T_u` (eq. 11):
    /// `q = k sqrt(T0 / T_u) p_u phi(p_d / p_u)`, folded into one square root.
    #[inline(always)]
    pub(crate) fn flow<R: Real>(&self, k: R, t0_over_tu: R, p_u: R, p_d: R) -> R {
        k * (t0_over_tu * self.p_phi_sq(p_u, p_d)).sqrt()
    }
}
