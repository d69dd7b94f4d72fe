//! `pneuflex new rig`: the rig directory of a datasheet written by `pneuflex_datasheet::new_rig`, its report
//! printed (the options are parsed into the datasheet, with their units, in cli/new.rs).

use std::path::Path;

use pneuflex_datasheet::Datasheet;

/// Writes the rig of `ds` into `dir` and prints what was written, the gains and the next command.
pub fn new_rig(ds: &Datasheet, dir: &Path) -> anyhow::Result<()> {
    let command = std::iter::once("pneuflex".to_string())
        .chain(std::env::args().skip(1))
        .collect::<Vec<_>>()
        .join(" ");
    let report = pneuflex_datasheet::new_rig(ds, dir, &command)?;
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
