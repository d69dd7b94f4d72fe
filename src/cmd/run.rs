//! `pneuflex run <scene.toml> [--out DIR]`: runs every controller of a scene, writes traces, summary and
//! figures into DIR (default `out/<scene name>/`), prints a short metrics table.
//!
//! DIR is written beside and renamed into place (pneuflex_files::OutputDir): a directory pneuflex did not
//! write is never replaced. SIGINT, SIGTERM and SIGHUP stop the simulation at the next tick; what exists is
//! written to `DIR.partial` with the reason in summary.json and the manifest, and the exit code is 128 +
//! the signal. A second signal ends the process at once.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use pneuflex_files::OutputDir;
use pneuflex_files::output::{Manifest, Partial, Writer};
use pneuflex_scene::{Limits, RunOptions, RunResult, Scene, WindowKind, run_scene_with};

use super::Exit;

/// Options of `run` beyond the scene and the output directory.
#[derive(Clone, Debug, Default)]
pub struct RunArgs {
    /// No progress bar and no metrics table.
    pub quiet: bool,
    /// `--rerun MODE [TARGET]`.
    pub rerun: Option<Vec<String>>,
    /// `--max-steps`: integration steps allowed per run.
    pub max_steps: Option<u64>,
    /// `--max-trace-mb`: trace memory allowed, MiB.
    pub max_trace_mb: Option<u64>,
}

/// The input files a run must never write over: the scene, and the sheet and URDF it names.
pub(super) fn inputs_of(scene: &Scene, scene_path: &Path) -> Vec<PathBuf> {
    let mut v = vec![scene_path.to_path_buf()];
    v.extend(scene.input_files().into_iter().skip(1).map(|(_, p)| p));
    v
}

/// The limits of one run from `--max-steps` and `--max-trace-mb` (the defaults where absent).
pub fn limits(max_steps: Option<u64>, max_trace_mb: Option<u64>) -> Limits {
    let mut limits = Limits::default();
    if let Some(n) = max_steps {
        limits.max_steps_per_run = n;
    }
    if let Some(mb) = max_trace_mb {
        limits.max_trace_bytes = mb.saturating_mul(1 << 20);
    }
    limits
}

/// Runs a scene file and writes its outputs; Err on bad input, on a write failure, when a run diverged
/// (the outputs are still written, with the run marked diverged in summary.json) or on a signal.
pub fn run(scene_path: &Path, out: Option<&Path>, args: &RunArgs) -> anyhow::Result<()> {
    let scene = Scene::load(scene_path)?;
    let limits = limits(args.max_steps, args.max_trace_mb);
    scene.check_budget(&limits)?;
    // The scene's warnings (the inner-loop margin analysis among them costs as much as a short simulation)
    // are worked out beside the runs and printed as soon as they are known, before the command ends.
    std::thread::scope(|s| {
        s.spawn(|| {
            for w in pneuflex_scene::analysis::advice::warnings(&scene) {
                let at = pneuflex_files::toml_key_position(&scene.text, &w.key)
                    .map(|p| format!(":{p}"))
                    .unwrap_or_default();
                errln!("warning: {}{at}: {w}", scene_path.display());
            }
        });
        run_scene_file(&scene, scene_path, out, args, limits)
    })
}

