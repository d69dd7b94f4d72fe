//! Contact stiffness: under a constant push the load cell and the deflection obey f = k (x - x_e), eq. (21).

use pneuflex_multibody::{CarriageRig, ConstantForce, RigConfig, STANDARD_GRAVITY};

fn rig_path() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../urdf/rig.urdf")
}

/// Flange mass in urdf/rig.urdf, kg.
const FLANGE_MASS_KG: f64 = 0.60;

/// Run a constant push against `material` at incline `alpha_deg` to steady state; return
/// (measured f_e, k (x - x_e), force balance F + m g sin(alpha)).
fn steady_push(
    material: &str,
    alpha_deg: f64,
    push_n: f64,
    dt: f64,
    iters: usize,
) -> (f64, f64, f64) {
    let mut cfg = RigConfig::paper_rig();
    cfg.initial_material = material.into();
    cfg.alpha_rad = alpha_deg.to_radians();
    cfg.dt_s = dt;
    cfg.solver_iterations = iters;
    let mut w = CarriageRig::from_urdf(rig_path(), &cfg).expect("rig builds");
    let mut act = ConstantForce { force_n: push_n };
    let steps = (3.0 / dt).round() as usize;
    for _ in 0..steps {
        w.step(&mut act);
    }
    let m = w.measurements();
    let k = w.material_params(material).unwrap().stiffness_n_per_m;
    let x_e = w.material_x_e(material).unwrap();
    let balance = push_n + FLANGE_MASS_KG * STANDARD_GRAVITY * cfg.alpha_rad.sin();
    (m.f_e, k * (m.x - x_e), balance)
}

#[test]
fn contact_force_obeys_spring_law_for_each_material_and_incline() {
    for material in ["wood", "iron"] {
        for alpha in [0.0, 30.0, 60.0] {
            let (f_e, spring, balance) = steady_push(material, alpha, 10.0, 1e-3, 4);
            eprintln!(
                "{material} alpha={alpha}: f_e={f_e:.6} k(x-x_e)={spring:.6} balance={balance:.6}"
            );
            assert!(
                (f_e - spring).abs() <= 0.02 * spring,
                "{material} {alpha}: f_e {f_e} vs k(x-x_e) {spring}"
            );
            assert!(
                (f_e - balance).abs() <= 0.02 * balance,
                "{material} {alpha}: f_e {f_e} vs balance {balance}"
            );
        }
    }
}

/// Free flight (before contact) under a constant push F on the incline: eq. (1) with f_e = 0,
/// m x'' + K_v x' = F + m g sin(alpha), from rest at x = 0, has the closed form
/// x(t) = (F_tot / K_v) (t - tau (1 - exp(-t / tau))), tau = m / K_v.
#[test]
fn free_flight_matches_eq1_closed_form() {
    const K_V: f64 = 20.0; // urdf/rig.urdf flange_slide damping, N s/m
    for alpha_deg in [0.0_f64, 30.0] {
        let mut cfg = RigConfig::paper_rig();
        cfg.dt_s = 1e-4;
        cfg.alpha_rad = alpha_deg.to_radians();
        let mut w = CarriageRig::from_urdf(rig_path(), &cfg).unwrap();
        let push = 1.0;
        let f_tot = push + FLANGE_MASS_KG * STANDARD_GRAVITY * cfg.alpha_rad.sin();
        let tau = FLANGE_MASS_KG / K_V;
        let mut act = ConstantForce { force_n: push };
        for _ in 0..500 {
            w.step(&mut act);
        }
        let m = w.measurements();
        assert!(!m.contact, "still in free flight");
        let t = m.t_s;
        let x_exact = f_tot / K_V * (t - tau * (1.0 - (-t / tau).exp()));
        let v_exact = f_tot / K_V * (1.0 - (-t / tau).exp());
        assert!(
            (m.x - x_exact).abs() <= 0.01 * x_exact,
            "alpha {alpha_deg}: x {} vs {x_exact}",
            m.x
        );
        assert!(
            (m.x_dot - v_exact).abs() <= 0.01 * v_exact,
            "alpha {alpha_deg}: v {} vs {v_exact}",
            m.x_dot
        );
    }
}

