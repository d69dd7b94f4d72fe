//! 1-DOF mechanics: static balance on an incline, end stops, stick-slip, and the transfer function of
//! eqs. (16)-(17) against the simulated nonlinear response.
mod common;
use common::*;
use pneuflex_pneumatics::*;

/// The pressures from `static_balance` hold the flange still on a 30 deg incline against gravity and a
/// load (simulated with the valve shut); 0.5 % more pressure in A makes it move.
#[test]
fn static_balance_on_incline() {
    let m = model(proportional(0.0, 0.0), no_coulomb(), 30.0);
    let f_ext = -5.0;
    let p_b = 3.0e5;
    let p_a = m.static_balance(p_b, f_ext);
    // Hand force balance: p_a S_a = p_b S_b + p_atm S_rod - m g sin(30deg) - f_ext.
    let (sa, srod) = (
        std::f64::consts::PI * 0.008 * 0.008,
        std::f64::consts::PI * 0.0025 * 0.0025,
    );
    let by_hand = (p_b * (sa - srod) + 101_325.0 * srod - 0.6 * 9.80665 * 0.5 - f_ext) / sa;
    assert!(
        (p_a - by_hand).abs() / by_hand < 1e-12,
        "{p_a} vs {by_hand}"
    );
    let run = |pa: f64| {
        let mut st = OneDofState::at_rest(0.025, ChamberState::new(pa, p_b), 0.0);
        for _ in 0..10_000 {
            m.step(&mut st, 0.0, f_ext, 1e-4);
        }
        st.x - 0.025
    };
    let still = run(p_a);
    assert!(still.abs() < 1e-12, "flange drifted {still} m");
    let moved = run(p_a * 1.005);
    assert!(moved > 5e-5, "perturbed balance moved only {moved} m");
}

/// Full command drives the piston onto the end stop, where it rests and chamber A reaches supply.
#[test]
fn end_stop_holds_at_full_extension() {
    let m = model(proportional(0.02, 0.005), no_coulomb(), 30.0);
    let mut st = OneDofState::at_rest(0.01, ChamberState::new(1.5e5, 1.5e5), 0.0);
    for _ in 0..20_000 {
        m.step(&mut st, 1.0, 0.0, 1e-4);
        assert!(st.x >= 0.0 && st.x <= 0.05);
    }
    assert_eq!(st.x, 0.05);
    assert_eq!(st.x_dot, 0.0);
    assert!(
        (st.chambers.p_a - P_S).abs() / P_S < 1e-3,
        "p_a = {}",
        st.chambers.p_a
    );
    assert!(
        (st.chambers.p_b - 101_325.0).abs() < 1e3,
        "p_b = {}",
        st.chambers.p_b
    );
}

/// Stick-slip friction: a drive below break-away leaves the flange exactly at rest; above it, it moves.
#[test]
fn stick_slip_holds_below_breakaway() {
    let fr = Friction::StickSlip {
        coulomb_n: 1.0,
        static_n: 1.5,
        stribeck_velocity_m_per_s: 1e-3,
        stick_velocity_m_per_s: 1e-4,
    };
    let m = model(proportional(0.0, 0.0), fr, 0.0);
    let p_b = 2.0e5;
    let p_a0 = m.static_balance(p_b, 0.0);
    let sa = m.actuator.cylinder.area_a();
    let run = |extra_n: f64| {
        let mut st = OneDofState::at_rest(0.025, ChamberState::new(p_a0 + extra_n / sa, p_b), 0.0);
        for _ in 0..5_000 {
            m.step(&mut st, 0.0, 0.0, 1e-4);
        }
        st.x - 0.025
    };
    assert_eq!(run(1.2), 0.0);
    assert_eq!(run(-1.4), 0.0);
    assert!(run(2.0) > 1e-5);
    assert!(run(-2.0) < -1e-5);
}

