//! pneuflex-multibody: the pneumatic rig of the paper (Fig. 1, Section IV) as a rapier3d-f64 world built
//! from URDF: a flange on a prismatic joint in the cylinder, an environment carriage with compliant wood
//! and iron contact faces (per-material k and c), an axial force element between cylinder and flange,
//! a load-cell reading from Rapier's contact impulses, and the scene events (environment swap, stiffness
//! change, incline change). See docs/multibody.md.

pub mod actuator;
pub mod error;
pub mod mechanism;
pub mod mesh;
pub mod spring;
pub mod urdf_build;
pub mod urdf_scan;
pub mod world;

pub use actuator::{AxialActuator, ConstantForce, PneumaticForceElement, SpringActuator};
pub use error::MultibodyError;
pub use mechanism::{
    ActuatorConfig, ContactConfig, ContactParams, ContactReading, Mechanism, MechanismConfig,
    Mount, MountState, SpringConfig,
};
pub use mesh::{ConvexHull, TriangleMesh};
/// The Rapier crate this world is built on.
pub use rapier3d_f64;
/// Rapier's f64 math types (glam), used for poses in the public API.
pub use rapier3d_f64::math::{Pose, Rotation, Vector};
pub use urdf_build::{LinkGeometry, LinkShape, LinkView};
pub use world::{
    MaterialConfig, MaterialParams, Measurements, MultibodyConfig, RigWorld, STANDARD_GRAVITY,
};
