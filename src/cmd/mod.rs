//! One module per subcommand; each returns `anyhow::Result` and leaves printing of errors to `main`.
pub mod identify;
pub mod live;
pub mod pil;
pub mod rig;
pub mod run;
pub mod sweep;
pub mod tf;
pub mod tune;

/// An error that ends the process with a given exit code (128 + signal for an interrupted command).
#[derive(Debug)]
pub struct Exit {
    /// The process exit code.
    pub code: u8,
    /// What to print.
    pub message: String,
}

impl std::fmt::Display for Exit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Exit {}
