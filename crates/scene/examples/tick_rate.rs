//! Time the scene runner's control tick (sense, controller, actuate, advance) of one run of a scene, after
//! `settle_s` of untimed ticks, as `scripts/bench` does through the Python bindings but without Python:
//! for interleaved before/after comparisons of two builds (docs/performance.md).
//!
//!     cargo run --release -p pneuflex-scene --example tick_rate -- SCENE RUN TICKS [SETTLE_S]
//!
//! Prints one line: `us_per_tick <value>` (wall time of the TICKS ticks / TICKS).

use std::time::Instant;

use pneuflex_scene::{Scene, build_plant};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        eprintln!("usage: tick_rate SCENE RUN TICKS [SETTLE_S]");
        std::process::exit(2);
    }
    let scene = Scene::load(std::path::Path::new(&args[1])).unwrap_or_else(|e| panic!("{e}"));
    let run = scene
        .runs
        .iter()
        .position(|r| r.name == args[2])
        .unwrap_or_else(|| panic!("no run {:?}", args[2]));
    let ticks: usize = args[3].parse().expect("TICKS: a whole number");
    let settle_s: f64 = args
        .get(4)
        .map_or(1.0, |s| s.parse().expect("SETTLE_S: seconds"));
    let setpoints = scene.setpoints().unwrap_or_else(|e| panic!("{e}"));
    let mut plant = build_plant(&scene).unwrap_or_else(|e| panic!("{e}"));
    let mut ctrl = scene.controller(run).unwrap_or_else(|e| panic!("{e}"));
    let dt = scene.dt_s;
    let mut t = 0.0;
    let mut tick = |t: &mut f64| {
        let mut s = plant.sense();
        s.t = *t;
        let cmd = ctrl.update(&s, &setpoints.at(*t), dt);
        let tel = ctrl.telemetry();
        plant.actuate(cmd, &tel);
        plant.advance(dt);
        *t += dt;
        s.f_e
    };
    for _ in 0..(settle_s / dt).round() as usize {
        tick(&mut t);
    }
    let t0 = Instant::now();
    let mut sum = 0.0;
    for _ in 0..ticks {
        sum += tick(&mut t);
    }
    let secs = t0.elapsed().as_secs_f64();
    println!(
        "us_per_tick {:.4} mean_f_e {:.4}",
        secs / ticks as f64 * 1e6,
        sum / ticks as f64
    );
}
