//! pneuflex as a library: one crate that re-exports the project's crates under short names, so a program
//! depends on `pneuflex` alone and writes `pneuflex::scene::run_scene`, `pneuflex::control::Controller`.
//! The `pneuflex` command line is this package's binary (src/main.rs); no CLI code lives here.
//!
//! ```no_run
//! use pneuflex::scene::{Scene, run_scene};
//! let scene = Scene::load(std::path::Path::new("scenes/paper-fig3.toml")).unwrap();
//! for run in run_scene(&scene, &mut |_| {}).unwrap() {
//!     let sine = run.window("sine").unwrap();
//!     println!("{}: RMS force error {:.3} N", run.name, sine.rms_force_error_n);
//! }
//! ```
//!
//! The programs in `examples/` (README, "Use it as a library") show a custom controller, a custom plant and
//! reading a trace.

/// Controllers (`no_std`): impedance filter, adaptive law, inner PID, references, the `Controller` trait.
pub use pneuflex_control as control;
/// Safe file handling: bounded input reads, output directories, provenance hashes.
pub use pneuflex_files as files;
/// System identification: rig logs, the fit, the report; a seal's friction and a chamber's leak from bench
/// tests (`identify::seal`, `identify::leak`).
pub use pneuflex_identify as identify;
/// URDF → Rapier multibody rig and the pneumatic force element.
pub use pneuflex_multibody as multibody;
/// PNG figures of a scene's runs.
pub use pneuflex_plot as plot;
/// The pneumatic actuator model: cylinder, valves, friction, the linearised transfer function.
pub use pneuflex_pneumatics as pneumatics;
/// Real-rig mode: the `Rig` trait, serial protocol, safety supervisor, emulator.
pub use pneuflex_rig as rig;
/// Scene files, plants, the run loop, metrics, trace.csv and summary.json.
pub use pneuflex_scene as scene;
pub use pneuflex_viz as viz;

/// Rerun recording (with the `rerun` feature).
#[cfg(feature = "rerun")]
pub use pneuflex_rerun as rerun;
