//! Time the product's control tick (`pneuflex_scene::time_ticks`: the one loop with its simulation host —
//! sense, controller, actuate, trace, checks, advance) of one run of a scene, after
//! `settle_s` of untimed ticks, as `scripts/bench` does through the Python bindings but without Python:
//! for interleaved before/after comparisons of two builds (docs/performance.md).
//!
//!     cargo run --release -p pneuflex-scene --example tick_rate -- SCENE RUN TICKS [SETTLE_S]
//!
//! Prints one line: `us_per_tick <value>` (wall time of the TICKS ticks / TICKS).

use pneuflex_scene::{Scene, time_ticks};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        eprintln!("usage: tick_rate SCENE RUN TICKS [SETTLE_S]");
        std::process::exit(2);
    }
    let scene = Scene::load(std::path::Path::new(&args[1])).unwrap_or_else(|e| panic!("{e}"));
    let run = scene.run_index(&args[2]).unwrap_or_else(|e| panic!("{e}"));
    let ticks: u64 = args[3].parse().expect("TICKS: a whole number");
    let settle_s: f64 = args
        .get(4)
        .map_or(1.0, |s| s.parse().expect("SETTLE_S: seconds"));
    // The product's loop (host, trace, checks), as `pneuflex run` runs it.
    let timing = time_ticks(&scene, run, ticks, settle_s).unwrap_or_else(|e| panic!("{e}"));
    println!(
        "us_per_tick {:.4} mean_f_e {:.4}",
        timing.wall.as_secs_f64() / timing.ticks as f64 * 1e6,
        timing.mean_f_e_n
    );
}
