//! A valve's flow rating as catalogues give it, converted to the ISO 6358-1 sonic conductance C and critical
//! pressure ratio b the valve sheet holds (docs/your-rig.md, "Valve flow"). The flow law is the one of
//! `pneuflex_pneumatics::flow` (eq. 11): Q_ANR = C p₁ √(T₀/T₁) φ(p₂/p₁), φ = √(1 − ((r − b)/(1 − b))²)
//! above b, 1 below; Q_ANR is the standard (ISO 8778, 20 °C, 100 kPa) volume flow.

use pneuflex_pneumatics::flow::Orifice;

/// The standard nominal flow QN (VDI 3290, the "Normalnenndurchfluss" of most catalogues): inlet 6 bar
/// gauge, outlet 5 bar gauge, air at 20 °C; the ISO 2533 atmosphere makes those absolute.
pub const QN_INLET_PA: f64 = 6e5 + ATMOSPHERE_PA;
/// The outlet pressure of the QN rating, Pa absolute.
pub const QN_OUTLET_PA: f64 = 5e5 + ATMOSPHERE_PA;
/// ISO 2533 standard atmosphere, Pa.
pub const ATMOSPHERE_PA: f64 = 101_325.0;

/// Kv per Cv: 1 US gal/min at 1 psi of water against 1 m³/h at 1 bar, Q = Kv √(Δp/1 bar) = Cv √(Δp/1 psi):
/// Kv = Cv · (3.785 411 784 L · 60 / 1000) / √(1 bar / 1 psi).
pub fn kv_from_cv(cv: f64) -> f64 {
    let gpm_in_m3_per_h = 3.785_411_784e-3 * 60.0;
    let bar_per_psi: f64 = 6_894.757_293_168 / 1e5;
    cv * gpm_in_m3_per_h / bar_per_psi.sqrt()
}

/// C from the nominal flow QN (m³/s ANR) and b: the law above solved for C at QN's pressures.
pub fn c_from_qn(qn_m3_per_s: f64, b: f64) -> f64 {
    let phi = Orifice {
        sonic_conductance_m3_per_s_pa: 1.0,
        critical_pressure_ratio: b,
    }
    .phi(QN_OUTLET_PA / QN_INLET_PA);
    qn_m3_per_s / (QN_INLET_PA * phi)
}

/// QN (m³/s ANR) of a valve of conductance C and ratio b: the inverse of [`c_from_qn`].
pub fn qn_from_c(c: f64, b: f64) -> f64 {
    let phi = Orifice {
        sonic_conductance_m3_per_s_pa: 1.0,
        critical_pressure_ratio: b,
    }
    .phi(QN_OUTLET_PA / QN_INLET_PA);
    c * QN_INLET_PA * phi
}

/// The critical pressure ratio the Kv gas law implies: VDI/VDE 2173 (and IEC 60534's simplified form)
/// treats the flow as choked from p₂ = p₁/2, so a valve known only by Kv or Cv gets b = 0.5.
pub const KV_CRITICAL_RATIO: f64 = 0.5;

/// C from Kv (m³/h of water at 1 bar). The VDI/VDE 2173 gas law for choked flow,
/// Q_N = 257 Kv p₁ / √(ρ_N T₁) (Q_N in m³/h at 0 °C and 1.013 25 bar, p₁ in bar, ρ_N = 1.293 kg/m³), taken
/// to ANR volume (×ρ_N/ρ₀) at T₁ = T₀ and divided by p₁: C ≈ 4.0e-8 m³/(s Pa) per unit of Kv.
pub fn c_from_kv(kv: f64) -> f64 {
    let rho_n = 1.293;
    let t0 = pneuflex_pneumatics::flow::ISO_T0_K;
    let q_n_m3_per_h_per_bar = 257.0 * kv / (rho_n * t0).sqrt();
    let q_anr = q_n_m3_per_h_per_bar * rho_n / pneuflex_pneumatics::flow::ISO_RHO0_KG_M3;
    q_anr / 3600.0 / 1e5
}

/// The mass flow a valve of conductance C passes choked from `p_supply_pa` at T₀, kg/s.
pub fn choked_mass_flow(c: f64, p_supply_pa: f64) -> f64 {
    c * pneuflex_pneumatics::flow::ISO_RHO0_KG_M3 * p_supply_pa
}
