//! `pneuflex compare SCENE --rig-log [RUN=]TRACE.csv ...`: each recorded run of the scene simulated for as
//! long as the rig ran, its windows' metrics and the rig's from the same metric code
//! (`pneuflex_scene::analysis::comparison`), the figures of both overlaid, `compare.json` and `compare.md`.
//! With the logs of two runs a claim compares, the claim's verdict on the rig beside the simulation's.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use pneuflex_files::output::{Manifest, OutputDir, Writer};
use pneuflex_scene::analysis::claims::{ClaimResult, check_all};
use pneuflex_scene::analysis::comparison::{Comparison, compare as compare_runs};
use pneuflex_scene::analysis::recorded::recorded_run;
use pneuflex_scene::{PlantSpec, RunResult, Scene, Trace};

/// One `--rig-log`: the run it recorded, its path, its trace.
struct Log {
    run: usize,
    path: PathBuf,
    trace: Trace,
}

/// The run a log recorded: `RUN=` before the path; else `--run` or, beside the trace, the summary.json
/// `rig run --scene` wrote; else, for a single log, the scene's first run.
fn run_of(
    scene: &Scene,
    arg: &str,
    run: Option<&str>,
    single: bool,
) -> anyhow::Result<(usize, PathBuf)> {
    if let Some((name, path)) = arg.split_once('=')
        && let Ok(i) = scene.run_index(name)
    {
        return Ok((i, PathBuf::from(path)));
    }
    let path = PathBuf::from(arg);
    if single && let Some(name) = run {
        return Ok((scene.run_index(name)?, path));
    }
    let beside = path.parent().unwrap_or(Path::new(".")).join("summary.json");
    let recorded = std::fs::read_to_string(&beside)
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .filter(|s| s["scene"].as_str() == Some(scene.name.as_str()))
        .and_then(|s| s["runs"][0]["name"].as_str().map(str::to_string));
    match recorded {
        Some(name) => Ok((scene.run_index(&name)?, path)),
        None if single => Ok((0, path)),
        None => bail!(
            "--rig-log {arg}: which run did it record? No summary.json of scene `{}` beside it: give RUN={arg}",
            scene.name
        ),
    }
}

fn read_log(scene: &Scene, run: usize, path: PathBuf) -> anyhow::Result<Log> {
    let shown = path.display().to_string();
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("--rig-log {shown}: cannot read"))?;
    let trace = Trace::from_csv(&text, &pneuflex_files::output::RIG_TRACE_COLUMNS)
        .map_err(|e| anyhow::anyhow!("--rig-log {shown}: {e}"))?;
    if trace.len() < 2 {
        bail!("--rig-log {shown}: fewer than two rows");
    }
    let t = trace.t();
    let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
    if (dt - scene.dt_s).abs() > 0.01 * scene.dt_s {
        bail!(
            "--rig-log {shown}: rows {dt:.6} s apart, the scene's dt_s is {} s: a log of another scene?",
            scene.dt_s
        );
    }
    Ok(Log { run, path, trace })
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
        logs.push(read_log(&scene, run, path)?);
    }
    // Every run simulated for as long as the shortest log ran (N ticks cover N·dt).
    let end_s = logs
        .iter()
        .map(|l| l.trace.t()[l.trace.len() - 1] + scene.dt_s)
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
    let first = &scene.runs[logs[0].run].name;
    let dest = a.out.map(Path::to_path_buf).unwrap_or_else(|| {
        let d = Path::new("out").join("compare").join(&scene.name);
        if single { d.join(first) } else { d }
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
    let rigs: Vec<RunResult> = logs
        .into_iter()
        .enumerate()
        .map(|(i, l)| {
            let name = sim_scene.runs[i].name.clone();
            recorded_run(&sim_scene, i, &name, l.trace, None, sims[i].pwm_period_s)
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
    for c in &comparisons {
        md.push_str(&markdown(c, a));
    }
    if !sim_scene.claims.is_empty() {
        md.push_str(&claims_markdown(&claims.0, &claims.1));
    }
    if single {
        std::fs::write(
            dir.join("compare.json"),
            serde_json::to_string_pretty(&comparisons[0])?,
        )?;
    } else {
        let json = serde_json::json!({
            "runs": comparisons,
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
    for arg in a.rig_log {
        let (_, path) = run_of(&scene, arg, a.run, single)?;
        inputs.push(pneuflex_files::InputDigest::of_file(&path, "log")?);
    }
    if let Some(s) = a.actuator {
        inputs.push(pneuflex_files::InputDigest::of_file(s, "actuator")?);
    }
    let dest = stage.commit(Manifest::new("compare", env!("CARGO_PKG_VERSION"), inputs))?;
    outln!("{md}");
    outln!("outputs in {}", dest.display());
    Ok(())
}

fn markdown(c: &Comparison, a: &CompareArgs<'_>) -> String {
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
