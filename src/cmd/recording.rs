//! How a recording on the rig is made in lockstep and how a recording's end is reported (`rig run`,
//! `rig excite`).

use std::path::Path;

use anyhow::{anyhow, bail};
use pneuflex_control::{Controller, Setpoint};
use pneuflex_rig::record;
use pneuflex_rig::rtloop::check_duration;
use pneuflex_rig::{RigFile, serial, session};

/// A recording on the rig file's emulator in lockstep with a simulated clock (not real time, no pty), the
/// emulator hiding the actuator sheet `truth`, its sensor noise seeded with `seed`: the board steps once
/// per loop tick, as crates/rig's tests run it (`rig excite --lockstep-truth`, `rig run --lockstep-truth`).
#[allow(clippy::too_many_arguments)]
pub(super) fn record_lockstep(
    command: &'static str,
    rig_file: &Path,
    truth: &Path,
    seed: u64,
    out_dir: &Path,
    inputs: &[(&Path, &str)],
    controller: &mut dyn Controller,
    reference: &mut dyn FnMut(f64) -> Setpoint,
    duration_s: f64,
    finish: record::Finish<'_>,
) -> anyhow::Result<()> {
    check_duration(duration_s).map_err(|e| anyhow!("--duration: {}", e.message))?;
    let mut rig = RigFile::load(rig_file)?;
    session::hide_truth(&mut rig, rig_file, truth, Some(seed), None)?;
    let mut clock = pneuflex_rig::clock::SimClock::new();
    let (link, _log) = session::lockstep_emulator(&rig, rig_file, clock.clone())?;
    let mut link_clock = clock.clone();
    let stop = session::install_ctrl_c()?;
    let rec = record::record_observed(
        command,
        &rig,
        || serial::connect_link(link, &rig, &mut link_clock),
        out_dir,
        inputs,
        controller,
        reference,
        duration_s,
        &stop,
        &mut clock,
        &mut (),
        finish,
    )?;
    finished(&rec)
}

/// What a recorded run's end prints, and its exit: 128 + the signal after an interruption (the
/// recording is committed as `<dest>.partial`), an error after a fault, success otherwise.
pub(super) fn finished(rec: &record::Recording) -> anyhow::Result<()> {
    for r in &rec.recovered {
        errln!(
            "note: the recording of an earlier run that died was kept in {}",
            r.display()
        );
    }
    outln!("{}", rec.report);
    let trace = rec.dir.join("trace.csv");
    if let Some(e) = &rec.analysis_error {
        errln!(
            "error: the recording is complete in {}, but its summary and figures could not be written: {e}",
            rec.dir.display()
        );
    } else if rec.dir.join("summary.json").is_file() {
        outln!("summary: {}", rec.dir.join("summary.json").display());
    }
    if rec.partial {
        return Err(super::interrupted(
            session::last_signal().max(2),
            format!(
                "stopped at t = {} s; the valve was put in its safe state; partial trace: {}",
                rec.report.time_reached_s,
                trace.display()
            ),
        ));
    }
    if let Some(f) = &rec.report.fault {
        bail!(
            "run ended on a fault: {}: {} (tick {}); trace: {}",
            f.kind,
            f.message,
            f.tick,
            trace.display()
        );
    }
    outln!("trace: {}", trace.display());
    if rec.analysis_error.is_some() {
        bail!("the recording's analysis failed (above); the recording itself is complete");
    }
    Ok(())
}
