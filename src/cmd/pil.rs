//! `pneuflex rig pil --scene S [--run NAME] [--firmware ELF] [--out DIR]`: processor-in-the-loop. Each run's
//! controller executes in the firmware on an emulated Cortex-M4F (QEMU mps2-an386), the scene's plant on the
//! host in lockstep; the same run is simulated on the host and the two are compared tick by tick. Writes the
//! runs' traces, summary.json and figures as `run` does, plus comparison.json and comparison.md. Exits
//! non-zero if a valve command differs from the host's by more than 1e-9 or a metric differs.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use pneuflex_outputs::{Outputs, Stopped};
use pneuflex_pil::{PilRun, U_TOLERANCE};
use pneuflex_scene::Scene;

/// Where the firmware image is looked for when --firmware is not given: beside the current directory (a
/// checkout), then relative to this executable (target/<profile>/pneuflex in a checkout).
fn default_firmware() -> PathBuf {
    let rel = Path::new("firmware/target/thumbv7em-none-eabihf/release/pneuflex-firmware");
    if rel.is_file() {
        return rel.to_path_buf();
    }
    std::env::current_exe()
        .ok()
        .and_then(|exe| Some(exe.parent()?.parent()?.parent()?.join(rel)))
        .filter(|p| p.is_file())
        .unwrap_or_else(|| rel.to_path_buf())
}