/// Eq. (16) coefficients: the printed beta_n is recovered when S_a p_a = S_b p_b, and omega_n, xi_n
/// equal modulus and damping of the roots of a3 s^2 + a2 s + a1 (checked via the quadratic formula).
#[test]
fn transfer_function_coefficients() {
    let (sa, sb) = (2.0e-4, 1.8e-4);
    let p_b = 3.0e5;
    let p = TfParams {
        area_a: sa,
        area_b: sb,
        volume_a: 8e-6,
        volume_b: 9e-6,
        p_a: p_b * sb / sa,
        p_b,
        temperature_k: 293.15,
        gas_constant: 287.05,
        exponent: 1.4,
        mass_kg: 0.6,
        viscous: 20.0,
        k_ca: 3e-10,
        k_cb: 2e-10,
    };
    let tf = TransferFunction::from_params(&p);
    let (r, n, k, rt) = (9.0 / 8.0, sb / sa, 1.4, 287.05 * 293.15);
    let beta_printed =
        sa * sa * p.p_a * k * r + sa * sa * p.p_a * k * n + p.k_ca * p.viscous * rt * k * r;
    assert!((tf.den[2] - beta_printed).abs() / beta_printed < 1e-12);
    let [a3, a2, a1, a0] = tf.den;
    assert_eq!(a0, 0.0);
    let disc = a2 * a2 - 4.0 * a3 * a1;
    assert!(disc < 0.0, "expected an oscillatory pair");
    let (re, im) = (-a2 / (2.0 * a3), (-disc).sqrt() / (2.0 * a3));
    let w = (re * re + im * im).sqrt();
    assert!((tf.omega_n - w).abs() / w < 1e-12);
    assert!((tf.xi_n - (-re / w)).abs() < 1e-12);
    assert!((tf.k_n - tf.num / a1).abs() <= 1e-15 * tf.k_n.abs());
}

/// The nonlinear model at mid-stroke, excited by a small force step, rings at the natural frequency and
/// damping of eq. (17) evaluated at the same operating point (within 5 %). Frequency and damping are
/// identified from zero crossings and successive extrema of the simulated acceleration.
#[test]
fn step_response_matches_transfer_function() {
    let m = model(proportional(0.02, 0.0), no_coulomb(), 30.0);
    let (op, tf) = m.transfer_function_mid_stroke().expect("operating point");
    let t = op.temperature_k;
    let mut st = OneDofState::at_rest(
        op.x,
        ChamberState::with_temperature(op.p_a, op.p_b, t),
        op.u,
    );
    let dt = 1e-5;
    let df = 0.05; // N, small step in the external force
    // The operating point is an equilibrium: without the step nothing moves.
    let mut still = st;
    for _ in 0..1000 {
        m.step(&mut still, op.u, op.f_ext, dt);
    }
    assert!(
        (still.x - op.x).abs() < 1e-9,
        "operating point drifts {}",
        still.x - op.x
    );

    let n = 40_000;
    let mut acc = Vec::with_capacity(n);
    for _ in 0..n {
        let v0 = st.x_dot;
        m.step(&mut st, op.u, op.f_ext + df, dt);
        acc.push((st.x_dot - v0) / dt);
    }
    // Zero crossings (linear interpolation) and the extreme |a| between consecutive crossings.
    let mut crossings = Vec::new();
    for i in 1..n {
        if acc[i - 1] > 0.0 && acc[i] <= 0.0 || acc[i - 1] < 0.0 && acc[i] >= 0.0 {
            let f = acc[i - 1] / (acc[i - 1] - acc[i]);
            crossings.push((i as f64 - 1.0 + f) * dt);
        }
    }
    assert!(
        crossings.len() >= 6,
        "only {} zero crossings",
        crossings.len()
    );
    let half: Vec<f64> = crossings.windows(2).take(5).map(|w| w[1] - w[0]).collect();
    let half_period = half.iter().sum::<f64>() / half.len() as f64;
    let peaks: Vec<f64> = crossings
        .windows(2)
        .take(5)
        .map(|w| {
            let (i0, i1) = ((w[0] / dt) as usize + 1, (w[1] / dt) as usize);
            acc[i0..=i1].iter().fold(0.0f64, |a, &b| a.max(b.abs()))
        })
        .collect();
    let sigma = peaks
        .windows(2)
        .map(|p| (p[0] / p[1]).ln() / half_period)
        .sum::<f64>()
        / (peaks.len() - 1) as f64;
    let wd = std::f64::consts::PI / half_period;
    let wn = (wd * wd + sigma * sigma).sqrt();
    let xi = sigma / wn;
    let ew = (wn - tf.omega_n).abs() / tf.omega_n;
    let ex = (xi - tf.xi_n).abs() / tf.xi_n;
    assert!(
        ew < 0.05,
        "omega: simulated {wn} vs eq. (17) {}",
        tf.omega_n
    );
    assert!(ex < 0.05, "xi: simulated {xi} vs eq. (17) {}", tf.xi_n);
    eprintln!(
        "omega_n sim {wn:.3} tf {:.3}; xi sim {xi:.4} tf {:.4}",
        tf.omega_n, tf.xi_n
    );
}

