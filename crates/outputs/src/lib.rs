//! A scene's output directory, written the same way by every caller (`pneuflex run`, `rig pil`, a program):
//! staged beside its destination ([`pneuflex_files::OutputDir`]: nothing pneuflex did not write is ever
//! replaced), each run's `trace*.csv`, `summary.json`, the figures and the manifest, then renamed into
//! place — or, after a signal, committed as `DEST.partial` with the reason in `summary.json` and the
//! manifest.
//!
//! [`simulate_into`] runs a scene into it; a host that runs the scene itself (PIL on the board) writes its
//! results with [`Outputs::commit`] / [`Outputs::commit_partial`].

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use pneuflex_control::Sink;
use pneuflex_files::OutputDir;
use pneuflex_files::output::{Manifest, Partial, Writer};
use pneuflex_scene::{Limits, Plant, RunOptions, RunResult, Scene, SceneError, Summary};

/// What went wrong while writing a scene's outputs.
#[derive(Debug, thiserror::Error)]
pub enum OutputsError {
    /// The output directory (refused, foreign, a recording, a write failure).
    #[error(transparent)]
    Directory(#[from] pneuflex_files::output::OutputError),
    /// The scene (refused before it ran) or a trace or summary.json that could not be written.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// The figures.
    #[error("writing figures: {0}")]
    Figures(#[from] pneuflex_plot::PlotError),
    /// A recording's trace that cannot be read back.
    #[error("{}: {message}", path.display())]
    Recording {
        /// The trace.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// A file the caller asked to keep outside (a Rerun recording) would be inside the directory.
    #[error(
        "{what} {}: it would be inside the output directory {}, which is replaced as a whole by the next \
         run; save it elsewhere (e.g. next to it)",
        file.display(), dest.display()
    )]
    Inside {
        /// What the file is, as its option spells it (`--rerun save`).
        what: String,
        /// The file.
        file: PathBuf,
        /// The output directory.
        dest: PathBuf,
    },
}

/// The input files an output must never write over: the scene file as given, and the sheet and URDF it
/// names.
pub fn input_files(scene: &Scene, scene_path: &Path) -> Vec<PathBuf> {
    let mut inputs = vec![scene_path.to_path_buf()];
    inputs.extend(scene.input_files().into_iter().skip(1).map(|(_, p)| p));
    inputs
}

/// A scene's output directory while it is being written.
pub struct Outputs {
    stage: OutputDir,
    dest: PathBuf,
    command: &'static str,
}

/// How a written output directory ended.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// Every run ran to its end: the directory is at its destination.
    Committed(PathBuf),
    /// A signal stopped the runs: what ran is in `DEST.partial`, the destination is untouched.
    Partial(Stopped),
}

/// Outputs committed as `DEST.partial` after a signal.
#[derive(Clone, Debug, PartialEq)]
pub struct Stopped {
    /// Where the partial outputs are.
    pub to: PathBuf,
    /// The signal's name (`SIGINT`).
    pub reason: String,
    /// The simulated time the last run reached, s.
    pub time_reached_s: f64,
}

impl Outputs {
    /// Stages `dest` for `command` (the manifest's name for it, `run`), protecting the scene file, the
    /// files it names, and `more_inputs` (a firmware ELF): a destination that is, or holds, one of them is
    /// refused, as is one holding a rig recording or files pneuflex did not write.
    pub fn stage(
        scene: &Scene,
        scene_path: &Path,
        dest: &Path,
        command: &'static str,
        more_inputs: &[&Path],
    ) -> Result<Self, OutputsError> {
        let inputs = input_files(scene, scene_path);
        let mut protect: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
        protect.extend_from_slice(more_inputs);
        let stage = OutputDir::create(dest, &protect, Writer::simulation(command))?;
        Ok(Self {
            stage,
            dest: dest.to_path_buf(),
            command,
        })
    }

    /// The staging directory the files are written into.
    pub fn dir(&self) -> &Path {
        self.stage.path()
    }

    /// The destination.
    pub fn dest(&self) -> &Path {
        &self.dest
    }

    /// Refuses `file` (named by `what`, e.g. `--rerun save`) when it lies inside the destination or its
    /// partial: the next run replaces both as a whole.
    pub fn refuse_inside(&self, file: &Path, what: &str) -> Result<(), OutputsError> {
        let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
        let f = abs(file);
        if f.starts_with(abs(&self.dest)) || f.starts_with(abs(&self.stage.partial_dest())) {
            return Err(OutputsError::Inside {
                what: what.to_string(),
                file: file.to_path_buf(),
                dest: self.dest.clone(),
            });
        }
        Ok(())
    }

    fn manifest(&self, summary: &Summary) -> Manifest {
        Manifest::new(
            self.command,
            env!("CARGO_PKG_VERSION"),
            summary.inputs.clone(),
        )
    }

