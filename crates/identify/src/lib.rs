//! pneuflex-identify: system identification of the pneumatic actuator from rig logs (issue 16,
//! docs/identification.md). The logged valve command is replayed through the 1-DOF model of
//! `pneuflex-pneumatics` ([`replay`]); the chosen sheet parameters are fitted to the measured pressures and
//! position with Levenberg-Marquardt ([`fit`]); the report gives 95 % intervals from the Jacobian, the
//! correlation matrix, residuals per signal, a validation overlay and warnings for what the data cannot
//! identify ([`report`]); the fitted values are written back into copies of the sheets ([`sheet`]).
//! [`excite`] designs the experiments, [`perturb`] makes hidden truths for tests.

pub mod board_time;
pub mod check;
pub mod excite;
pub mod fit;
pub mod leak;
pub mod log;
pub mod log_bag;
pub mod log_format;
pub mod log_rows;
pub mod params;
pub mod perturb;
pub mod replay;
pub mod report;
pub mod request;
pub mod seal;
pub mod select;
pub mod sheet;

use std::path::PathBuf;

/// What went wrong; every variant names the file and, where one is to blame, the line, column or key.
#[derive(Debug, thiserror::Error)]
pub enum IdentifyError {
    /// A log could not be read (missing, not a regular file, too large).
    #[error("{0}")]
    Input(String),
    /// A log is malformed.
    #[error("{}{}{}: {message}", file.display(), line.map(|l| format!(":{l}")).unwrap_or_default(),
            column.as_ref().map(|c| format!(": column `{c}`")).unwrap_or_default())]
    Log {
        /// The log file.
        file: PathBuf,
        /// 1-based line, when a line is to blame.
        line: Option<usize>,
        /// The column to blame.
        column: Option<String>,
        /// What is wrong.
        message: String,
    },
    /// A sheet could not be read or written.
    #[error(transparent)]
    Sheet(#[from] pneuflex_pneumatics::ComponentError),
    /// A `--free` or `--bounds` entry is wrong.
    #[error("{option}: {key}: {message}")]
    Key {
        /// `--free` or `--bounds`.
        option: &'static str,
        /// The key as given.
        key: String,
        /// What is wrong.
        message: String,
    },
    /// The output directory is refused or cannot be made (the message names it).
    #[error(transparent)]
    OutputDir(#[from] pneuflex_files::OutputError),
    /// Writing an output failed.
    #[error("{}: {message}", file.display())]
    Output {
        /// The file or directory.
        file: PathBuf,
        /// What failed.
        message: String,
    },
    /// The fit could not be carried out (no data, a diverging replay).
    #[error("{0}")]
    Fit(String),
    /// A signal stopped the fit before it converged.
    #[error("interrupted during {pass}, before the fit converged")]
    Interrupted {
        /// The signal's number.
        signal: usize,
        /// Each free key's value when it stopped (not converged, no interval).
        reached: Vec<(String, f64)>,
        /// Which pass was under way.
        pass: String,
    },
}
