//! Errors of the Rerun recorder.

use std::path::PathBuf;

/// Everything that can go wrong while opening, feeding or closing a Rerun recording.
#[derive(Debug, thiserror::Error)]
pub enum RerunError {
    /// `--rerun save` into a directory that does not exist (checked before anything is created).
    #[error(
        "cannot save Rerun recording to `{path}`: directory `{dir}` does not exist (create it first)"
    )]
    SaveDirMissing {
        /// The requested .rrd file.
        path: PathBuf,
        /// Its parent directory, which is missing.
        dir: PathBuf,
    },

    /// The .rrd file could not be created (permissions, path is a directory, ...).
    #[error("cannot create Rerun recording file `{path}`: {reason}")]
    SaveCreate {
        /// The requested .rrd file.
        path: PathBuf,
        /// What the operating system or Rerun said.
        reason: String,
    },

    /// The connect address is not a Rerun gRPC proxy URL.
    #[error(
        "invalid Rerun viewer address `{url}`: {reason} (expected e.g. `rerun+http://127.0.0.1:9876/proxy` or `127.0.0.1:9876`)"
    )]
    BadUrl {
        /// The address as given.
        url: String,
        /// Why it was rejected.
        reason: String,
    },

    /// Nothing accepted a TCP connection at the viewer address within the probe timeout.
    #[error(
        "no Rerun viewer reachable at `{url}` ({addr}): {reason}. Start one with `rerun` (listens on port 9876 by default) or use `--rerun save FILE.rrd`"
    )]
    ConnectFailed {
        /// The URL handed to Rerun.
        url: String,
        /// The socket address that was probed.
        addr: String,
        /// The connect error or "timed out".
        reason: String,
    },

    /// `spawn` was asked for but no `rerun` executable is on PATH.
    #[error(
        "no `rerun` viewer executable found on PATH; install the matching viewer with `pip install rerun-sdk=={version}` (it provides the `rerun` command) or `cargo install rerun-cli --version {version} --locked`"
    )]
    ViewerNotFound {
        /// The Rerun version this crate records with.
        version: &'static str,
    },

    /// Starting the viewer process failed.
    #[error("cannot start the Rerun viewer: {0}")]
    Spawn(String),

    /// A static shape with a non-finite or non-positive size.
    #[error("invalid shape for entity `{entity}`: {reason}")]
    BadShape {
        /// Entity path of the shape.
        entity: String,
        /// What was wrong.
        reason: String,
    },

    /// A recorder setting out of range (e.g. a non-positive batch size or pressure span).
    #[error("invalid Rerun recorder option `{option}`: {reason}")]
    BadOption {
        /// Option name.
        option: &'static str,
        /// What was wrong.
        reason: String,
    },

    /// Rerun refused some data (serialisation or chunk construction).
    #[error("Rerun logging failed for `{entity}`: {reason}")]
    Log {
        /// Entity path that was being logged.
        entity: String,
        /// Rerun's message.
        reason: String,
    },

    /// Data could not be flushed to the sink before the timeout.
    #[error("Rerun recording could not be flushed: {0}")]
    Flush(String),

    /// The recording of one run of a scene failed.
    #[error("Rerun recording of run `{run}`: {source}")]
    Run {
        /// Run name.
        run: String,
        /// What failed.
        source: Box<RerunError>,
    },
}