/// The wood-to-iron swap: contact is lost while the carriage moves, regained on iron, and the new steady
/// state obeys the iron spring.
#[test]
fn swap_wood_to_iron_loses_and_regains_contact() {
    let cfg = RigConfig::paper_rig();
    let mut w = CarriageRig::from_urdf(rig_path(), &cfg).unwrap();
    let push = 10.0;
    let mut act = ConstantForce { force_n: push };
    for _ in 0..1000 {
        w.step(&mut act);
    }
    assert!(w.measurements().contact);
    assert_eq!(w.active_material(), Some("wood"));
    let x_wood = w.measurements().x;
    w.swap_environment("iron", 0.9).unwrap();
    let mut lost = false;
    for _ in 0..900 {
        let m = w.step(&mut act);
        lost |= !m.contact && m.f_e == 0.0;
    }
    assert!(lost, "the flange must lose contact during the swap");
    assert_eq!(w.active_material(), Some("iron"));
    for _ in 0..2000 {
        w.step(&mut act);
    }
    let m = w.measurements();
    assert!(m.contact);
    let k_iron = w.material_params("iron").unwrap().stiffness_n_per_m;
    let x_e = w.material_x_e("iron").unwrap();
    assert!((m.f_e - push).abs() <= 0.01 * push, "f_e {}", m.f_e);
    assert!(
        (k_iron * (m.x - x_e) - push).abs() <= 0.01 * push,
        "x {}",
        m.x
    );
    // Iron is twice as stiff: the flange stands half as deep in it.
    let x_e_wood = w.material_x_e("wood").unwrap();
    let ratio = (x_wood - x_e_wood) / (m.x - x_e);
    assert!((ratio - 2.0).abs() < 0.02, "depth ratio {ratio}");
}

/// A run-time stiffness change moves the steady state to the new spring.
#[test]
fn stiffness_change_at_run_time() {
    let cfg = RigConfig::paper_rig();
    let mut w = CarriageRig::from_urdf(rig_path(), &cfg).unwrap();
    let mut act = ConstantForce { force_n: 10.0 };
    for _ in 0..1000 {
        w.step(&mut act);
    }
    let mut p = w.material_params("wood").unwrap();
    p.stiffness_n_per_m = 1400.0;
    w.set_material("wood", p).unwrap();
    for _ in 0..2000 {
        w.step(&mut act);
    }
    let m = w.measurements();
    let depth = m.x - w.material_x_e("wood").unwrap();
    assert!(
        (1400.0 * depth - 10.0).abs() <= 0.01 * 10.0,
        "depth {depth}"
    );
    assert!(w.set_material("steel", p).is_err());
}

/// Changing alpha at run time adds m g sin(alpha) to the steady contact force (eq. (1)'s G_alpha).
#[test]
fn incline_change_at_run_time() {
    let cfg = RigConfig::paper_rig();
    let mut w = CarriageRig::from_urdf(rig_path(), &cfg).unwrap();
    let mut act = ConstantForce { force_n: 10.0 };
    for _ in 0..1000 {
        w.step(&mut act);
    }
    let alpha = 45f64.to_radians();
    w.set_alpha(alpha).unwrap();
    for _ in 0..2000 {
        w.step(&mut act);
    }
    let expect = 10.0 + FLANGE_MASS_KG * STANDARD_GRAVITY * alpha.sin();
    let m = w.measurements();
    assert!(
        (m.f_e - expect).abs() <= 0.01 * expect,
        "f_e {} vs {expect}",
        m.f_e
    );
    // The world tilt for viewers turns the rig's axis downhill by alpha.
    let axis_world = w.world_from_rig().rotation * pneuflex_multibody::Vector::X;
    assert!((axis_world.z + alpha.sin()).abs() < 1e-12);
    assert!(w.set_alpha(f64::NAN).is_err());
}

