//! A custom sink: something that watches every tick of a run without changing it — here a valve-wear
//! meter (how often the valve command reverses, and the travel the spool makes) and the peak contact
//! force, for each run of scenes/paper-fig3.toml.
//!
//! Files touched in the library to add it: none. A sink implements `pneuflex::control::Sink`; its rows
//! are the loop's columns as the run declares them in `begin` (`LOOP_SIGNALS`, then the controller's and
//! the plant's own), so the same sink watches a simulated run (`run_scene_observed`) and a run on the real
//! rig (`rig::rtloop`), which hands it `()` as the world.
//!
//! `cargo run --example custom_sink`

use std::path::Path;

use pneuflex::control::signal::index;
use pneuflex::control::{Signal, Sink};
use pneuflex::scene::{Scene, run_scene_observed};

#[derive(Default)]
struct ValveWear {
    run: String,
    last_u: Option<f64>,
    reversals: u64,
    travel: f64,
    peak_force_n: f64,
    ticks: u64,
    /// (run, reversals, travel, peak force, ticks) of each finished run.
    done: Vec<(String, u64, f64, f64, u64)>,
}

impl<W: ?Sized> Sink<W> for ValveWear {
    fn begin(&mut self, run: &str, columns: &[Signal], _world: &W) {
        // The loop's own columns come first, at their fixed places.
        assert_eq!(columns[index::U].name, "u");
        *self = Self {
            run: run.to_string(),
            done: std::mem::take(&mut self.done),
            ..Self::default()
        };
    }

    fn row(&mut self, values: &[f64], _world: &W) {
        let u = values[index::U];
        if let Some(last) = self.last_u {
            // A reversal is a change of the command's sign (through or across zero).
            if last * u < 0.0 {
                self.reversals += 1;
            }
            self.travel += (u - last).abs();
        }
        self.last_u = Some(u);
        self.peak_force_n = self.peak_force_n.max(values[index::F_E]);
        self.ticks += 1;
    }

    fn end(&mut self, why: Option<&str>) {
        if let Some(why) = why {
            println!("run {} ended early: {why}", self.run);
        }
        self.done.push((
            self.run.clone(),
            self.reversals,
            self.travel,
            self.peak_force_n,
            self.ticks,
        ));
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/paper-fig3.toml"
    ));
    let scene = Scene::load(path)?;
    let mut wear = ValveWear::default();
    let results = run_scene_observed(&scene, &mut |_| {}, &mut wear)?;
    println!("{}: valve wear and peak force per run", scene.name);
    for ((run, reversals, travel, peak, ticks), r) in wear.done.iter().zip(&results) {
        // The sink saw every tick the trace holds: it watched the run, it did not change it.
        assert_eq!(*ticks as usize, r.trace.t().len(), "run {run}");
        println!(
            "  {run:<13} {reversals:>6} reversals, travel {travel:>8.1} (command units), peak f_e {peak:>6.2} N over {ticks} ticks"
        );
    }
    Ok(())
}
