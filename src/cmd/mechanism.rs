//! `pneuflex run <scene.toml>` for a scene with `[[actuators]]` (any URDF, several cylinders): every run
//! puts its controller on every actuator; traces, summary.json, a force figure per run (`--format`) and the claims go
//! into DIR (default `out/<scene name>/`), staged beside it and renamed into place as `run` does. A signal
//! stops at the next tick and keeps what ran in `DIR.partial`.

use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;

use pneuflex_files::output::{Manifest, Partial, Writer};
use pneuflex_files::{InputDigest, OutputDir};
use pneuflex_scene::RunResult;
use pneuflex_scene::mechanism::{self, MechanismScene, MechanismSummary};

use super::Exit;

/// Runs a mechanism scene file and writes its outputs.
pub fn run(
    scene_path: &Path,
    out: Option<&Path>,
    quiet: bool,
    rerun: Option<&[String]>,
    limits: pneuflex_scene::Limits,
    figures: pneuflex_viz::Format,
    mcap: bool,
) -> anyhow::Result<()> {
    let scene = MechanismScene::load(scene_path)?;
    scene.check_budget(&limits)?;
    // The viewer (`--rerun spawn | save FILE | connect ADDR`, docs/rerun.md): links and per-actuator signals.
    #[cfg(feature = "rerun")]
    let mut viewer = match rerun {
        Some(words) => Some(pneuflex_rerun::MechanismRecorder::new(
            pneuflex_rerun::parse_sink(words)?,
            &scene,
        )?),
        None => None,
    };
    #[cfg(not(feature = "rerun"))]
    if let Some(words) = rerun {
        return Err(super::live::without_rerun(words, "run"));
    }
    let dest = out
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new("out").join(&scene.name));
    let inputs = scene.input_files();
    let protect: Vec<&Path> = std::iter::once(scene_path)
        .chain(inputs.iter().map(|(_, p)| p.as_path()))
        .collect();
    // Staged before anything runs: a bad --out fails at once.
    let stage = OutputDir::create(&dest, &protect, Writer::simulation("run"))?;
    let stop = super::stop_flag()?;
    let bar = super::progress::Progress::new(quiet, format!("simulating {}", scene.name));
    let started = std::time::Instant::now();
    #[cfg(feature = "rerun")]
    let runs = match viewer.as_mut() {
        Some(v) => mechanism::run_all(&scene, &mut |f| bar.set(f), Some(&stop), v)?,
        None => mechanism::run_all(&scene, &mut |f| bar.set(f), Some(&stop), &mut ())?,
    };
    #[cfg(not(feature = "rerun"))]
    let runs = mechanism::run_all(&scene, &mut |f| bar.set(f), Some(&stop), &mut ())?;
    bar.finish();
    #[cfg(feature = "rerun")]
    if let Some(v) = viewer {
        let cost = v.cost().as_secs_f64();
        v.finish()?;
        if !quiet {
            outln!("rerun: {cost:.2} s of logging");
        }
    }
    let elapsed = started.elapsed().as_secs_f64();
    let summary = mechanism::summarise(&scene, &runs);
    mechanism::write(stage.path(), &summary, &runs)?;
    if mcap {
        // Into the staged directory: committed with the traces, or with the partial.
        let actuators: Vec<String> = scene.actuators.iter().map(|a| a.name.clone()).collect();
        super::bag::write_runs(stage.path(), &runs, &actuators)?;
    }
    let digests: Vec<InputDigest> = inputs
        .iter()
        .filter_map(|(role, p)| InputDigest::of_file(p, role).ok())
        .collect();
    let manifest = Manifest::new("run", env!("CARGO_PKG_VERSION"), digests);
    let signal = stop.load(Ordering::Relaxed);
    if signal != 0 {
        let time_reached_s = runs
            .last()
            .and_then(|r| r.trace.t().last().copied())
            .unwrap_or(0.0);
        let reason = pneuflex_scene::signal_name(signal);
        let to = stage.commit_partial(
            manifest,
            Partial {
                reason: reason.clone(),
                time_reached_s,
                done: Some(format!("{} of {} runs", runs.len(), scene.runs.len())),
            },
        )?;
        return Err(Exit {
            code: 128 + signal.clamp(1, 64) as u8,
            message: format!(
                "{reason}: stopped at t = {time_reached_s:.3} s; the partial results are in {} (marked \
                 incomplete in its manifest); {} is untouched",
                to.display(),
                dest.display()
            ),
        }
        .into());
    }
    write_figures(stage.path(), &scene, &runs, figures)?;
    let dest = stage.commit(manifest)?;
    if !quiet {
        print_tables(&summary)?;
        outln!(
            "{}: {} run(s) of {} s, {} actuator(s), simulated in {elapsed:.3} s ({:.1}x real time); outputs in {}",
            scene.name,
            runs.len(),
            scene.duration_s,
            scene.actuators.len(),
            runs.len() as f64 * scene.duration_s / elapsed.max(1e-9),
            dest.display()
        );
    }
    super::fail_on_divergence(
        runs.iter()
            .map(|r| (r.name.as_str(), r.diverged.as_deref())),
        &dest,
    )
}

/// One figure per run: each actuator's contact force against its reference, a panel each.
pub(super) fn write_figures(
    dir: &Path,
    scene: &MechanismScene,
    runs: &[RunResult],
    format: pneuflex_viz::Format,
) -> anyhow::Result<()> {
    for r in runs.iter().filter(|r| r.diverged.is_none()) {
        let column = |name: &str| r.trace.column(name).unwrap_or_default();
        let t = column("t");
        let cols: Vec<(String, &[f64], &[f64])> = scene
            .actuators
            .iter()
            .map(|a| {
                (
                    a.name.clone(),
                    column(&format!("{}.f_ref", a.name)),
                    column(&format!("{}.f_e", a.name)),
                )
            })
            .collect();
        let panels: Vec<pneuflex_plot::overlay::Panel<'_>> = cols
            .iter()
            .map(|(name, f_r, f_e)| pneuflex_plot::overlay::Panel {
                title: format!("{} — {name}: contact force, run {}", scene.name, r.name),
                y_desc: "force [N]".into(),
                series: vec![
                    pneuflex_plot::overlay::Series {
                        label: "f_ref".into(),
                        t,
                        y: f_r,
                    },
                    pneuflex_plot::overlay::Series {
                        label: "f_e".into(),
                        t,
                        y: f_e,
                    },
                ],
                include_zero: true,
            })
            .collect();
        pneuflex_plot::overlay::write_overlay(
            &dir.join(&r.name).join(format!("force.{}", format.ext())),
            &panels,
        )?;
    }
    Ok(())
}

fn print_tables(summary: &MechanismSummary) -> anyhow::Result<()> {
    for r in &summary.runs {
        for w in &r.windows {
            let per: Vec<String> = w
                .actuators
                .iter()
                .map(|(a, m)| {
                    format!(
                        "{a} rms {:.3} N (mean {:.2} N)",
                        m.rms_force_error_n, m.mean_force_n
                    )
                })
                .collect();
            outln!(
                "{:<12} {:<14} {}; imbalance {:.3} N",
                r.name,
                w.window,
                per.join(", "),
                w.force_imbalance_n
            );
        }
    }
    for c in &summary.claims {
        outln!(
            "[{}] {}{}: {:.4} vs {:.4} ({})",
            if c.holds { "holds" } else { "FAILS" },
            c.statement,
            c.actuator
                .as_ref()
                .map(|a| format!(" ({a})"))
                .unwrap_or_default(),
            c.better_value,
            c.than_value,
            c.metric
        );
    }
    Ok(())
}
