//! Errors of scene loading, simulation and output writing. Each names the file, and where a key is to blame,
//! the line and column of that key and its dotted path — the convention of every pneuflex file error:
//! fields `file`, `at` (line and column), `key` (dotted path), `message`; shown as `file:line:col: key: message`.

use std::path::PathBuf;

use pneuflex_files::Position;

fn located(file: &std::path::Path, at: &Option<Position>, key: &str) -> String {
    let mut s = file.display().to_string();
    if let Some(p) = at {
        s.push_str(&format!(":{}:{}", p.line, p.column));
    }
    if !key.is_empty() {
        s.push_str(": ");
        s.push_str(key);
    }
    s
}

/// Everything that can go wrong between a scene file and its outputs.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read (missing, not a regular file, too large, not text).
    #[error(transparent)]
    Input(#[from] pneuflex_files::InputError),
    /// TOML syntax error, unknown key, missing key or wrong type.
    #[error("{}: {message}", located(file, at, key))]
    Parse {
        /// The scene file.
        file: PathBuf,
        /// Line and column of the error, when known.
        at: Option<Position>,
        /// Dotted key path, e.g. `environment.stiffness_n_per_m` (empty at the top level).
        key: String,
        /// What was wrong.
        message: String,
    },
    /// A value out of range (negative stiffness, NaN, ...).
    #[error("{}: {message}", located(file, at, key))]
    Invalid {
        /// The scene file.
        file: PathBuf,
        /// Line and column of the key, when known.
        at: Option<Position>,
        /// Dotted key path.
        key: String,
        /// What was expected and what was found.
        message: String,
    },
    /// The plant could not be built for a reason no single key explains.
    #[error("{}: plant: {message}", file.display())]
    Plant {
        /// The scene file.
        file: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// An output directory could not be prepared or committed.
    #[error(transparent)]
    Output(#[from] pneuflex_files::OutputError),
    /// Writing outputs failed.
    #[error("{}: cannot write: {os_error}", path.display())]
    Write {
        /// The file or directory being written.
        path: PathBuf,
        /// The underlying error (in the message, printed once).
        os_error: std::io::Error,
    },
}

/// `v` with `decimals` decimals, or in scientific notation from 1e9 on: a blown-up or absurd value in a
/// message is a number to read, not 300 digits.
pub(crate) fn readable(v: f64, decimals: usize) -> String {
    if v.abs() < 1e9 {
        format!("{v:.decimals$}")
    } else {
        format!("{v:.3e}")
    }
}
