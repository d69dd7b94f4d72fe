//! Scenes of any URDF with several pneumatic actuators (docs/multibody.md "Your own URDF"): the file
//! ([`schema`]), the runs ([`run`]: one controller per actuator on the general
//! [`pneuflex_multibody::Mechanism`]) and their metrics, claims and files ([`summary`]).

pub mod draw;
pub mod run;
pub mod schema;
pub mod summary;

pub use pneuflex_multibody::Mechanism;
pub use run::{ACTUATOR_COLUMNS, ColumnSignal, MechanismObserver, MechanismRun, run_all};
pub use schema::MechanismScene;
pub use summary::{MechanismSummary, summarise, write};
