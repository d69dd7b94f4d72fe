//! Steps per second of the rig world (Rapier, 3 dynamic bodies + a kinematic carriage, one contact).
//! `cargo bench -p pneuflex-multibody --bench step -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use pneuflex_multibody::{AxialActuator, MultibodyConfig, RigWorld, SpringActuator};

fn rig(dt: f64, iterations: usize) -> RigWorld {
    let mut cfg = MultibodyConfig::paper_rig();
    cfg.dt_s = dt;
    cfg.solver_iterations = iterations;
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../urdf/rig.urdf");
    RigWorld::from_urdf(path, &cfg).expect("rig builds")
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

criterion_group!(benches, bench_step);
criterion_main!(benches);
