//! One recorded run into an output directory, in the order that never loses data: check the destination
//! (read only), connect, stage the output beside it (crates/files `OutputDir`), run, commit. A failed
//! connect leaves everything untouched; an interrupted run is committed as `<dest>.partial`; a trace write
//! error keeps the staging directory.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use pneuflex_control::{Controller, Setpoint};
use pneuflex_files::InputDigest;
use pneuflex_files::output::{
    Manifest, OutputDir, OutputError, Partial, Writer, check_not_protected, check_replaceable,
};

use crate::clock::Clock;
use crate::error::ErrorKind;
use crate::rigfile::RigFile;
use crate::rtloop::{LoopReport, check_duration};
use crate::serial::{Link, SerialRig};
use crate::session;
use crate::trace::TraceWriter;

/// The recording commands, as their manifests name them.
pub const COMMAND: &str = "rig run";
/// `rig excite`'s recordings.
pub const EXCITE: &str = "rig excite";

/// What a recorded run produced.
#[derive(Debug)]
pub struct Recording {
    /// The loop's report (the fault, if any, and timing).
    pub report: LoopReport,
    /// Where the output now is: the destination, or `<dest>.partial` after a signal.
    pub dir: PathBuf,
    /// Whether the run was interrupted by a signal (committed as partial).
    pub partial: bool,
    /// Staging directories of earlier runs that died, kept as `<dest>.unfinished-<pid>`.
    pub recovered: Vec<PathBuf>,
    /// Why the caller's analysis of the recording ([`Finish`]) failed; the recording was committed all
    /// the same, without the analysis.
    pub analysis_error: Option<String>,
}

/// What the caller adds to a recording before it is committed (`rig run --scene`: summary.json and the
/// figures), given the staging directory with the complete trace and the loop's report. An error leaves
/// the recording committed without what this wrote; it must remove its own files on failure.
pub type Finish<'a> = &'a mut dyn FnMut(&Path, &LoopReport) -> Result<(), String>;

/// Why nothing (or only a kept staging directory) was recorded.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The run length is not usable.
    #[error("--duration: {0}")]
    Duration(crate::rtloop::OptionError),
    /// An input could not be hashed.
    #[error("{}: cannot read input: {os_error}", path.display())]
    Input {
        /// The input.
        path: PathBuf,
        /// The OS error (in the message, printed once).
        os_error: std::io::Error,
    },
    /// The output directory is refused or cannot be made.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// The rig did not connect (nothing was written).
    #[error("{0}")]
    Connect(String),
    /// The trace could not be written; the safe state was commanded first.
    #[error("{message}; what was recorded is kept in {}", kept.display())]
    Trace {
        /// The error, naming the trace file.
        message: String,
        /// The staging directory, kept.
        kept: PathBuf,
    },
}

/// Records one run of `controller` on the rig into `out_dir/trace.csv` (+ the manifest). `inputs` are
/// (path, role) pairs: hashed into the trace header and the manifest, and their folders refused as
/// outputs. `connect` is called only after the destination was checked and before anything is written.
#[allow(clippy::too_many_arguments)]
pub fn record<L, E, C, K>(
    command: &'static str,
    rig: &RigFile,
    connect: impl FnOnce() -> Result<SerialRig<L>, E>,
    out_dir: &Path,
    inputs: &[(&Path, &str)],
    controller: &mut C,
    reference: &mut dyn FnMut(f64) -> Setpoint,
    duration_s: f64,
    stop: &AtomicBool,
    clock: &mut K,
) -> Result<Recording, RecordError>
where
    L: Link,
    E: std::fmt::Display,
    C: Controller + ?Sized,
    K: Clock + ?Sized,
{
    record_observed(
        command,
        rig,
        connect,
        out_dir,
        inputs,
        controller,
        reference,
        duration_s,
        stop,
        clock,
        &mut (),
        &mut |_, _| Ok(()),
    )
}