/// The coarsest step found (see docs/multibody.md): dt = 20 ms with 2 solver iterations still holds the
/// steady contact force within 1 % of the force balance and of k (x - x_e).
#[test]
fn coarse_step_keeps_steady_force_within_one_percent() {
    for material in ["wood", "iron"] {
        let (f_e, spring, balance) = steady_push(material, 30.0, 10.0, 0.02, 2);
        assert!(
            (f_e - balance).abs() <= 0.01 * balance,
            "{material}: f_e {f_e} vs {balance}"
        );
        assert!(
            (spring - balance).abs() <= 0.01 * balance,
            "{material}: k(x-x_e) {spring} vs {balance}"
        );
    }
}

/// The realistic variant (wood 2e5 N/m, iron 2e7 N/m) at the finer steps docs/multibody.md prescribes.
#[test]
fn realistic_materials_obey_spring_law_at_fine_steps() {
    use pneuflex_multibody::ContactParams;
    for (material, dt) in [("wood", 1e-3), ("iron", 1e-4)] {
        let mut cfg = RigConfig::paper_rig();
        cfg.materials[0].params = ContactParams::REALISTIC_WOOD;
        cfg.materials[1].params = ContactParams::REALISTIC_IRON;
        cfg.initial_material = material.into();
        cfg.dt_s = dt;
        cfg.alpha_rad = 30f64.to_radians();
        // Start just short of the face so the short run reaches steady state.
        cfg.initial_x_m = 0.0195;
        let mut w = CarriageRig::from_urdf(rig_path(), &cfg).unwrap();
        let mut act = ConstantForce { force_n: 10.0 };
        for _ in 0..(0.5 / dt) as usize {
            w.step(&mut act);
        }
        let m = w.measurements();
        let k = w.material_params(material).unwrap().stiffness_n_per_m;
        let balance = 10.0 + FLANGE_MASS_KG * STANDARD_GRAVITY * cfg.alpha_rad.sin();
        let spring = k * (m.x - w.material_x_e(material).unwrap());
        assert!(
            (m.f_e - balance).abs() <= 0.02 * balance,
            "{material}: f_e {} vs {balance}",
            m.f_e
        );
        assert!(
            (spring - balance).abs() <= 0.02 * balance,
            "{material}: k(x-x_e) {spring} vs {balance}"
        );
    }
}

/// Dynamic bodies Rapier simulates now.
fn simulated_dynamic_bodies(w: &CarriageRig) -> usize {
    w.physics()
        .bodies
        .iter()
        .filter(|(_, b)| b.is_dynamic() && b.is_enabled())
        .count()
}

/// While the carriage rests only the face in front of the flange is simulated (with the flange); every face
/// rides a carriage move, and the other faces leave the simulation after it.
#[test]
fn faces_out_of_reach_leave_the_simulation_while_the_carriage_rests() {
    let mut w = CarriageRig::from_urdf(rig_path(), &RigConfig::paper_rig()).unwrap();
    let mut act = ConstantForce { force_n: 10.0 };
    w.step(&mut act);
    assert_eq!(simulated_dynamic_bodies(&w), 2, "flange and wood face");
    w.swap_environment("iron", 0.9).unwrap();
    w.step(&mut act);
    assert_eq!(simulated_dynamic_bodies(&w), 3, "all faces during the move");
    for _ in 0..900 {
        w.step(&mut act);
    }
    assert_eq!(w.active_material(), Some("iron"));
    assert_eq!(simulated_dynamic_bodies(&w), 2, "flange and iron face");
}

/// A face the flange can touch while another material faces it stays simulated: in this fixture the iron
/// face overlaps the flange by 5 mm while the wood faces it, at the same first-touch extension.
#[test]
fn a_face_within_the_flanges_reach_stays_simulated() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/close_faces.urdf");
    let mut w = CarriageRig::from_urdf(path, &RigConfig::paper_rig()).unwrap();
    let mut act = ConstantForce { force_n: 10.0 };
    for _ in 0..1000 {
        w.step(&mut act);
    }
    assert_eq!(
        simulated_dynamic_bodies(&w),
        3,
        "flange, wood face and the iron face in reach"
    );
    assert!(w.measurements().contact);
}