/// [`run`] once the scene is loaded and within its limits.
fn run_scene_file(
    scene: &Scene,
    scene_path: &Path,
    out: Option<&Path>,
    args: &RunArgs,
    limits: Limits,
) -> anyhow::Result<()> {
    let (quiet, rerun) = (args.quiet, args.rerun.as_deref());
    let dest = out
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new("out").join(&scene.name));
    // The output directory is checked and staged before anything runs: a bad --out fails at once.
    let inputs = inputs_of(scene, scene_path);
    let protect: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let stage = OutputDir::create(&dest, &protect, Writer::simulation("run"))?;
    if let Some(words) = rerun
        && words.first().map(String::as_str) == Some("save")
        && let Some(target) = words.get(1)
    {
        let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
        let t = abs(Path::new(target));
        if t.starts_with(abs(&dest)) || t.starts_with(abs(&stage.partial_dest())) {
            bail!(
                "--rerun save {target}: the recording would be inside the output directory {}, which is \
                 replaced as a whole by the next run; save it elsewhere (e.g. next to it)",
                dest.display()
            );
        }
    }
    #[cfg(feature = "rerun")]
    let mut observer = match rerun {
        Some(words) => Some(pneuflex_rerun::SceneRecorder::new(
            pneuflex_rerun::parse_sink(words)?,
            scene,
        )?),
        None => None,
    };
    #[cfg(not(feature = "rerun"))]
    if let Some(words) = rerun {
        bail!(
            "--rerun {}: this pneuflex was built without Rerun; rebuild with \
             `cargo run --release --features rerun -- run ...` (docs/rerun.md)",
            words.join(" ")
        );
    }

    // The bar stays hidden unless the simulation lasts longer than a moment.
    let bar = ProgressBar::with_draw_target(Some(1000), ProgressDrawTarget::hidden());
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} {msg} [{bar:40}] {percent:>3}% ({elapsed}, eta {eta})",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    bar.set_message(format!("simulating {}", scene.name));
    let start = Instant::now();
    let mut shown = false;
    let mut progress = |f: f64| {
        if !quiet && !shown && start.elapsed() > Duration::from_millis(300) {
            bar.set_draw_target(ProgressDrawTarget::stderr());
            shown = true;
        }
        bar.set_position((f.clamp(0.0, 1.0) * 1000.0) as u64);
    };
    let stop = super::stop_flag()?;
    // Each run's trace is written as soon as the run is done, while the other runs still simulate: the runs
    // end at different times, and the core that finished first would otherwise idle (docs/performance.md).
    // The last run's trace waits for the end, beside the figures: they can start only then, and queued behind
    // it they left one core alone with the last figure. The scope ends when every trace is written.
    let dir = stage.path();
    let trace_errors = std::sync::Mutex::new(Vec::new());
    let write_trace_of = |r: &RunResult| {
        if let Err(e) = pneuflex_scene::write_trace(dir, r) {
            trace_errors
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .push((r.name.clone(), e));
        }
    };
    let ended = std::sync::atomic::AtomicUsize::new(0);
    let last_run = std::sync::Mutex::new(None::<String>);
    let (results, sim_time, summary, written, figures) = rayon::in_place_scope(
        |writers| -> anyhow::Result<_> {
            let write_trace = |r: &RunResult| {
                if ended.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1 == scene.runs.len()
                {
                    *last_run.lock().unwrap_or_else(|e| e.into_inner()) = Some(r.name.clone());
                    return;
                }
                let (r, write) = (r.clone(), &write_trace_of);
                writers.spawn(move |_| write(&r));
            };
            let opts = RunOptions {
                limits,
                stop: Some(&stop),
                on_run: Some(&write_trace),
            };
            #[cfg(feature = "rerun")]
            let results = match observer.as_mut() {
                Some(obs) => run_scene_with(scene, &opts, &mut progress, obs)?,
                None => run_scene_with(scene, &opts, &mut progress, &mut ())?,
            };
            #[cfg(not(feature = "rerun"))]
            let results = run_scene_with(scene, &opts, &mut progress, &mut ())?;
            bar.finish_and_clear();
            let sim_time = start.elapsed();

            // Rerun logging only reads the plant: the results are those of a run without it. Its cost is
            // reported.
            #[cfg(feature = "rerun")]
            if let Some(obs) = observer {
                let (cost, steps) = (obs.cost().as_secs_f64(), obs.steps());
                obs.finish()?;
                if !quiet {
                    let sim_s = (sim_time.as_secs_f64() - cost).max(1e-9);
                    outln!(
                        "rerun: {steps} steps logged; {:.0} steps/s without logging, {:.0} with ({cost:.2} s of logging)",
                        steps as f64 / sim_s,
                        steps as f64 / (sim_s + cost)
                    );
                }
            }

            let summary = pneuflex_scene::summary(scene, &results);
            // summary.json beside the figures (different files), while the last traces are written. Figures
            // only for a complete command with a run that did not diverge.
            let figures = summary.complete && results.iter().any(|r| r.diverged.is_none());
            let last_run = last_run.into_inner().unwrap_or_else(|e| e.into_inner());
            let (figures, written) = rayon::join(
                || {
                    figures.then(|| {
                        pneuflex_viz::write_figures(dir, scene, &results, pneuflex_viz::Format::Png)
                    })
                },
                // The other core takes this first (a join's second half is what is stolen), then figures.
                || {
                    if let Some(r) = results.iter().find(|r| Some(&r.name) == last_run.as_ref()) {
                        write_trace_of(r);
                    }
                    pneuflex_scene::write_summary(dir, scene, &results)
                },
            );
            Ok((results, sim_time, summary, written, figures))
        },
    )?;
    // The first failed trace in run order, then summary.json.
    let mut trace_errors = trace_errors.into_inner().unwrap_or_else(|e| e.into_inner());
    trace_errors.sort_by_key(|(name, _)| results.iter().position(|r| &r.name == name));
    if let Some((_, e)) = trace_errors.into_iter().next() {
        return Err(e.into());
    }
    written?;
    let manifest = Manifest::new("run", env!("CARGO_PKG_VERSION"), summary.inputs.clone());
    let signal = stop.load(std::sync::atomic::Ordering::Relaxed);
    if !summary.complete {
        let reason = pneuflex_scene::signal_name(signal.max(2));
        let time_reached_s = results
            .last()
            .and_then(|r| r.trace.t().last().copied())
            .unwrap_or(0.0);
        let to = stage.commit_partial(
            manifest,
            Partial {
                reason: reason.clone(),
                time_reached_s,
                done: None,
            },
        )?;
        return Err(Exit {
            code: 128 + signal.clamp(1, 64) as u8,
            message: format!(
                "{reason}: stopped at t = {time_reached_s:.3} s of run `{}`; the partial results are in {} \
                 (marked incomplete in summary.json); {} is untouched",
                results.last().map_or("", |r| r.name.as_str()),
                to.display(),
                dest.display()
            ),
        }
        .into());
    }
    if let Some(figures) = figures {
        figures.context("writing figures")?;
    }
    let dest = stage.commit(manifest)?;

    if !quiet {
        outln!("{}", table(&results));
        for w in results.iter().flat_map(|r| &r.warnings) {
            outln!("warning: {w}");
        }
        let claims = pneuflex_scene::analysis::claims::check_all(scene, &results);
        if !claims.is_empty() {
            outln!("{}", claims_table(&claims));
        }
        outln!(
            "{}: {} run(s) of {} s simulated in {:.3} s; outputs in {}",
            scene.name,
            results.len(),
            scene.duration_s,
            sim_time.as_secs_f64(),
            dest.display()
        );
    }
    let diverged: Vec<String> = results
        .iter()
        .filter_map(|r| {
            r.diverged
                .as_ref()
                .map(|why| format!("run `{}` diverged: {why}", r.name))
        })
        .collect();
    if !diverged.is_empty() {
        bail!(
            "{} (marked in {})",
            diverged.join("; "),
            dest.join("summary.json").display()
        );
    }
    Ok(())
}

