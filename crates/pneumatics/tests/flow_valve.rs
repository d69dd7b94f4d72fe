//! ISO 6358 flow and valve behaviour.
mod common;
use common::*;
use pneuflex_pneumatics::*;

const T: f64 = 293.15;

/// Choked flow equals the closed form C rho0 p1 sqrt(T0/T1) and does not depend on the downstream
/// pressure below the critical ratio b.
#[test]
fn choked_flow_is_independent_of_downstream() {
    let o = orifice();
    let p1 = 6.0e5;
    let expected = 5e-9 * 1.185 * p1; // T1 = T0
    for r in [0.0, 0.05, 0.1, 0.2, 0.29, 0.3] {
        let (q, _) = o.mass_flow(1.0, p1, T, r * p1, T);
        assert!((q - expected).abs() <= 1e-15, "r = {r}: {q} vs {expected}");
    }
    // Hotter upstream gas flows less: sqrt(T0/T1).
    let (q, _) = o.mass_flow(1.0, p1, 4.0 * T, 0.1 * p1, T);
    assert!((q - 0.5 * expected).abs() < 1e-15);
}

/// The flow is continuous at p2/p1 = b (the subsonic ellipse meets the choked value).
#[test]
fn flow_is_continuous_at_critical_ratio() {
    let o = orifice();
    let p1 = 6.0e5;
    let b = o.critical_pressure_ratio;
    let (q_c, _) = o.mass_flow(1.0, p1, T, b * p1, T);
    for eps in [1e-6, 1e-8, 1e-10] {
        let (q_s, _) = o.mass_flow(1.0, p1, T, (b + eps) * p1, T);
        // The ellipse is flat at b: the jump must vanish like eps^2, certainly below eps.
        assert!((q_c - q_s).abs() / q_c < eps, "eps {eps}: {q_c} vs {q_s}");
    }
    // Subsonic value against the ISO formula at one point.
    let r = 0.65;
    let (q, _) = o.mass_flow(1.0, p1, T, r * p1, T);
    let expected = 5e-9 * 1.185 * p1 * (1.0 - ((r - b) / (1.0 - b)).powi(2)).sqrt();
    assert!((q - expected).abs() / expected < 1e-12);
}

/// Zero flow at equal pressures; the flow reverses when the pressures swap.
#[test]
fn flow_zero_at_equal_pressure_and_reverses() {
    let o = orifice();
    assert_eq!(o.mass_flow(1.0, 3.0e5, T, 3.0e5, T).0, 0.0);
    for (p1, p2) in [(6.0e5, 1.0e5), (3.0e5, 2.5e5), (2.0e5, 1.9999e5)] {
        let (q12, _) = o.mass_flow(1.0, p1, T, p2, T);
        let (q21, _) = o.mass_flow(1.0, p2, T, p1, T);
        assert!(q12 > 0.0);
        assert_eq!(q12, -q21);
    }
    // Flow decreases monotonically as the downstream pressure rises towards the upstream one.
    let mut prev = f64::INFINITY;
    for i in 0..=1000 {
        let p2 = 1.0e5 + 5.0e5 * i as f64 / 1000.0;
        let (q, _) = o.mass_flow(1.0, 6.0e5, T, p2, T);
        assert!(q <= prev);
        prev = q;
    }
    assert_eq!(prev, 0.0);
}

/// Supply and exhaust ports of the actuator: +u fills A and empties B, -u the reverse.
#[test]
fn valve_ports_follow_command_sign() {
    let act = actuator(proportional(0.0, 0.0), 1.4);
    let s = ChamberState::new(3.0e5, 3.0e5);
    let f = act.port_flows(&s, 1.0);
    assert!(f.into_a() > 0.0 && f.into_b() < 0.0);
    assert_eq!(f.a_r, 0.0);
    assert_eq!(f.p_b, 0.0);
    let f = act.port_flows(&s, -1.0);
    assert!(f.into_a() < 0.0 && f.into_b() > 0.0);
    let f = act.port_flows(&s, 0.0);
    assert_eq!(f, PortFlows::default());
}

/// PWM: the fraction of time the 5/2 valve spends energised is (1 + u)/2, and every edge is late by
/// the switching delay.
#[test]
fn pwm_duty_and_delay() {
    let freq = 50.0;
    let delay = 0.004;
    let v = pwm(freq, delay);
    let dt = 1e-5;
    for u in [-0.6, 0.0, 0.5] {
        let mut st = ValveState::default();
        let mut on = 0usize;
        let mut first_on = None;
        let n = 100_000; // 1 s = 50 periods
        for k in 0..n {
            let t = k as f64 * dt;
            let s = v.spool(&mut st, u, t, dt);
            if s > 0.0 {
                on += 1;
                first_on.get_or_insert(t);
            }
        }
        let duty = on as f64 / n as f64;
        let expected = 0.5 * (1.0 + u);
        // The first `delay` is spent in the spring position: one delay per second is lost at most.
        assert!(
            (duty - expected).abs() < delay * freq / 50.0 + 2e-3,
            "u {u}: duty {duty} vs {expected}"
        );
        let t_on = first_on.unwrap();
        assert!(
            (t_on - delay).abs() <= dt,
            "u {u}: first energised at {t_on}, expected {delay}"
        );
    }
}