/// A 3 N, 40 Hz ripple (the rig's PWM frequency) on a push that holds 10 N on the face, through a spring
/// k_a about the contact position x_c: F = 10 + 3 sin(ωt) - k_a (x - x_c), so the ripple meets a resonance
/// near 30 Hz as it does through the chambers' air spring.
struct RipplingPush {
    t_s: f64,
    k_a: f64,
    x_c: f64,
}

impl pneuflex_multibody::AxialActuator for RipplingPush {
    fn force(&mut self, x: f64, _x_dot: f64, dt: f64) -> f64 {
        let f = 10.0 + 3.0 * (std::f64::consts::TAU * 40.0 * self.t_s).sin()
            - self.k_a * (x - self.x_c);
        self.t_s += dt;
        f
    }
}

/// (RMS of f_e about its mean over the last second of 2 s of rippling push on `material`, the closed form
/// for flange and face moving together: f_e = (k + jωc - m ω²) X, X = F / (k + k_a - M ω² + jω(c + K_v))).
fn ripple_rms(material: &str, face_mass_kg: f64, dt: f64, iters: usize) -> (f64, f64) {
    let mut cfg = RigConfig::paper_rig();
    cfg.initial_material = material.into();
    cfg.dt_s = dt;
    cfg.solver_iterations = iters;
    let mut w = CarriageRig::from_urdf(rig_path(), &cfg).expect("rig builds");
    let p = w.material_params(material).unwrap();
    let (k, c) = (p.stiffness_n_per_m, p.damping_n_s_per_m);
    let mass = FLANGE_MASS_KG + face_mass_kg;
    let k_a = mass * (std::f64::consts::TAU * 30.0).powi(2) - k;
    let x_c = w.material_x_e(material).unwrap() + 10.0 / k;
    let mut act = RipplingPush { t_s: 0.0, k_a, x_c };
    let steps = (2.0 / dt).round() as usize;
    let mut f = Vec::new();
    for n in 0..steps {
        let m = w.step(&mut act);
        if n >= steps / 2 {
            f.push(m.f_e);
        }
    }
    let mean = f.iter().sum::<f64>() / f.len() as f64;
    let rms = (f.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / f.len() as f64).sqrt();
    // K_v: the flange slide's damping in urdf/rig.urdf.
    let (omega, k_v) = (std::f64::consts::TAU * 40.0, 20.0);
    let abs = |re: f64, im: f64| re.hypot(im);
    let x_amp = 3.0 / abs(k + k_a - mass * omega * omega, omega * (c + k_v));
    let f_amp = abs(k - face_mass_kg * omega * omega, omega * c) * x_amp;
    (rms, f_amp / std::f64::consts::SQRT_2)
}

/// The mount's damping is the material's whatever the solver substep (`Mechanism::set_spring`: Rapier's
/// implicit motor alone damps with c + k h): the 40 Hz ripple of the contact force matches the closed form
/// within 7 % at a 1 ms substep (the shipped Fig. 7 step, 2 ms / 2 iterations; measured wood -5.7 %, iron
/// +4.5 %) and 4 % at 0.125 ms (1 ms / 8; +1.0 %, +2.9 %). Without the correction: +26 % and +52 % at 1 ms,
/// +5 % and +8.7 % at 0.125 ms.
#[test]
fn contact_force_ripple_matches_the_closed_form_at_any_substep() {
    for (material, mass) in [("wood", 0.009), ("iron", 0.028)] {
        for (dt, iters, tol) in [(2e-3, 2, 0.07), (1e-3, 8, 0.04)] {
            let (rms, closed) = ripple_rms(material, mass, dt, iters);
            eprintln!(
                "{material} {dt} s x {iters}: ripple RMS {rms:.4} N, closed form {closed:.4} N"
            );
            assert!(
                (rms - closed).abs() <= tol * closed,
                "{material} at {dt} s / {iters} iterations: ripple RMS {rms} N against {closed} N"
            );
        }
    }
}
