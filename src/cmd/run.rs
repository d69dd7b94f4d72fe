//! `pneuflex run <scene.toml> [--out DIR]`: runs every controller of a scene, writes traces, summary and
//! figures into DIR (default `out/<scene name>/`), prints a short metrics table.
//!
//! DIR is written beside and renamed into place (pneuflex_files::OutputDir): a directory pneuflex did not
//! write is never replaced. SIGINT, SIGTERM and SIGHUP stop the simulation at the next tick; what exists is
//! written to `DIR.partial` with the reason in summary.json and the manifest, and the exit code is 128 +
//! the signal. A second signal ends the process at once.

use std::path::{Path, PathBuf};

use pneuflex_control::Sink;
use pneuflex_outputs::{Outcome, Outputs, Simulate, Simulated, Stopped, simulate_into};
use pneuflex_scene::{Limits, Plant, RunOptions, Scene};

use super::Exit;

/// Options of `run` beyond the scene and the output directory.
#[derive(Clone, Debug, Default)]
pub struct RunArgs {
    /// No progress bar and no metrics table.
    pub quiet: bool,
    /// `--rerun MODE [TARGET]`.
    pub rerun: Option<Vec<String>>,
    /// `--max-steps` and `--max-trace-mb`: what the scene's runs may cost.
    pub limits: Limits,
    /// `--format`: the figures' format.
    pub figures: pneuflex_viz::Format,
    /// `--mcap`: each run's trace also as a rosbag2 folder `<run>/bag/` (docs/ros2.md).
    pub mcap: bool,
}

/// Runs a scene file and writes its outputs; Err on bad input, on a write failure, when a run diverged
/// (the outputs are still written, with the run marked diverged in summary.json) or on a signal.
pub fn run(scene_path: &Path, out: Option<&Path>, args: &RunArgs) -> anyhow::Result<()> {
    // A scene with `[[actuators]]` (any URDF, several cylinders) has its own runner.
    let text = pneuflex_files::read_text(scene_path, pneuflex_files::InputKind::Scene)?;
    if pneuflex_scene::mechanism::MechanismScene::is_mechanism(&text) {
        return super::mechanism::run(
            scene_path,
            out,
            args.quiet,
            args.rerun.as_deref(),
            args.limits,
            args.figures,
            args.mcap,
        );
    }
    let scene = Scene::load(scene_path)?;
    let limits = args.limits;
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

/// [`run`] once the scene is loaded and within its limits: the output pipeline is
/// [`pneuflex_outputs::simulate_into`]; here the progress bar, the Rerun view and what is printed.
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
    let outputs = Outputs::stage(scene, scene_path, &dest, "run", &[])?;
    if let Some(words) = rerun
        && words.first().map(String::as_str) == Some("save")
        && let Some(target) = words.get(1)
    {
        outputs.refuse_inside(Path::new(target), "--rerun save")?;
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
        return Err(super::live::without_rerun(words, "run"));
    }

    // The bar stays hidden unless the simulation lasts longer than a moment.
    let bar = super::progress::Progress::new(quiet, format!("simulating {}", scene.name));
    let mut progress = |f: f64| bar.set(f);
    let stop = super::stop_flag()?;
    let how = Simulate {
        limits,
        stop: Some(&stop),
        figures: args.figures,
    };
    // With --mcap the bags go into the staged directory between the runs and the commit.
    let simulate = if args.mcap {
        simulate_with_bags
    } else {
        simulate_plain
    };
    #[cfg(feature = "rerun")]
    let simulated = match observer.as_mut() {
        Some(obs) => simulate(scene, outputs, how, &mut progress, obs)?,
        None => simulate(scene, outputs, how, &mut progress, &mut ())?,
    };
    #[cfg(not(feature = "rerun"))]
    let simulated = simulate(scene, outputs, how, &mut progress, &mut ())?;
    bar.finish();
    let Simulated {
        results,
        simulation_time,
        outcome,
        ..
    } = simulated;

    // Rerun logging only reads the plant: the results are those of a run without it. Its cost is reported.
    #[cfg(feature = "rerun")]
    if let Some(obs) = observer {
        let (cost, steps) = (obs.cost().as_secs_f64(), obs.steps());
        obs.finish()?;
        if !quiet {
            let sim_s = (simulation_time.as_secs_f64() - cost).max(1e-9);
            outln!(
                "rerun: {steps} steps logged; {:.0} steps/s without logging, {:.0} with ({cost:.2} s of logging)",
                steps as f64 / sim_s,
                steps as f64 / (sim_s + cost)
            );
        }
    }
    let dest = match outcome {
        Outcome::Committed(dest) => dest,
        Outcome::Partial(Stopped {
            to,
            reason,
            time_reached_s,
        }) => {
            let signal = stop.load(std::sync::atomic::Ordering::Relaxed);
            return Err(Exit {
                code: 128 + signal.clamp(1, 64) as u8,
                message: format!(
                    "{reason}: stopped at t = {time_reached_s:.3} s of run `{}`; the partial results are in \
                     {} (marked incomplete in summary.json); {} is untouched",
                    results.last().map_or("", |r| r.name.as_str()),
                    to.display(),
                    dest.display()
                ),
            }
            .into());
        }
    };

    if !quiet {
        outln!("{}", super::tables::metrics(&results));
        for w in results.iter().flat_map(|r| &r.warnings) {
            outln!("warning: {w}");
        }
        let claims = pneuflex_scene::analysis::claims::check_all(scene, &results);
        if !claims.is_empty() {
            outln!("{}", super::tables::claims(&claims));
        }
        outln!(
            "{}: {} run(s) of {} s simulated in {:.3} s; outputs in {}",
            scene.name,
            results.len(),
            scene.duration_s,
            simulation_time.as_secs_f64(),
            dest.display()
        );
    }
    super::fail_on_divergence(
        results
            .iter()
            .map(|r| (r.name.as_str(), r.diverged.as_deref())),
        &dest,
    )
}

