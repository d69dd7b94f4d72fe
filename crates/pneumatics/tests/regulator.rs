//! The pressure regulator in front of each chamber (src/regulator.rs, (R1)-(R3)) against closed forms: the
//! first-order step response of a closed chamber, the choked-flow ramp where the valve's conductance limits
//! it, the force balance a 1-DOF flange comes to rest at, and the force element behind the regulators.
mod common;
use common::*;
use pneuflex_pneumatics::*;

const TAU: f64 = 0.02;

fn reg(tau: f64) -> PressureRegulator {
    PressureRegulator::new(tau).unwrap()
}

/// A closed chamber (the piston held) behind the regulator: p = p_set + (p0 - p_set) e^(-t/tau), filling A
/// and venting B, while the flow stays within the valve's limit (checked along the way).
#[test]
fn a_closed_chamber_follows_the_first_order_step_response() {
    let a = actuator(proportional(0.0, 0.0), 1.4);
    let r = reg(TAU);
    let (p0, set) = ((2.0e5, 4.0e5), (3.0e5, 1.5e5));
    let mut s = ChamberState::new(p0.0, p0.1);
    let (x, dt) = (0.025, 1e-5);
    let mut worst: f64 = 0.0;
    for k in 1..=(5.0 * TAU / dt) as usize {
        // Within the flow limits: the flow the regulator passes is the one (R2) asks for.
        let (qa, qb) = a.regulated_flows(&r, set, &s, x, 0.0);
        let (va, vb) = a.cylinder.volumes(x);
        let (n, rg) = (1.4, 287.05);
        let want_a = va * (set.0 - s.p_a) / (TAU * n) / (rg * 293.15);
        let want_b = vb * (set.1 - s.p_b) / (TAU * n) / (rg * s.t_b);
        assert!(
            (qa - want_a).abs() <= 1e-12 * want_a.abs().max(1e-9),
            "{qa} vs {want_a}"
        );
        assert!(
            (qb - want_b).abs() <= 1e-12 * want_b.abs().max(1e-9),
            "{qb} vs {want_b}"
        );
        a.step_chambers_regulated(&r, set, &mut s, x, 0.0, dt);
        let t = k as f64 * dt;
        let e = (-t / TAU).exp();
        let (pa, pb) = (set.0 + (p0.0 - set.0) * e, set.1 + (p0.1 - set.1) * e);
        worst = worst.max((s.p_a - pa).abs()).max((s.p_b - pb).abs());
    }
    // RK4 at tau/2000: the closed form to 1e-6 Pa over five time constants.
    assert!(worst < 1e-6, "worst deviation {worst} Pa");
    // The temperatures moved (compression heats A, expansion cools B): the law holds for p regardless.
    assert!(s.t_a > 293.15 && s.t_b < 293.15, "{s:?}");
}

/// A step the valve's conductance cannot pass: with tau = 10 us the regulator asks for far more than the
/// supply path gives, so a closed chamber fills at the choked flow q = C rho0 p_s sqrt(T0/T_s) (eq. (11),
/// p <= b p_s), dp/dt = n R T_s q / V: a straight ramp, then reaches its set-point.
#[test]
fn a_choked_fill_ramps_at_the_valves_flow_limit() {
    let a = actuator(proportional(0.0, 0.0), 1.4);
    let r = reg(1e-5);
    let set = (5.0e5, 3.0e5);
    let (x, dt) = (0.025, 1e-5);
    let p0 = 1.2e5;
    let mut s = ChamberState::new(p0, 3.0e5);
    let q = 5e-9 * 1.185 * P_S; // T_s = T0: sqrt(T0/T_s) = 1
    let (va, _) = a.cylinder.volumes(x);
    let ramp = 1.4 * 287.05 * 293.15 * q / va;
    let (qa, _) = a.regulated_flows(&r, set, &s, x, 0.0);
    assert!((qa - q).abs() <= 1e-15, "{qa} vs the choked flow {q}");
    let mut k = 0;
    while s.p_a + ramp * dt <= 0.3 * P_S {
        a.step_chambers_regulated(&r, set, &mut s, x, 0.0, dt);
        k += 1;
        let want = p0 + ramp * k as f64 * dt;
        assert!(
            (s.p_a - want).abs() <= 1e-9 * want,
            "step {k}: {} vs the ramp {want}",
            s.p_a
        );
    }
    assert!(k > 100, "{k} steps on the ramp");
    // Beyond the choke the flow falls; the chamber still reaches the set-point.
    for _ in 0..2000 {
        a.step_chambers_regulated(&r, set, &mut s, x, 0.0, dt);
    }
    assert!((s.p_a - set.0).abs() < 1e-3, "p_a {} for {}", s.p_a, set.0);
}

/// The piston moving (the chambers' volumes changing), within the flow limits, dp/dt is still
/// (p_set - p) / tau: (R2) pays the volume's change.
#[test]
fn a_moving_piston_keeps_the_first_order_law() {
    let a = actuator(proportional(0.0, 0.0), 1.4);
    let r = reg(TAU);
    for (x, xd) in [(0.01, 0.2), (0.04, -0.3)] {
        for (pa, pb, set) in [(2e5, 3e5, (2.5e5, 2.2e5)), (4e5, 1.5e5, (3.5e5, 2e5))] {
            let s = ChamberState::with_temperature(pa, pb, 280.0);
            let d = a.regulated_rates(&r, set, &s, x, xd);
            for (got, want) in [(d.p_a, (set.0 - pa) / TAU), (d.p_b, (set.1 - pb) / TAU)] {
                assert!(
                    (got - want).abs() <= 1e-9 * want.abs(),
                    "x {x}, v {xd}: {got} vs {want}"
                );
            }
        }
    }
}

