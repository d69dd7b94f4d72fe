//! `pneuflex compare SCENE --rig-log [RUN=]TRACE.csv ...`: each recorded run of the scene simulated for as
//! long as the rig ran, its windows' metrics and the rig's from the same metric code
//! (`pneuflex_scene::analysis::comparison`), the figures of both overlaid, `compare.json` and `compare.md`.
//! With the logs of two runs a claim compares, the claim's verdict on the rig beside the simulation's. Each
//! log is checked first to be a recording of this scene's run on the rig (rig_log.rs).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use pneuflex_files::output::{Manifest, OutputDir, Writer};
use pneuflex_scene::analysis::claims::{ClaimResult, check_all};
use pneuflex_scene::analysis::comparison::{Comparison, compare as compare_runs};
use pneuflex_scene::analysis::recorded::recorded_run;
use pneuflex_scene::{PlantSpec, RunResult, Scene};

mod mechanism;
mod rig_log;

/// One `--rig-log`: the run it recorded, its path, its trace (up to a fault), how it ended and what the
/// checks could not confirm.
struct Log {
    run: usize,
    path: PathBuf,
    log: rig_log::RigLog,
}

/// The run a log recorded: `RUN=` before the path, or `--run` for a single log; else the run the
/// summary.json beside it names (`rig run --scene` writes it); else, for a single log, the scene's first
/// run. A summary.json of another scene or another run than the one named is refused.
fn run_of(
    scene: &Scene,
    arg: &str,
    run: Option<&str>,
    single: bool,
) -> anyhow::Result<(usize, PathBuf)> {
    let runs = || {
        scene
            .runs
            .iter()
            .map(|r| format!("`{}`", r.name))
            .collect::<Vec<_>>()
            .join(", ")
    };
    if arg.trim().is_empty() {
        bail!("--rig-log: an empty path; give a recording's trace.csv");
    }
    let (mut named, path) = match arg.split_once('=') {
        Some((name, p)) if scene.run_index(name).is_ok() => (Some(name), PathBuf::from(p)),
        Some((name, _)) if !Path::new(arg).exists() => bail!(
            "--rig-log {arg}: `{name}` is not a run of scene `{}` (its runs: {}), and there is no file {arg}",
            scene.name,
            runs()
        ),
        _ => (None, PathBuf::from(arg)),
    };
    if single && let Some(r) = run {
        if scene.run_index(r).is_err() {
            bail!(
                "--run {r}: not a run of scene `{}` (its runs: {})",
                scene.name,
                runs()
            );
        }
        if let Some(n) = named
            && n != r
        {
            bail!("--run {r} and --rig-log {arg} name two different runs; give one");
        }
        named = Some(r);
    }
    let recorded = rig_log::summary_of(&path);
    if let Some((s, _)) = &recorded
        && *s != scene.name
    {
        bail!(
            "--rig-log {arg}: a recording of scene `{s}` (its summary.json), not of `{}`",
            scene.name
        );
    }
    match (named, recorded) {
        (Some(n), Some((_, r))) if n != r => {
            bail!("--rig-log {arg}: a recording of run `{r}` (its summary.json), not of run `{n}`")
        }
        (Some(n), _) => Ok((scene.run_index(n)?, path)),
        (None, Some((_, r))) => match scene.run_index(&r) {
            Ok(i) => Ok((i, path)),
            Err(_) => bail!(
                "--rig-log {arg}: its summary.json names run `{r}`, which scene `{}` does not have (its runs: {})",
                scene.name,
                runs()
            ),
        },
        (None, None) if single => Ok((0, path)),
        (None, None) => bail!(
            "--rig-log {arg}: which run did it record? No summary.json of scene `{}` beside it: give RUN={arg}",
            scene.name
        ),
    }
}

/// What `pneuflex compare` was given (cli/simulate.rs's `Compare`, parsed).
pub struct CompareArgs<'a> {
    /// The scene the rig ran.
    pub scene: &'a Path,
    /// `[RUN=]TRACE.csv` per recorded run.
    pub rig_log: &'a [String],
    /// The run a single log recorded, when named.
    pub run: Option<&'a str>,
    /// An actuator sheet to simulate with instead of the scene's.
    pub actuator: Option<&'a Path>,
    /// The output directory, when given.
    pub out: Option<&'a Path>,
    /// The figures' format.
    pub format: pneuflex_viz::Format,
}

