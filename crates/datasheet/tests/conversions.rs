//! The datasheet conversions against worked examples computed here, independently of the crate's code.

use pneuflex_datasheet::iso6358;
use pneuflex_pneumatics::flow::{ISO_RHO0_KG_M3, ISO_T0_K, Orifice};

#[test]
fn kv_per_cv_from_the_unit_definitions() {
    // 1 US gallon = 231 in³, 1 in = 25.4 mm; 1 psi = 4.448 221 615 N / (0.0254 m)².
    let gallon_m3 = 231.0 * 0.0254_f64.powi(3);
    let psi_pa: f64 = 4.448_221_615_260_5 / (0.0254 * 0.0254);
    let kv_per_cv = gallon_m3 * 60.0 / (psi_pa / 1e5).sqrt();
    assert!((iso6358::kv_from_cv(1.0) - kv_per_cv).abs() < 1e-9 * kv_per_cv);
    // The catalogue figure: Kv ≈ 0.865 Cv.
    assert!((kv_per_cv - 0.865).abs() < 1e-3, "{kv_per_cv}");
}

#[test]
fn qn_to_c_reproduces_the_rated_flow_through_the_simulators_own_flow_law() {
    // A 600 l/min valve with b = 0.3: the orifice the sheet gets must pass 600 l/min ANR at 6 → 5 bar gauge
    // through pneuflex_pneumatics' mass flow (eq. 11) at 20 °C.
    for (qn_l_min, b) in [(600.0, 0.3), (90.0, 0.45), (2000.0, 0.2)] {
        let qn = qn_l_min * 1e-3 / 60.0;
        let c = iso6358::c_from_qn(qn, b);
        let o = Orifice {
            sonic_conductance_m3_per_s_pa: c,
            critical_pressure_ratio: b,
        };
        let (q_m, _) = o.mass_flow(1.0, 6e5 + 101_325.0, ISO_T0_K, 5e5 + 101_325.0, ISO_T0_K);
        let q_anr_l_min = q_m / ISO_RHO0_KG_M3 * 6e4;
        assert!(
            (q_anr_l_min - qn_l_min).abs() < 1e-9 * qn_l_min,
            "{q_anr_l_min} vs {qn_l_min}"
        );
        // And by hand: r = 6.01325 / 7.01325, φ = √(1 − ((r − b)/(1 − b))²), C = Q / (p₁ φ).
        let r = 601_325.0 / 701_325.0;
        let phi = (1.0 - ((r - b) / (1.0 - b)).powi(2)).sqrt();
        assert!((c - qn / (701_325.0 * phi)).abs() < 1e-12 * c);
        assert!((iso6358::qn_from_c(c, b) - qn).abs() < 1e-12 * qn);
    }
    // A worked figure: 600 l/min at b = 0.3 is C ≈ 2.36 dm³/(s bar) (r = 0.857, φ = 0.605).
    let c = iso6358::c_from_qn(0.01, 0.3);
    assert!((c / 1e-8 - 2.357).abs() < 0.002, "{}", c / 1e-8);
}

#[test]
fn kv_to_c_follows_the_choked_gas_law() {
    // VDI/VDE 2173, choked: Q_N = 257 Kv p₁ / √(ρ_N T₁) m³/h (normal conditions, 0 °C, 1.013 25 bar).
    // Here by mass flow: ṁ = Q_N ρ_N / 3600, and ISO 6358 choked ṁ = C ρ₀ p₁ at T₁ = T₀.
    let (kv, p1_bar) = (1.7, 7.0);
    let q_n = 257.0 * kv * p1_bar / (1.293 * 293.15_f64).sqrt();
    let m_dot = q_n * 1.293 / 3600.0;
    let c = m_dot / (1.185 * p1_bar * 1e5);
    assert!((iso6358::c_from_kv(kv) - c).abs() < 1e-9 * c);
    // About 4 dm³/(s bar) per Kv, the catalogue rule of thumb.
    assert!((iso6358::c_from_kv(1.0) / 1e-8 - 4.0).abs() < 0.1);
    // The law's subsonic branch Q_N = 514 Kv √(Δp p₂ / (ρ_N T₁)) meets the choked one at p₂ = p₁/2:
    // the critical ratio it implies.
    let sub = 514.0 * kv * ((p1_bar / 2.0) * (p1_bar / 2.0) / (1.293 * 293.15_f64)).sqrt();
    assert!((sub - q_n).abs() < 1e-9 * q_n);
    assert_eq!(iso6358::KV_CRITICAL_RATIO, 0.5);
}

#[test]
fn the_iso_series_gives_the_standard_rods() {
    use pneuflex_datasheet::series::by_bore;
    assert_eq!(by_bore(32.0).map(|s| s.rod_mm), Some(12.0));
    assert_eq!(by_bore(63.0).map(|s| s.rod_mm), Some(20.0));
    assert_eq!(by_bore(100.0).map(|s| s.rod_mm), Some(25.0));
    assert_eq!(
        by_bore(16.0).map(|s| (s.standard, s.rod_mm)),
        Some(("ISO 6432", 6.0))
    );
    assert!(by_bore(33.0).is_none());
}
