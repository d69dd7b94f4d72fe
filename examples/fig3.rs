//! The paper's Fig. 3 from Rust: impedance vs adaptive impedance control on the 1-DOF pneumatic plant,
//! 10 N step then a 1 Hz sine, environment stiffness 700 → 1400 N/m at 6 s.
//!
//! `cargo run --example fig3 [-- scenes/other.toml]`. `pneuflex run` does the same and also writes
//! trace.csv, summary.json and the figures.

use std::path::PathBuf;

use pneuflex::scene::{Scene, run_scene};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // The shipped scene, found from the repository root wherever the example is started.
    let path = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/scenes/paper-fig3.toml"
            ))
        });
    let scene = Scene::load(&path)?;
    // Every run the scene lists, each on a fresh plant; the closure receives the progress in [0, 1].
    let runs = run_scene(&scene, &mut |_| {})?;

    println!("{}\nRMS force error, N:", scene.description);
    print!("{:<24}", "window");
    runs.iter().for_each(|r| print!("{:>14}", r.name));
    println!();
    for w in &scene.metrics {
        print!("{:<24}", format!("{} {}-{} s", w.name, w.t0_s, w.t1_s));
        for r in &runs {
            // A diverged run has no metrics.
            match r.window(&w.name) {
                Some(m) => print!("{:>14.3}", m.rms_force_error_n),
                None => print!("{:>14}", "-"),
            }
        }
        println!();
    }
    Ok(())
}
