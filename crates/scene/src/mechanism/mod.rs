//! Scenes of any URDF with several pneumatic actuators (docs/multibody.md "Your own URDF"): the file
//! ([`schema`]), the runs ([`run`]: one controller per actuator on the general
//! [`pneuflex_multibody::Mechanism`]) and their metrics, claims and files ([`summary`]).

pub mod run;
pub mod schema;
pub mod summary;

pub use run::{ACTUATOR_COLUMNS, MechanismRun, run_all};
pub use schema::MechanismScene;
pub use summary::{MechanismSummary, summarise, write};
