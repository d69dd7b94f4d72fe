//! The force element between the cylinder body and the flange.

/// An axial force element: given the flange state it returns the force along +x on the flange, N.
/// The world applies the same force with opposite sign on the cylinder body, every physics step.
pub trait AxialActuator {
    /// Advance the element's own state by `dt` (s) at flange extension `x` (m) and velocity `x_dot`
    /// (m/s) and return the force on the flange along +x, N (eq. (1)'s F_1 - F_2 term).
    fn force(&mut self, x: f64, x_dot: f64, dt: f64) -> f64;
}

/// A constant axial force, N: the "constant push" of the contact-stiffness tests.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConstantForce {
    /// Force on the flange along +x, N.
    pub force_n: f64,
}

impl AxialActuator for ConstantForce {
    fn force(&mut self, _x: f64, _x_dot: f64, _dt: f64) -> f64 {
        self.force_n
    }
}

/// A linear spring-damper towards a set extension: F = k (x_set - x) - c x_dot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpringActuator {
    /// Spring rate, N/m.
    pub stiffness_n_per_m: f64,
    /// Damping, N s/m.
    pub damping_n_s_per_m: f64,
    /// Extension at which the spring is relaxed, m.
    pub set_x_m: f64,
}

impl AxialActuator for SpringActuator {
    fn force(&mut self, x: f64, x_dot: f64, _dt: f64) -> f64 {
        self.stiffness_n_per_m * (self.set_x_m - x) - self.damping_n_s_per_m * x_dot
    }
}

impl<T: AxialActuator + ?Sized> AxialActuator for &mut T {
    fn force(&mut self, x: f64, x_dot: f64, dt: f64) -> f64 {
        (**self).force(x, x_dot, dt)
    }
}

/// The pneumatic cylinder as a force element: it integrates the two chamber states (eqs. (2)-(10), via
/// `pneuflex_pneumatics::Actuator::step_chambers`) and the valve (`ValveModel::segment`) over each physics
/// step, in `substeps` equal substeps split at the valve's spool edges, with the flange moving at the step's velocity, and returns the
/// piston force p_a S_a - p_b S_b - p_atm S_rod (eq. (1)'s F_1 - F_2). Viscous friction K_v is the
/// URDF joint damping and is not added here.
#[derive(Debug, Clone)]
pub struct PneumaticForceElement {
    /// Cylinder, gas, valve and supply.
    pub actuator: pneuflex_pneumatics::Actuator,
    /// Chamber pressures and temperatures.
    pub chambers: pneuflex_pneumatics::ChamberState,
    /// Valve internal state (spool position, PWM clock).
    pub valve: pneuflex_pneumatics::ValveState,
    /// Valve command u in [-1, 1] held until changed (+1: supply to chamber A).
    command: f64,
    /// Chamber substeps per physics step (>= 1).
    substeps: u32,
    /// Time of the element's own clock, s (drives the PWM period of an on/off valve).
    time_s: f64,
}

impl PneumaticForceElement {
    /// A force element with chambers `chambers`, valve at rest at spool 0, and `substeps` (>= 1; 0 is
    /// taken as 1) chamber substeps per physics step.
    pub fn new(
        actuator: pneuflex_pneumatics::Actuator,
        chambers: pneuflex_pneumatics::ChamberState,
        substeps: u32,
    ) -> Self {
        Self {
            actuator,
            chambers,
            valve: pneuflex_pneumatics::ValveState::default(),
            command: 0.0,
            substeps: substeps.max(1),
            time_s: 0.0,
        }
    }

    /// Set the valve command u in [-1, 1] (clamped; NaN closes the valve), held from the next step on.
    pub fn set_command(&mut self, u: f64) {
        self.command = if u.is_nan() { 0.0 } else { u.clamp(-1.0, 1.0) };
    }

    /// The valve command in force.
    pub fn command(&self) -> f64 {
        self.command
    }

    /// Chamber substeps per physics step.
    pub fn substeps(&self) -> u32 {
        self.substeps
    }

    /// Chamber pressures (p_a, p_b), Pa absolute: what the rig's pressure sensors read.
    pub fn pressures(&self) -> (f64, f64) {
        (self.chambers.p_a, self.chambers.p_b)
    }

    /// Piston force for the current chamber state, N.
    pub fn piston_force(&self) -> f64 {
        self.actuator.piston_force(&self.chambers)
    }
}

impl AxialActuator for PneumaticForceElement {
    fn force(&mut self, x: f64, x_dot: f64, dt: f64) -> f64 {
        let n = self.substeps;
        let h = dt / f64::from(n);
        let mut f_sum = 0.0;
        for i in 0..n {
            let xi = x + x_dot * h * f64::from(i);
            // The substep is split at every spool edge inside it (`ValveModel::segment`: the delayed PWM
            // edges of an on/off valve; never for the proportional valve): RK4 up to the edge with the
            // spool before it, on from it with the spool after it.
            let (t_sub, t_end) = (self.time_s, self.time_s + h);
            let (mut tau, mut rest) = (t_sub, h);
            loop {
                let (spool, edge) =
                    self.actuator
                        .valve
                        .segment(&mut self.valve, self.command, tau, rest);
                let len = edge.map_or(rest, |e| e - tau);
                // Average of the force at both ends of the piece (trapezoid over the physics step,
                // weighted by the piece's share of the substep: 1 for an unsplit substep).
                let f0 = self.actuator.piston_force(&self.chambers);
                let x_piece = if tau == t_sub {
                    xi
                } else {
                    xi + x_dot * (tau - t_sub)
                };
                self.actuator
                    .step_chambers(&mut self.chambers, x_piece, x_dot, spool, len);
                f_sum += 0.5 * (f0 + self.actuator.piston_force(&self.chambers)) * (len / h);
                match edge {
                    Some(e) if e < t_end => {
                        tau = e;
                        rest = t_end - e;
                    }
                    _ => break,
                }
            }
            self.time_s += h;
        }
        f_sum / f64::from(n)
    }
}
