//! Steps per second of the rig world (Rapier: the flange and the face in front of it dynamic, the carriage
//! kinematic, one contact; the other faces are out of the simulation while the carriage rests), and
//! of Rapier's floor: the scene of the MuJoCo anchor (2 bodies on slide joints, one contact) built
//! directly in Rapier, with nothing of this crate in the loop.
//! The bare gripper (`gripper_bare_*`): urdf/gripper.urdf's three slides as the engine builds them, no pads,
//! constant cylinder forces, nothing else: the engine's floor on the scene issue 42 times against MuJoCo's
//! bare `mj_step` (`crossval.bench_mechanism`).
//! `cargo bench -p pneuflex-multibody --bench step -- --warm-up-time 1 --measurement-time 4`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use pneuflex_multibody::{
    ActuatorConfig, AxialActuator, CarriageRig, Mechanism, MechanismConfig, Mount, RigConfig,
    SpringActuator,
};
use rapier3d_f64::prelude::*;

fn rig(dt: f64, iterations: usize) -> CarriageRig {
    let mut cfg = RigConfig::paper_rig();
    cfg.dt_s = dt;
    cfg.solver_iterations = iterations;
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../urdf/rig.urdf");
    CarriageRig::from_urdf(path, &cfg).expect("rig builds")
}

fn spring() -> SpringActuator {
    // Holds the flange pressed ~10 N into the wood (set point beyond the contact).
    SpringActuator {
        stiffness_n_per_m: 500.0,
        damping_n_s_per_m: 0.0,
        set_x_m: 0.055,
    }
}

fn bench_step(c: &mut Criterion) {
    for (name, dt, it) in [
        ("step_spring_in_contact_dt1ms_it4", 1e-3, 4),
        ("step_spring_in_contact_dt1ms_it2", 1e-3, 2),
        ("step_spring_in_contact_dt1ms_it1", 1e-3, 1),
        ("step_spring_in_contact_dt100us_it4", 1e-4, 4),
    ] {
        let mut w = rig(dt, it);
        let mut act = spring();
        for _ in 0..(1.0 / dt) as usize {
            w.step(&mut act);
        }
        assert!(w.measurements().contact, "bench runs in contact");
        c.bench_function(name, |b| {
            b.iter(|| black_box(w.step(black_box(&mut act as &mut dyn AxialActuator))))
        });
    }
}

/// The anchor scene in plain Rapier: a 0.6 kg flange on a prismatic joint (stroke limits, K_v = 20 N·s/m)
/// pushed by 10 N into a 9 g face on a 700 N/m, 2 N·s/m prismatic mount; rigid contact, dt = 1 ms. Gravity
/// is the rig's at 30°, so the flange presses with ~12.9 N (10 N + m g sin 30°).
fn anchor_world(iterations: usize) -> (PhysicsWorld, RigidBodyHandle) {
    let mut w = PhysicsWorld::new();
    w.gravity = Vector::new(4.9, -8.5, 0.0);
    let ip = &mut w.integration_parameters;
    ip.dt = 1e-3;
    ip.num_solver_iterations = iterations;
    ip.contact_softness = SpringCoefficients::new(1.0e6, 1.0);
    ip.max_ccd_substeps = 0;
    let base = w.insert_body(RigidBodyBuilder::fixed().can_sleep(false));
    // A 10 mm x 40 mm x 40 mm box of `mass` at x on a prismatic joint along x to the base, whose
    // force-based motor is the spring-damper (k, c) about that x.
    let mut slider = |x: f64, mass: f64, k: f64, c: f64, limits: Option<[f64; 2]>| {
        let body = w.insert_body(
            RigidBodyBuilder::dynamic()
                .translation(Vector::new(x, 0.0, 0.0))
                .can_sleep(false),
        );
        w.insert_collider(
            ColliderBuilder::cuboid(0.005, 0.02, 0.02).mass(mass),
            Some(body),
        );
        let mut j = GenericJointBuilder::new(JointAxesMask::LOCKED_PRISMATIC_AXES)
            .contacts_enabled(false)
            .local_anchor1(Vector::new(x, 0.0, 0.0))
            .build();
        j.set_motor_model(JointAxis::LinX, MotorModel::ForceBased);
        j.set_motor(JointAxis::LinX, 0.0, 0.0, k, c);
        if let Some(l) = limits {
            j.set_limits(JointAxis::LinX, l);
        }
        w.insert_impulse_joint(base, body, j);
        body
    };
    let flange = slider(0.02, 0.6, 0.0, 20.0, Some([-0.02, 0.03]));
    slider(0.0301, 0.009, 700.0, 2.0, None);
    (w, flange)
}

fn bench_anchor(c: &mut Criterion) {
    for it in [1, 2, 4] {
        let (mut w, flange) = anchor_world(it);
        let mut step = move || {
            let b = &mut w.bodies[flange];
            b.reset_forces(false);
            b.add_force(Vector::new(10.0, 0.0, 0.0), true);
            w.step();
            w.narrow_phase
                .contact_pairs()
                .filter(|p| p.has_any_active_contact())
                .count()
        };
        for _ in 0..1000 {
            step();
        }
        assert_eq!(step(), 1, "the anchor scene runs in contact");
        c.bench_function(&format!("anchor_plain_rapier_dt1ms_it{it}"), |b| {
            b.iter(|| black_box(step()))
        });
    }
}

fn bench_gripper_bare(c: &mut Criterion) {
    let urdf = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../urdf/gripper.urdf");
    let finger = |name: &str, joint: &str| ActuatorConfig {
        name: name.into(),
        mount: Mount::Joint {
            joint: joint.into(),
        },
    };
    for it in [1, 2] {
        let mut config = MechanismConfig::new(
            vec![finger("left", "left_slide"), finger("right", "right_slide")],
            Vec::new(),
        );
        config.solver_iterations = it;
        let mut m = Mechanism::from_urdf(&urdf, &config).expect("the gripper builds");
        for _ in 0..1000 {
            m.step_with_forces(&[1.0, 1.0]);
        }
        c.bench_function(&format!("gripper_bare_dt1ms_it{it}"), |b| {
            b.iter(|| m.step_with_forces(black_box(&[1.0, 1.0])))
        });
    }
}

criterion_group!(benches, bench_step, bench_anchor, bench_gripper_bare);
criterion_main!(benches);
