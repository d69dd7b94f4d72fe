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