/// Set-points outside [p_atm, p_s] are the nearest bound; NaN passes no flow.
#[test]
fn set_points_are_clamped_and_nan_closes_the_chamber() {
    let a = actuator(proportional(0.0, 0.0), 1.4);
    let r = reg(TAU);
    let s = ChamberState::new(3e5, 3e5);
    let d = a.regulated_rates(&r, (9e5, 5e4), &s, 0.025, 0.0);
    assert!((d.p_a - (P_S - 3e5) / TAU).abs() < 1e-6 * d.p_a);
    assert!((d.p_b - (101_325.0 - 3e5) / TAU).abs() < 1e-6 * d.p_b.abs());
    let d = a.regulated_rates(&r, (f64::NAN, f64::NAN), &s, 0.025, 0.0);
    assert_eq!((d.p_a, d.p_b, d.t_a, d.t_b), (0.0, 0.0, 0.0, 0.0));
    assert!(PressureRegulator::new(0.0).is_err());
    assert!(PressureRegulator::new(f64::NAN).is_err());
    assert!(PressureRegulator::new(20.0).is_err());
}

/// The 1-DOF flange behind the regulators against a spring comes to rest where eq. (1) balances: the
/// chambers at their set-points and k_e (x - x_e) = p_a S_a - p_b S_b - p_atm S_rod (no Coulomb friction,
/// level), S from the bore and rod by hand.
#[test]
fn a_flange_behind_regulators_rests_at_the_force_balance() {
    let m = model(proportional(0.0, 0.0), no_coulomb(), 0.0);
    let r = reg(TAU);
    let (k_e, x_e) = (1000.0, 0.02);
    let set = (3.0e5, 2.5e5);
    let mut st = OneDofState::at_rest(x_e, ChamberState::new(2.0e5, 2.0e5), 0.0);
    for _ in 0..3000 {
        m.advance_regulated(&mut st, &r, set, 0.0, 1e-3, 10, |x| {
            if x > x_e { -k_e * (x - x_e) } else { 0.0 }
        });
    }
    let (sa, srod) = (
        std::f64::consts::PI * 0.008 * 0.008,
        std::f64::consts::PI * 0.0025 * 0.0025,
    );
    let f = set.0 * sa - set.1 * (sa - srod) - 101_325.0 * srod;
    let x = x_e + f / k_e;
    assert!((st.chambers.p_a - set.0).abs() < 1e-6, "{:?}", st.chambers);
    assert!((st.chambers.p_b - set.1).abs() < 1e-6, "{:?}", st.chambers);
    assert!((st.x - x).abs() < 1e-9, "x {} vs {x} (force {f} N)", st.x);
    assert!(st.x_dot.abs() < 1e-9);
}

/// The force element behind the regulators, the flange held: the same closed-form step response, the force
/// the mean over the step of p_a S_a - p_b S_b - p_atm S_rod; back on the valve it takes the valve command.
#[test]
fn the_force_element_behind_regulators() {
    let a = actuator(proportional(0.0, 0.0), 1.4);
    let mut el = PneumaticForceElement::new(a, ChamberState::new(2e5, 4e5), 4);
    el.set_regulator(Some(reg(TAU)));
    assert_eq!(
        el.pressure_command(),
        (2e5, 4e5),
        "the set-points start at the chambers"
    );
    el.set_pressure_command(3e5, 1.5e5);
    let h = 1e-4;
    for k in 1..=500 {
        let f = el.step(0.025, 0.0, h);
        let t = k as f64 * h;
        let e = (-t / TAU).exp();
        let (pa, pb) = (3e5 - 1e5 * e, 1.5e5 + 2.5e5 * e);
        let (p_a, p_b) = el.pressures();
        assert!(
            (p_a - pa).abs() < 1e-3 && (p_b - pb).abs() < 1e-3,
            "t {t}: {p_a} {p_b}"
        );
        assert!(f.is_finite());
    }
    // The next step's force: the trapezoid over its 4 substeps of the closed form's force.
    let f = el.step(0.025, 0.0, h);
    let c = &a.cylinder;
    let force = |t: f64| {
        let e = (-t / TAU).exp();
        (3e5 - 1e5 * e) * c.area_a() - (1.5e5 + 2.5e5 * e) * c.area_b() - 101_325.0 * c.area_rod()
    };
    let t0 = 500.0 * h;
    let want = (0..4)
        .map(|i| 0.5 * (force(t0 + i as f64 * h / 4.0) + force(t0 + (i + 1) as f64 * h / 4.0)))
        .sum::<f64>()
        / 4.0;
    assert!((f - want).abs() < 1e-6, "{f} vs {want}");
    assert_eq!(el.valve.spool, 0.0, "the valve stays at rest");
    el.set_regulator(None);
    el.set_command(1.0);
    let before = el.pressures().0;
    el.step(0.025, 0.0, 1e-3);
    assert!(
        el.pressures().0 > before,
        "back on the valve, u = 1 fills A"
    );
}
