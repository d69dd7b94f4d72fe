//! A custom plant driven by a shipped scene's controllers: a first-order position servo (time constant
//! tau) pressing on a linear spring, in place of the ideal second-order loop of scenes/paper-fig3-ideal.toml.
//!
//! `cargo run --example custom_plant [-- TAU_S]` (default 0.005 s).
//!
//! Files touched in the library to add it: none. Any type implementing `pneuflex::scene::Plant` runs a
//! scene's schedule, events and divergence checks through `pneuflex::scene::simulate`.

use std::path::Path;

use pneuflex::control::{Sensors, Telemetry, ValveCommand};
use pneuflex::scene::analysis::windows::compute_windows;
use pneuflex::scene::{EventSpec, Plant, Scene, run_scene, simulate};

/// x' = (x_r - x) / tau: a position servo that follows the controller's x_r, against a spring
/// f_e = k_e (x - x_e) while in contact (eq. 21).
struct FirstOrderServo {
    tau_s: f64,
    x_e_m: f64,
    k0_n_per_m: f64,
    k_n_per_m: f64,
    x_m: f64,
    x_r_m: f64,
}

impl FirstOrderServo {
    /// At rest on the spring's surface.
    fn new(tau_s: f64, k_n_per_m: f64, x_e_m: f64) -> Self {
        Self {
            tau_s,
            x_e_m,
            k0_n_per_m: k_n_per_m,
            k_n_per_m,
            x_m: x_e_m,
            x_r_m: x_e_m,
        }
    }
}

impl Plant for FirstOrderServo {
    fn sense(&self) -> Sensors {
        Sensors {
            t: 0.0, // the loop sets the time
            x: self.x_m,
            x_dot: (self.x_r_m - self.x_m) / self.tau_s,
            f_e: self.k_n_per_m * (self.x_m - self.x_e_m).max(0.0),
            // No chambers: NaN is an empty cell in trace.csv.
            p_a: f64::NAN,
            p_b: f64::NAN,
        }
    }

    fn actuate(&mut self, _command: ValveCommand, telemetry: &Telemetry) {
        // A position servo takes the position reference, not the valve command.
        self.x_r_m = telemetry.x_r;
    }

    fn advance(&mut self, dt: f64) {
        // Exact solution over the step with x_r held: stable for any dt.
        self.x_m = self.x_r_m + (self.x_m - self.x_r_m) * (-dt / self.tau_s).exp();
    }

    fn apply(&mut self, event: &EventSpec) -> Result<(), pneuflex::scene::plants::PlantError> {
        match event {
            EventSpec::Stiffness {
                stiffness_n_per_m, ..
            } => {
                self.k_n_per_m = *stiffness_n_per_m;
                Ok(())
            }
            other => Err(pneuflex::scene::plants::PlantError::unsupported(format!(
                "a first-order servo cannot apply {other:?}"
            ))),
        }
    }

    fn reset(&mut self) {
        *self = Self::new(self.tau_s, self.k0_n_per_m, self.x_e_m);
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let tau_s: f64 = std::env::args().nth(1).map_or(Ok(0.005), |a| a.parse())?;
    let path = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/paper-fig3-ideal.toml"
    ));
    let scene = Scene::load(path)?;
    let env = &scene.environment;

    // The scene as shipped: its ideal second-order loop (200 rad/s, critically damped).
    let shipped = run_scene(&scene, &mut |_| {})?;

    // Each of the scene's controllers on the custom plant.
    let setpoints = scene.setpoints()?;
    let mut servo = FirstOrderServo::new(tau_s, env.stiffness_n_per_m, env.x_e_m);
    let mut custom = Vec::new();
    for i in 0..scene.runs.len() {
        servo.reset();
        let mut c = scene.controller(i)?;
        let mut r = simulate(&scene, i, &mut servo, c.as_mut(), &setpoints, &mut |_| {})?;
        if let Some(why) = &r.diverged {
            println!("{} on the servo diverged: {why}", r.name);
        }
        // `simulate` returns the trace; the scene's window metrics of it are the ones summary.json holds.
        r.windows = compute_windows(&scene, &r.trace, r.pwm_period_s);
        custom.push(r);
    }

    println!(
        "{}\nRMS force error, N: the shipped ideal loop vs a first-order servo, tau = {tau_s} s",
        scene.name
    );
    print!("{:<24}", "window");
    for r in &shipped {
        print!("{:>16}{:>16}", format!("{} ideal", r.name), "servo");
    }
    println!();
    for w in &scene.metrics {
        print!("{:<24}", format!("{} {}-{} s", w.name, w.t0_s, w.t1_s));
        for (r, c) in shipped.iter().zip(&custom) {
            let ideal = r.window(&w.name).map_or(f64::NAN, |m| m.rms_force_error_n);
            let servo = c.window(&w.name).map_or(f64::NAN, |m| m.rms_force_error_n);
            print!("{ideal:>16.3}{servo:>16.3}");
        }
        println!();
    }
    Ok(())
}
