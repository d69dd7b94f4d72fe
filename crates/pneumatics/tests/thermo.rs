//! Chamber thermodynamics: polytropic compression and mass conservation.
mod common;
use common::*;
use pneuflex_pneumatics::*;

/// A closed chamber compressed by the piston follows p V^n = const (closed form), for the adiabatic
/// default and a polytropic exponent.
#[test]
fn closed_chamber_follows_p_v_to_the_n() {
    for n in [1.4, 1.2, 1.0] {
        // Underlap 0 and spool 0: every valve path is shut.
        let act = actuator(proportional(0.0, 0.0), n);
        let cyl = act.cylinder;
        let x0 = 0.04;
        let (va0, vb0) = cyl.volumes(x0);
        // Move the piston towards the cap so V_a shrinks by 10 %.
        let dx = 0.10 * va0 / cyl.area_a();
        let steps = 2000;
        let t_end = 0.05;
        let dt = t_end / steps as f64;
        let v = -dx / t_end;
        let mut s = ChamberState::new(3.0e5, 2.0e5);
        let (pa0, pb0) = (s.p_a, s.p_b);
        let mut x = x0;
        for _ in 0..steps {
            act.step_chambers(&mut s, x, v, 0.0, dt);
            x += v * dt;
        }
        let (va1, vb1) = cyl.volumes(x);
        assert!((va1 / va0 - 0.9).abs() < 1e-9);
        let pa_expected = pa0 * (va0 / va1).powf(n);
        let pb_expected = pb0 * (vb0 / vb1).powf(n);
        let ea = (s.p_a - pa_expected).abs() / pa_expected;
        let eb = (s.p_b - pb_expected).abs() / pb_expected;
        assert!(
            ea <= 1e-6,
            "n = {n}: p_a {} vs {pa_expected}, rel err {ea}",
            s.p_a
        );
        assert!(
            eb <= 1e-6,
            "n = {n}: p_b {} vs {pb_expected}, rel err {eb}",
            s.p_b
        );
        // Temperature follows T V^(n-1) = const.
        let ta_expected = 293.15 * (va0 / va1).powf(n - 1.0);
        assert!((s.t_a - ta_expected).abs() / ta_expected < 1e-6);
    }
}

/// Over a run with the PWM valve switching, the change of chamber mass (ideal gas p V / (R T) of the
/// state) equals the mass that went in minus the mass that went out (trapezoidal sum of the port flows).
#[test]
fn mass_balance_with_switching_valve() {
    let m = model(pwm(40.0, 0.005), no_coulomb(), 30.0);
    let mut st = OneDofState::at_rest(0.025, ChamberState::new(2.0e5, 2.0e5), -1.0);
    let dt = 2e-6;
    let (ma0, mb0) = m.actuator.chamber_masses(&st.chambers, st.x);
    let (mut in_a, mut in_b, mut through) = (0.0, 0.0, 0.0);
    let mut switches = 0;
    let mut last_spool = st.valve.spool;
    let t_stop = 100_000.0 * dt;
    while st.t < t_stop {
        // A command sweeping through the duty range, so the valve switches many times.
        let u = (2.0 * std::f64::consts::PI * 3.0 * st.t).sin() * 0.8;
        // Steps end on the valve's edges (`ValveModel::segment`), so the spool is constant over each
        // step and the trapezoid of the port flows is the step's mass flow.
        let mut probe = st.valve;
        let (spool, edge) = m.actuator.valve.segment(&mut probe, u, st.t, dt);
        let h = edge.map_or(dt, |e| e - st.t);
        let f0 = m.actuator.port_flows(&st.chambers, spool);
        m.step(&mut st, u, 0.0, h);
        assert_eq!(st.valve.spool, spool);
        let f1 = m.actuator.port_flows(&st.chambers, spool);
        in_a += 0.5 * h * (f0.into_a() + f1.into_a());
        in_b += 0.5 * h * (f0.into_b() + f1.into_b());
        through += 0.5 * h * (f0.p_a.abs() + f0.a_r.abs() + f1.p_a.abs() + f1.a_r.abs());
        if spool != last_spool {
            switches += 1;
            last_spool = spool;
        }
    }
    assert!(switches >= 14, "valve switched only {switches} times");
    let (ma1, mb1) = m.actuator.chamber_masses(&st.chambers, st.x);
    let ea = ((ma1 - ma0) - in_a).abs() / through;
    let eb = ((mb1 - mb0) - in_b).abs() / through;
    assert!(
        through > 10.0 * ma0,
        "too little flow to test: {through} kg"
    );
    assert!(
        ea < 1e-5,
        "chamber A: dm {} vs net inflow {in_a}, rel {ea}",
        ma1 - ma0
    );
    assert!(
        eb < 1e-5,
        "chamber B: dm {} vs net inflow {in_b}, rel {eb}",
        mb1 - mb0
    );
}
