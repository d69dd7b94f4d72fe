//! `pneuflex compare SCENE --rig-log [RUN=]TRACE.csv` for a scene with `[[actuators]]`: the recording of one of
//! its runs on a board of several channels (`rig run --scene`, src/cmd/rig_mechanism.rs), checked to be one,
//! against the scene's simulation of the same run for as long as the board ran: each actuator's force and
//! position differences, each window's metrics per actuator from the mechanism's own metric code (rig,
//! simulation, difference), a figure per actuator with both forces, `compare.json` and `compare.md`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::bail;
use pneuflex_files::output::{Manifest, OutputDir, Writer};
use pneuflex_scene::mechanism::summary::{MechanismSummary, summarise};
use pneuflex_scene::mechanism::{MechanismScene, run_all};
use pneuflex_scene::{RunResult, Trace};

use super::CompareArgs;
use super::rig_log::{Recording, check_scene_hash, read_recording};

/// One metric of one actuator in one window, on the board and in simulation.
struct Row {
    window: String,
    actuator: String,
    metric: &'static str,
    rig: f64,
    simulation: f64,
    difference: f64,
}

/// One actuator's traces against each other over the samples both have.
struct Traces {
    actuator: String,
    f_e_rms_difference_n: f64,
    x_rms_difference_m: f64,
}

struct Report {
    scene: String,
    run: String,
    samples: usize,
    span_s: f64,
    rig_ended: Option<String>,
    notes: Vec<String>,
    actuators: Vec<Traces>,
    metrics: Vec<Row>,
}

/// The run a log recorded (`RUN=` before the path, `--run`, or the summary.json of its recording) and its
/// path.
fn run_of(
    scene: &MechanismScene,
    arg: &str,
    run: Option<&str>,
) -> anyhow::Result<(usize, PathBuf)> {
    let names = || {
        scene
            .runs
            .iter()
            .map(|r| format!("`{}`", r.name))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let index = |name: &str| scene.runs.iter().position(|r| r.name == name);
    let (named, path) = match arg.split_once('=') {
        Some((name, p)) if index(name).is_some() => (Some(name.to_string()), PathBuf::from(p)),
        _ => (run.map(str::to_string), PathBuf::from(arg)),
    };
    // A recording of a mechanism keeps its summary.json one folder above the run's trace.
    let summary = path
        .parent()
        .and_then(Path::parent)
        .map(|d| d.join("summary.json"))
        .and_then(|p| std::fs::read_to_string(p).ok())
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok());
    let recorded = summary.as_ref().and_then(|s| {
        Some((
            s["scene"].as_str()?.to_string(),
            s["runs"][0]["name"].as_str()?.to_string(),
        ))
    });
    if let Some((s, _)) = &recorded
        && *s != scene.name
    {
        bail!(
            "--rig-log {arg}: a recording of scene `{s}` (its summary.json), not of `{}`",
            scene.name
        );
    }
    let name = match (named, recorded) {
        (Some(n), Some((_, r))) if n != r => {
            bail!("--rig-log {arg}: its summary.json says it recorded run `{r}`, not `{n}`")
        }
        (Some(n), _) | (None, Some((_, n))) => n,
        (None, None) => scene.runs[0].name.clone(),
    };
    let i = index(&name).ok_or_else(|| {
        anyhow::anyhow!(
            "--rig-log {arg}: `{name}` is not a run of scene `{}` (its runs: {})",
            scene.name,
            names()
        )
    })?;
    Ok((i, path))
}