pub fn compare(a: &CompareArgs<'_>) -> anyhow::Result<()> {
    // A scene of several actuators: its recording on a board of several channels (compare/mechanism.rs).
    if pneuflex_files::read_text(a.scene, pneuflex_files::InputKind::Scene)
        .is_ok_and(|t| pneuflex_scene::mechanism::MechanismScene::is_mechanism(&t))
    {
        return mechanism::compare(a);
    }
    let scene = Scene::load(a.scene)?;
    let single = a.rig_log.len() == 1;
    if !single && a.run.is_some() {
        bail!(
            "--run names the run of a single --rig-log; with several, write each as RUN=TRACE.csv"
        );
    }
    let mut logs = Vec::new();
    for arg in a.rig_log {
        let (run, path) = run_of(&scene, arg, a.run, single)?;
        if let Some(other) = logs.iter().find(|l: &&Log| l.run == run) {
            bail!(
                "--rig-log {arg}: run `{}` is already given by {}",
                scene.runs[run].name,
                other.path.display()
            );
        }
        let log = rig_log::check(&scene, a.scene, run, arg, &path)?;
        logs.push(Log { run, path, log });
    }
    // What the checks could not confirm, and a recording that ended early, are said before the work.
    for l in &logs {
        let shown = l.path.display();
        for n in &l.log.notes {
            errln!("warning: {n}");
        }
        if let Some(f) = &l.log.fault {
            errln!("note: --rig-log {shown}: {f}");
        }
    }
    // Every run simulated for as long as the shortest log ran (N ticks cover N·dt).
    let end_s = logs
        .iter()
        .map(|l| l.log.trace.t()[l.log.trace.len() - 1] + scene.dt_s)
        .fold(f64::INFINITY, f64::min);
    let indices: Vec<usize> = logs.iter().map(|l| l.run).collect();
    let mut sim_scene = scene.some_runs(&indices, end_s);
    if let Some(sheet) = a.actuator {
        let abs = std::fs::canonicalize(sheet)
            .with_context(|| format!("--actuator {}", sheet.display()))?;
        pneuflex_pneumatics::ActuatorSheet::load(&abs)
            .map_err(|e| anyhow::anyhow!("--actuator: {e}"))?;
        match &mut sim_scene.plant {
            PlantSpec::Pneumatic { actuator, .. } => *actuator = abs,
            other => bail!(
                "--actuator: the scene's plant is `{}`; compare swaps the sheet of a pneumatic plant only",
                other.kind()
            ),
        }
    }
    // One log's output and several logs' are folders side by side, never one inside the other.
    let names: Vec<&str> = logs
        .iter()
        .map(|l| scene.runs[l.run].name.as_str())
        .collect();
    let dest = a.out.map(Path::to_path_buf).unwrap_or_else(|| {
        Path::new("out")
            .join("compare")
            .join(&scene.name)
            .join(names.join("+"))
    });
    let log_dirs: Vec<PathBuf> = logs
        .iter()
        .map(|l| l.path.parent().map(Path::to_path_buf).unwrap_or_default())
        .collect();
    let protect: Vec<&Path> = log_dirs.iter().map(PathBuf::as_path).collect();
    let stage = OutputDir::create(&dest, &protect, Writer::simulation("compare"))?;
    let sims = pneuflex_scene::run_scene(&sim_scene, &mut |_| {})?;
    if let Some(why) = sims.iter().find_map(|r| r.diverged.as_ref()) {
        bail!("the simulation diverged: {why}");
    }
    let mut ends = Vec::new();
    let mut paths = Vec::new();
    let rigs: Vec<RunResult> = logs
        .into_iter()
        .enumerate()
        .map(|(i, l)| {
            let name = sim_scene.runs[i].name.clone();
            let mut notes = l.log.notes;
            let ran_s = l.log.trace.t()[l.log.trace.len() - 1] + scene.dt_s;
            if ran_s > sim_scene.duration_s + 0.5 * scene.dt_s {
                notes.push(format!(
                    "{}: the log runs {ran_s} s, compared over the first {} s",
                    l.path.display(),
                    sim_scene.duration_s
                ));
            }
            ends.push((l.log.fault, notes));
            paths.push(l.path);
            recorded_run(
                &sim_scene,
                i,
                &name,
                l.log.trace,
                None,
                sims[i].pwm_period_s,
            )
        })
        .collect();
    let comparisons: Vec<Comparison> = rigs
        .iter()
        .zip(&sims)
        .map(|(r, s)| compare_runs(&r.name, r, s))
        .collect();
    let claims = (check_all(&sim_scene, &rigs), check_all(&sim_scene, &sims));
    let dir = stage.path();
    let mut md = String::new();
    for (c, (fault, notes)) in comparisons.iter().zip(&ends) {
        md.push_str(&markdown(c, a, fault.as_deref(), notes));
    }
    // Each run's comparison with how its recording ended and what was not confirmed.
    let runs_json: Vec<serde_json::Value> = comparisons
        .iter()
        .zip(&ends)
        .map(|(c, (fault, notes))| {
            let mut v = serde_json::to_value(c)?;
            v["rig_fault"] = serde_json::json!(fault);
            v["rig_notes"] = serde_json::json!(notes);
            Ok(v)
        })
        .collect::<anyhow::Result<_>>()?;
    if !sim_scene.claims.is_empty() {
        md.push_str(&claims_markdown(&claims.0, &claims.1));
    }
    if single {
        std::fs::write(
            dir.join("compare.json"),
            serde_json::to_string_pretty(&runs_json[0])?,
        )?;
    } else {
        let json = serde_json::json!({
            "runs": runs_json,
            "claims": {"rig": claims.0, "simulation": claims.1},
        });
        std::fs::write(
            dir.join("compare.json"),
            serde_json::to_string_pretty(&json)?,
        )?;
    }
    std::fs::write(dir.join("compare.md"), &md)?;
    // Each run's figures, the rig and the simulation overlaid (in the run's folder with several runs).
    for (i, (rig, sim)) in rigs.into_iter().zip(sims).enumerate() {
        let one = sim_scene.one_run(i, sim_scene.duration_s);
        let fig_dir = if single {
            dir.to_path_buf()
        } else {
            dir.join(&rig.name)
        };
        std::fs::create_dir_all(&fig_dir)?;
        let rig = RunResult {
            name: "rig".into(),
            ..rig
        };
        let sim = RunResult {
            name: "simulation".into(),
            ..sim
        };
        pneuflex_viz::write_figures(&fig_dir, &one, &[rig, sim], a.format)?;
    }
    let mut inputs = vec![pneuflex_files::InputDigest::of_file(a.scene, "scene")?];
    for path in &paths {
        inputs.push(pneuflex_files::InputDigest::of_file(path, "log")?);
    }
    if let Some(s) = a.actuator {
        inputs.push(pneuflex_files::InputDigest::of_file(s, "actuator")?);
    }
    let dest = stage.commit(Manifest::new("compare", env!("CARGO_PKG_VERSION"), inputs))?;
    outln!("{md}");
    outln!("outputs in {}", dest.display());
    Ok(())
}

