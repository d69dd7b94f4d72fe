//! One module per subcommand; each returns `anyhow::Result` and leaves printing of errors to `main`.
pub mod rig;
pub mod run;
pub mod tf;
