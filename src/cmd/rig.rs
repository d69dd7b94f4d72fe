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
        None => println!("emulating rig `{}` on {}  (Ctrl-C stops)", rig.name, port.unwrap_or("")),
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
    std::fs::create_dir_all(out_dir).with_context(|| format!("cannot create {}", out_dir.display()))?;
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
    if let Some(f) = &report.fault {
        if f.kind != pneuflex_rig::ErrorKind::Interrupted {
            bail!("run ended on a fault: {}: {} (tick {})", f.kind, f.message, f.tick);
        }
    }
    Ok(report)
}
