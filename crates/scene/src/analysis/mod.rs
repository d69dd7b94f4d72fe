//! What a scene's runs are judged by: the metrics of each window, the claims, the inner loop's margins and
//! limit cycle, the advice given before a run, and what the adaptive law did.

pub mod adaptation;
pub mod advice;
pub mod claims;
pub mod comparison;
pub mod injection;
pub mod loop_margins;
pub mod metrics;
pub mod outer_law;
pub mod pwm_onset;
pub mod recorded;
pub mod run_onset;
pub mod windows;
