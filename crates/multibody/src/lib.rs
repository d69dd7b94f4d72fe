//! pneuflex-multibody: any URDF with pneumatic actuators in rapier3d-f64 ([`Mechanism`]): cylinders along
//! prismatic joints or between anchor points, compliant pads and rigid contacts, joint springs, held links
//! moved along scripted waypoints, contact-force sensors. The paper's rig (Fig. 1, Section IV: a flange
//! pushed against wood and iron faces on a carriage that swaps them) is one such mechanism
//! ([`CarriageRig`]). See docs/multibody.md.

pub mod actuator;
pub mod error;
pub mod mechanism;
pub mod mesh;
pub mod spring;
pub mod urdf_build;
pub mod urdf_scan;

pub use actuator::{
    ActuatorFamily, AxialActuator, ConstantForce, PneumaticForceElement, SensorSpec, SpringActuator,
};
pub use error::MultibodyError;
pub use mechanism::{
    ActuatorConfig, CarriageRig, ContactConfig, ContactParams, ContactReading, MaterialConfig,
    Measurements, Mechanism, MechanismConfig, Mount, MountState, PadIntegration, RigConfig,
    RigidContactConfig, SpringConfig,
};
pub use mesh::{ConvexHull, TriangleMesh};
/// The Rapier crate this world is built on.
pub use rapier3d_f64;
/// Rapier's f64 math types (glam), used for poses in the public API.
pub use rapier3d_f64::math::{Pose, Rotation, Vector};
pub use urdf_build::{LinkGeometry, LinkShape, LinkView};

/// Standard gravity, m/s^2.
pub const STANDARD_GRAVITY: f64 = 9.80665;
