//! `pneuflex sweep <scene> --set KEY=SPEC ... [--out DIR]`: the scene at every point of a grid or sample of
//! its keys, in parallel; one table of every point's metrics per run, and heatmaps for two keys. The
//! engine is `pneuflex_sweep`; this wires arguments, the progress bar and the output directory.
//!
//! Limits come before work: the number of points (`--max-points`) and, with `--traces`, the bytes written
//! (`--max-output-mb`) are worked out from the arguments and refused before anything is allocated. SIGINT,
//! SIGTERM or SIGHUP stop the sweep at the next point: the rows done so far go to `DIR.partial` (marked in
//! its manifest and sweep.json), the previous output stays untouched, and the exit code is 128 + the signal.

use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::Instant;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use pneuflex_files::OutputDir;
use pneuflex_files::output::{Manifest, Partial, Writer};
use pneuflex_sweep::{SetArg, Status, Sweep, SweepError};

/// Options of `sweep`.
#[derive(Clone, Debug, Default)]
pub struct SweepArgs {
    /// `--set KEY=SPEC`, in order.
    pub sets: Vec<String>,
    /// `--samples N` for sampled keys.
    pub samples: Option<usize>,
    /// `--seed S` for sampled keys.
    pub seed: u64,
    /// `--threads N` (0: one per core).
    pub threads: usize,
    /// `--metric WINDOW.METRIC` for the heatmaps (several: a set of heatmaps each).
    pub metric: Vec<String>,
    /// `--format`: the heatmaps' format.
    pub format: pneuflex_viz::Format,
    /// `--traces`: every point's traces and summary.json.
    pub traces: bool,
    /// No progress bar and no summary line.
    pub quiet: bool,
    /// `--max-points`: the most points the sweep may have.
    pub max_points: u64,
    /// `--max-output-mb`: the most `--traces` may write, MiB.
    pub max_output_mb: u64,
    /// `--max-steps`, `--max-trace-mb`: what one run of a point may cost.
    pub limits: pneuflex_scene::Limits,
}

/// The default of `--max-output-mb`: what `--traces` may write unless raised, MiB.
pub const DEFAULT_MAX_OUTPUT_MB: u64 = 4096;

/// A progress bar over `n` items that appears when the work lasts more than a moment.
pub fn bar(n: u64, what: &str, quiet: bool) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(
        Some(n),
        if quiet {
            ProgressDrawTarget::hidden()
        } else {
            ProgressDrawTarget::stderr()
        },
    );
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} {msg} [{bar:40}] {pos}/{len} ({elapsed}, eta {eta}, {per_sec})",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    bar.set_message(what.to_string());
    bar
}

/// Runs the sweep and writes its directory.
pub fn sweep(scene_path: &Path, out: Option<&Path>, args: &SweepArgs) -> anyhow::Result<()> {
    let sets = args
        .sets
        .iter()
        .map(|s| SetArg::parse(s))
        .collect::<Result<Vec<_>, _>>()?;
    // The pool is made after the points are checked; its size is refused before that.
    pneuflex_sweep::engine::thread_pool(args.threads)?;
    let stop = super::stop_flag()?;
    let (sweep, checked_s) = checked_sweep(scene_path, &sets, args, &stop)?;
    let metrics = metrics_of(&sweep, args)?;
    let scene = &sweep.base_scene;
    let dest = out
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new("out").join(format!("{}-sweep", scene.name())));
    let inputs = scene.input_files(scene_path);
    let protect: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let stage = OutputDir::create(&dest, &protect, Writer::simulation("sweep"))?;
    let traces = args.traces.then(|| stage.path().join("points"));

    let n = sweep.len();
    let bar = bar(n as u64, &format!("sweeping {}", scene.name()), args.quiet);
    let start = Instant::now();
    let indices: Vec<usize> = (0..n).collect();
    // Rows go to sweep.csv chunk by chunk; only a heatmap's metrics are kept (memory does not grow with
    // the number of points otherwise), with a settling time's fragility that its map marks.
    let mut keep: Vec<usize> = metrics
        .iter()
        .map(|m| sweep.metric_index(m))
        .collect::<Result<_, _>>()?;
    keep.extend(
        keep.clone()
            .into_iter()
            .filter_map(|m| sweep.fragile_column(m)),
    );
    let heatmaps = pneuflex_sweep::output::has_heatmaps(&sweep);
    let mut table = pneuflex_sweep::output::TableWriter::create(stage.path(), &sweep)?;
    let mut kept = Vec::new();
    let mut counts = [0usize; 4];
    let mut done = 0usize;
    let ran = sweep.run_chunked(
        &indices,
        args.threads,
        traces.as_deref(),
        Some(&stop),
        &|| bar.inc(1),
        &mut |chunk| {
            table.write(&sweep, chunk)?;
            done += chunk.len();
            for r in chunk.iter().flat_map(|p| &p.runs) {
                counts[match r.status {
                    Status::Ok => 0,
                    Status::NotSettled => 1,
                    Status::Diverged => 2,
                    Status::Error => 3,
                }] += 1;
            }
            if heatmaps {
                kept.extend(chunk.iter().map(|p| p.slim(&keep)));
            }
            Ok(())
        },
    );
    let signal = match ran {
        Ok(()) => None,
        Err(SweepError::Interrupted) => Some(stop.load(Ordering::Relaxed)),
        Err(e) => return Err(e.into()),
    };
    table.finish()?;
    bar.finish_and_clear();
    let run_s = start.elapsed().as_secs_f64();

    let manifest = Manifest::new("sweep", env!("CARGO_PKG_VERSION"), scene.input_digests());
    if let Some(signal) = signal {
        return interrupted(stage, manifest, &sweep, signal, done, &dest);
    }
    pneuflex_sweep::output::write_figures(stage.path(), &sweep, &kept, &metrics, args.format)?;
    let dest = stage.commit(manifest)?;
    if !args.quiet {
        let threads = if args.threads == 0 {
            std::thread::available_parallelism().map_or(1, |n| n.get())
        } else {
            args.threads
        };
        outln!(
            "{}: {n} point(s) x {} run(s) on {threads} thread(s) in {run_s:.2} s ({:.1} scene-runs/s; points checked in {checked_s:.2} s): \
             {} ok, {} not settled, {} diverged, {} error; table in {}",
            scene.name(),
            scene.runs().len(),
            (n * scene.runs().len()) as f64 / run_s.max(1e-9),
            counts[0],
            counts[1],
            counts[2],
            counts[3],
            dest.join("sweep.csv").display()
        );
    }
    Ok(())
}

