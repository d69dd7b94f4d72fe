//! `pneuflex run <scene.toml> [--out DIR]`: runs every controller of a scene, writes traces, summary and
//! figures into DIR (default `out/<scene name>/`), prints a short metrics table.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use pneuflex_scene::{RunResult, Scene, Staging, WindowKind, run_scene, write_results};

/// Runs a scene file and writes its outputs; Err on bad input, on a write failure or when a run diverged
/// (the outputs are still written, with the run marked diverged in summary.json).
pub fn run(
    scene_path: &Path,
    out: Option<&Path>,
    quiet: bool,
    rerun: Option<&[String]>,
) -> anyhow::Result<()> {
    let scene = Scene::load(scene_path)?;
    #[cfg(feature = "rerun")]
    let mut observer = match rerun {
        Some(words) => Some(super::rerun_log::RerunObserver::new(
            super::rerun_log::parse_sink(words)?,
            &scene,
            scene_path,
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
    let dest = out
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new("out").join(&scene.name));

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
    #[cfg(feature = "rerun")]
    let results = match observer.as_mut() {
        Some(obs) => pneuflex_scene::run_scene_observed(&scene, &mut progress, obs)?,
        None => run_scene(&scene, &mut progress)?,
    };
    #[cfg(not(feature = "rerun"))]
    let results = run_scene(&scene, &mut progress)?;
    bar.finish_and_clear();
    let sim_time = start.elapsed();

    // Rerun logging only reads the plant: the results are those of a run without it. Its cost is reported.
    #[cfg(feature = "rerun")]
    if let Some(obs) = observer {
        let (cost, steps) = (obs.cost.as_secs_f64(), obs.steps);
        obs.finish()?;
        if !quiet {
            let sim_s = (sim_time.as_secs_f64() - cost).max(1e-9);
            println!(
                "rerun: {steps} steps logged; {:.0} steps/s without logging, {:.0} with ({cost:.2} s of logging)",
                steps as f64 / sim_s,
                steps as f64 / (sim_s + cost)
            );
        }
    }

    let stage = Staging::new(&dest)?;
    write_results(stage.path(), &scene, &results)?;
    if results.iter().any(|r| r.diverged.is_none()) {
        pneuflex_viz::write_figures(stage.path(), &scene, &results, pneuflex_viz::Format::Png)
            .context("writing figures")?;
    }
    let dest = stage.commit()?;

    if !quiet {
        println!("{}", table(&results));
        println!(
            "{}: {} run(s) of {} s simulated in {:.2} s; outputs in {}",
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
                        "peak {}, overshoot {}, settling {} (2% band: {})",
                        opt(Some(e.peak_force_n), "N", 2),
                        opt(Some(e.recovery_overshoot_n), "N", 3),
                        opt(e.settling_time_to_tracking_s, "s", 3),
                        e.settling_time_s
                            .map_or("not settled".into(), |t| format!("{t:.3} s")),
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
