//! The force element's state as numbers (what a host such as MuJoCo's plugin_state keeps between steps):
//! a round trip through `state`/`set_state` continues the run bit for bit, and numbers the element never
//! writes are refused.
mod common;
use common::*;
use pneuflex_pneumatics::*;

/// Steps `el` under a command that changes every 1.3 ms (so PWM periods latch different duties) while
/// the flange moves, and returns the forces.
fn drive(el: &mut PneumaticForceElement, from: usize, n: usize, h: f64) -> Vec<f64> {
    (from..from + n)
        .map(|k| {
            let t = k as f64 * h;
            el.set_command((t / 1.3e-3).floor().sin() * 0.8);
            el.step(0.02 + 0.01 * (7.0 * t).sin(), 0.07 * (7.0 * t).cos(), h)
        })
        .collect()
}

#[test]
fn a_state_round_trip_continues_the_run_bit_for_bit() {
    for valve in [pwm(40.0, 0.005), proportional(0.02, 0.005)] {
        let act = actuator(valve, 1.4);
        let h = 25e-6;
        let mut a = PneumaticForceElement::new(act, ChamberState::new(3.0e5, 3.5e5), 3);
        // Stop mid-period (1000 steps = 25 ms = one PWM period, plus 437 steps), with edges behind it.
        let _ = drive(&mut a, 0, 1437, h);
        let s = a.state();
        let mut b = PneumaticForceElement::new(act, ChamberState::new(1e5, 1e5), 3);
        assert!(b.set_state(&s));
        assert_eq!(b.state(), s);
        let fa = drive(&mut a, 1437, 3000, h);
        let fb = drive(&mut b, 1437, 3000, h);
        assert_eq!(fa, fb, "{:?}", act.valve.kind);
        assert_eq!(a.state(), b.state());
        // And the run did something: the pressures moved by more than a kPa.
        assert!((a.chambers.p_a - s[0]).abs() > 1e3 || (a.chambers.p_b - s[1]).abs() > 1e3);
    }
}

#[test]
fn numbers_the_element_never_writes_are_refused() {
    let act = actuator(pwm(40.0, 0.005), 1.4);
    let mut el = PneumaticForceElement::new(act, ChamberState::new(3.0e5, 3.5e5), 1);
    let _ = drive(&mut el, 0, 500, 25e-6);
    let good = el.state();
    let bad = [
        (0, -1.0),               // p_a
        (1, f64::NAN),           // p_b
        (3, 0.0),                // T_b
        (4, 1.5),                // spool
        (5, 0.5),                // the PWM clock flag
        (6, f64::INFINITY),      // first period start
        (7, 2.5),                // period index
        (7, -1.0),               // period index
        (8, 1.01),               // duty
        (9, -0.1),               // previous duty
        (10, f64::NEG_INFINITY), // clock
    ];
    for (i, v) in bad {
        let mut s = good;
        s[i] = v;
        assert!(!el.set_state(&s), "slot {i} = {v} accepted");
        assert_eq!(el.state(), good, "a refused state changed the element");
    }
    assert!(el.set_state(&good));
}

/// The element's step is, bit for bit, its substeps split at every spool edge and integrated piece by piece
/// with the valve asked at every piece (`ValveModel::segment`, `Actuator::step_chambers`), the force the
/// trapezoid of each piece weighted by its share: the element holds the spool between the valve's edges
/// and the chamber constants between spool changes without changing a bit. On/off valves with edges inside
/// substeps and on their boundaries, and a lagging proportional valve.
#[test]
fn a_step_is_its_pieces_bit_for_bit() {
    for (valve, substeps, dt) in [
        (pwm(40.0, 0.005), 10, 1e-3),
        (pwm(50.0, 0.002), 4, 1e-3),
        (pwm(37.0, 0.00123), 3, 25e-6),
        (proportional(0.02, 0.005), 10, 1e-3),
    ] {
        let act = actuator(valve, 1.4);
        let start = ChamberState::new(3.0e5, 3.5e5);
        let mut el = PneumaticForceElement::new(act, start, substeps);
        let (mut chambers, mut spool_state, mut t) = (start, el.valve, 0.0);
        for k in 0..4000 {
            let u = [0.0, 0.6, -0.35, 1.0, -1.0, 0.5][k % 6];
            let tk = k as f64 * dt;
            let (x, x_dot) = (0.02 + 0.01 * (7.0 * tk).sin(), 0.07 * (7.0 * tk).cos());
            el.set_command(u);
            let f = el.step(x, x_dot, dt);
            // The reference: the valve at every piece.
            let h = dt / f64::from(substeps);
            let mut f_sum = 0.0;
            for i in 0..substeps {
                let xi = x + x_dot * h * f64::from(i);
                let (t_sub, t_end) = (t, t + h);
                let (mut tau, mut rest) = (t_sub, h);
                loop {
                    let (spool, edge) = act.valve.segment(&mut spool_state, u, tau, rest);
                    let len = edge.map_or(rest, |e| e - tau);
                    let f0 = act.piston_force(&chambers);
                    let x_piece = if tau == t_sub {
                        xi
                    } else {
                        xi + x_dot * (tau - t_sub)
                    };
                    act.step_chambers(&mut chambers, x_piece, x_dot, spool, len);
                    f_sum += 0.5 * (f0 + act.piston_force(&chambers)) * (len / h);
                    match edge {
                        Some(e) if e < t_end => (tau, rest) = (e, t_end - e),
                        _ => break,
                    }
                }
                t += h;
            }
            assert_eq!(
                f,
                f_sum / f64::from(substeps),
                "{:?}, step {k}",
                act.valve.kind
            );
            assert_eq!((el.chambers, el.valve), (chambers, spool_state), "step {k}");
        }
    }
}