/// Proportional valve: first-order spool response with the given time constant.
#[test]
fn proportional_spool_first_order() {
    let tau = 0.005;
    let v = proportional(0.02, tau);
    let mut st = ValveState::default();
    let dt = 1e-4;
    let mut s = 0.0;
    for k in 0..50 {
        s = v.spool(&mut st, 1.0, k as f64 * dt, dt);
    }
    let expected = 1.0 - (-0.005f64 / tau).exp();
    assert!((s - expected).abs() < 1e-12, "{s} vs {expected}");
    // NaN command closes the valve instead of opening it.
    let mut st = ValveState::default();
    let ideal = proportional(0.02, 0.0);
    assert_eq!(ideal.spool(&mut st, f64::NAN, 0.0, dt), 0.0);
    assert_eq!(ideal.spool(&mut st, 7.0, 0.0, dt), 1.0);
}

/// `ValveModel::segment` locates every PWM edge: walking a run in 1 ms calls (as a control loop does) with a
/// steady command, the spool rises exactly `delay` after each period start and falls `d T` later, and the
/// energised time is the duty to rounding.
#[test]
fn pwm_segment_locates_every_delayed_edge() {
    let (freq, delay) = (40.0, 0.005);
    let period = 1.0 / freq;
    let v = pwm(freq, delay);
    for u in [-0.6, 0.0, 0.5, 1.0, -1.0] {
        let d = 0.5 * (1.0 + u);
        let mut st = ValveState::default();
        let (mut on, mut edges) = (0.0, Vec::new());
        let dt = 1e-3;
        let mut last = None;
        for k in 0..200 {
            // A control tick [k dt, (k + 1) dt], split at the edges inside it.
            let (t0, t1) = (k as f64 * dt, (k + 1) as f64 * dt);
            let mut t = t0;
            loop {
                let (s, edge) = v.segment(&mut st, u, t, t1 - t);
                let end = edge.unwrap_or(t1);
                assert!(end > t, "u {u}: empty piece at {t}");
                if s > 0.0 {
                    on += end - t;
                }
                if last.is_some_and(|l| l != s) {
                    edges.push((t, s));
                }
                last = Some(s);
                match edge {
                    Some(e) => t = e,
                    None => break,
                }
            }
        }
        // 0.2 s = 8 periods: the first `delay` is spent in the spring position, the delayed edge of the
        // 8th period's fall may lie beyond the run.
        let t_run = 0.2;
        let expected_on = (0..8)
            .map(|j| {
                let rise = j as f64 * period + delay;
                (rise + d * period).min(t_run) - rise.min(t_run)
            })
            .sum::<f64>();
        assert!(
            (on - expected_on).abs() < 1e-12,
            "u {u}: energised {on} s vs {expected_on} s"
        );
        for (t, s) in edges {
            let phase = (t - delay).rem_euclid(period);
            let want = if s > 0.0 { 0.0 } else { d * period };
            let err = (phase - want).abs().min((phase - want - period).abs());
            assert!(
                err < 1e-12,
                "u {u}: edge to {s} at {t}, phase {phase} vs {want}"
            );
        }
    }
}

/// With the edges located, the 1-DOF model under PWM converges with the step: after 0.2 s of a swept duty
/// (8 PWM periods, up to 16 edges), p_a at 10 and 20 substeps of a 1 ms tick agrees with 80 substeps
/// to 0.01 Pa (3e-8 relative; measured 3.3e-4 and 1.3e-4 Pa). With the spool held over a whole step
/// (sampled at mid-step) an edge was rounded to the step grid: an error of O(step) per edge.
#[test]
fn one_dof_pwm_converges_with_the_step() {
    // A heavy, damped load keeps the piston mid-stroke (away from the end stops): the chambers fill and
    // vent with the valve's edges.
    let mut m = model(pwm(40.0, 0.005), no_coulomb(), 0.0);
    m.mechanics.moving_mass_kg = 50.0;
    m.mechanics.viscous_n_s_per_m = 2000.0;
    let run = |substeps: u32| {
        let mut st = OneDofState::at_rest(0.025, ChamberState::new(3.0e5, 3.5e5), -1.0);
        let h = 1e-3 / f64::from(substeps);
        for k in 0..200 {
            // A command held over each 1 ms tick, sweeping the duty range.
            let u = 0.8 * (2.0 * std::f64::consts::PI * 3.0 * k as f64 * 1e-3).sin();
            for _ in 0..substeps {
                m.step(&mut st, u, 0.0, h);
            }
        }
        st
    };
    let reference = run(80);
    let err = |s: &OneDofState| (s.chambers.p_a - reference.chambers.p_a).abs();
    let (e10, e20) = (err(&run(10)), err(&run(20)));
    println!("p_a error vs 80 substeps: 10: {e10:.3e} Pa, 20: {e20:.3e} Pa");
    assert!(e10 < 1e-2, "p_a error at 10 substeps {e10} Pa");
    assert!(e20 < e10, "p_a error 10 -> 20 substeps: {e10} -> {e20} Pa");
}
