//! The per-point cost of a sweep split into its parts (scripts/bench_sweep, docs/sweeps.md "Performance"):
//! building the point's scene (edit the TOML text, parse, validate), building the plants (sheets, URDF),
//! simulating, and making the table row; medians over the points, one thread.
//!
//!     cargo run --release -p pneuflex-sweep --example sweep_overhead -- SCENE [POINTS]

use std::path::Path;
use std::time::Instant;

use pneuflex_sweep::{SetArg, Sweep};

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let mut args = std::env::args().skip(1);
    let scene = args.next().expect("usage: sweep_overhead SCENE [POINTS]");
    let n: usize = args.next().map_or(9, |s| s.parse().expect("POINTS"));
    // A key every scene has and whose value barely matters: each point is a full scene run.
    let set = SetArg::parse(&format!("runs[*].impedance.b_d_ns_per_m=lin:52:53:{n}")).unwrap();
    let t = Instant::now();
    let sweep = Sweep::new(
        Path::new(&scene),
        &[set],
        None,
        0,
        pneuflex_sweep::points::DEFAULT_MAX_POINTS,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let check_s = t.elapsed().as_secs_f64();
    let (mut build, mut plants, mut sim, mut rows) = (vec![], vec![], vec![], vec![]);
    for i in 0..n {
        let t0 = Instant::now();
        let any = sweep.scene_at(i).unwrap();
        let scene = any.one().expect("a one-actuator scene");
        let t1 = Instant::now();
        // The plants' construction is inside run_scene (one per run): timed apart and counted as loading.
        for _ in &scene.runs {
            let _ = pneuflex_scene::build_plant(scene).unwrap();
        }
        let t2 = Instant::now();
        let results = pneuflex_scene::run_scene(scene, &mut |_| {}).unwrap();
        let t3 = Instant::now();
        let r: Vec<_> = results.iter().map(|r| sweep.row_of(&any, r)).collect();
        let text = sweep.rows(&pneuflex_sweep::PointResult { index: i, runs: r });
        let t4 = Instant::now();
        std::hint::black_box(text);
        build.push((t1 - t0).as_secs_f64());
        let p = (t2 - t1).as_secs_f64();
        plants.push(p);
        // run_scene builds the plants again: the simulation proper is its time less that.
        sim.push((t3 - t2).as_secs_f64() - p);
        rows.push((t4 - t3).as_secs_f64());
    }
    let (b, p, s, r) = (
        median(&mut build),
        median(&mut plants),
        median(&mut sim),
        median(&mut rows),
    );
    let overhead = b + p + r;
    println!(
        "{{\"scene\": \"{scene}\", \"points\": {n}, \"runs\": {}, \"check_all_s\": {check_s:.6}, \
         \"scene_build_s\": {b:.6}, \"plant_build_s\": {p:.6}, \"simulate_s\": {s:.6}, \"row_s\": {r:.6}, \
         \"overhead_pct\": {:.3}}}",
        sweep.base_scene.runs().len(),
        100.0 * overhead / s
    );
}
