//! The coupled multibody scene (Rapier + pneumatic force element + adaptive controller):
//! - `tick/adaptive`: one control tick (sense, adaptive update, actuate, advance = physics steps per tick)
//!   of `paper-fig7-wood-to-iron` in steady contact on wood; steps/s = steps_per_tick / time per tick;
//! - `paper-fig7-wood-to-iron/both-runs`: the whole scene (both controllers, no files), from which the
//!   real-time factor is 2 · duration_s / time.
//!
//! Run: `cargo bench -p pneuflex-scene --bench multibody -- --warm-up-time 1 --measurement-time 3`.

use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use pneuflex_control::Controller;
use pneuflex_scene::{MultibodyPlant, Plant, Scene, run_scene};

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
    let setpoints = scene.setpoints().unwrap_or_else(|e| panic!("{e}"));

    let mut plant = MultibodyPlant::from_scene(&scene).unwrap_or_else(|e| panic!("{e}"));
    let mut ctrl: Box<dyn Controller> =
        scene.controller(adaptive).unwrap_or_else(|e| panic!("{e}"));
    let dt = scene.dt_s;
    // Settle into steady contact on wood first (1 s).
    let mut t = 0.0;
    let tick = |plant: &mut MultibodyPlant, ctrl: &mut dyn Controller, t: &mut f64| {
        let mut s = plant.sense();
        s.t = *t;
        let cmd = ctrl.update(&s, &setpoints.at(*t), dt);
        let tel = ctrl.telemetry();
        plant.actuate(cmd, &tel);
        plant.advance(dt);
        *t += dt;
    };
    for _ in 0..(1.0 / dt) as usize {
        tick(&mut plant, ctrl.as_mut(), &mut t);
    }
    eprintln!(
        "multibody bench: physics dt = {} s, {} steps per {} s tick",
        plant.config().dt_s,
        plant.steps_per_tick(),
        dt
    );
    let mut g = c.benchmark_group("multibody");
    g.bench_function("tick/adaptive", |b| {
        b.iter(|| tick(&mut plant, ctrl.as_mut(), &mut t))
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
