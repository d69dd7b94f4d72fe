//! A custom valve model: a proportional valve with a centre overlap (a dead band) and hysteresis in its
//! spool, as real servo-valves have, in front of the scene's actuator — run with each of the scene's
//! controllers on scenes/paper-fig3-proportional.toml and compared with the ideal valve the scene ships.
//!
//! Files touched in the library to add it: none. A valve law is a map from the controller's command to
//! the spool position the chambers see (`pneuflex::pneumatics::Actuator::step_chambers` takes a spool
//! position); here it wraps the scene's own plant (`build_plant`, any plant: 1-DOF or multibody) and changes
//! the command on its way to the scene's proportional valve. A valve with its own flow law would instead be
//! a plant of its own that calls `Actuator::step_chambers` with its spool (examples/custom_plant.rs).
//!
//! `cargo run --example custom_valve [-- DEADBAND HYSTERESIS]` (defaults 0.05 and 0.02, command units).

use std::path::Path;

use pneuflex::control::{Sensors, Telemetry, ValveCommand};
use pneuflex::scene::analysis::windows::compute_windows;
use pneuflex::scene::plants::PlantError;
use pneuflex::scene::{EventSpec, Plant, Scene, build_plant, run_scene, simulate};

/// The spool of an overlapped valve with backlash: the spool stays within `hysteresis / 2` of the
/// command it last followed (it moves only when the command has moved further), and no port opens while
/// the spool is inside the overlap `|s| < deadband`; beyond it the opening rises from zero (rescaled to
/// reach 1 at full command).
struct OverlappedValve {
    plant: Box<dyn Plant>,
    deadband: f64,
    hysteresis: f64,
    spool: f64,
}

impl OverlappedValve {
    fn opening(&self) -> f64 {
        let s = self.spool;
        let beyond = (s.abs() - self.deadband).max(0.0) / (1.0 - self.deadband);
        beyond.copysign(s)
    }
}

impl Plant for OverlappedValve {
    fn sense(&self) -> Sensors {
        self.plant.sense()
    }

    fn actuate(&mut self, command: ValveCommand, telemetry: &Telemetry) {
        // Backlash: the spool follows the command only once it is more than h/2 away.
        let half = 0.5 * self.hysteresis;
        let u = command.u.clamp(-1.0, 1.0);
        if u > self.spool + half {
            self.spool = u - half;
        } else if u < self.spool - half {
            self.spool = u + half;
        }
        let u = self.opening();
        self.plant.actuate(ValveCommand { u }, telemetry);
    }

    fn advance(&mut self, dt: f64) {
        self.plant.advance(dt);
    }

    fn apply(&mut self, event: &EventSpec) -> Result<(), PlantError> {
        self.plant.apply(event)
    }

    fn reset(&mut self) {
        self.plant.reset();
        self.spool = 0.0;
    }

    fn check_invariants(&self) -> Result<(), PlantError> {
        self.plant.check_invariants()
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1).map(|a| a.parse::<f64>());
    let deadband = args.next().unwrap_or(Ok(0.05))?;
    let hysteresis = args.next().unwrap_or(Ok(0.02))?;
    let path = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/paper-fig3-proportional.toml"
    ));
    let scene = Scene::load(path)?;
    let shipped = run_scene(&scene, &mut |_| {})?;

    let setpoints = scene.setpoints()?;
    let mut valve = OverlappedValve {
        plant: build_plant(&scene)?,
        deadband,
        hysteresis,
        spool: 0.0,
    };
    println!(
        "{}: RMS force error, N, the scene's ideal proportional valve vs one with a {deadband} overlap and \
         {hysteresis} hysteresis",
        scene.name
    );
    for (i, ideal) in shipped.iter().enumerate() {
        if scene.runs[i].frozen.is_some() {
            // A frozen run holds values its source reached in the whole scene's run (docs/scenes.md, "What
            // adaptation buys"): it has no controller of its own to put on another valve.
            continue;
        }
        valve.reset();
        let mut controller = scene.controller(i)?;
        let r = simulate(
            &scene,
            i,
            &mut valve,
            controller.as_mut(),
            &setpoints,
            &mut |_| {},
        )?;
        if let Some(why) = &r.diverged {
            println!("{} with the overlapped valve diverged: {why}", r.name);
            continue;
        }
        // `simulate` runs the loop; the scene's metrics are computed from its trace as `run` does.
        let windows = compute_windows(&scene, &r.trace, r.pwm_period_s);
        for (w, ours) in scene.metrics.iter().zip(&windows) {
            let theirs = ideal
                .window(&w.name)
                .map_or(f64::NAN, |m| m.rms_force_error_n);
            println!(
                "  {:<10} {:<17} ideal {theirs:>7.3}   overlapped {:>7.3}",
                r.name, w.name, ours.rms_force_error_n
            );
        }
    }
    Ok(())
}
