//! Plants: what the controller drives. Every plant is stepped the same way,
//! `sense → controller.update → actuate → advance(dt)`.

use pneuflex_control::{Sensors, Telemetry, ValveCommand};

use crate::schema::EventSpec;

/// What kind of thing went wrong in a plant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlantErrorKind {
    /// The plant has nothing the event could change (a swap on a 1-DOF plant, an incline on the ideal loop).
    Unsupported,
    /// The event's values cannot be applied here (an unknown material, a carriage in motion).
    Rejected,
    /// A physical invariant of the state is violated: the run has diverged.
    Invariant,
    /// The plant's own machinery failed (an exception in a plant written in Python).
    External,
}

/// A plant's error: its kind and a message for people.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{message}")]
pub struct PlantError {
    /// What kind of failure.
    pub kind: PlantErrorKind,
    /// What happened, with the numbers.
    pub message: String,
}

impl PlantError {
    /// An error of `kind`.
    pub fn new(kind: PlantErrorKind, message: impl Into<String>) -> Self {
        Self {
            kind,
            message: message.into(),
        }
    }
    /// The plant has nothing the event could change.
    pub fn unsupported(message: impl Into<String>) -> Self {
        Self::new(PlantErrorKind::Unsupported, message)
    }
    /// A violated physical invariant.
    pub fn invariant(message: impl Into<String>) -> Self {
        Self::new(PlantErrorKind::Invariant, message)
    }
}

impl From<String> for PlantError {
    fn from(message: String) -> Self {
        Self::new(PlantErrorKind::Rejected, message)
    }
}

impl From<&str> for PlantError {
    fn from(message: &str) -> Self {
        Self::new(PlantErrorKind::Rejected, message)
    }
}

/// Something a controller drives: a simulated plant (integrated) or, later, an adapter to the rig.
pub trait Plant {
    /// Sensor values of the current state (the caller sets `t`).
    fn sense(&self) -> Sensors;
    /// Applies the controller's output for the next period. The ideal plant follows `telemetry.x_r`,
    /// a pneumatic plant the valve `command`.
    fn actuate(&mut self, command: ValveCommand, telemetry: &Telemetry);
    /// Integrates the plant over `dt` seconds with the last command held (zero-order hold).
    fn advance(&mut self, dt: f64);
    /// Applies a scene event; Err explains why this plant cannot.
    fn apply(&mut self, event: &EventSpec) -> Result<(), PlantError>;
    /// Back to the initial state and initial environment.
    fn reset(&mut self);
    /// Checks the physical invariants of the current state (absolute pressures within [0, a margin above
    /// supply], temperatures positive, the piston within its stroke); Err names the variable and its value.
    fn check_invariants(&self) -> Result<(), PlantError> {
        Ok(())
    }
    /// The plant's own recorded signals (beyond what `sense` returns), declared once.
    fn signals(&self) -> &'static [pneuflex_control::Signal] {
        &[]
    }
    /// Writes the values of [`Plant::signals`] at the current state into `out` (same length).
    fn record(&self, _out: &mut [f64]) {}
    /// The plant's bodies as drawn in 3D (name and shape), for viewers; empty for plants without geometry.
    fn visuals(&self) -> Vec<Visual> {
        Vec::new()
    }
    /// World pose of each entry of [`Plant::visuals`], in that order, at the current state.
    fn visual_poses(&self, _pose: &mut dyn FnMut(usize, VisualPose)) {}
    /// The actuator's geometry as a viewer draws it (cylinder, chambers, incline, environment surface);
    /// None for a plant without a pneumatic actuator (the ideal loop).
    fn actuator_geometry(&self) -> Option<ActuatorGeometry> {
        None
    }
}

/// What a drawn shape is to the experiment, set by the plant that builds it: viewers colour by it and
/// attach the chambers to the cylinder and the contact force to the flange.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum VisualRole {
    /// The moving flange (piston rod end) that pushes the environment.
    Flange,
    /// The cylinder body, in which the chambers are.
    Cylinder,
    /// The environment the flange pushes (faces and their blocks).
    Environment,
    /// Anything else (platform, carriage, ...).
    #[default]
    Other,
}

/// The actuator's geometry for viewers (SI), at the plant's initial state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ActuatorGeometry {
    /// Piston stroke, m.
    pub stroke_m: f64,
    /// Cylinder bore, m.
    pub bore_m: f64,
    /// Incline of the actuator axis below the horizontal, rad.
    pub alpha_rad: f64,
    /// Flange extension at which the environment is first touched, m.
    pub x_e_m: f64,
    /// Period of the valve's PWM carrier, s (an on/off valve under PWM); None for a proportional valve.
    pub pwm_period_s: Option<f64>,
}

