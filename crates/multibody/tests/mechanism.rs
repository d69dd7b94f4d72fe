//! The general mechanism against closed forms: a joint turned through a lever, a gripper squeezing an
//! object, two cylinders in antagonism. Each static state is computed here independently (plain geometry
//! and the gas laws, solved by bisection) and the simulation must settle on it.

use std::path::{Path, PathBuf};

use pneuflex_multibody::{
    ActuatorConfig, AxialActuator, ContactConfig, ContactParams, Mechanism, MechanismConfig, Mount,
    MultibodyError, PneumaticForceElement, STANDARD_GRAVITY,
};
use pneuflex_pneumatics::{Actuator, ChamberState, P_ATM};

fn urdf(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../urdf")
        .join(name)
}

/// Bisection for the root of a function that changes sign on [lo, hi].
fn root(f: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
    let s = f(lo).signum();
    assert!(s != f(hi).signum(), "no sign change on [{lo}, {hi}]");
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if f(mid).signum() == s {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

mod common;

/// A cylinder with a zero-lap proportional valve (u = 0 closes both chambers), rod 0.3 of the bore.
fn cylinder(bore_m: f64, stroke_m: f64, supply_pa: f64) -> Actuator {
    common::cylinder(bore_m, 0.3 * bore_m, stroke_m, 3.0e-6, supply_pa)
}

// ---- the lever -------------------------------------------------------------------------------------

/// Clevis on the base, rod eye on the arm's bracket (0.15 m from the pivot).
const CLEVIS: [f64; 3] = [0.05, 0.0, -0.25];
const LEVER_M: f64 = 0.15;

fn lever_config() -> MechanismConfig {
    MechanismConfig::new(
        vec![ActuatorConfig {
            name: "elbow_cylinder".into(),
            mount: Mount::Anchors {
                link_a: "base".into(),
                point_a_m: CLEVIS,
                link_b: "lever_bracket".into(),
                point_b_m: [0.0; 3],
                retracted_length_m: 0.2,
                stroke_m: 0.2,
            },
        }],
        vec![],
    )
}

/// Net moment about the raising axis (−y) at angle θ with cylinder force F: the cylinder's F × r(θ)
/// against the arm's (0.5 kg at 0.2 m) and the payload's (1 kg at 0.4 m) weight.
fn lever_moment(theta: f64, force_n: f64) -> f64 {
    let (s, c) = theta.sin_cos();
    // Rotation about −y by θ takes x to (cos θ, 0, sin θ).
    let b = [LEVER_M * c, 0.0, LEVER_M * s];
    let d = [b[0] - CLEVIS[0], b[1] - CLEVIS[1], b[2] - CLEVIS[2]];
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let f = [
        force_n * d[0] / len,
        force_n * d[1] / len,
        force_n * d[2] / len,
    ];
    // (b × f)·(−y) = −(b_z f_x − b_x f_z)
    let cylinder = -(b[2] * f[0] - b[0] * f[2]);
    let weight = (0.5 * 0.2 + 1.0 * 0.4) * STANDARD_GRAVITY * c;
    cylinder - weight
}

/// Where the arm, released at θ = 0, comes to rest under force F: the first zero of the net moment in
/// the direction it turns (the lever arm shrinks as the arm rises, so a second, unstable balance lies
/// beyond it).
fn rest_angle(force_n: f64) -> f64 {
    let dir = lever_moment(0.0, force_n).signum();
    let mut a = 0.0;
    loop {
        let b = a + dir * 0.01;
        assert!(
            (-0.4..=1.2).contains(&b),
            "no balance within the joint's range at {force_n} N"
        );
        if lever_moment(b, force_n).signum() != dir {
            return root(|t| lever_moment(t, force_n), a.min(b), a.max(b));
        }
        a = b;
    }
}

/// The cylinder's lever arm r(θ) about the pivot, m: the moment per newton.
fn lever_arm(theta: f64) -> f64 {
    lever_moment(theta, 1.0) - lever_moment(theta, 0.0)
}

#[test]
fn a_lever_settles_at_the_angle_where_f_times_r_balances_the_load() {
    for force_n in [31.0, 34.0, 37.0] {
        let theta_star = rest_angle(force_n);
        let mut m = Mechanism::from_urdf(urdf("lever.urdf"), &lever_config()).unwrap();
        for _ in 0..10_000 {
            m.step_with_forces(&[force_n]);
        }
        let (theta, omega) = m.joint_position("elbow").unwrap();
        assert!(
            (theta - theta_star).abs() < 2e-3,
            "F = {force_n} N: angle {theta} rad, closed form {theta_star} rad"
        );
        assert!(omega.abs() < 1e-3, "still turning at {omega} rad/s");
        m.check_strokes().unwrap();
    }
}

#[test]
fn the_lever_arm_follows_the_geometry_as_the_joint_turns() {
    // From rest the angular acceleration is (F r(θ) − W cos θ) / I about the pivot: the first step's
    // velocity checks the moment the anchors produce at θ = 0, and again after the arm has turned.
    let i_pivot = 6.7042e-3 + 0.5 * 0.2 * 0.2 + 4.1667e-4 + 1.0 * 0.4 * 0.4;
    let mut m = Mechanism::from_urdf(urdf("lever.urdf"), &lever_config()).unwrap();
    // Hold the arm at a few angles with a balancing force, then add 10 N and look at one step.
    for theta_target in [0.0, 0.5, 1.0] {
        let f_hold = -lever_moment(theta_target, 0.0) / lever_arm(theta_target);
        // Walk the arm to the target with a spring-like force law, then hold.
        for _ in 0..20_000 {
            let (theta, omega) = m.joint_position("elbow").unwrap();
            let f = f_hold + 200.0 * (theta_target - theta) - 20.0 * omega;
            m.step_with_forces(&[f]);
        }
        let (theta0, omega0) = m.joint_position("elbow").unwrap();
        assert!((theta0 - theta_target).abs() < 1e-3 && omega0.abs() < 1e-4);
        let extra = 10.0;
        let f = -lever_moment(theta0, 0.0) / lever_arm(theta0) + extra;
        m.step_with_forces(&[f]);
        let (_, omega1) = m.joint_position("elbow").unwrap();
        // Joint damping 1 N m s/rad over one 1 ms step is negligible against this acceleration.
        let alpha_expected = extra * lever_arm(theta0) / i_pivot;
        let alpha = (omega1 - omega0) / m.dt();
        assert!(
            (alpha - alpha_expected).abs() < 0.02 * alpha_expected,
            "θ = {theta0}: angular acceleration {alpha} rad/s², F r(θ)/I = {alpha_expected}"
        );
    }
}

#[test]
fn anchors_on_a_moving_body_span_exactly_the_distance_between_them_at_every_tick() {
    let mut m = Mechanism::from_urdf(urdf("lever.urdf"), &lever_config()).unwrap();
    let mut seen = (f64::INFINITY, f64::NEG_INFINITY);
    for k in 0..3000 {
        let t = k as f64 * 1e-3;
        m.step_with_forces(&[45.0 + 15.0 * (6.0 * t).sin()]);
        // The anchors from the links' poses (the bracket is merged into the arm's body by a fixed joint).
        let pa = m.link_pose("base").unwrap().transform_point(CLEVIS.into());
        let pb = m
            .link_pose("lever_bracket")
            .unwrap()
            .transform_point([0.0; 3].into());
        let s = m.actuator_state(0);
        let distance = (pb - pa).length();
        assert!(
            (s.x_m + 0.2 - distance).abs() < 1e-12,
            "tick {k}: stroke {} + retracted 0.2 m vs anchors {distance} m apart",
            s.x_m
        );
        assert!((s.end_a - pa).length() < 1e-12 && (s.end_b - pb).length() < 1e-12);
        seen = (seen.0.min(s.x_m), seen.1.max(s.x_m));
    }
    assert!(
        seen.1 - seen.0 > 0.01,
        "the arm moved: stroke range {seen:?}"
    );
}

#[test]
fn an_anchored_pneumatic_cylinder_lifts_the_arm_to_where_its_full_force_balances_the_load() {
    // Valve fully open (u = 1): chamber A at supply, B at the atmosphere, so at rest
    // F = p_s S_a − p_atm S_b − p_atm S_rod = (p_s − p_atm) S_a.
    let act = cylinder(0.016, 0.2, 2.8e5);
    let f_static = (2.8e5 - P_ATM) * act.cylinder.area_a();
    let theta_star = rest_angle(f_static);
    let mut m = Mechanism::from_urdf(urdf("lever.urdf"), &lever_config()).unwrap();
    let mut el = PneumaticForceElement::new(act, ChamberState::new(P_ATM, P_ATM), 4);
    el.set_command(1.0);
    for _ in 0..15_000 {
        m.step(&mut [&mut el as &mut dyn AxialActuator]);
    }
    let (theta, _) = m.joint_position("elbow").unwrap();
    assert!(
        (theta - theta_star).abs() < 5e-3,
        "angle {theta} rad, closed form {theta_star} rad at F = {f_static} N"
    );
    assert!((m.actuator_force(0) - f_static).abs() < 0.01 * f_static);
}

// ---- the gripper -----------------------------------------------------------------------------------

const FOAM: ContactParams = ContactParams {
    stiffness_n_per_m: 2.0e3,
    damping_n_s_per_m: 5.0,
};
const RUBBER: ContactParams = ContactParams {
    stiffness_n_per_m: 2.0e4,
    damping_n_s_per_m: 10.0,
};

fn gripper_config() -> MechanismConfig {
    let finger = |name: &str, joint: &str| ActuatorConfig {
        name: name.into(),
        mount: Mount::Joint {
            joint: joint.into(),
        },
    };
    let pad = |name: &str, finger: &str| ContactConfig {
        name: name.into(),
        link_a: finger.into(),
        link_b: "object".into(),
        stiffness_n_per_m: FOAM.stiffness_n_per_m,
        damping_n_s_per_m: FOAM.damping_n_s_per_m,
    };
    MechanismConfig::new(
        vec![finger("left", "left_slide"), finger("right", "right_slide")],
        vec![
            pad("left_pad", "finger_left"),
            pad("right_pad", "finger_right"),
        ],
    )
}

#[test]
fn a_gripper_squeezes_the_object_with_its_cylinders_force_on_both_sides() {
    // Both cylinders fully open: each finger presses with (p_s − p_atm) S_a; the object, free on its slide,
    // is held between two equal forces, and each pad is compressed by F / k.
    let act = cylinder(0.010, 0.05, 4.0e5);
    let f_static = (4.0e5 - P_ATM) * act.cylinder.area_a();
    let mut m = Mechanism::from_urdf(urdf("gripper.urdf"), &gripper_config()).unwrap();
    let mut left = PneumaticForceElement::new(act, ChamberState::new(P_ATM, P_ATM), 4);
    let mut right = left.clone();
    left.set_command(1.0);
    right.set_command(1.0);
    let (lp, rp) = (
        m.contact_index("left_pad").unwrap(),
        m.contact_index("right_pad").unwrap(),
    );
    for (material, run_steps) in [(FOAM, 3000), (RUBBER, 3000)] {
        m.set_contact(lp, material).unwrap();
        m.set_contact(rp, material).unwrap();
        for _ in 0..run_steps {
            m.step(&mut [
                &mut left as &mut dyn AxialActuator,
                &mut right as &mut dyn AxialActuator,
            ]);
        }
        let (l, r) = (m.contact(lp), m.contact(rp));
        for (side, c) in [("left", l), ("right", r)] {
            assert!(
                (c.force_n - f_static).abs() < 0.01 * f_static,
                "{side} squeeze {} N, closed form (p_s − p_atm) S_a = {f_static} N",
                c.force_n
            );
            let depth = f_static / material.stiffness_n_per_m;
            assert!(
                (c.penetration_m - depth).abs() < 0.01 * depth,
                "{side} pad compressed {} m, F/k = {depth} m",
                c.penetration_m
            );
        }
        // Symmetric fingers: equal strokes and forces, the object centred.
        let (xl, xr) = (m.actuator_state(0).x_m, m.actuator_state(1).x_m);
        assert!((xl - xr).abs() < 1e-5, "finger strokes {xl} m and {xr} m");
        assert!((l.force_n - r.force_n).abs() < 1e-3 * f_static);
        let (y, _) = m.joint_position("object_slide").unwrap();
        assert!(y.abs() < 1e-5, "object off centre by {y} m");
        // First touch at a stroke of 0.03 m (URDF): the stroke is that plus the pad's compression.
        assert!((xl - (0.03 + f_static / material.stiffness_n_per_m)).abs() < 1e-4);
    }
}

#[test]
fn a_gripper_with_unequal_forces_pushes_the_object_to_the_weaker_side() {
    let mut m = Mechanism::from_urdf(urdf("gripper.urdf"), &gripper_config()).unwrap();
    for _ in 0..3000 {
        m.step_with_forces(&[12.0, 8.0]);
    }
    // Net 4 N towards +y: the object slides until the left finger reaches its end stop (stroke 0.05 m,
    // pad face at y = 0); the stop takes 4 N, both pads then carry the right finger's 8 N, each compressed
    // 8 N / k, so the object's left face sits at −8/k and its centre at 0.02 − 8/k.
    let k = FOAM.stiffness_n_per_m;
    let (y, _) = m.joint_position("object_slide").unwrap();
    assert!((y - (0.02 - 8.0 / k)).abs() < 1e-4, "object at {y} m");
    assert!((m.actuator_state(0).x_m - 0.05).abs() < 1e-4);
    for pad in ["left_pad", "right_pad"] {
        let f = m.contact(m.contact_index(pad).unwrap()).force_n;
        assert!((f - 8.0).abs() < 0.08, "{pad}: {f} N");
    }
}

// ---- two cylinders in antagonism --------------------------------------------------------------------

const LIFT_CLEVIS: [f64; 3] = [0.1, 0.0, -0.3];
const LIFT_EYE: [f64; 3] = [0.0, 0.0, -0.05];
const PRESS_CLEVIS: [f64; 3] = [-0.1, 0.0, 0.3];
const PRESS_EYE: [f64; 3] = [0.0, 0.0, 0.05];

fn antagonist_config() -> MechanismConfig {
    let anchored = |name: &str, clevis: [f64; 3], eye: [f64; 3]| ActuatorConfig {
        name: name.into(),
        mount: Mount::Anchors {
            link_a: "base".into(),
            point_a_m: clevis,
            link_b: "carriage".into(),
            point_b_m: eye,
            retracted_length_m: 0.2,
            stroke_m: 0.15,
        },
    };
    MechanismConfig::new(
        vec![
            anchored("lift", LIFT_CLEVIS, LIFT_EYE),
            anchored("press", PRESS_CLEVIS, PRESS_EYE),
        ],
        vec![],
    )
}

#[test]
fn two_closed_cylinders_in_antagonism_hold_the_carriage_where_their_forces_balance_its_weight() {
    // Both valves closed: each cylinder is a polytropic gas spring p V^n = const (eqs. (5)-(6)). At rest
    // along the slide: F_lift(z) n_lift,z + F_press(z) n_press,z = m g.
    let act = cylinder(0.016, 0.15, 6.0e5);
    let (pa0, pb0) = (3.0e5, 1.5e5);
    let mut m = Mechanism::from_urdf(urdf("antagonist.urdf"), &antagonist_config()).unwrap();
    let x0 = [m.actuator_state(0).x_m, m.actuator_state(1).x_m];
    let n = act.gas.polytropic_exponent;
    let c = act.cylinder;
    let gas_spring = |x: f64, x0: f64| {
        let ((va, vb), (va0, vb0)) = (c.volumes(x), c.volumes(x0));
        pa0 * (va0 / va).powf(n) * c.area_a()
            - pb0 * (vb0 / vb).powf(n) * c.area_b()
            - P_ATM * c.area_rod()
    };
    let along_slide = |z: f64| {
        let line = |clevis: [f64; 3], eye: [f64; 3]| {
            let d = [
                eye[0] - clevis[0],
                eye[1] - clevis[1],
                eye[2] + z - clevis[2],
            ];
            let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            (len - 0.2, d[2] / len)
        };
        let (x_lift, up) = line(LIFT_CLEVIS, LIFT_EYE);
        let (x_press, down) = line(PRESS_CLEVIS, PRESS_EYE);
        gas_spring(x_lift, x0[0]) * up + gas_spring(x_press, x0[1]) * down - 2.0 * STANDARD_GRAVITY
    };
    let z_star = root(along_slide, -0.05, 0.05);
    let mut lift = PneumaticForceElement::new(act, ChamberState::new(pa0, pb0), 4);
    let mut press = lift.clone();
    lift.set_command(0.0);
    press.set_command(0.0);
    for _ in 0..8000 {
        m.step(&mut [
            &mut lift as &mut dyn AxialActuator,
            &mut press as &mut dyn AxialActuator,
        ]);
    }
    let (z, v) = m.joint_position("slide").unwrap();
    assert!(
        (z - z_star).abs() < 2e-4,
        "carriage at {z} m, closed form {z_star} m"
    );
    assert!(v.abs() < 1e-4);
    assert!(z_star < -1e-3, "the weight sinks the carriage: {z_star}");
    // The cylinders' own forces, resolved along the slide, carry the weight.
    let s = [m.actuator_state(0), m.actuator_state(1)];
    let along = m.actuator_force(0) * s[0].axis.z + m.actuator_force(1) * s[1].axis.z;
    assert!((along - 2.0 * STANDARD_GRAVITY).abs() < 0.01 * 2.0 * STANDARD_GRAVITY);
}

// ---- bad input ---------------------------------------------------------------------------------------

fn error_of(file: &str, config: &MechanismConfig) -> String {
    match Mechanism::from_urdf(urdf(file), config) {
        Ok(_) => panic!("{file}: accepted"),
        Err(e) => e.to_string(),
    }
}

fn with_anchors(f: impl FnOnce(&mut Mount)) -> MechanismConfig {
    let mut c = lever_config();
    f(&mut c.actuators[0].mount);
    c
}

#[test]
fn every_new_key_refuses_bad_input_naming_the_file_the_item_and_the_key() {
    let set_anchor = |k: &str, v: &str| {
        with_anchors(|m| {
            if let Mount::Anchors {
                link_a,
                link_b,
                point_a_m,
                retracted_length_m,
                stroke_m,
                ..
            } = m
            {
                match k {
                    "link_a" => *link_a = v.into(),
                    "link_b" => *link_b = v.into(),
                    "point_a" => point_a_m[1] = f64::NAN,
                    "retracted_length" => *retracted_length_m = v.parse().unwrap(),
                    "stroke" => *stroke_m = v.parse().unwrap(),
                    _ => unreachable!(),
                }
            }
        })
    };
    let cases: Vec<(&str, MechanismConfig, &[&str])> = vec![
        (
            "lever.urdf",
            set_anchor("link_a", "plinth"),
            &[
                "lever.urdf",
                "actuator 'elbow_cylinder'",
                "`link_a`",
                "'plinth'",
            ],
        ),
        (
            "lever.urdf",
            set_anchor("link_b", "base"),
            &["`link_b`", "one rigid body"],
        ),
        (
            "lever.urdf",
            set_anchor("point_a", ""),
            &["`point_a`", "finite"],
        ),
        (
            "lever.urdf",
            set_anchor("retracted_length", "0.3"),
            &[
                "`retracted_length`",
                "apart in the URDF's zero configuration",
            ],
        ),
        (
            "lever.urdf",
            set_anchor("stroke", "-1"),
            &["`stroke`", "> 0"],
        ),
        (
            "lever.urdf",
            set_anchor("retracted_length", "NaN"),
            &["`retracted_length`", "finite"],
        ),
        (
            "lever.urdf",
            {
                let mut c = lever_config();
                c.actuators[0].mount = Mount::Joint {
                    joint: "elbow".into(),
                };
                c
            },
            &[
                "actuator 'elbow_cylinder'",
                "`joint`",
                "must be a prismatic joint",
            ],
        ),
        (
            "gripper.urdf",
            {
                let mut c = gripper_config();
                c.actuators[1].mount = Mount::Joint {
                    joint: "thumb_slide".into(),
                };
                c
            },
            &[
                "actuator 'right'",
                "`joint`",
                "no joint named 'thumb_slide'",
            ],
        ),
        (
            "gripper.urdf",
            {
                let mut c = gripper_config();
                c.actuators[1].name = "left".into();
                c
            },
            &["actuator 'left'", "`name`", "listed twice"],
        ),
        (
            "gripper.urdf",
            {
                let mut c = gripper_config();
                c.contacts[0].link_a = "palm".into();
                c
            },
            &["contact 'left_pad'", "`link_a`", "no <collision>"],
        ),
        (
            "gripper.urdf",
            {
                let mut c = gripper_config();
                c.contacts[1].stiffness_n_per_m = 0.0;
                c
            },
            &["contact 'right_pad'", "`stiffness`", "> 0"],
        ),
        (
            "gripper.urdf",
            {
                let mut c = gripper_config();
                c.contacts[1].damping_n_s_per_m = f64::NAN;
                c
            },
            &["contact 'right_pad'", "`damping`"],
        ),
        (
            "gripper.urdf",
            {
                let mut c = gripper_config();
                c.contacts[1].link_b = "finger_right".into();
                c
            },
            &["contact 'right_pad'", "`link_b`", "one rigid body"],
        ),
    ];
    for (file, config, wanted) in cases {
        let msg = error_of(file, &config);
        for w in wanted {
            assert!(msg.contains(w), "{msg:?} lacks {w:?}");
        }
    }
    // Settings and events.
    let mut c = gripper_config();
    c.gravity_m_s2[2] = f64::INFINITY;
    assert!(error_of("gripper.urdf", &c).contains("gravity_m_s2"));
    let mut m = Mechanism::from_urdf(urdf("gripper.urdf"), &gripper_config()).unwrap();
    let e = m
        .set_contact(
            0,
            ContactParams {
                stiffness_n_per_m: -1.0,
                damping_n_s_per_m: 0.0,
            },
        )
        .unwrap_err();
    assert!(
        matches!(
            e,
            MultibodyError::BadMechanism {
                key: "stiffness",
                ..
            }
        ),
        "{e}"
    );
    let e = m.contact_index("thumb_pad").unwrap_err().to_string();
    assert!(e.contains("left_pad, right_pad"), "{e}");
}
