//! A custom controller in a shipped scene: a plain PI force controller on the valve, run on
//! scenes/paper-fig3.toml next to the scene's own impedance and adaptive runs.
//!
//! `cargo run --example pi_controller [-- KP KI]` (defaults 0.01 /N and 0.2 /(N s)).
//!
//! Files touched in the library to add it: none. Any type implementing `pneuflex::control::Controller`
//! runs in every scene through `pneuflex::scene::simulate`; the scene supplies the plant, the setpoints,
//! the events and the divergence checks. Reaching it from a scene file's `runs[].controller.kind` as well
//! touches the controller's file and its form (docs/architecture.md).

use std::path::Path;

use pneuflex::control::{Controller, Sensors, Setpoint, Telemetry, ValveCommand};
use pneuflex::scene::analysis::windows::compute_windows;
use pneuflex::scene::{Scene, build_plant, run_scene, simulate};

/// u = kp e + ki ∫e on the force error e = f_ref - f_e, straight to the valve (no impedance filter,
/// no inner position loop). It drives the valve, so it needs a plant with one (pneumatic or multibody).
struct PiForce {
    kp_per_n: f64,
    ki_per_n_s: f64,
    integral_n_s: f64,
    last: Telemetry,
}

impl PiForce {
    fn new(kp_per_n: f64, ki_per_n_s: f64) -> Self {
        Self {
            kp_per_n,
            ki_per_n_s,
            integral_n_s: 0.0,
            last: Telemetry::default(),
        }
    }
}

impl Controller for PiForce {
    fn update(&mut self, s: &Sensors, sp: &Setpoint, dt: f64) -> ValveCommand {
        let e = sp.f_ref - s.f_e;
        let u = self.kp_per_n * e + self.ki_per_n_s * (self.integral_n_s + e * dt);
        // Anti-windup: integrate only while the valve is not saturated.
        if u.abs() < 1.0 {
            self.integral_n_s += e * dt;
        }
        // No position reference: report the flange position as x_r so traces and the divergence
        // check see a plausible value.
        self.last = Telemetry {
            x_r: s.x,
            e,
            ..Telemetry::default()
        };
        ValveCommand::clamped(u)
    }

    fn telemetry(&self) -> Telemetry {
        self.last
    }

    fn reset(&mut self) {
        *self = Self::new(self.kp_per_n, self.ki_per_n_s);
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let arg = |i: usize, default: f64| -> Result<f64, Box<dyn std::error::Error>> {
        Ok(std::env::args().nth(i).map_or(Ok(default), |a| a.parse())?)
    };
    let (kp, ki) = (arg(1, 0.01)?, arg(2, 0.2)?);
    let path = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/paper-fig3.toml"
    ));
    let scene = Scene::load(path)?;

    // The scene's own runs, with the metrics the CLI writes to summary.json.
    let shipped = run_scene(&scene, &mut |_| {})?;

    // The PI controller on a fresh plant of the same scene; the result is filed under run 0's name.
    let mut plant = build_plant(&scene)?;
    let setpoints = scene.setpoints()?;
    let mut pi = PiForce::new(kp, ki);
    let mut result = simulate(&scene, 0, plant.as_mut(), &mut pi, &setpoints, &mut |_| {})?;
    if let Some(why) = &result.diverged {
        println!("PI (kp = {kp}, ki = {ki}) diverged: {why}");
    }
    // `simulate` returns the trace; the scene's window metrics of it are the ones summary.json holds.
    result.windows = compute_windows(&scene, &result.trace, result.pwm_period_s);

    println!("{}\nRMS force error, N:", scene.description);
    print!("{:<24}", "window");
    shipped.iter().for_each(|r| print!("{:>14}", r.name));
    println!("{:>14}", "PI");
    for w in &scene.metrics {
        print!("{:<24}", format!("{} {}-{} s", w.name, w.t0_s, w.t1_s));
        for r in &shipped {
            let m = r.window(&w.name).map(|m| m.rms_force_error_n);
            print!("{:>14.3}", m.unwrap_or(f64::NAN));
        }
        let m = result.window(&w.name).map(|m| m.rms_force_error_n);
        println!("{:>14.3}", m.unwrap_or(f64::NAN));
    }
    println!("PI gains: kp = {kp} /N, ki = {ki} /(N s)");
    Ok(())
}