/// Reads and checks the log: a `rig run` recording of this scene file, every actuator's columns and the
/// board's time, finite, on the scene's ticks from t = 0. A run that ended on a fault keeps its rows.
fn check(
    scene: &MechanismScene,
    scene_path: &Path,
    arg: &str,
    path: &Path,
) -> anyhow::Result<(Trace, Vec<String>, Option<String>)> {
    let Recording {
        text,
        mut notes,
        owner,
    } = read_recording(arg, path)?;
    check_scene_hash(
        arg,
        path,
        &scene.name,
        scene_path,
        owner.as_ref(),
        None,
        &mut notes,
    )?;
    // Read as the mechanism's own trace (each actuator's block after `t`), rows with their line numbers.
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.starts_with('#'));
    let Some((_, header)) = lines.next() else {
        bail!("--rig-log {arg}: empty: no header row");
    };
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let columns: Vec<pneuflex_scene::run::trace::Column> = names
        .iter()
        .map(|n| pneuflex_scene::run::trace::Column {
            name: (*n).to_string(),
            unit: String::new(),
            group: "other".into(),
        })
        .collect();
    let mut trace = Trace::with_capacity(text.len() / 200, columns);
    let mut row = vec![0.0; names.len()];
    for (i, line) in lines {
        let cells: Vec<&str> = line.split(',').collect();
        if cells.len() != names.len() {
            bail!(
                "--rig-log {arg}: line {}: {} values, the header has {}",
                i + 1,
                cells.len(),
                names.len()
            );
        }
        for ((v, c), name) in row.iter_mut().zip(&cells).zip(&names) {
            *v = c.trim().parse().map_err(|_| {
                anyhow::anyhow!(
                    "--rig-log {arg}: line {}, column `{name}`: `{c}` is not a number",
                    i + 1
                )
            })?;
        }
        trace.push(&row);
    }
    let mut wanted: Vec<String> = vec!["t".into(), "board_t".into()];
    for a in &scene.actuators {
        for c in ["f_ref", "f_e", "x", "u"] {
            wanted.push(format!("{}.{c}", a.name));
        }
    }
    let missing: Vec<String> = wanted
        .iter()
        .filter(|w| !trace.has(w))
        .map(|m| format!("`{m}`"))
        .collect();
    if !missing.is_empty() {
        bail!(
            "--rig-log {arg}: line 1: no column {}: not a recording of this scene's {} actuators on a board \
             (`rig run --scene {}` writes them)",
            missing.join(", "),
            scene.actuators.len(),
            scene_path.display()
        );
    }
    for w in &wanted {
        let v = trace.column(w).unwrap_or_default();
        if let Some(k) = v.iter().position(|v| !v.is_finite()) {
            bail!("--rig-log {arg}: line {}, column `{w}`: {}", k + 2, v[k]);
        }
    }
    let t = trace.t();
    if t.len() < 2 {
        bail!(
            "--rig-log {arg}: {} rows: fewer than two to compare",
            t.len()
        );
    }
    if let Some(k) = t
        .iter()
        .enumerate()
        .position(|(k, &t)| (t - k as f64 * scene.dt_s).abs() > 1e-6 * scene.dt_s.max(t.abs()))
    {
        bail!(
            "--rig-log {arg}: line {}: t = {} s, the scene's tick {k} is at {} s: not a recording of this \
             scene's ticks from t = 0 (another dt_s, or rows missing)",
            k + 2,
            t[k],
            k as f64 * scene.dt_s
        );
    }
    let ended = path
        .file_name()
        .is_some_and(|f| f != "trace.csv")
        .then(|| format!("the recording is {} (it ended early)", path.display()));
    Ok((trace, notes, ended))
}