/// Runs the command; `rerun` is `--rerun save PATH | spawn | connect URL` (the `rerun` feature).
pub fn pil(
    scene_path: &Path,
    run: Option<&str>,
    firmware: Option<&Path>,
    out: Option<&Path>,
    rerun: Option<&[String]>,
    figures: pneuflex_viz::Format,
) -> anyhow::Result<()> {
    // A scene of several actuators: one controller per channel of the board (pil_mechanism.rs).
    if pneuflex_files::read_text(scene_path, pneuflex_files::InputKind::Scene)
        .is_ok_and(|t| pneuflex_scene::mechanism::MechanismScene::is_mechanism(&t))
    {
        if let Some(words) = rerun {
            bail!(
                "--rerun {}: a scene of several actuators on the board shows no live view yet",
                words.join(" ")
            );
        }
        let elf = firmware.map_or_else(default_firmware, Path::to_path_buf);
        pneuflex_pil::qemu::qemu_binary()?;
        if !elf.exists() {
            bail!(
                "firmware {}: not found; build it with `cargo build --release` in firmware/ (docs/firmware.md), \
                 or pass --firmware",
                elf.display()
            );
        }
        pneuflex_pil::qemu::check_firmware(&elf)?;
        return super::pil_mechanism::pil(scene_path, run, &elf, out, figures);
    }
    let scene = Scene::load(scene_path)?;
    let indices: Vec<usize> = match run {
        Some(name) => vec![scene.run_index(name)?],
        // Frozen runs hold values from a whole-scene run: the board runs the adapting controllers.
        None => (0..scene.runs.len())
            .filter(|&i| scene.runs[i].frozen.is_none())
            .collect(),
    };
    let elf = firmware.map_or_else(default_firmware, Path::to_path_buf);
    // Missing QEMU or a file that is not the board's firmware: said before any output directory is made.
    pneuflex_pil::qemu::qemu_binary()?;
    if !elf.exists() {
        bail!(
            "firmware {}: not found; build it with `cargo build --release` in firmware/ (docs/firmware.md), \
             or pass --firmware",
            elf.display()
        );
    }
    pneuflex_pil::qemu::check_firmware(&elf)?;
    // The live view: each run's rows on the simulated timeline with `run`'s entity paths, plus the link's
    // quality and the board's update cost; one recording per run. Checked before anything runs.
    let live = super::live::LiveSink::parse(rerun, "rig pil")?;
    let dest = out
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new("out/pil").join(&scene.name));
    let outputs = Outputs::stage(&scene, scene_path, &dest, "rig pil", &[&elf])?;
    if let Some(words) = rerun
        && words.first().map(String::as_str) == Some("save")
        && let Some(target) = words.get(1)
    {
        outputs.refuse_inside(Path::new(target), "--rerun save")?;
    }

    let stop = super::stop_flag()?;
    let mut runs: Vec<PilRun> = Vec::new();
    for &i in &indices {
        errln!(
            "{}: run `{}` on the emulated board ...",
            scene.name,
            scene.runs[i].name
        );
        let name = &scene.runs[i].name;
        let mut view = live.view(
            &format!("pil/{}/{name}", scene.name),
            name,
            indices.len(),
            super::live::Timeline::Sim,
            scene.dt_s,
            pneuflex_scene::build_plant(&scene)?.pwm_period_s(),
        )?;
        let r = match pneuflex_pil::run_pil_observed(
            &scene,
            i,
            &elf,
            &mut |_| {},
            view.observer(),
            Some(stop.clone()),
        ) {
            Ok(r) => r,
            Err(pneuflex_pil::PilError::Interrupted(cut)) => {
                let _ = view.finish();
                return interrupted(outputs, &scene, &indices, &runs, Some(*cut), &stop);
            }
            Err(pneuflex_pil::PilError::Stopped) => {
                let _ = view.finish();
                return interrupted(outputs, &scene, &indices, &runs, None, &stop);
            }
            Err(e) => {
                return Err(anyhow::Error::new(e)
                    .context(format!("run `{name}` on the firmware {}", elf.display())));
            }
        };
        if let Some(rows) = view.finish()? {
            errln!("rerun: {rows} ticks of `{name}` logged");
        }
        runs.push(r);
    }
    // The outputs describe the runs done, as `run` writes them.
    let mut done = scene.clone();
    done.runs = indices.iter().map(|&i| scene.runs[i].clone()).collect();
    done.claims.clear();
    let results: Vec<_> = runs.iter().map(|r| r.firmware.clone()).collect();
    let report = comparison_json(&done, &runs);
    let json = serde_json::to_string_pretty(&report).context("comparison.json")?;
    std::fs::write(outputs.dir().join("comparison.json"), json + "\n")
        .context("writing comparison.json")?;
    let table = comparison_table(&done, &runs);
    std::fs::write(outputs.dir().join("comparison.md"), &table).context("writing comparison.md")?;
    let dest = outputs.commit(&done, &results, figures)?;
    outln!("{table}");
    outln!("outputs in {}", dest.display());
    let bad: Vec<String> = done
        .runs
        .iter()
        .zip(&runs)
        .filter_map(|(spec, r)| {
            let c = &r.comparison;
            if let Some(k) = c.first_divergent_tick {
                Some(format!(
                    "run `{}`: the firmware's valve command differs from the host's by more than {U_TOLERANCE:e} \
                     from tick {k} (max |du| = {:e})",
                    spec.name, c.max_abs_du
                ))
            } else if !c.metrics_equal || c.ticks_firmware != c.ticks_host {
                Some(format!("run `{}`: the metrics differ from the host's", spec.name))
            } else {
                r.firmware
                    .diverged
                    .as_ref()
                    .map(|why| format!("run `{}` diverged: {why}", spec.name))
            }
        })
        .collect();
    if !bad.is_empty() {
        bail!(
            "{} (see {})",
            bad.join("; "),
            dest.join("comparison.md").display()
        );
    }
    Ok(())
}

