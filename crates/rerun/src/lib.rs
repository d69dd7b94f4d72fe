//! Rerun recording of pneuflex runs: links as collision shapes with poses over time, the contact
//! point and force arrow, the chambers coloured by pressure, the control signals as time series and
//! scene events as text, on a `sim_time` (simulation) or `wall_time` (rig) timeline.
//!
//! [`RunRecorder`] takes plain numbers and strings; [`SceneRecorder`] is an observer of the scene run
//! loop that draws a plant from the visuals and actuator geometry the plant describes; [`RowRecorder`]
//! shows the rows of any loop (the real rig, live). Only the CLI
//! depends on this crate, behind a cargo feature (Rerun's build is long). See `docs/rerun.md`.

mod error;
mod layout;
mod mechanism_observer;
pub mod paths;
mod recorder;
mod row_observer;
mod scene_observer;
mod sink;
pub mod units;

pub use error::RerunError;
pub use layout::{Eye, Layout, Plot, blueprint, default_blueprint};
pub use mechanism_observer::MechanismRecorder;
pub use recorder::{
    ChamberSample, Clock, Contact, EventLevel, LinkShape, RecorderOptions, RunRecorder,
    wall_clock_s,
};
pub use row_observer::RowRecorder;
pub use scene_observer::{SceneRecorder, force_arrow_scale, parse_sink, sink_for_run};
pub use sink::{CONNECT_PROBE_TIMEOUT, DEFAULT_VIEWER_PORT, RERUN_VERSION, Sink};
