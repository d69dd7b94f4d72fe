//! Scenes of any URDF with several pneumatic actuators (docs/multibody.md "Your own URDF"): the file
//! ([`schema`]), the mechanism built from it ([`build`]), the plant the one loop drives ([`plant`]: one
//! controller per actuator on the general [`pneuflex_multibody::Mechanism`]), the runs ([`run`]) and their
//! metrics, claims and files ([`summary`]).

pub mod build;
pub mod draw;
pub mod plant;
pub mod run;
pub mod schema;
pub mod summary;

pub use plant::MechanismPlant;
pub use pneuflex_multibody::Mechanism;
pub use run::run_all;
pub use schema::MechanismScene;
pub use summary::{MechanismSummary, summarise, write};
