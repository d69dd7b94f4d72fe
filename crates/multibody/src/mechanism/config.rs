//! What a mechanism is besides its URDF: the actuators and how they are mounted, the compliant contacts,
//! gravity and the step. Names only; [`super::Mechanism::from_robot`] resolves them against the URDF.

/// How a cylinder is attached to the bodies it moves.
#[derive(Debug, Clone, PartialEq)]
pub enum Mount {
    /// Along a prismatic URDF joint: the piston force acts on the joint's child along the joint axis and its
    /// reaction on the parent; the stroke x is the joint position above its lower limit (the retracted
    /// stop), and the joint's limits are the cylinder's end stops.
    Joint {
        /// The prismatic joint.
        joint: String,
    },
    /// Between two anchor points: the cylinder's clevis on one body and its rod eye on another, e.g. a
    /// cylinder turning a revolute joint through a lever. The cylinder is a massless line force: its length
    /// is L = |p_b − p_a|, its stroke x = L − L_retracted, its rate ẋ = (v_b − v_a)·n with n = (p_b − p_a)/L,
    /// and the piston force F pushes the anchors apart: +F n at p_b, −F n at p_a.
    Anchors {
        /// Link of the clevis (the cylinder body's pivot).
        link_a: String,
        /// Clevis point in `link_a`'s frame, m.
        point_a_m: [f64; 3],
        /// Link of the rod eye.
        link_b: String,
        /// Rod-eye point in `link_b`'s frame, m.
        point_b_m: [f64; 3],
        /// Pin-to-pin length with the piston at its retracted stop, m.
        retracted_length_m: f64,
        /// Stroke, m: the cylinder spans [retracted, retracted + stroke].
        stroke_m: f64,
    },
}

/// One pneumatic actuator of a mechanism.
#[derive(Debug, Clone, PartialEq)]
pub struct ActuatorConfig {
    /// Its name in the scene (signal prefix, messages).
    pub name: String,
    /// Where it acts.
    pub mount: Mount,
}

/// A compliant contact between the colliders of two links: a Kelvin–Voigt pad, F = max(0, k δ + c δ̇)
/// along the contact normal, δ the penetration depth (the lumped stiffness of a pad, an object, a seal).
/// Frictionless.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactConfig {
    /// Its name in the scene (the contact-force sensor's name).
    pub name: String,
    /// One side's link.
    pub link_a: String,
    /// The other side's link.
    pub link_b: String,
    /// Normal stiffness k, N/m.
    pub stiffness_n_per_m: f64,
    /// Normal damping c, N s/m.
    pub damping_n_s_per_m: f64,
}

/// A spring-damper on a prismatic or revolute joint (a compliant mount: the lumped stiffness of an
/// environment behind its contact face, a return spring). Its rest position is the URDF's zero, where a
/// prismatic joint's child rests under its own weight at any gravity.
#[derive(Debug, Clone, PartialEq)]
pub struct SpringConfig {
    /// Its name in the scene (events).
    pub name: String,
    /// The joint.
    pub joint: String,
    /// Stiffness, N/m or N m/rad.
    pub stiffness: f64,
    /// Damping, N s/m or N m s/rad.
    pub damping: f64,
}

/// Everything a mechanism needs besides its URDF.
#[derive(Debug, Clone, PartialEq)]
pub struct MechanismConfig {
    /// The actuators, in the order their forces are given to [`super::Mechanism::step_with_forces`].
    pub actuators: Vec<ActuatorConfig>,
    /// The compliant contacts. Colliders not named here never touch anything.
    pub contacts: Vec<ContactConfig>,
    /// Gravity in the URDF's root frame, m/s².
    pub gravity_m_s2: [f64; 3],
    /// Physics step, s.
    pub dt_s: f64,
    /// Rapier solver iterations per step.
    pub solver_iterations: usize,
    /// Prismatic joints that start away from the URDF's zero configuration: (joint, position in m).
    pub initial_positions: Vec<(String, f64)>,
    /// Spring-dampers on joints.
    pub springs: Vec<SpringConfig>,
    /// Links held where the URDF puts them (a carriage, a fixture), with everything fixed to them.
    pub held_links: Vec<String>,
    /// How the pads' forces enter a step.
    pub pad_integration: super::PadIntegration,
}

impl MechanismConfig {
    /// A mechanism with these actuators and contacts, standard gravity along −z, dt = 1 ms, 4 iterations.
    pub fn new(actuators: Vec<ActuatorConfig>, contacts: Vec<ContactConfig>) -> Self {
        Self {
            actuators,
            contacts,
            gravity_m_s2: [0.0, 0.0, -crate::STANDARD_GRAVITY],
            dt_s: 1.0e-3,
            solver_iterations: 4,
            initial_positions: Vec::new(),
            springs: Vec::new(),
            held_links: Vec::new(),
            pad_integration: super::PadIntegration::Explicit,
        }
    }
}