    /// Writes every run's trace, `summary.json` and (when a run did not diverge) the figures, in
    /// `figures`' format, of runs made elsewhere, then moves the directory into place; files the caller
    /// wrote into [`Outputs::dir`] go with it.
    pub fn commit(
        self,
        scene: &Scene,
        results: &[RunResult],
        figures: pneuflex_viz::Format,
    ) -> Result<PathBuf, OutputsError> {
        pneuflex_scene::write_results(self.dir(), scene, results)?;
        if results.iter().any(|r| r.diverged.is_none()) {
            pneuflex_viz::write_figures(self.dir(), scene, results, figures)?;
        }
        let summary = pneuflex_scene::summary(scene, results);
        let manifest = self.manifest(&summary);
        Ok(self.stage.commit(manifest)?)
    }

    /// Writes the traces and `summary.json` of what ran before `signal` stopped it (no figures), and
    /// commits them as `DEST.partial`; `done` says how much ran (`2 of 3 runs`).
    pub fn commit_partial(
        self,
        scene: &Scene,
        results: &[RunResult],
        signal: usize,
        done: Option<String>,
    ) -> Result<Stopped, OutputsError> {
        pneuflex_scene::write_results(self.dir(), scene, results)?;
        let summary = pneuflex_scene::summary(scene, results);
        self.partial(&summary, results, signal, done)
    }

    fn partial(
        self,
        summary: &Summary,
        results: &[RunResult],
        signal: usize,
        done: Option<String>,
    ) -> Result<Stopped, OutputsError> {
        let reason = pneuflex_scene::signal_name(signal.max(2));
        let time_reached_s = results
            .last()
            .and_then(|r| r.trace.t().last().copied())
            .unwrap_or(0.0);
        let manifest = self.manifest(summary);
        let to = self.stage.commit_partial(
            manifest,
            Partial {
                reason: reason.clone(),
                time_reached_s,
                done,
            },
        )?;
        Ok(Stopped {
            to,
            reason,
            time_reached_s,
        })
    }
}

/// How [`simulate_into`] runs the scene.
#[derive(Clone, Copy, Debug, Default)]
pub struct Simulate<'a> {
    /// Refuse scenes beyond these before anything runs.
    pub limits: Limits,
    /// Non-zero (a signal's number) stops the current run at the next tick; the outputs become a partial.
    pub stop: Option<&'a AtomicUsize>,
    /// The figures' format (`run --format`).
    pub figures: pneuflex_viz::Format,
}

/// What [`simulate_into`] ran and wrote.
#[derive(Debug)]
pub struct Simulated {
    /// One result per run that ran, in the scene's order.
    pub results: Vec<RunResult>,
    /// `summary.json` as written.
    pub summary: Summary,
    /// The wall time of the simulation alone (without the last trace, the summary and the figures).
    pub simulation_time: Duration,
    /// Where the outputs are.
    pub outcome: Outcome,
}

/// Runs every run of `scene` and writes the outputs: each run's trace as soon as the run is done, while
/// the other runs still simulate (they end at different times, and the core that finished first would
/// otherwise idle: docs/performance.md); the last run's trace beside the figures, which can start only
/// then (queued behind it they left one core alone with the last figure); `summary.json`; the figures
/// for a complete command with a run that did not diverge; then the commit, or the partial after a stop.
/// `progress` gets the fraction done; `sink` every tick of every run.
pub fn simulate_into(
    scene: &Scene,
    outputs: Outputs,
    how: Simulate<'_>,
    progress: &mut dyn FnMut(f64),
    sink: &mut dyn Sink<dyn Plant>,
) -> Result<Simulated, OutputsError> {
    let start = Instant::now();
    let dir = outputs.dir();
    let trace_errors = Mutex::new(Vec::new());
    let write_trace_of = |r: &RunResult| {
        if let Err(e) = pneuflex_scene::write_trace(dir, r) {
            trace_errors
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .push((r.name.clone(), e));
        }
    };
    let ended = AtomicUsize::new(0);
    let last_run = Mutex::new(None::<String>);
    let (results, simulation_time, summary, written, figures) =
        rayon::in_place_scope(|writers| -> Result<_, OutputsError> {
            let write_trace = |r: &RunResult| {
                if ended.fetch_add(1, Ordering::Relaxed) + 1 == scene.runs.len() {
                    *last_run.lock().unwrap_or_else(|e| e.into_inner()) = Some(r.name.clone());
                    return;
                }
                let (r, write) = (r.clone(), &write_trace_of);
                writers.spawn(move |_| write(&r));
            };
            let opts = RunOptions {
                limits: how.limits,
                stop: how.stop,
                on_run: Some(&write_trace),
            };
            let results = pneuflex_scene::run_scene_with(scene, &opts, progress, sink)?;
            let simulation_time = start.elapsed();
            let summary = pneuflex_scene::summary(scene, &results);
            let figures = summary.complete && results.iter().any(|r| r.diverged.is_none());
            let last_run = last_run.into_inner().unwrap_or_else(|e| e.into_inner());
            let (figures, written) = rayon::join(
                || figures.then(|| pneuflex_viz::write_figures(dir, scene, &results, how.figures)),
                // The other core takes this first (a join's second half is what is stolen), then figures.
                || {
                    if let Some(r) = results.iter().find(|r| Some(&r.name) == last_run.as_ref()) {
                        write_trace_of(r);
                    }
                    pneuflex_scene::write_summary(dir, scene, &results)
                },
            );
            Ok((results, simulation_time, summary, written, figures))
        })?;
    // The first failed trace in run order, then summary.json, then the figures.
    let mut trace_errors = trace_errors.into_inner().unwrap_or_else(|e| e.into_inner());
    trace_errors.sort_by_key(|(name, _)| results.iter().position(|r| &r.name == name));
    if let Some((_, e)) = trace_errors.into_iter().next() {
        return Err(e.into());
    }
    written?;
    let outcome = if summary.complete {
        if let Some(figures) = figures {
            figures?;
        }
        let manifest = outputs.manifest(&summary);
        Outcome::Committed(outputs.stage.commit(manifest)?)
    } else {
        let signal = how.stop.map_or(0, |s| s.load(Ordering::Relaxed));
        Outcome::Partial(outputs.partial(&summary, &results, signal, None)?)
    };
    Ok(Simulated {
        results,
        summary,
        simulation_time,
        outcome,
    })
}

