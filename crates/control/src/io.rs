//! The controller's inputs and outputs, shared by every plant and by the real rig. SI units.

/// What the controller reads each tick (SI units, pressures absolute).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sensors {
    /// Time of the sample, s.
    pub t: f64,
    /// Flange (piston) position along the cylinder axis, m; positive = extension towards the environment.
    pub x: f64,
    /// Flange velocity, m/s.
    pub x_dot: f64,
    /// Contact force measured between flange and environment, N; positive = flange pushes on the environment.
    pub f_e: f64,
    /// Chamber A (cap side, extends the rod) pressure, Pa absolute.
    pub p_a: f64,
    /// Chamber B (rod side) pressure, Pa absolute.
    pub p_b: f64,
}

/// What the controller wants this tick: force and position references.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Setpoint {
    /// Reference contact force f_r, N.
    pub f_ref: f64,
    /// Desired (free-space) position x_d, m.
    pub x_d: f64,
}

/// Valve command in [-1, 1]. +1 connects supply to chamber A and exhausts B (extend), -1 the reverse.
/// A proportional 5/3 valve takes it as the spool position (0 = closed centre); the rig's 5/2 on/off valve
/// under PWM takes it as duty (1 + u)/2 of the energised position (0 = 50 % duty, the mean holds the load).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ValveCommand {
    /// Normalised spool position / signed duty, in [-1, 1].
    pub u: f64,
}

impl ValveCommand {
    /// A command clamped to [-1, 1]; NaN becomes 0 (closed), never an open valve.
    pub fn clamped(u: f64) -> Self {
        let u = if u.is_nan() { 0.0 } else { u.clamp(-1.0, 1.0) };
        Self { u }
    }
}

/// The impedance structure's internal signals, which the plants and the loop read (zero where a controller
/// has no such signal). A controller's own signals (the adaptive law's g, p, d, or any new controller's)
/// are not here: it declares them in [`Controller::signals`] and writes them in [`Controller::record`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Telemetry {
    /// Reference position handed to the inner position loop, x_r, m.
    pub x_r: f64,
    /// Impedance filter output x_f, m (eq. 22).
    pub x_f: f64,
    /// Adaptive position correction Δx_f, m (eq. 36).
    pub dx_f: f64,
    /// Force error e = f_r - f_e, N.
    pub e: f64,
}

/// A force/position controller: one call per control tick, no allocation, no std.
pub trait Controller {
    /// Computes the valve command from the latest sensors and setpoint; `dt` is the control period, s.
    fn update(&mut self, sensors: &Sensors, setpoint: &Setpoint, dt: f64) -> ValveCommand;
    /// Internal signals of the last update, for traces.
    fn telemetry(&self) -> Telemetry;
    /// Returns to the initial state (integrators, filters, adaptive parameters).
    fn reset(&mut self);
    /// The controller's own recorded signals (beyond the loop's, `signal::LOOP_SIGNALS`), declared once.
    fn signals(&self) -> &'static [crate::signal::Signal] {
        &[]
    }
    /// Writes the values of [`Controller::signals`] after the last update into `out` (same length).
    fn record(&self, _out: &mut [f64]) {}
}