pub(super) fn compare(a: &CompareArgs<'_>) -> anyhow::Result<()> {
    let mut scene = MechanismScene::load(a.scene)?;
    if a.rig_log.len() != 1 {
        bail!(
            "--rig-log: a scene with several actuators is compared one recorded run at a time ({} given)",
            a.rig_log.len()
        );
    }
    let arg = &a.rig_log[0];
    if arg.trim().is_empty() {
        bail!("--rig-log: an empty path; give a recording's trace.csv");
    }
    let (run, path) = run_of(&scene, arg, a.run)?;
    let (trace, notes, ended) = check(&scene, a.scene, arg, &path)?;
    for n in &notes {
        errln!("warning: {n}");
    }
    if let Some(sheet) = a.actuator {
        let abs = std::path::absolute(sheet)?;
        for act in &mut scene.actuators {
            act.sheet.clone_from(&abs);
        }
        scene
            .check_sheets()
            .map_err(|e| anyhow::anyhow!("--actuator: {e}"))?;
    }
    // The run simulated for as long as the board ran (N rows cover N·dt).
    let span = trace.t()[trace.len() - 1];
    let spec = scene.runs[run].clone();
    let controller = spec.controller;
    scene.runs = vec![spec];
    scene.duration_s = span + scene.dt_s * 0.5;
    let dest = a.out.map(Path::to_path_buf).unwrap_or_else(|| {
        Path::new("out")
            .join("compare")
            .join(&scene.name)
            .join(&scene.runs[0].name)
    });
    let log_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let stage = OutputDir::create(
        &dest,
        &[log_dir.as_path(), a.scene],
        Writer::simulation("compare"),
    )?;
    let sims = run_all(&scene, &mut |_| {}, None, &mut ())?;
    let sim = &sims[0];
    if let Some(why) = &sim.diverged {
        bail!("the simulation diverged: {why}");
    }
    let rig = RunResult {
        name: scene.runs[0].name.clone(),
        controller,
        trace,
        windows: Vec::new(),
        lyapunov: None,
        diverged: ended.clone(),
        interrupted: None,
        warnings: Vec::new(),
        pwm_period_s: sim.pwm_period_s,
    };
    let n = rig.trace.len().min(sim.trace.len());
    let actuators: Vec<Traces> = scene
        .actuators
        .iter()
        .map(|act| {
            let rms = |c: &str| {
                let name = format!("{}.{c}", act.name);
                let (r, s) = (
                    rig.trace.column(&name).unwrap_or_default(),
                    sim.trace.column(&name).unwrap_or_default(),
                );
                (r[..n]
                    .iter()
                    .zip(&s[..n])
                    .map(|(r, s)| (r - s).powi(2))
                    .sum::<f64>()
                    / n as f64)
                    .sqrt()
            };
            Traces {
                actuator: act.name.clone(),
                f_e_rms_difference_n: rms("f_e"),
                x_rms_difference_m: rms("x"),
            }
        })
        .collect();
    let both: [MechanismSummary; 2] = [
        summarise(&scene, std::slice::from_ref(&rig)),
        summarise(&scene, std::slice::from_ref(sim)),
    ];
    let mut metrics = Vec::new();
    for (wr, ws) in both[0].runs[0].windows.iter().zip(&both[1].runs[0].windows) {
        for ((name, mr), (_, ms)) in wr.actuators.iter().zip(&ws.actuators) {
            for (metric, r, s) in [
                (
                    "rms_force_error_n",
                    mr.rms_force_error_n,
                    ms.rms_force_error_n,
                ),
                (
                    "max_abs_force_error_n",
                    mr.max_abs_force_error_n,
                    ms.max_abs_force_error_n,
                ),
                ("mean_force_n", mr.mean_force_n, ms.mean_force_n),
            ] {
                metrics.push(Row {
                    window: wr.window.clone(),
                    actuator: name.clone(),
                    metric,
                    rig: r,
                    simulation: s,
                    difference: r - s,
                });
            }
        }
        metrics.push(Row {
            window: wr.window.clone(),
            actuator: "all".into(),
            metric: "force_imbalance_n",
            rig: wr.force_imbalance_n,
            simulation: ws.force_imbalance_n,
            difference: wr.force_imbalance_n - ws.force_imbalance_n,
        });
    }
    let report = Report {
        scene: scene.name.clone(),
        run: scene.runs[0].name.clone(),
        samples: n,
        span_s: span,
        rig_ended: ended,
        notes,
        actuators,
        metrics,
    };
    let dir = stage.path();
    std::fs::write(
        dir.join("compare.json"),
        serde_json::to_string_pretty(&report.json())?,
    )?;
    let md = markdown(&report, &path, a.actuator);
    std::fs::write(dir.join("compare.md"), &md)?;
    write_figure(dir, &scene, &rig, sim, a.format)?;
    let mut inputs = vec![
        pneuflex_files::InputDigest::of_file(a.scene, "scene")?,
        pneuflex_files::InputDigest::of_file(&path, "log")?,
    ];
    if let Some(s) = a.actuator {
        inputs.push(pneuflex_files::InputDigest::of_file(s, "actuator")?);
    }
    let dest = stage.commit(Manifest::new("compare", env!("CARGO_PKG_VERSION"), inputs))?;
    outln!("{md}");
    outln!("outputs in {}", dest.display());
    Ok(())
}

