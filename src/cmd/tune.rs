//! `pneuflex tune <scene> --free KEY=[LO,HI] ... --over KEY=V1,V2,... --budget N --seed S`: CMA-ES over the
//! free keys, minimising the worst case over the environments of a weighted sum of a run's metrics. The
//! engine is `pneuflex_sweep::tune`; this wires arguments, the progress bar and the output directory.

use std::path::{Path, PathBuf};
use std::time::Instant;

use pneuflex_files::OutputDir;
use pneuflex_files::output::{Manifest, Recoverable};
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
    // The scene at the box's corners and at its own values, in every environment: checked before anything runs.
    let tuner = Tuner::new(scene_path, free, &over, args.run.as_deref(), terms)?;
    let scene = &tuner.base_scene;
    let dest = out
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new("out").join(format!("{}-tune", scene.name)));
    let inputs = super::run::inputs_of(scene, scene_path);
    let protect: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let stage = OutputDir::create(&dest, &protect, Recoverable::Regenerable)?;

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
            scene.name,
            tuner.envs.values.len()
        ),
        args.quiet,
    );
    let start = Instant::now();
    let history = tuner.search(&args.options, &|| bar.inc(1))?;
    bar.finish_and_clear();
    let search_s = start.elapsed().as_secs_f64();
    let summary = pneuflex_sweep::tune_output::write(
        stage.path(),
        &tuner,
        &args.options,
        &history,
        &command,
    )?;
    let manifest = Manifest::new(
        "tune",
        env!("CARGO_PKG_VERSION"),
        pneuflex_scene::scene_inputs(scene),
    );
    let dest = stage.commit(manifest)?;
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
            println!("{k}: {b} -> {a}");
        }
        println!(
            "{}: worst-case J {} -> {} after {} candidates ({} generations) in {search_s:.1} s; tuned scene {}, report {}",
            scene.name,
            j(summary.j_before),
            j(summary.j_after),
            summary.evaluations,
            summary.generations,
            dest.join(&summary.tuned_scene).display(),
            dest.join("report.md").display()
        );
    }
    Ok(())
}
