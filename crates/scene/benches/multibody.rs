//! The coupled multibody scene (Rapier + pneumatic force element + adaptive controller):
//! - `tick/adaptive`: one control tick (sense, adaptive update, actuate, advance = physics steps per tick)
//!   of `paper-fig7-wood-to-iron` in steady contact on wood; steps/s = steps_per_tick / time per tick;
//! - `paper-fig7-wood-to-iron/both-runs`: the whole scene (both controllers, no files), from which the
//!   real-time factor is 2 · duration_s / time.
//!
//! Run: `cargo bench -p pneuflex-scene --bench multibody -- --warm-up-time 1 --measurement-time 3`.

use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use pneuflex_scene::{MultibodyPlant, Scene, run_scene, time_ticks};

fn load(name: &str) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(name);
    Scene::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

fn bench(c: &mut Criterion) {
    let scene = load("paper-fig7-wood-to-iron.toml");
    let adaptive = scene
        .runs
        .iter()
        .position(|r| r.name == "adaptive")
        .expect("the fig7 scene has an adaptive run");
    let plant = MultibodyPlant::from_scene(&scene).unwrap_or_else(|e| panic!("{e}"));
    eprintln!(
        "multibody bench: physics dt = {} s, {} steps per {} s tick",
        plant.config().dt_s,
        plant.steps_per_tick(),
        scene.dt_s
    );
    let mut g = c.benchmark_group("multibody");
    // The product's loop (host, trace, checks) after 1 s of settling into steady contact on wood; each
    // sample times `iters` ticks of one run.
    g.bench_function("tick/adaptive", |b| {
        b.iter_custom(|iters| {
            time_ticks(&scene, adaptive, iters, 1.0)
                .unwrap_or_else(|e| panic!("{e}"))
                .wall
        })
    });
    g.finish();

    let mut g = c.benchmark_group("paper-fig7-wood-to-iron");
    g.sample_size(10);
    g.bench_function("both-runs", |b| {
        b.iter(|| run_scene(&scene, &mut |_| {}).unwrap_or_else(|e| panic!("{e}")))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
