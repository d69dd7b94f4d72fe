//! `pneuflex rig pil --scene <scene with [[actuators]]>`: processor-in-the-loop for several actuators. One
//! firmware runs each actuator's controller on its own channel (docs/protocol.md §5, "Several controllers"),
//! the scene's mechanism runs on the host in lockstep through the one loop, and the same run is simulated on
//! the host; each actuator is compared tick by tick (`pneuflex_pil::mechanism`). Writes the runs' traces,
//! summary.json and figures as `run` writes a mechanism's, plus comparison.json and comparison.md; exits
//! non-zero if any actuator's valve command differs from the host's by more than 1e-9 or a metric differs.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use pneuflex_files::OutputDir;
use pneuflex_files::output::{Manifest, Writer};
use pneuflex_pil::U_TOLERANCE;
use pneuflex_pil::mechanism::{MechanismPilRun, run_pil_mechanism};
use pneuflex_scene::mechanism::MechanismScene;

/// Runs the command on a mechanism scene (`elf` checked by the caller).
pub fn pil(
    scene_path: &Path,
    run: Option<&str>,
    elf: &Path,
    out: Option<&Path>,
    figures: pneuflex_viz::Format,
) -> anyhow::Result<()> {
    let scene = MechanismScene::load(scene_path)?;
    let indices: Vec<usize> = match run {
        Some(name) => vec![
            scene
                .runs
                .iter()
                .position(|r| r.name == name)
                .ok_or_else(|| {
                    anyhow::anyhow!(
                        "{}: no run named '{name}' (runs: {})",
                        scene_path.display(),
                        scene
                            .runs
                            .iter()
                            .map(|r| r.name.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                })?,
        ],
        None => (0..scene.runs.len()).collect(),
    };
    let dest = out
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new("out/pil").join(&scene.name));
    let inputs = scene.input_files();
    let protect: Vec<&Path> = std::iter::once(scene_path)
        .chain(std::iter::once(elf))
        .chain(inputs.iter().map(|(_, p)| p.as_path()))
        .collect();
    let stage = OutputDir::create(&dest, &protect, Writer::simulation("rig pil"))?;
    let stop = super::stop_flag()?;
    let mut runs: Vec<MechanismPilRun> = Vec::new();
    for &i in &indices {
        errln!(
            "{}: run `{}` on the emulated board, {} controllers ...",
            scene.name,
            scene.runs[i].name,
            scene.actuators.len()
        );
        let r = match run_pil_mechanism(&scene, i, elf, &mut |_| {}, Some(stop.clone())) {
            Ok(r) => r,
            // A signal: nothing of this command is kept (the stage is removed), the exit says which.
            Err(pneuflex_pil::PilError::Interrupted(_) | pneuflex_pil::PilError::Stopped) => {
                let signal = stop.load(std::sync::atomic::Ordering::Relaxed);
                return Err(super::interrupted(
                    signal.max(2),
                    format!(
                        "stopped during run `{}` on the board; {} is untouched",
                        scene.runs[i].name,
                        dest.display()
                    ),
                ));
            }
            Err(e) => {
                return Err(anyhow::Error::new(e).context(format!(
                    "run `{}` on the firmware {}",
                    scene.runs[i].name,
                    elf.display()
                )));
            }
        };
        runs.push(r);
    }
    let mut done = scene.clone();
    done.runs = indices.iter().map(|&i| scene.runs[i].clone()).collect();
    done.claims.clear();
    let results: Vec<_> = runs.iter().map(|r| r.firmware.clone()).collect();
    let summary = pneuflex_scene::mechanism::summarise(&done, &results);
    pneuflex_scene::mechanism::write(stage.path(), &summary, &results)?;
    super::mechanism::write_figures(stage.path(), &done, &results, figures)?;
    let json =
        serde_json::to_string_pretty(&comparison_json(&done, &runs)).context("comparison.json")?;
    std::fs::write(stage.path().join("comparison.json"), json + "\n")
        .context("writing comparison.json")?;
    let table = comparison_table(&done, &runs);
    std::fs::write(stage.path().join("comparison.md"), &table).context("writing comparison.md")?;
    let mut digests: Vec<pneuflex_files::InputDigest> = inputs
        .iter()
        .filter_map(|(role, p)| pneuflex_files::InputDigest::of_file(p, role).ok())
        .collect();
    digests.push(pneuflex_files::InputDigest::of_file(elf, "firmware")?);
    let dest = stage.commit(Manifest::new("rig pil", env!("CARGO_PKG_VERSION"), digests))?;
    outln!("{table}");
    outln!("outputs in {}", dest.display());
    let mut bad = Vec::new();
    for (spec, r) in done.runs.iter().zip(&runs) {
        for (name, c, _) in &r.actuators {
            if let Some(k) = c.first_divergent_tick {
                bad.push(format!(
                    "run `{}`, actuator `{name}`: the firmware's valve command differs from the host's by more \
                     than {U_TOLERANCE:e} from tick {k} (max |du| = {:e})",
                    spec.name, c.max_abs_du
                ));
            }
        }
        if !r.metrics_equal {
            bad.push(format!(
                "run `{}`: the metrics differ from the host's",
                spec.name
            ));
        }
        if let Some(why) = &r.firmware.diverged {
            bad.push(format!("run `{}` diverged: {why}", spec.name));
        }
    }
    if !bad.is_empty() {
        bail!(
            "{} (see {})",
            bad.join("; "),
            dest.join("comparison.md").display()
        );
    }
    Ok(())
}

fn comparison_json(scene: &MechanismScene, runs: &[MechanismPilRun]) -> serde_json::Value {
    let per_run: Vec<serde_json::Value> = scene
        .runs
        .iter()
        .zip(runs)
        .map(|(spec, r)| {
            serde_json::json!({
                "run": spec.name,
                "actuators": r.actuators.iter().map(|(name, c, cost)| serde_json::json!({
                    "actuator": name,
                    "comparison": c,
                    "update_cost_ns": cost,
                })).collect::<Vec<_>>(),
                "metrics_equal": r.metrics_equal,
                "link": r.link,
                "stack_peak_bytes": r.ends.iter().map(|e| e.stack_peak_bytes).max(),
            })
        })
        .collect();
    serde_json::json!({
        "scene": scene.name,
        "board": "QEMU mps2-an386 (Cortex-M4F), -icount shift=0: 1 instruction = 1 virtual ns; one controller per channel",
        "u_tolerance": U_TOLERANCE,
        "runs": per_run,
    })
}

/// One row per run and actuator.
fn comparison_table(scene: &MechanismScene, runs: &[MechanismPilRun]) -> String {
    let mut s = format!(
        "# {} on the emulated board, one controller per actuator, vs the host simulation\n\n\
         | run | actuator | ticks | bit-identical ticks | max abs du | first tick abs du > 1e-9 | the controller's \
         own signals identical | metrics equal | update on board, mean (min-max) ns | stack peak (B) |\n\
         |---|---|---|---|---|---|---|---|---|---|\n",
        scene.name
    );
    for (spec, r) in scene.runs.iter().zip(runs) {
        for (name, c, cost) in &r.actuators {
            let own = if c.controller_signals.is_empty() {
                "none declared".to_string()
            } else {
                c.controller_signals
                    .iter()
                    .map(|g| format!("{} {}/{}", g.name, g.bit_identical_ticks, c.ticks))
                    .collect::<Vec<_>>()
                    .join(", ")
            };
            let _ = writeln!(
                s,
                "| {} | {name} | {} | {} | {:e} | {} | {own} | {} | {:.0} ({}-{}) | {} |",
                spec.name,
                c.ticks,
                c.bit_identical_ticks,
                c.max_abs_du,
                c.first_divergent_tick
                    .map_or("none".to_string(), |k| k.to_string()),
                if r.metrics_equal { "yes" } else { "NO" },
                cost.mean_ns,
                cost.min_ns,
                cost.max_ns,
                r.ends.iter().map(|e| e.stack_peak_bytes).max().unwrap_or(0),
            );
        }
    }
    s
}