/// How a recording on the rig ended, for [`judge_recording`].
#[derive(Clone, Debug, PartialEq)]
pub enum RecordingEnd {
    /// It ran its whole duration.
    Complete,
    /// A fault ended it (the message): judged as a diverged simulation is, no window metrics or figures.
    Fault(String),
    /// A signal stopped it (the message): summary.json marked incomplete, no figures.
    Interrupted(String),
}

/// What [`judge_recording`] found beside the windows: which record they were judged on, the host's stalls,
/// and where the host's own columns would have judged the plant otherwise (for the command to say).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RecordingJudged {
    /// The record and the stalls, as `summary.json` `rig` has them (None: the trace has neither).
    pub rig: Option<pneuflex_scene::analysis::recorded::RigRecord>,
    /// Windows the loop's own columns judge otherwise than the board's record, one line each.
    pub host_verdicts: Vec<String>,
    /// Whether the windows were judged (not after a fault or a signal).
    pub windows_judged: bool,
}

/// A recording of run `index` of `scene` (its `trace.csv` in `dir`, the rig's columns) judged as `run`
/// judges a simulated run, from the same code: `summary.json` with the windows' metrics, the Lyapunov
/// check and the warnings (the claims are left out: they compare two runs), and for a complete recording
/// the figures (in `figures`' format). The windows are judged on the board's own record (its samples on
/// its clock) when the trace has one, so that the host's stalls are not read as the plant's motion; the
/// stalls are counted in `summary.json` `rig`. On an error the files it wrote are removed again, so the
/// recording stays as it was.
pub fn judge_recording(
    dir: &Path,
    scene: &Scene,
    index: usize,
    end: RecordingEnd,
    pwm_period_s: Option<f64>,
    figures: pneuflex_viz::Format,
) -> Result<RecordingJudged, OutputsError> {
    use pneuflex_scene::analysis::recorded::{self, RigRecord};
    let before: Vec<_> = list(dir)?;
    let written = (|| -> Result<RecordingJudged, OutputsError> {
        let path = dir.join("trace.csv");
        let unreadable = |message: String| OutputsError::Recording {
            path: path.clone(),
            message,
        };
        let text =
            std::fs::read_to_string(&path).map_err(|e| unreadable(format!("cannot read: {e}")))?;
        let trace =
            pneuflex_scene::Trace::from_csv(&text, &pneuflex_files::output::RIG_TRACE_COLUMNS)
                .map_err(unreadable)?;
        let rig_columns = recorded::rig_columns(&text).map_err(unreadable)?;
        let stalls = rig_columns
            .wall_time
            .as_ref()
            .and_then(|w| recorded::host_stalls(trace.t(), w, scene.dt_s));
        let on_board = recorded::on_board_grid(&trace, &rig_columns.board, scene.dt_s);
        // N ticks cover N·dt (the last one's time + dt): a full-length recording keeps its last window.
        let one = scene.one_run(index, trace.t().last().map_or(0.0, |t| t + scene.dt_s));
        let (fault, interrupted) = match end {
            RecordingEnd::Complete => (None, None),
            RecordingEnd::Fault(why) => (Some(why), None),
            RecordingEnd::Interrupted(why) => (None, Some(why)),
        };
        let name = &scene.runs[index].name;
        let mut r = pneuflex_scene::analysis::recorded::recorded_run(
            &one,
            0,
            name,
            trace,
            fault.or(interrupted.clone()),
            pwm_period_s,
        );
        if interrupted.is_some() {
            r.interrupted = r.diverged.take();
        }
        let mut judged = RecordingJudged {
            windows_judged: r.diverged.is_none() && r.interrupted.is_none(),
            ..RecordingJudged::default()
        };
        let has_record = rig_columns.wall_time.is_some() || !rig_columns.board.is_empty();
        let (judged_on, note) = match on_board {
            Ok((board, note)) => {
                // The windows on the board's record; the loop's columns stay the trace (the figures, what
                // the controller saw). Where the two verdicts differ, the difference is the host's.
                if judged.windows_judged {
                    let on_board = pneuflex_scene::analysis::windows::compute_windows(
                        &one,
                        &board,
                        pwm_period_s,
                    );
                    let on_host = std::mem::replace(&mut r.windows, on_board);
                    judged.host_verdicts = host_verdicts(&on_host, &r.windows, stalls.as_ref());
                    r.warnings.extend(judged.host_verdicts.iter().cloned());
                }
                ("board", note)
            }
            Err(why) => (
                "host",
                format!("the loop's columns (the newest sample at each tick): {why}"),
            ),
        };
        if has_record {
            judged.rig = Some(RigRecord {
                judged_on,
                note,
                host_stalls: stalls,
            });
        }
        let results = std::slice::from_ref(&r);
        let mut summary = pneuflex_scene::summary(&one, results);
        // The recording's trace is the rig's own, beside summary.json.
        summary.runs[0].trace = "trace.csv".into();
        summary.rig = judged.rig.clone();
        let path = dir.join("summary.json");
        let text = serde_json::to_string_pretty(&summary)
            .map_err(|e| write_error(&path, std::io::Error::other(e)))?;
        std::fs::write(&path, text + "\n").map_err(|e| write_error(&path, e))?;
        if r.diverged.is_none() && r.interrupted.is_none() {
            pneuflex_viz::write_figures(dir, &one, results, figures)?;
        }
        Ok(judged)
    })();
    if written.is_err() {
        for name in list(dir)? {
            if !before.contains(&name) {
                let p = dir.join(&name);
                let _ = if p.is_dir() {
                    std::fs::remove_dir_all(&p)
                } else {
                    std::fs::remove_file(&p)
                };
            }
        }
    }
    written
}

