//! Simulating both runs of paper-fig3 (no figures, no files): target <= 50 ms on the pneumatic plant; and
//! one control tick of its plant.

use std::path::Path;

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use pneuflex_control::{Telemetry, ValveCommand};
use pneuflex_scene::{LinearSpring, OneDofPneumatic, Plant, Scene, run_scene};

fn load(name: &str) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(name);
    Scene::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("paper-fig3");
    g.sample_size(10);
    for file in ["paper-fig3.toml", "paper-fig3-ideal.toml"] {
        let scene = load(file);
        g.bench_function(file, |b| {
            b.iter(|| run_scene(&scene, &mut |_| {}).unwrap_or_else(|e| panic!("{e}")))
        });
    }
    g.finish();
    // One control tick of the 1-DOF plant (1 ms, the scene's 10 RK4 substeps) under a command that changes
    // every tick, as the Gymnasium task steps it (docs/gymnasium.md): the cost of one env-step's physics.
    let scene = load("paper-fig3.toml");
    let env = LinearSpring {
        stiffness_n_per_m: 700.0,
        x_e_m: 0.02,
    };
    let mut plant = OneDofPneumatic::from_scene(&scene, env).unwrap_or_else(|e| panic!("{e}"));
    let mut k = 0u64;
    c.bench_function("paper-fig3 plant tick", |b| {
        b.iter(|| {
            // A command in [-0.2, 0.2] that keeps the valve switching and the flange on the spring.
            k = k
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = 0.4 * ((k >> 11) as f64 / (1u64 << 53) as f64) - 0.2;
            plant.actuate(ValveCommand { u }, &Telemetry::default());
            plant.advance(black_box(0.001));
            if plant.state().t > 10.0 {
                plant.reset();
            }
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