/// The PWM period of `valve`, s, if it is an on/off valve switched by PWM.
pub fn pwm_period_s(valve: &pneuflex_pneumatics::ValveModel) -> Option<f64> {
    match valve.kind {
        pneuflex_pneumatics::ValveKind::OnOffPwm {
            pwm_frequency_hz, ..
        } => Some(1.0 / pwm_frequency_hz),
        pneuflex_pneumatics::ValveKind::Proportional { .. } => None,
    }
}

/// One drawable collision shape of a plant's link.
#[derive(Clone, Debug, PartialEq)]
pub struct Visual {
    /// Link name (with `/<i>` for a link's i-th shape when it has several).
    pub name: String,
    /// The shape, centred on its pose.
    pub shape: VisualShape,
    /// What the shape is to the experiment.
    pub role: VisualRole,
}

/// A primitive shape for viewers (SI).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VisualShape {
    /// Box with half edge lengths along its x, y, z, m.
    Box {
        /// Half edge lengths, m.
        half_extents_m: [f64; 3],
    },
    /// Cylinder along its z axis, m.
    Cylinder {
        /// Radius, m.
        radius_m: f64,
        /// Half length, m.
        half_length_m: f64,
    },
    /// Sphere, m.
    Sphere {
        /// Radius, m.
        radius_m: f64,
    },
}

/// Pose of a shape in the world: translation (m) and unit quaternion [x, y, z, w].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VisualPose {
    /// Translation, m.
    pub translation_m: [f64; 3],
    /// Rotation as a unit quaternion [x, y, z, w].
    pub rotation_xyzw: [f64; 4],
}

/// Linear-spring environment of eq. (21): f_e = k_e (x - x_e) while x > x_e; no contact (0) otherwise.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearSpring {
    /// Stiffness k_e, N/m.
    pub stiffness_n_per_m: f64,
    /// Surface position x_e, m.
    pub x_e_m: f64,
}

impl LinearSpring {
    /// Contact force f_e >= 0 on the environment (positive = the flange pushes), N. eq. (21)
    pub fn force(&self, x: f64) -> f64 {
        let d = x - self.x_e_m;
        if d > 0.0 {
            self.stiffness_n_per_m * d
        } else {
            0.0
        }
    }
}

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

/// The valve's recorded signal, for plants with a pneumatic valve: its spool, which under PWM is the
/// energised side (+1 / -1) — the valve's PWM state.
pub const VALVE_SIGNALS: [pneuflex_control::Signal; 1] = [pneuflex_control::Signal::new(
    "spool",
    "1",
    "valve",
    "valve spool position in [-1, 1] (on/off valve under PWM: the energised side, +1 or -1)",
)];

/// How far above the supply pressure a chamber may go before the state is impossible: a closed chamber
/// compressed by the piston can exceed supply, but not double it in any case the model is meant for.
pub const PRESSURE_MARGIN: f64 = 2.0;

/// The physical invariants of a two-chamber actuator: 0 < p <= PRESSURE_MARGIN · p_supply (absolute),
/// 0 < T < 2000 K, and the piston within the stroke plus 1 mm + 1 % (the end stops are inelastic).
pub fn chamber_invariants(
    ch: &pneuflex_pneumatics::ChamberState,
    supply: &pneuflex_pneumatics::Supply,
    x_m: f64,
    stroke_m: f64,
) -> Result<(), PlantError> {
    let p_max = PRESSURE_MARGIN * supply.supply_pressure_pa;
    for (name, p) in [("p_a", ch.p_a), ("p_b", ch.p_b)] {
        if !(p > 0.0 && p <= p_max) {
            return Err(PlantError::invariant(format!(
                "chamber pressure {name} = {p:.6e} Pa (absolute) outside (0, {p_max:.3e}] Pa \
                 ({PRESSURE_MARGIN} x supply)"
            )));
        }
    }
    for (name, t) in [("T_a", ch.t_a), ("T_b", ch.t_b)] {
        if !(t > 0.0 && t < 2000.0) {
            return Err(PlantError::invariant(format!(
                "chamber temperature {name} = {t:.6e} K outside (0, 2000) K"
            )));
        }
    }
    let tol = 1e-3 + 0.01 * stroke_m;
    if !(x_m >= -tol && x_m <= stroke_m + tol) {
        return Err(PlantError::invariant(format!(
            "piston position x = {x_m:.6e} m outside the stroke [0, {stroke_m}] m (+/- {tol:.4} m)"
        )));
    }
    Ok(())
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