/// One line for each event window whose verdict (settled, oscillating) on the loop's own columns differs from
/// the board's record's: what the host's columns read, and that it is the host's timing.
fn host_verdicts(
    on_host: &[pneuflex_scene::run::result::WindowMetrics],
    on_board: &[pneuflex_scene::run::result::WindowMetrics],
    stalls: Option<&pneuflex_scene::analysis::recorded::HostStalls>,
) -> Vec<String> {
    let verdict = |e: &pneuflex_scene::analysis::metrics::EventResponse| match (
        e.settling_time_s,
        &e.not_settled,
    ) {
        (Some(ts), _) => format!("settled in {ts:.3} s"),
        (None, Some(why)) => format!("not settled: {why}"),
        (None, None) => "not settled".to_string(),
    };
    let why = match stalls {
        Some(s) if s.count > 0 => format!(
            "the host loop's {} stalls (the longest {:.1} ms), not the plant",
            s.count,
            1e3 * s.longest_s
        ),
        _ => "the host's reading of the samples (late, repeated or skipped), not the plant".into(),
    };
    on_host
        .iter()
        .zip(on_board)
        .filter_map(|(h, b)| match (&h.event, &b.event) {
            (Some(he), Some(be)) if he.settled != be.settled
                || he.oscillation.is_some() != be.oscillation.is_some() => {
                Some(format!(
                    "window `{}`: judged on the board's record: {}; the loop's own columns read {}: that is \
                     {why}",
                    b.name,
                    verdict(be),
                    verdict(he)
                ))
            }
            _ => None,
        })
        .collect()
}

fn list(dir: &Path) -> Result<Vec<std::ffi::OsString>, OutputsError> {
    let entries = std::fs::read_dir(dir).map_err(|e| write_error(dir, e))?;
    Ok(entries.flatten().map(|e| e.file_name()).collect())
}

fn write_error(path: &Path, os_error: std::io::Error) -> OutputsError {
    OutputsError::Scene(SceneError::Write {
        path: path.to_path_buf(),
        os_error,
    })
}
