//! The ideal inner loop: x follows the reference position x_r through a stiff second-order loop.

use pneuflex_control::{Sensors, Telemetry, ValveCommand};

use super::{EventSpec, LinearSpring, Plant, PlantError};

/// An ideal inner position loop: x'' = ω² (x_r - x) - 2 ζ ω x', with x_r from the controller's telemetry.
///
/// The loop is a position servo that holds x_r whatever the contact force, so the closed force loop is
/// the paper's linear analysis with x ≈ x_r (Section III-A). Integrated with fixed-step RK4.
#[derive(Clone, Debug, PartialEq)]
pub struct IdealLoop {
    omega: f64,
    zeta: f64,
    x0: f64,
    env0: LinearSpring,
    env: LinearSpring,
    x: f64,
    v: f64,
    x_r: f64,
}

impl IdealLoop {
    /// A loop at rest at `x0_m` (x_r = x0) against `env`.
    pub fn new(omega_rad_per_s: f64, zeta: f64, x0_m: f64, env: LinearSpring) -> Self {
        Self {
            omega: omega_rad_per_s,
            zeta,
            x0: x0_m,
            env0: env,
            env,
            x: x0_m,
            v: 0.0,
            x_r: x0_m,
        }
    }

    fn accel(&self, x: f64, v: f64) -> f64 {
        self.omega * self.omega * (self.x_r - x) - 2.0 * self.zeta * self.omega * v
    }

    /// The current environment.
    pub fn environment(&self) -> LinearSpring {
        self.env
    }
}

impl Plant for IdealLoop {
    fn sense(&self) -> Sensors {
        // No chambers: pressures are NaN (written as empty cells in trace.csv).
        Sensors {
            t: 0.0,
            x: self.x,
            x_dot: self.v,
            f_e: self.env.force(self.x),
            p_a: f64::NAN,
            p_b: f64::NAN,
        }
    }

    fn actuate(&mut self, _command: ValveCommand, telemetry: &Telemetry) {
        self.x_r = telemetry.x_r;
    }

    fn advance(&mut self, dt: f64) {
        // Classical RK4 on (x, v) with x_r held.
        let (x, v) = (self.x, self.v);
        let (k1x, k1v) = (v, self.accel(x, v));
        let (k2x, k2v) = (
            v + 0.5 * dt * k1v,
            self.accel(x + 0.5 * dt * k1x, v + 0.5 * dt * k1v),
        );
        let (k3x, k3v) = (
            v + 0.5 * dt * k2v,
            self.accel(x + 0.5 * dt * k2x, v + 0.5 * dt * k2v),
        );
        let (k4x, k4v) = (v + dt * k3v, self.accel(x + dt * k3x, v + dt * k3v));
        self.x = x + dt / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
        self.v = v + dt / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
    }

    fn apply(&mut self, event: &EventSpec) -> Result<(), PlantError> {
        match *event {
            EventSpec::Stiffness {
                stiffness_n_per_m, ..
            } => {
                self.env.stiffness_n_per_m = stiffness_n_per_m;
                Ok(())
            }
            EventSpec::SwapEnvironment { .. } => Err(PlantError::unsupported(
                "swap_environment needs the multibody plant: the ideal loop has one linear-spring environment",
            )),
            EventSpec::Alpha { .. } => Err(PlantError::unsupported(
                "alpha has no effect on the ideal loop (it has no gravity)",
            )),
        }
    }

    fn reset(&mut self) {
        self.env = self.env0;
        self.x = self.x0;
        self.v = 0.0;
        self.x_r = self.x0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ideal_loop_has_no_actuator_to_draw() {
        let env = LinearSpring {
            stiffness_n_per_m: 700.0,
            x_e_m: 0.0,
        };
        let p = IdealLoop::new(100.0, 0.7, 0.0, env);
        assert!(p.actuator_geometry().is_none());
        assert!(p.visuals().is_empty());
    }
}
