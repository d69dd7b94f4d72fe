//! Rerun recording of pneuflex runs.
pub use rerun;
