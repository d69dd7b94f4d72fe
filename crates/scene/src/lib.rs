//! Scenes for pneuflex: the scene file (TOML, validated), the plants a controller drives, the run loop
//! `sense → controller.update → actuate → advance(dt)`, metrics, and the trace.csv / summary.json writers.
//!
//! ```no_run
//! use pneuflex_scene::{Scene, run_scene};
//! let scene = Scene::load(std::path::Path::new("scenes/paper-fig3.toml")).unwrap();
//! let results = run_scene(&scene, &mut |_| {}).unwrap();
//! for r in &results { println!("{}: {:?}", r.name, r.window("sine").map(|w| w.rms_force_error_n)); }
//! ```

pub mod advice;
pub mod claims;
pub mod error;
pub mod linear;
mod locate;
pub mod loop_analysis;
pub mod metrics;
pub mod multibody;
pub mod output;
pub mod plant;
pub mod pneumatic;
pub mod runner;
pub mod schema;
pub mod trace;

pub use error::SceneError;
pub use multibody::{FlangeDrive, MultibodyPlant};
pub use output::{Summary, scene_inputs, summary, write_results, write_summary, write_trace};
pub use plant::{IdealLoop, LinearSpring, Plant, Visual, VisualPose, VisualShape};
pub use pneumatic::OneDofPneumatic;
pub use runner::{
    LyapunovSummary, Observers, Rows, RunOptions, RunResult, StepObserver, WindowMetrics,
    build_controller, build_plant, build_setpoints, run_scene, run_scene_observed, run_scene_with,
    signal_name, simulate, simulate_observed,
};
pub use schema::{
    Budget, ControllerKind, EventSpec, Limits, MaterialSpec, MultibodySpec, PlantSpec,
    SCENE_SCHEMA_VERSION, Scene, WindowKind,
};
pub use trace::Trace;
