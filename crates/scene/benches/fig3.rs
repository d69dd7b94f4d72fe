//! Simulating both runs of paper-fig3 (no figures, no files): target <= 50 ms on the pneumatic plant.

use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use pneuflex_scene::{Scene, run_scene};

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
}

criterion_group!(benches, bench);
criterion_main!(benches);
