//! The pneumatic force element coupled to the rig: with the valve closed the chambers are gas springs
//! (p V^n = const, eqs. (5)-(6)), so the flange must come to rest where the piston force equals the
//! environment spring, F_gas(x) = k (x - x_e) (eqs. (1) and (21) in steady state, alpha = 0).

use pneuflex_multibody::{CarriageRig, PneumaticForceElement, RigConfig};
use pneuflex_pneumatics::{Actuator, ChamberState, P_ATM};

mod common;

/// The paper's 16 mm x 50 mm cylinder at 0.6 MPa absolute.
fn actuator() -> Actuator {
    common::cylinder(0.016, 0.005, 0.05, 3.5e-6, 6.0e5)
}

#[test]
fn closed_valve_gas_spring_balances_environment_spring() {
    let act = actuator();
    let x0 = 0.018;
    let (pa0, pb0) = (4.0e5, 2.5e5);
    let mut cfg = RigConfig::paper_rig();
    cfg.initial_x_m = x0;
    let mut w = CarriageRig::from_urdf(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../urdf/rig.urdf"),
        &cfg,
    )
    .unwrap();
    let mut el = PneumaticForceElement::new(act, ChamberState::new(pa0, pb0), 4);
    el.set_command(0.0); // zero-lap valve centred: both chambers closed
    for _ in 0..3000 {
        w.step(&mut el);
    }
    let m = w.measurements();
    // Independent steady state: bisection on the polytropic gas spring against the wood spring.
    let k = w.material_params("wood").unwrap().stiffness_n_per_m;
    let x_e = w.material_x_e("wood").unwrap();
    let n = act.gas.polytropic_exponent;
    let (va0, vb0) = act.cylinder.volumes(x0);
    let f_gas = |x: f64| {
        let (va, vb) = act.cylinder.volumes(x);
        let pa = pa0 * (va0 / va).powf(n);
        let pb = pb0 * (vb0 / vb).powf(n);
        pa * act.cylinder.area_a() - pb * act.cylinder.area_b() - P_ATM * act.cylinder.area_rod()
    };
    let g = |x: f64| f_gas(x) - k * (x - x_e);
    let (mut lo, mut hi) = (x_e, 0.05);
    assert!(g(lo) > 0.0 && g(hi) < 0.0);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if g(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let x_star = 0.5 * (lo + hi);
    let f_star = k * (x_star - x_e);
    assert!(m.contact);
    assert!(
        (m.x - x_star).abs() <= 0.01 * (x_star - x_e),
        "x {} vs {x_star}",
        m.x
    );
    assert!(
        (m.f_e - f_star).abs() <= 0.01 * f_star,
        "f_e {} vs {f_star}",
        m.f_e
    );
    // The element's own force equals the load-cell reading at rest (no other axial load at alpha = 0).
    assert!((el.piston_force() - m.f_e).abs() <= 0.01 * f_star);
    let (pa, _pb) = el.pressures();
    assert!(pa < pa0, "chamber A expanded");
}