/// The scene's claims: the statement, the two values and the verdict.
fn claims_table(claims: &[pneuflex_scene::analysis::claims::ClaimResult]) -> String {
    let mut s = String::from("claims:\n");
    for c in claims {
        let v = |x: Option<f64>| x.map_or("-".to_string(), |x| format!("{x:.4}"));
        let fragile = c
            .fragile
            .as_ref()
            .map_or(String::new(), |f| format!("; fragile: {f}"));
        let _ = writeln!(
            s,
            "  {:<13} {} ({} {}: {} {}, {} {}{fragile})",
            if c.holds { "holds" } else { "DOES NOT HOLD" },
            c.statement,
            c.window,
            c.metric,
            c.better,
            v(c.better_value),
            c.than,
            v(c.than_value)
        );
    }
    s
}

fn opt(v: Option<f64>, unit: &str, prec: usize) -> String {
    match v {
        Some(x) if x.is_finite() => format!("{x:.prec$} {unit}"),
        _ => "-".into(),
    }
}

/// A short text table: one line per run and window with the window's main metrics.
fn table(results: &[RunResult]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<12} {:<18} {:>12}  details",
        "run", "window", "RMS error"
    );
    for r in results {
        if let Some(why) = &r.diverged {
            let _ = writeln!(s, "{:<12} DIVERGED: {why}", r.name);
            continue;
        }
        for w in &r.windows {
            let details = match w.kind {
                WindowKind::Sine => format!("phase lag {}", opt(w.phase_lag_deg, "deg", 2)),
                WindowKind::Step => {
                    format!("steady-state error {}", opt(w.steady_state_error_n, "N", 3))
                }
                WindowKind::Event => match &w.event {
                    Some(e) => format!(
                        "peak {}, jump {}, overshoot {} ({:.0} % of the jump), {}",
                        opt(Some(e.peak_force_n), "N", 2),
                        opt(Some(e.jump_n), "N", 2),
                        opt(Some(e.recovery_overshoot_n), "N", 3),
                        e.recovery_overshoot_pct,
                        match (e.settling_time_s, &e.not_settled) {
                            (Some(ts), _) => match e.fragility() {
                                Some(f) => format!("settled in {ts:.3} s ({f})"),
                                None => format!("settled in {ts:.3} s"),
                            },
                            (None, Some(why)) => format!("NOT SETTLED: {why}"),
                            (None, None) => "not settled".into(),
                        }
                    ),
                    None => "-".into(),
                },
            };
            let _ = writeln!(
                s,
                "{:<12} {:<18} {:>10.4} N  {details}",
                r.name, w.name, w.rms_force_error_n
            );
        }
    }
    s
}
