//! `pneuflex tune <scene> --free KEY=[LO,HI] ... --over KEY=V1,V2,... --budget N --seed S`: CMA-ES over the
//! free keys, minimising the worst case over the environments of a weighted sum of a run's metrics. The
//! engine is `pneuflex_sweep::tune`; this wires arguments, the progress bar and the output directory.
//!
//! Everything is checked before the search starts (the keys, one meaning each; the boxes at their corners
//! in every environment; the budget against one generation and `--max-runs`). SIGINT, SIGTERM or SIGHUP
//! end the search after the generation under way: its history and a report marked interrupted go to
//! `DIR.partial`, the previous output stays untouched, and the exit code is 128 + the signal.

use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::Instant;

use pneuflex_files::OutputDir;
use pneuflex_files::output::{Manifest, Partial, Writer};
use pneuflex_sweep::SetArg;
use pneuflex_sweep::tune::{FreeArg, Term, TuneOptions, Tuner};

/// Options of `tune`.
#[derive(Clone, Debug, Default)]
pub struct TuneArgs {
    /// `--free KEY=[LO,HI]`.
    pub free: Vec<String>,
    /// `--over KEY=V1,V2,...`.
    pub over: Vec<String>,
    /// `--run NAME`.
    pub run: Option<String>,
    /// `--term WINDOW.METRIC=WEIGHT`.
    pub terms: Vec<String>,
    /// CMA-ES settings, budget, seed, threads.
    pub options: TuneOptions,
    /// No progress bar and no summary.
    pub quiet: bool,
    /// `--max-steps`, `--max-trace-mb`: what one run of a candidate may cost.
    pub limits: pneuflex_scene::Limits,
    /// `--format`: the convergence plot's.
    pub figures: pneuflex_viz::Format,
}

fn shell_word(s: &str) -> String {
    if !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_./=:,+".contains(c))
    {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

/// Runs the search and writes its directory.
pub fn tune(scene_path: &Path, out: Option<&Path>, args: &TuneArgs) -> anyhow::Result<()> {
    let free = args
        .free
        .iter()
        .map(|s| FreeArg::parse(s))
        .collect::<Result<Vec<_>, _>>()?;
    let over = args
        .over
        .iter()
        .map(|s| SetArg::parse(s))
        .collect::<Result<Vec<_>, _>>()?;
    let terms = args
        .terms
        .iter()
        .map(|s| Term::parse(s))
        .collect::<Result<Vec<_>, _>>()?;
    // The size of the search from the arguments alone, then the scene at the box's corners and at its own
    // values in every environment: checked before anything runs.
    pneuflex_sweep::tune::check_plan(free.len(), &over, &args.options)?;
    let tuner = Tuner::with_limits(
        scene_path,
        free,
        &over,
        args.run.as_deref(),
        terms,
        args.options.max_runs,
        args.limits,
    )?;
    args.options.check(tuner.free.len(), tuner.envs.len())?;
    let scene = &tuner.base_scene;
    let dest = out
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new("out").join(format!("{}-tune", scene.name())));
    let inputs = scene.input_files(scene_path);
    let protect: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let stage = OutputDir::create(&dest, &protect, Writer::simulation("tune"))?;

    // The command as recorded in the tuned scene and the report: without the options that do not change
    // the result (where it is written, threads, quiet), so that the files are the same whatever they are.
    let mut words = vec!["pneuflex".to_string()];
    let mut argv = std::env::args().skip(1);
    while let Some(a) = argv.next() {
        match a.as_str() {
            "--out" | "--threads" => {
                argv.next();
            }
            "-q" | "--quiet" => {}
            _ if a.starts_with("--out=") || a.starts_with("--threads=") => {}
            _ => words.push(shell_word(&a)),
        }
    }
    let command = words.join(" ");
    let bar = super::sweep::bar(
        args.options.budget as u64,
        &format!(
            "tuning {} over {} environment(s)",
            scene.name(),
            tuner.envs.len()
        ),
        args.quiet,
    );
    let start = Instant::now();
    let stop = super::stop_flag()?;
    let history = tuner.search(&args.options, Some(&stop), &|| bar.inc(1))?;
    bar.finish_and_clear();
    let search_s = start.elapsed().as_secs_f64();
    let signal = stop.load(Ordering::Relaxed);
    let reason = (signal != 0).then(|| pneuflex_scene::signal_name(signal));
    let summary = pneuflex_sweep::tune_output::write(
        stage.path(),
        &tuner,
        &args.options,
        &history,
        &command,
        reason.as_deref(),
        args.figures,
    )?;
    let manifest = Manifest::new("tune", env!("CARGO_PKG_VERSION"), scene.input_digests());
    if let Some(reason) = reason {
        let to = stage.commit_partial(
            manifest,
            Partial {
                reason,
                time_reached_s: 0.0,
                done: Some(format!(
                    "{} of {} candidates",
                    history.len(),
                    args.options.budget
                )),
            },
        )?;
        return Err(super::interrupted(
            signal,
            format!(
                "stopped after {} of {} candidates; the history and a report marked interrupted are in {} \
                 (no tuned scene); {} is untouched",
                history.len(),
                args.options.budget,
                to.display(),
                dest.display()
            ),
        ));
    }
    let dest = stage.commit(manifest)?;
    if let Some(why) = &summary.kept_start {
        errln!("note: {why} (report: {})", dest.join("report.md").display());
    }
    if !args.quiet {
        let j = |x: f64| {
            if x.is_finite() {
                format!("{x:.4}")
            } else {
                "inf".into()
            }
        };
        for (k, (b, a)) in summary
            .keys
            .iter()
            .zip(summary.before.iter().zip(&summary.after))
        {
            outln!("{k}: {b} -> {a}");
        }
        outln!(
            "{}: worst-case J {} -> {} after {} candidates ({} generations) in {search_s:.1} s; tuned scene {}, report {}",
            scene.name(),
            j(summary.j_before),
            j(summary.j_after),
            summary.evaluations,
            summary.generations,
            summary
                .tuned_scene
                .as_ref()
                .map_or("none (the start is kept)".into(), |t| dest
                    .join(t)
                    .display()
                    .to_string()),
            dest.join("report.md").display()
        );
    }
    Ok(())
}
