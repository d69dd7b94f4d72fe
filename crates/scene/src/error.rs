//! Errors of scene loading, simulation and output writing.

use std::path::PathBuf;

/// Everything that can go wrong between a scene file and its outputs.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("{}: cannot read: {source}", file.display())]
    Io {
        /// The scene file.
        file: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// TOML syntax error, unknown key, missing key or wrong type.
    #[error("{}: {}{message}", file.display(), if path.is_empty() { String::new() } else { format!("{path}: ") })]
    Parse {
        /// The scene file.
        file: PathBuf,
        /// Dotted key path, e.g. `environment.stiffness_n_per_m` (empty at the top level).
        path: String,
        /// What was wrong.
        message: String,
    },
    /// A value out of range (negative stiffness, NaN, ...).
    #[error("{}: {path}: {message}", file.display())]
    Invalid {
        /// The scene file.
        file: PathBuf,
        /// Dotted key path.
        path: String,
        /// What was expected and what was found.
        message: String,
    },
    /// The plant could not be built (for instance a bad actuator sheet).
    #[error("{}: plant: {message}", file.display())]
    Plant {
        /// The scene file.
        file: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// Writing outputs failed.
    #[error("{}: cannot write: {source}", path.display())]
    Write {
        /// The file or directory being written.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
}
