//! One module per subcommand; each returns `anyhow::Result` and leaves printing of errors to `main`.
#[cfg(feature = "rerun")]
pub mod rerun_log;
pub mod rig;
pub mod run;
pub mod tf;
