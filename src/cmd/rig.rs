//! `pneuflex rig emulate` and `pneuflex rig run`: command bodies (the lead wires them into main.rs).

use std::path::Path;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use pneuflex_control::{Controller, Setpoint};
use pneuflex_rig::rtloop::{self, LoopReport};
use pneuflex_rig::trace::TraceWriter;
use pneuflex_rig::{RigFile, serial, session};

/// `pneuflex rig emulate <rig.toml> [--port <tty>] [--duration <s>]`: runs the rig file's emulated plant in
/// real time behind a new pseudo-terminal (its path is printed) or on a given serial port, until Ctrl-C or
/// `duration_s`. Faults listed in the rig file's `[emulator].faults` are injected.
pub fn emulate(rig_file: &Path, port: Option<&str>, duration_s: Option<f64>) -> anyhow::Result<()> {
    let rig = RigFile::load(rig_file)?;
    let handle = match port {
        Some(p) => session::spawn_port_emulator(&rig, rig_file, p)?,
        None => session::spawn_pty_emulator(&rig, rig_file)?,
    };
    let stop = session::install_ctrl_c()?;
    match &handle.path {
        Some(p) => println!(
            "emulating rig `{}` on {}  (connect with: pneuflex rig run --port {} ...; Ctrl-C stops)",
            rig.name,
            p.display(),
            p.display()
        ),
        None => println!(
            "emulating rig `{}` on {}  (Ctrl-C stops)",
            rig.name,
            port.unwrap_or("")
        ),
    }
    let start = Instant::now();
    while !stop.load(Ordering::Relaxed)
        && !handle.is_finished()
        && duration_s.is_none_or(|d| start.elapsed().as_secs_f64() < d)
    {
        std::thread::sleep(Duration::from_millis(20));
    }
    let log = handle.stop();
    println!(
        "emulator stopped: {} samples sent, {} valve commands received, {} board-watchdog trips{}",
        log.samples_sent,
        log.commands.len(),
        log.board_watchdog_trips,
        log.ended.map(|e| format!(" ({e})")).unwrap_or_default()
    );
    Ok(())
}

/// `pneuflex rig run --rig <rig.toml> [--port <tty>] --scene <scene.toml> [--out DIR]`: runs `controller`
/// against the reference on the rig (real or emulated) for `duration_s`, writing `out_dir/trace.csv`.
/// Ctrl-C, any rig fault, a controller panic or NaN puts the valve in its safe state and ends the run
/// `loop.post_fault_s` later. Returns the loop report; an error if the run ended on a fault other than Ctrl-C.
pub fn run(
    rig_file: &Path,
    port: Option<&str>,
    controller: &mut dyn Controller,
    reference: &mut dyn FnMut(f64) -> Setpoint,
    duration_s: f64,
    out_dir: &Path,
) -> anyhow::Result<LoopReport> {
    let rig = RigFile::load(rig_file)?;
    std::fs::create_dir_all(out_dir)
        .with_context(|| format!("cannot create {}", out_dir.display()))?;
    let trace_path = out_dir.join("trace.csv");
    let file = std::fs::File::create(&trace_path)
        .with_context(|| format!("cannot create {}", trace_path.display()))?;
    let stop = session::install_ctrl_c()?;
    let link = serial::connect(&rig, rig_file, port)?;
    let mut sup = session::supervised(link, &rig);
    let mut trace = TraceWriter::new(file, rig.rt.trace_flush_every)?;
    let opts = session::run_options(&rig, duration_s);
    println!(
        "running on `{}` at {} Hz for {duration_s} s; trace: {}",
        port.unwrap_or(&rig.link.port),
        rig.rt.rate_hz,
        trace_path.display()
    );
    let report = rtloop::run(&mut sup, controller, reference, &mut trace, &opts, &stop)?;
    drop(sup);
    println!("{report}");
    if let Some(f) = &report.fault
        && f.kind != pneuflex_rig::ErrorKind::Interrupted
    {
        bail!(
            "run ended on a fault: {}: {} (tick {})",
            f.kind,
            f.message,
            f.tick
        );
    }
    Ok(report)
}

/// `pneuflex rig run --scene <scene.toml>`: the controller and reference of one of the scene's runs (by name,
/// or the first) on the rig, for the scene's duration unless `duration_s` is given. Output in
/// `out/rig/<scene>/<run>/` unless `out` is given.
pub fn run_scene(
    rig_file: &Path,
    port: Option<&str>,
    scene_path: &Path,
    run_name: Option<&str>,
    duration_s: Option<f64>,
    out: Option<&Path>,
) -> anyhow::Result<()> {
    let scene = pneuflex_scene::Scene::load(scene_path)?;
    let index = match run_name {
        None => 0,
        Some(name) => scene
            .runs
            .iter()
            .position(|r| r.name == name)
            .with_context(|| {
                let names: Vec<&str> = scene.runs.iter().map(|r| r.name.as_str()).collect();
                format!(
                    "{}: no run named `{name}` (runs: {})",
                    scene_path.display(),
                    names.join(", ")
                )
            })?,
    };
    let mut controller = pneuflex_scene::runner::build_controller(&scene, index)?;
    let setpoints = pneuflex_scene::runner::build_setpoints(&scene)?;
    let mut reference = |t: f64| setpoints.at(t);
    let out_dir = match out {
        Some(dir) => dir.to_path_buf(),
        None => Path::new("out")
            .join("rig")
            .join(&scene.name)
            .join(&scene.runs[index].name),
    };
    let duration = duration_s.unwrap_or(scene.duration_s);
    run(
        rig_file,
        port,
        controller.as_mut(),
        &mut reference,
        duration,
        &out_dir,
    )
    .map(|_| ())
}