/// With the 5/2 valve held in the spring position (u = -1) the piston retracts onto the cap-end stop,
/// chamber A vents to the atmosphere and B fills to supply; RK4 at dt = 1e-4 s stays stable with the
/// smallest chamber volume (the stiffest case).
#[test]
fn retract_to_cap_end_is_stable_at_documented_step() {
    let m = model(pwm(40.0, 0.005), no_coulomb(), 30.0);
    let mut st = OneDofState::at_rest(0.04, ChamberState::new(3.0e5, 3.0e5), -1.0);
    for _ in 0..10_000 {
        m.step(&mut st, -1.0, 0.0, 1e-4);
        assert!(st.chambers.p_a.is_finite() && st.chambers.p_a > 0.0);
    }
    assert_eq!(st.x, 0.0);
    assert!(
        (st.chambers.p_a - 101_325.0).abs() < 100.0,
        "p_a = {}",
        st.chambers.p_a
    );
    assert!(
        (st.chambers.p_b - P_S).abs() < 600.0,
        "p_b = {}",
        st.chambers.p_b
    );
}

/// `OneDofModel::advance` (a control period of substeps, the chamber constants and the valve's spool held
/// between them) gives bit for bit the state of its substeps taken one by one with `step_with_gravity`:
/// on/off valves whose PWM edges fall inside substeps and exactly on their boundaries (delays and periods
/// that are multiples of the substep, duty 0.5), a proportional valve with a spool lag, smooth and
/// stick-slip friction, a contact spring re-evaluated at each substep, commands that change every period.
#[test]
fn advance_is_its_substeps_bit_for_bit() {
    let smooth = Friction::Smooth {
        coulomb_n: 2.0,
        smooth_velocity_m_per_s: 1e-3,
    };
    let stick = Friction::StickSlip {
        coulomb_n: 2.0,
        static_n: 3.0,
        stribeck_velocity_m_per_s: 0.01,
        stick_velocity_m_per_s: 1e-4,
    };
    let cases = [
        (pwm(40.0, 0.005), smooth),
        (pwm(50.0, 0.002), stick),
        (pwm(100.0, 0.0), smooth),
        (pwm(37.0, 0.00123), stick),
        (proportional(0.02, 0.003), smooth),
    ];
    let (dt, substeps) = (1e-3, 10);
    let spring = |x: f64| -700.0 * (x - 0.02).max(0.0);
    for (i, (valve, friction)) in cases.into_iter().enumerate() {
        let m = model(valve, friction, 30.0);
        let start = OneDofState::at_rest(0.02, ChamberState::new(2.6e5, 3.5e5), 0.0);
        let (mut whole, mut pieces) = (start, start);
        let g = m.mechanics.gravity_force();
        let mut seed = 0x2545_f491_4f6c_dd1du64 ^ i as u64;
        for tick in 0..3000 {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            // Every fourth period one of the commands whose edges land on substep boundaries.
            let u = match tick % 4 {
                0 => [0.0, -1.0, 1.0, 0.5][(seed >> 62) as usize],
                _ => 2.0 * ((seed >> 11) as f64 / (1u64 << 53) as f64) - 1.0,
            };
            m.advance(&mut whole, u, g, dt, substeps, spring);
            let h = dt / f64::from(substeps);
            for _ in 0..substeps {
                let f = spring(pieces.x);
                m.step_with_gravity(&mut pieces, u, f, g, h);
            }
            assert_eq!(whole, pieces, "case {i}, tick {tick}");
        }
        assert!(
            (whole.x - start.x).abs() > 1e-4,
            "case {i}: the flange never moved ({} m)",
            whole.x
        );
    }
}
