//! `pneuflex compare SCENE --rig-log TRACE.csv`: the scene's run simulated for as long as the rig ran, its
//! windows' metrics and the rig's from the same metric code (`pneuflex_scene::analysis::comparison`), the
//! figures of both runs overlaid, `compare.json` and `compare.md`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use pneuflex_files::output::{Manifest, OutputDir, Writer};
use pneuflex_scene::analysis::comparison::{Comparison, compare as compare_runs};
use pneuflex_scene::{PlantSpec, Scene, Trace};

use crate::cli::simulate::Compare;

pub fn compare(a: &Compare) -> anyhow::Result<()> {
    let scene = Scene::load(&a.scene)?;
    let index = match &a.run {
        None => 0,
        Some(name) => scene.run_index(name)?,
    };
    let text = std::fs::read_to_string(&a.rig_log)
        .with_context(|| format!("--rig-log {}: cannot read", a.rig_log.display()))?;
    let rig_trace = Trace::from_csv(&text, &["wall_time", "fault"])
        .map_err(|e| anyhow::anyhow!("--rig-log {}: {e}", a.rig_log.display()))?;
    if rig_trace.len() < 2 {
        bail!("--rig-log {}: fewer than two rows", a.rig_log.display());
    }
    let t = rig_trace.t();
    let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
    if (dt - scene.dt_s).abs() > 0.01 * scene.dt_s {
        bail!(
            "--rig-log {}: rows {dt:.6} s apart, the scene's dt_s is {} s: a log of another scene?",
            a.rig_log.display(),
            scene.dt_s
        );
    }
    let mut sim_scene = scene.one_run(index, t[t.len() - 1]);
    if let Some(sheet) = &a.actuator {
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
    let dest = a.out.clone().unwrap_or_else(|| {
        Path::new("out")
            .join("compare")
            .join(&scene.name)
            .join(&scene.runs[index].name)
    });
    let log_dir: PathBuf = a
        .rig_log
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    let stage = OutputDir::create(&dest, &[&log_dir], Writer::simulation("compare"))?;
    let mut results = pneuflex_scene::run_scene(&sim_scene, &mut |_| {})?;
    let mut sim = results.remove(0);
    if let Some(why) = &sim.diverged {
        bail!("the simulation diverged: {why}");
    }
    sim.name = "simulation".into();
    let rig = pneuflex_scene::analysis::recorded::recorded_run(
        &sim_scene,
        "rig",
        rig_trace,
        None,
        sim.pwm_period_s,
    );
    let c = compare_runs(&scene.runs[index].name, &rig, &sim);
    let md = markdown(&c, a);
    let dir = stage.path();
    std::fs::write(dir.join("compare.json"), serde_json::to_string_pretty(&c)?)?;
    std::fs::write(dir.join("compare.md"), &md)?;
    pneuflex_viz::write_figures(dir, &sim_scene, &[rig, sim], pneuflex_viz::Format::Png)?;
    let mut inputs = vec![
        pneuflex_files::InputDigest::of_file(&a.scene, "scene")?,
        pneuflex_files::InputDigest::of_file(&a.rig_log, "log")?,
    ];
    if let Some(s) = &a.actuator {
        inputs.push(pneuflex_files::InputDigest::of_file(s, "actuator")?);
    }
    let dest = stage.commit(Manifest::new("compare", env!("CARGO_PKG_VERSION"), inputs))?;
    outln!("{md}");
    outln!("outputs in {}", dest.display());
    Ok(())
}

fn markdown(c: &Comparison, a: &Compare) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# rig against simulation: run `{}`\n\nrig log {}; simulated with {}.\n",
        c.run,
        a.rig_log.display(),
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
    s
}
