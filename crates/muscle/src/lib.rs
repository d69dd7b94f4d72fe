//! pneuflex-muscle: the McKibben pneumatic artificial muscle as a second actuator family.
//!
//! - [`braid`]: the braided muscle's statics: geometry and bladder volume against contraction, the force
//!   against gauge pressure and contraction (Chou & Hannaford 1996, Tondu & Lopez 2000 with the end-effect
//!   factor), braid friction, the slack and stretch end stops;
//! - [`chamber`]: the chamber's mass and energy balance (the paper's eqs. (2)-(10)) with a volume that
//!   depends on the length, fed by a 3/2 valve (ISO 6358, eq. (11), the pneumatics crate's flow and valve)
//!   or a first-order pressure regulator;
//! - [`element`]: the muscle as a force element between two anchors, stepped by a host (the engine's
//!   mechanism, the MuJoCo plugin `pneuflex.muscle`) over each of its steps;
//! - [`plant`]: a muscle pulling a mass against a spring, integrated with RK4;
//! - [`sheet`]: muscle sheets as TOML.
//!
//! SI units; chamber pressures absolute, the force laws' pressures gauge. Equations (M1)-(M12) are
//! numbered in docs/muscles.md.

pub mod braid;
pub mod chamber;
pub mod element;
pub mod plant;
pub mod sheet;

pub use braid::{Braid, BraidFriction, Muscle, NEUTRAL_BRAID_ANGLE_RAD, geometric_max_contraction};
pub use chamber::{ChamberRates, ChamberState, MuscleChamber, Port};
pub use element::MuscleForceElement;
pub use plant::{Feed, Load, MusclePlant, PlantState};
pub use sheet::{FeedSheet, MuscleSheet, SheetError};