fn markdown(c: &Comparison, a: &CompareArgs<'_>, fault: Option<&str>, notes: &[String]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# rig against simulation: run `{}`\n\nrig logs {}; simulated with {}.\n",
        c.run,
        a.rig_log.join(", "),
        a.actuator
            .as_ref()
            .map_or("the scene's actuator sheet".to_string(), |p| p
                .display()
                .to_string())
    );
    let _ = writeln!(
        s,
        "{} samples over {:.3} s: f_e differs by {:.4} N RMS, x by {:.4} mm RMS.\n",
        c.samples,
        c.span_s,
        c.f_e_rms_difference_n,
        c.x_rms_difference_m * 1e3
    );
    if let Some(f) = fault {
        let _ = writeln!(s, "**The rig's run ended early**: {f}.\n");
    }
    for n in notes {
        let _ = writeln!(s, "Warning: {n}.\n");
    }
    let _ = writeln!(
        s,
        "| window | metric | rig | simulation | rig − simulation |\n|---|---|---|---|---|"
    );
    let f = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.4}"));
    for m in &c.metrics {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} |",
            m.window,
            m.metric,
            f(m.rig),
            f(m.simulation),
            f(m.difference)
        );
    }
    s.push('\n');
    s
}

/// The scene's claims between the recorded runs: the verdict on the rig beside the simulation's.
fn claims_markdown(rig: &[ClaimResult], sim: &[ClaimResult]) -> String {
    let mut s = String::from(
        "# the claims, on the rig and in simulation\n\n| claim | rig | simulation |\n|---|---|---|\n",
    );
    let side = |c: &ClaimResult| {
        let f = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.4}"));
        format!(
            "{}: {} {} against {} {}",
            if c.holds { "holds" } else { "DOES NOT HOLD" },
            c.better,
            f(c.better_value),
            c.than,
            f(c.than_value)
        )
    };
    for (r, m) in rig.iter().zip(sim) {
        let _ = writeln!(s, "| {} | {} | {} |", r.statement, side(r), side(m));
    }
    s
}
