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

/// The pneumatic cylinder as a force element (chambers and valve over each physics step, the mean
/// piston force): `pneuflex_pneumatics::PneumaticForceElement`, the one implementation every engine uses
/// (this rig, MuJoCo from Python and the native MuJoCo plugin). Viscous friction K_v is the URDF joint
/// damping and is not added here.
pub use pneuflex_pneumatics::PneumaticForceElement;

impl AxialActuator for PneumaticForceElement {
    fn force(&mut self, x: f64, x_dot: f64, dt: f64) -> f64 {
        self.step(x, x_dot, dt)
    }
}