impl Report {
    fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "scene": self.scene,
            "run": self.run,
            "samples": self.samples,
            "span_s": self.span_s,
            "rig_ended": self.rig_ended,
            "rig_notes": self.notes,
            "actuators": self.actuators.iter().map(|a| serde_json::json!({
                "actuator": a.actuator,
                "f_e_rms_difference_n": a.f_e_rms_difference_n,
                "x_rms_difference_m": a.x_rms_difference_m,
            })).collect::<Vec<_>>(),
            "metrics": self.metrics.iter().map(|m| serde_json::json!({
                "window": m.window,
                "actuator": m.actuator,
                "metric": m.metric,
                "rig": m.rig,
                "simulation": m.simulation,
                "difference": m.difference,
            })).collect::<Vec<_>>(),
        })
    }
}

fn markdown(r: &Report, log: &Path, actuator: Option<&Path>) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# rig against simulation: scene `{}`, run `{}`\n\nrig log {}; simulated with {}.\n",
        r.scene,
        r.run,
        log.display(),
        actuator.map_or("the scene's actuator sheets".to_string(), |p| p
            .display()
            .to_string())
    );
    let _ = writeln!(s, "{} samples over {:.3} s.\n", r.samples, r.span_s);
    if let Some(e) = &r.rig_ended {
        let _ = writeln!(s, "**The rig's run ended early**: {e}.\n");
    }
    for n in &r.notes {
        let _ = writeln!(s, "Warning: {n}.\n");
    }
    let _ = writeln!(
        s,
        "| actuator | f_e RMS difference (N) | x RMS difference (mm) |\n|---|---|---|"
    );
    for a in &r.actuators {
        let _ = writeln!(
            s,
            "| {} | {:.4} | {:.4} |",
            a.actuator,
            a.f_e_rms_difference_n,
            a.x_rms_difference_m * 1e3
        );
    }
    let _ = writeln!(
        s,
        "\n| window | actuator | metric | rig | simulation | rig − simulation |\n|---|---|---|---|---|---|"
    );
    for m in &r.metrics {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.4} | {:.4} | {:.4} |",
            m.window, m.actuator, m.metric, m.rig, m.simulation, m.difference
        );
    }
    s
}

/// A figure's curve: its label, times and values.
type Curve = (String, Vec<f64>, Vec<f64>);

/// `force.<format>`: per actuator, the board's and the simulation's contact force and the reference.
fn write_figure(
    dir: &Path,
    scene: &MechanismScene,
    rig: &RunResult,
    sim: &RunResult,
    format: pneuflex_viz::Format,
) -> anyhow::Result<()> {
    let col = |r: &RunResult, c: &str| r.trace.column(c).unwrap_or_default().to_vec();
    let data: Vec<(String, [Curve; 3])> = scene
        .actuators
        .iter()
        .map(|a| {
            let f = |c: &str| format!("{}.{c}", a.name);
            (
                a.name.clone(),
                [
                    ("f_ref".to_string(), col(sim, "t"), col(sim, &f("f_ref"))),
                    ("rig f_e".to_string(), col(rig, "t"), col(rig, &f("f_e"))),
                    (
                        "simulation f_e".to_string(),
                        col(sim, "t"),
                        col(sim, &f("f_e")),
                    ),
                ],
            )
        })
        .collect();
    let panels: Vec<pneuflex_plot::overlay::Panel<'_>> = data
        .iter()
        .map(|(name, series)| pneuflex_plot::overlay::Panel {
            title: format!(
                "{} — {name}: contact force, rig against simulation",
                scene.name
            ),
            y_desc: "force [N]".into(),
            series: series
                .iter()
                .map(|(label, t, y)| pneuflex_plot::overlay::Series {
                    label: label.clone(),
                    t,
                    y,
                })
                .collect(),
            include_zero: true,
        })
        .collect();
    pneuflex_plot::overlay::write_overlay(&dir.join(format!("force.{}", format.ext())), &panels)?;
    Ok(())
}
