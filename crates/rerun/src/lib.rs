//! Rerun recording of pneuflex runs: links as collision shapes with poses over time, the contact
//! point and force arrow, the chambers coloured by pressure, the control signals as time series and
//! scene events as text, on a `sim_time` (simulation) or `wall_time` (rig) timeline.
//!
//! The API takes plain numbers and strings only, so that the rest of pneuflex can keep this crate
//! (and Rerun's long build) behind a cargo feature. See `docs/rerun.md`.

mod error;
mod layout;
pub mod paths;
mod recorder;
mod sink;

pub use error::RerunError;
pub use layout::default_blueprint;
pub use recorder::{
    ChamberSample, Clock, Contact, EventLevel, LinkShape, RecorderOptions, RunRecorder, Shape,
    wall_clock_s,
};
pub use sink::{CONNECT_PROBE_TIMEOUT, DEFAULT_VIEWER_PORT, RERUN_VERSION, Sink};
