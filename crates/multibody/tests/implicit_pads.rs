//! Pads implicit in their own stiffness and damping (`PadIntegration::Implicit`, docs/multibody.md
//! "Pads at the control step"): the gripper's two fingers pushed into the object by a constant force.

use std::path::{Path, PathBuf};

use pneuflex_multibody::{
    ActuatorConfig, ContactConfig, Mechanism, MechanismConfig, Mount, PadIntegration,
};

fn urdf() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../urdf/gripper.urdf")
}

/// The gripper with both pads at (k, c), each finger 2 mm from the object, stepped at `dt`.
fn gripper(k: f64, c: f64, pads: PadIntegration, dt: f64) -> Mechanism {
    let finger = |name: &str, joint: &str| ActuatorConfig {
        name: name.into(),
        mount: Mount::Joint {
            joint: joint.into(),
        },
    };
    let pad = |name: &str, link: &str| ContactConfig {
        name: name.into(),
        link_a: link.into(),
        link_b: "object".into(),
        stiffness_n_per_m: k,
        damping_n_s_per_m: c,
    };
    let mut config = MechanismConfig::new(
        vec![finger("left", "left_slide"), finger("right", "right_slide")],
        vec![
            pad("left_pad", "finger_left"),
            pad("right_pad", "finger_right"),
        ],
    );
    config.pad_integration = pads;
    config.dt_s = dt;
    config.solver_iterations = 2;
    config.initial_positions = vec![("left_slide".into(), 0.028), ("right_slide".into(), 0.028)];
    Mechanism::from_urdf(urdf(), &config).expect("the gripper builds")
}

/// The left pad's force and penetration every `every` s over `duration` s, both fingers pushed with
/// `force` N.
fn squeeze(m: &mut Mechanism, force: f64, duration: f64, every: f64) -> Vec<(f64, f64)> {
    let steps = (duration / m.dt()).round() as usize;
    let stride = (every / m.dt()).round() as usize;
    let mut out = Vec::new();
    for i in 1..=steps {
        m.step_with_forces(&[force, force]);
        if i % stride == 0 {
            let c = m.contact(0);
            out.push((c.force_n, c.penetration_m));
        }
    }
    out
}

#[test]
fn an_implicit_pad_holds_a_squeeze_at_f_over_k_on_the_control_step() {
    // 10 N on each finger against rubber (20 kN/m): at rest each pad carries 10 N at 10 / 20e3 = 0.5 mm.
    let mut m = gripper(2.0e4, 10.0, PadIntegration::Implicit, 1.0e-3);
    squeeze(&mut m, 10.0, 1.0, 1.0);
    let (l, r) = (m.contact(0), m.contact(1));
    assert!((l.force_n - 10.0).abs() < 1e-6, "left pad {} N", l.force_n);
    assert!((r.force_n - 10.0).abs() < 1e-6, "right pad {} N", r.force_n);
    assert!(
        (l.penetration_m - 5.0e-4).abs() < 1e-9 && (r.penetration_m - 5.0e-4).abs() < 1e-9,
        "penetrations {} and {} m, F/k = 5e-4 m",
        l.penetration_m,
        r.penetration_m
    );
}

#[test]
fn a_pad_too_stiff_for_the_explicit_step_holds_when_implicit() {
    // 1 MN/m (20 N s/m) on the 0.1 kg finger: ω h = sqrt(1e6 / 0.1) 1e-3 ≈ 3.2 > 2 at 1 ms, past the
    // explicit step's stability. Implicit, it rests at F/k = 10 µm.
    let k = 1.0e6;
    let mut explicit = gripper(k, 20.0, PadIntegration::Explicit, 1.0e-3);
    let trace = squeeze(&mut explicit, 10.0, 0.3, 0.001);
    let worst = trace.iter().map(|t| t.1).fold(0.0, f64::max);
    assert!(
        !worst.is_finite() || worst > 1e-3,
        "the explicit pad at 1 ms should blow up (deepest {worst} m)"
    );
    let mut implicit = gripper(k, 20.0, PadIntegration::Implicit, 1.0e-3);
    squeeze(&mut implicit, 10.0, 0.3, 0.3);
    let c = implicit.contact(0);
    // The solver's sweeps leave 0.2 % on so stiff a pad (mechanism/mod.rs).
    assert!(
        (c.force_n - 10.0).abs() < 1e-3,
        "implicit pad {} N",
        c.force_n
    );
    assert!(
        (c.penetration_m - 1.0e-5).abs() < 1e-7,
        "implicit pad {} m deep, F/k = 1e-5 m",
        c.penetration_m
    );
}

#[test]
fn an_implicit_pad_converges_to_the_explicit_one_as_the_step_halves() {
    // The fingers close 2 mm onto foam (2 kN/m, 5 N s/m) and ring down. Reference: the explicit pad at
    // 1/64 ms. The implicit pad's penetration, sampled every ms over 0.3 s, approaches it as its step
    // halves (RMS difference).
    let reference = squeeze(
        &mut gripper(2.0e3, 5.0, PadIntegration::Explicit, 1.0e-3 / 64.0),
        10.0,
        0.3,
        1.0e-3,
    );
    let error = |dt: f64| {
        let t = squeeze(
            &mut gripper(2.0e3, 5.0, PadIntegration::Implicit, dt),
            10.0,
            0.3,
            1.0e-3,
        );
        let sq: f64 = t
            .iter()
            .zip(&reference)
            .map(|(a, b)| (a.1 - b.1).powi(2))
            .sum();
        (sq / t.len() as f64).sqrt()
    };
    let errors: Vec<f64> = [1.0e-3, 0.5e-3, 0.25e-3, 0.125e-3]
        .iter()
        .map(|&dt| error(dt))
        .collect();
    println!("RMS of δ - δ_ref at 1, 0.5, 0.25, 0.125 ms: {errors:?} m");
    for w in errors.windows(2) {
        assert!(
            w[1] < 0.7 * w[0],
            "the error must fall as the step halves: {errors:?}"
        );
    }
    // The squeeze is 5 mm deep: within 1 % of it at 0.125 ms.
    assert!(
        errors[3] < 5.0e-5,
        "at 0.125 ms within 50 µm of the reference: {errors:?}"
    );
}