/// [`record`] with an observer of every row (a live Rerun view): the loop's signals, the controller's and
/// the link's quality ([`crate::serial::LINK_SIGNALS`]), and the fault as an event; `finish` adds the
/// caller's analysis to the staged recording before the commit.
#[allow(clippy::too_many_arguments)]
pub fn record_observed<L, E, C, K>(
    command: &'static str,
    rig: &RigFile,
    connect: impl FnOnce() -> Result<SerialRig<L>, E>,
    out_dir: &Path,
    inputs: &[(&Path, &str)],
    controller: &mut C,
    reference: &mut dyn FnMut(f64) -> Setpoint,
    duration_s: f64,
    stop: &AtomicBool,
    clock: &mut K,
    observer: &mut dyn pneuflex_control::Sink<()>,
    finish: Finish<'_>,
) -> Result<Recording, RecordError>
where
    L: Link,
    E: std::fmt::Display,
    C: Controller + ?Sized,
    K: Clock + ?Sized,
{
    check_duration(duration_s).map_err(RecordError::Duration)?;
    let digests = inputs
        .iter()
        .map(|(p, role)| {
            InputDigest::of_file(p, role).map_err(|os_error| RecordError::Input {
                path: p.to_path_buf(),
                os_error,
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let protect: Vec<&Path> = inputs.iter().map(|(p, _)| *p).collect();
    // Read-only checks first: a refused destination costs no connection.
    let writer = Writer::recording(command);
    check_not_protected(out_dir, &protect)?;
    check_replaceable(out_dir, &writer)?;
    let link = connect().map_err(|e| RecordError::Connect(e.to_string()))?;
    let out = OutputDir::create(out_dir, &protect, writer)?;
    let recovered = out.recovered.clone();
    let trace_path = out.path().join("trace.csv");
    let kept = |out: OutputDir, message: String| RecordError::Trace {
        message,
        kept: out.keep(),
    };
    let file = match std::fs::File::create_new(&trace_path) {
        Ok(f) => f,
        Err(e) => {
            let m = format!("{}: cannot create the trace: {e}", trace_path.display());
            return Err(kept(out, m));
        }
    };
    let name = trace_path.display().to_string();
    let mut sup = session::supervised(link, rig);
    let mut trace = match TraceWriter::create(file, rig.rt.trace_flush_every, &name, &digests) {
        Ok(t) => t,
        Err(e) => return Err(kept(out, e.to_string())),
    };
    let opts = session::run_options(rig, duration_s);
    let result = crate::rtloop::run_observed(
        &mut sup, controller, reference, &mut trace, &opts, stop, clock, observer,
    );
    // The valve is parked safe (again) before anything else happens to the files.
    drop(sup);
    drop(trace);
    let report = match result {
        Ok(r) => r,
        Err(e) => return Err(kept(out, e.to_string())),
    };
    // The trace is closed and complete: the caller's analysis goes beside it (its failure never costs
    // the recording).
    let analysis_error = finish(out.path(), &report).err();
    // Checked again before the commit: a commit refused now must not lose the recording.
    let target = match &report.fault {
        Some(f) if f.kind == ErrorKind::Interrupted => out.partial_dest(),
        _ => out_dir.to_path_buf(),
    };
    if let Err(e) = check_replaceable(&target, &writer) {
        return Err(kept(out, e.to_string()));
    }
    let manifest = Manifest::new(command, env!("CARGO_PKG_VERSION"), digests);
    let (dir, partial) = match &report.fault {
        Some(f) if f.kind == ErrorKind::Interrupted => (
            out.commit_partial(
                manifest,
                Partial {
                    reason: "signal (SIGINT, SIGTERM or SIGHUP)".into(),
                    time_reached_s: report.time_reached_s,
                    done: None,
                },
            )?,
            true,
        ),
        _ => (out.commit(manifest)?, false),
    };
    Ok(Recording {
        report,
        dir,
        partial,
        recovered,
        analysis_error,
    })
}
