//! `pneuflex new rig`: the rig directory of a datasheet written by `pneuflex_datasheet::new_rig`, its report
//! printed (the options are parsed into the datasheet, with their units, in cli/new.rs); SIGINT, SIGTERM or
//! SIGHUP stop it with nothing written (exit 128 + the signal).

use std::path::Path;

use pneuflex_datasheet::{Datasheet, DesignError};

/// Writes the rig of `ds` into `dir` and prints what was written, the gains and the next command.
pub fn new_rig(ds: &Datasheet, dir: &Path) -> anyhow::Result<()> {
    let command = std::iter::once("pneuflex".to_string())
        .chain(std::env::args().skip(1))
        .collect::<Vec<_>>()
        .join(" ");
    // A signal stops the gains' search at its next simulation, and the staging folder goes with it.
    let stop = super::stop_flag()?;
    let signal = || stop.load(std::sync::atomic::Ordering::Relaxed);
    let report = match pneuflex_datasheet::new_rig_until(ds, dir, &command, &|| signal() != 0) {
        Err(DesignError::Interrupted) => {
            return Err(super::interrupted(
                signal(),
                format!(
                    "{}: nothing written (new rig writes the directory whole or not at all)",
                    dir.display()
                ),
            ));
        }
        r => r?,
    };
    for w in &report.warnings {
        errln!("warning: {}: {}", w.key, w.message);
    }
    outln!(
        "{}: {} (README.md lists the {} assumptions)",
        report.dir.display(),
        "sheet set, scene.toml and rig.toml written",
        report.design.assumptions.len()
    );
    outln!(
        "gains: kp = {} /m, ki = {} /(m s): {}",
        report.gains.kp_per_m,
        report.gains.ki_per_m_s,
        report.gains.note
    );
    outln!("next: pneuflex run {}/scene.toml", report.dir.display());
    Ok(())
}
