//! Scenes for pneuflex, one folder per concept: the scene file and its checks ([`schema`]), the plants a
//! controller drives ([`plants`]), running a scene through the one loop and writing its traces and summary
//! ([`run`]), and what the runs are judged by ([`analysis`]: metrics, claims, loop margins, advice).
//!
//! ```no_run
//! use pneuflex_scene::{Scene, run_scene};
//! let scene = Scene::load(std::path::Path::new("scenes/paper-fig3.toml")).unwrap();
//! let results = run_scene(&scene, &mut |_| {}).unwrap();
//! for r in &results { println!("{}: {:?}", r.name, r.window("sine").map(|w| w.rms_force_error_n)); }
//! ```

pub mod analysis;
pub mod any_scene;
pub mod error;
pub mod mechanism;
pub mod origin;
pub mod plants;
pub mod run;
pub mod schema;

pub use any_scene::AnyScene;
pub use error::SceneError;
pub use plants::{
    IdealLoop, LinearSpring, MultibodyPlant, OneDofPneumatic, Plant, Visual, VisualPose,
    VisualShape,
};
pub use run::output::{Summary, scene_inputs, summary, write_results, write_summary, write_trace};
pub use run::trace::Trace;
pub use run::{
    LyapunovSummary, RunOptions, RunResult, Sink, Sinks, TickTiming, WindowMetrics, run_scene,
    run_scene_observed, run_scene_with, signal_name, simulate, simulate_observed, time_ticks,
};
pub use schema::plant::build_plant;
pub use schema::{
    Budget, ControllerKind, EventSpec, FrozenAt, FrozenValues, Limits, MaterialSpec, MultibodySpec,
    PlantSpec, SCENE_SCHEMA_VERSION, Scene, WindowKind,
};