/// [`simulate_into`] as it is (no `--mcap`).
fn simulate_plain(
    scene: &Scene,
    outputs: Outputs,
    how: Simulate<'_>,
    progress: &mut dyn FnMut(f64),
    sink: &mut dyn Sink<dyn Plant>,
) -> anyhow::Result<Simulated> {
    Ok(simulate_into(scene, outputs, how, progress, sink)?)
}

/// [`simulate_into`] with each run's bag (`--mcap`): the runs, then the bags into the staged directory,
/// then the traces, summary.json and figures and the commit (or the partial after a signal). The traces
/// are written after every run ended, not while the others simulate as simulate_into does.
fn simulate_with_bags(
    scene: &Scene,
    outputs: Outputs,
    how: Simulate<'_>,
    progress: &mut dyn FnMut(f64),
    sink: &mut dyn Sink<dyn Plant>,
) -> anyhow::Result<Simulated> {
    let start = std::time::Instant::now();
    let opts = RunOptions {
        limits: how.limits,
        stop: how.stop,
        on_run: None,
    };
    let results = pneuflex_scene::run_scene_with(scene, &opts, progress, sink)?;
    let simulation_time = start.elapsed();
    super::bag::write_runs(outputs.dir(), &results, &[])?;
    let summary = pneuflex_scene::summary(scene, &results);
    let outcome = if summary.complete {
        Outcome::Committed(outputs.commit(scene, &results, how.figures)?)
    } else {
        let signal = how
            .stop
            .map_or(0, |s| s.load(std::sync::atomic::Ordering::Relaxed));
        Outcome::Partial(outputs.commit_partial(scene, &results, signal, None)?)
    };
    Ok(Simulated {
        results,
        summary,
        simulation_time,
        outcome,
    })
}