/// Commits an interrupted sweep as `<dest>.partial`: the `done` points' rows, marked partial in its manifest
/// and sweep.json.
fn interrupted(
    stage: OutputDir,
    manifest: Manifest,
    sweep: &Sweep,
    signal: usize,
    done: usize,
    dest: &Path,
) -> anyhow::Result<()> {
    let n = sweep.len();
    // The rows done so far, marked: no heatmaps of a grid with holes.
    pneuflex_sweep::output::write_record(stage.path(), sweep, Vec::new(), Some(done))?;
    let reason = pneuflex_scene::signal_name(signal);
    let to = stage.commit_partial(
        manifest,
        Partial {
            reason,
            time_reached_s: 0.0,
            done: Some(format!("{done} of {n} points")),
        },
    )?;
    Err(super::interrupted(
        signal,
        format!(
            "stopped after {done} of {n} points; their rows are in {} (marked partial); {} is untouched",
            to.join("sweep.csv").display(),
            dest.display()
        ),
    ))
}

/// Every point's scene parsed and validated, before anything runs (and before an output directory exists),
/// the point count checked first; a bar appears if the check takes over half a second. Returns the sweep
/// and the seconds the check took.
fn checked_sweep(
    scene_path: &Path,
    sets: &[SetArg],
    args: &SweepArgs,
    stop: &std::sync::atomic::AtomicUsize,
) -> anyhow::Result<(Sweep, f64)> {
    let checking = Instant::now();
    let sweep = {
        let probe =
            Sweep::new_unchecked(scene_path, sets, args.samples, args.seed, args.max_points)?;
        let bar = bar(probe.len() as u64, "checking the points", args.quiet);
        bar.set_draw_target(ProgressDrawTarget::hidden());
        let shown = std::sync::atomic::AtomicBool::new(false);
        let tick = || {
            if !args.quiet
                && checking.elapsed().as_millis() > 500
                && !shown.swap(true, Ordering::Relaxed)
            {
                bar.set_draw_target(ProgressDrawTarget::stderr());
            }
            bar.inc(1);
        };
        let checked = Sweep::new_checked(
            scene_path,
            sets,
            args.samples,
            args.seed,
            args.max_points,
            args.limits,
            pneuflex_sweep::Checking {
                stop: Some(stop),
                tick: &tick,
            },
        );
        bar.finish_and_clear();
        match checked {
            Err(SweepError::Interrupted) => {
                return Err(super::interrupted(
                    stop.load(Ordering::Relaxed),
                    "stopped while checking the points; nothing was run or written".into(),
                ));
            }
            other => other?,
        }
    };
    Ok((sweep, checking.elapsed().as_secs_f64()))
}

/// The metrics to tabulate (`--metric`, or the scene's default), each checked; `--traces` refused when it
/// would write more than `--max-output-mb`.
fn metrics_of(sweep: &Sweep, args: &SweepArgs) -> anyhow::Result<Vec<String>> {
    let metrics = if args.metric.is_empty() {
        vec![
            sweep
                .default_metric()
                .context("the scene has no metric windows: nothing to tabulate")?,
        ]
    } else {
        args.metric.clone()
    };
    for m in &metrics {
        sweep.metric_index(m)?;
    }
    if args.traces {
        let bytes = sweep.traces_bytes();
        let limit = args.max_output_mb.saturating_mul(1 << 20);
        if bytes > limit {
            anyhow::bail!(
                "--traces: {} points x {} run(s) of {} s at dt {} s would write about {:.1} GiB, more than \
                 the limit of {} MiB; sweep fewer points, or raise --max-output-mb",
                sweep.len(),
                sweep.base_scene.runs().len(),
                sweep.base_scene.duration_s(),
                sweep.base_scene.dt_s(),
                bytes as f64 / (1u64 << 30) as f64,
                args.max_output_mb
            );
        }
    }
    Ok(metrics)
}