/// Commits an interrupted PIL command as `<dest>.partial`: the runs done, and the cut run's trace
/// (`trace.interrupted.csv`), with summary.json marked incomplete; no comparison of a cut run.
fn interrupted(
    outputs: Outputs,
    scene: &Scene,
    indices: &[usize],
    runs: &[PilRun],
    cut: Option<pneuflex_scene::RunResult>,
    stop: &std::sync::atomic::AtomicUsize,
) -> anyhow::Result<()> {
    let signal = stop.load(std::sync::atomic::Ordering::Relaxed);
    // The runs the command was asked for: summary.json lists those reached and, with fewer results than
    // runs, is incomplete even when the signal came before the first tick of the first run.
    let mut done = scene.clone();
    done.runs = indices.iter().map(|&i| scene.runs[i].clone()).collect();
    done.claims.clear();
    let mut results: Vec<_> = runs.iter().map(|r| r.firmware.clone()).collect();
    let cut_name = scene.runs[indices[runs.len()]].name.clone();
    results.extend(cut);
    let dest = outputs.dest().to_path_buf();
    let done_runs = format!("{} of {} runs", runs.len(), indices.len());
    let Stopped {
        to, time_reached_s, ..
    } = outputs.commit_partial(&done, &results, signal, Some(done_runs))?;
    Err(super::interrupted(
        signal,
        format!(
            "stopped at t = {time_reached_s:.3} s of run `{cut_name}` on the board; what ran is in {} (marked incomplete in summary.json); {} is untouched",
            to.display(),
            dest.display()
        ),
    ))
}

fn comparison_json(scene: &Scene, runs: &[PilRun]) -> serde_json::Value {
    let per_run: Vec<serde_json::Value> = scene
        .runs
        .iter()
        .zip(runs)
        .map(|(spec, r)| {
            serde_json::json!({
                "run": spec.name,
                "comparison": r.comparison,
                "link": r.link,
                "update_cost_ns": r.cost,
                "stack_peak_bytes": r.end.stack_peak_bytes,
            })
        })
        .collect();
    serde_json::json!({
        "scene": scene.name,
        "board": "QEMU mps2-an386 (Cortex-M4F), -icount shift=0: 1 instruction = 1 virtual ns",
        "u_tolerance": U_TOLERANCE,
        "runs": per_run,
    })
}

/// The comparison as a Markdown table, one row per run.
fn comparison_table(scene: &Scene, runs: &[PilRun]) -> String {
    let mut s = format!(
        "# {} on the emulated board vs the host simulation\n\n\
         | run | ticks | bit-identical ticks | max abs du | max abs dfe (N) | first tick abs du > 1e-9 | \
         the controller's own signals | metrics equal | update on board, mean (min-max) ns | stack peak (B) | \
         frames in/out, CRC errors, gaps |\n\
         |---|---|---|---|---|---|---|---|---|---|---|\n",
        scene.name
    );
    for (spec, r) in scene.runs.iter().zip(runs) {
        let c = &r.comparison;
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:e} | {:e} | {} | {} | {} | {:.0} ({}-{}) | {} | {}/{}, {}, {} |",
            spec.name,
            c.ticks,
            c.bit_identical_ticks,
            c.max_abs_du,
            c.max_abs_dfe_n,
            c.first_divergent_tick
                .map_or("none".to_string(), |k| k.to_string()),
            own_signals(&c.controller_signals, c.ticks),
            if c.metrics_equal { "yes" } else { "NO" },
            r.cost.mean_ns,
            r.cost.min_ns,
            r.cost.max_ns,
            r.end.stack_peak_bytes,
            r.link.frames_in,
            r.link.frames_out,
            r.link.crc_errors,
            r.link.seq_gaps,
        );
    }
    s
}

/// The controller's own signals in a cell: each name, with its largest difference where a tick differs.
fn own_signals(signals: &[pneuflex_pil::SignalComparison], ticks: usize) -> String {
    if signals.is_empty() {
        return "none declared".into();
    }
    let each: Vec<String> = signals
        .iter()
        .map(|s| {
            if s.bit_identical_ticks == ticks {
                format!("{} identical", s.name)
            } else {
                format!(
                    "{}: {} of {ticks} identical, max abs diff {:e} {}",
                    s.name, s.bit_identical_ticks, s.max_abs_diff, s.unit
                )
            }
        })
        .collect();
    each.join("; ")
}
