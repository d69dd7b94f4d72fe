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
