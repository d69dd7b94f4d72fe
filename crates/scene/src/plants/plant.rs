//! What a plant is: the trait every plant implements (`sense → controller.update → actuate → advance(dt)`),
//! its errors, what the loop analyses ask of it, and the linear-spring environment of eq. (21).

use pneuflex_control::{Sensors, Telemetry, ValveCommand};
use pneuflex_pneumatics::PressureRegulator;

use super::events::EventSpec;
use super::visual::{ActuatorGeometry, Visual, VisualPose};

/// Something a controller drives: a simulated plant (integrated) or, later, an adapter to the rig.
pub trait Plant {
    /// Sensor values of the current state (the caller sets `t`).
    fn sense(&self) -> Sensors;
    /// Applies the controller's output for the next period. The ideal plant follows `telemetry.x_r`,
    /// a pneumatic plant the valve `command`.
    fn actuate(&mut self, command: ValveCommand, telemetry: &Telemetry);
    /// Integrates the plant over `dt` seconds with the last command held (zero-order hold).
    fn advance(&mut self, dt: f64);
    /// The names of the plant's actuators when it has several, each the prefix of its columns
    /// (`left.f_e`) and driven by a controller of its own; empty for a plant of one actuator (its columns
    /// are the loop's, unprefixed).
    fn actuator_names(&self) -> &[String] {
        &[]
    }
    /// Actuator `i`'s sensors ([`Plant::sense`] for a plant of one actuator).
    fn sense_actuator(&self, _i: usize) -> Sensors {
        self.sense()
    }
    /// Applies actuator `i`'s command ([`Plant::actuate`] for a plant of one actuator).
    fn actuate_actuator(&mut self, _i: usize, command: ValveCommand, telemetry: &Telemetry) {
        self.actuate(command, telemetry);
    }
    /// Fits a pressure regulator in front of each of actuator `i`'s chambers in place of its valve
    /// (`pneuflex_pneumatics::regulator`: a first-order regulator limited by the valve's paths fully open), or
    /// with `None` gives the valve back. The regulators stay through [`Plant::reset`]; their set-points start
    /// at the chambers' pressures. Returns the set-points' range, (atmosphere, supply) in Pa absolute; Err for
    /// a plant that has no regulator option (no chambers, or effects beyond the paper's model).
    fn set_regulators(
        &mut self,
        _i: usize,
        _regulator: Option<PressureRegulator>,
    ) -> Result<(f64, f64), PlantError> {
        Err(PlantError::unsupported(
            "this plant takes a valve command only (no pressure regulators)",
        ))
    }
    /// Sets the set-points (p_a, p_b) of actuator `i`'s regulators, Pa absolute, held until changed (the
    /// model clamps them to [atmosphere, supply]); ignored without regulators fitted.
    fn actuate_pressures(&mut self, _i: usize, _p_a_pa: f64, _p_b_pa: f64) {}
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
    /// The period of the valve's PWM carrier, s (an on/off valve under PWM), which the metrics average
    /// over; None for a proportional valve or a plant without one. The plant knows it once built.
    fn pwm_period_s(&self) -> Option<f64> {
        self.actuator_geometry().and_then(|g| g.pwm_period_s)
    }
}

/// What a plant gives the analysis: its continuous state as a vector, and back.
pub trait Linearisable: Plant {
    /// A copy at the same state, for an analysis that tries several linearisations from one point.
    fn boxed_clone(&self) -> Box<dyn Linearisable>;
    /// Whether the plant has the valve saturation and friction the describing-function prediction of a
    /// limit cycle models ([`crate::analysis::loop_margins::limit_cycle_onset`]).
    fn has_valve_and_friction(&self) -> bool {
        false
    }
    /// The state (position first).
    fn state_vector(&self) -> Vec<f64>;
    /// Sets the state from a vector of the same layout.
    fn set_state_vector(&mut self, v: &[f64]);
    /// A perturbation size per state component for the finite differences.
    fn perturbation_scales(&self) -> Vec<f64>;
    /// Whether the valve switches (PWM): then the analysis uses its period-averaged model.
    fn switching(&self) -> bool {
        false
    }
    /// Replaces a switching valve by its average over one PWM period: the spool's duty d = (1 + u)/2 opens
    /// supply→A and B→exhaust for d of the period and the other paths for 1 − d, i.e. a proportional valve
    /// open both ways at the centre (underlap 1), lagging by the switching delay plus half a period.
    fn average_switching(&mut self) {}
    /// For the sampled-data analysis of a switching valve ([`crate::analysis::pwm_onset`]): replaces it by
    /// the valve its latched duty drives over a period — open both ways at the centre as in
    /// [`Linearisable::average_switching`], but without the lag, which the analysis models exactly as the
    /// hold of the duty over the period and the switching delay. Returns (PWM period, switching delay), s;
    /// None for a valve that does not switch.
    fn hold_switching(&mut self) -> Option<(f64, f64)> {
        None
    }
    /// Leaves out Coulomb friction: linearised at rest its tanh or stick band is a steep viscous damping
    /// (F_c/v_s, 600 N·s/m on the shipped sheet) that an oscillation of any size never sees — its describing
    /// function falls as 4 F_c/(π ω A) — so a small-signal margin with it would promise far more than the
    /// loop has. The viscous K_v stays.
    fn without_coulomb_friction(&mut self) {}
    /// The Coulomb friction force F_c, N (0 without), for its describing function.
    fn coulomb_n(&self) -> f64 {
        0.0
    }
    /// Adds a viscous damping c, N·s/m (the describing function of Coulomb friction at an amplitude).
    fn add_viscous(&mut self, _c: f64) {}
}

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
