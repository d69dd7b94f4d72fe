//! `pneuflex rig excite`: an identification experiment on the rig (docs/identification.md), through the
//! same supervised loop and recording as `rig run`.

use std::path::Path;

use pneuflex_control::Setpoint;
use pneuflex_rig::RigFile;
use pneuflex_rig::record;

use super::excitation::{ExciteArgs, excitation};
use super::rig::run;

/// `pneuflex rig excite`: an identification experiment (pneuflex_identify::excite) on the rig, through the
/// same supervised loop and trace as `rig run`.
pub fn excite(
    rig_file: &Path,
    port: Option<&str>,
    a: &ExciteArgs,
    out: Option<&Path>,
) -> anyhow::Result<()> {
    use pneuflex_identify::excite::Exciter;
    // A scene of several actuators: each actuator its own excitation, on its channel.
    if let Some(scene) = &a.scene {
        return super::rig_mechanism::excite(rig_file, port, scene, a, out);
    }
    let limits = RigFile::load(rig_file)?.limits.position_m;
    let excitation = excitation(a, a.seed, limits, rig_file, "limits.position_m")?;
    let mut controller = Exciter::new(excitation);
    let mut reference = |_t: f64| Setpoint::default();
    let out_dir = match out {
        Some(d) => d.to_path_buf(),
        None => pneuflex_files::output::fresh_destination(
            &Path::new("out").join("rig").join("excite").join(&a.signal),
        ),
    };
    // The bag is written from the closed trace into the staged recording, before its commit.
    let mut finish = |dir: &Path, _: &pneuflex_rig::rtloop::LoopReport| {
        if a.mcap {
            super::bag::write_recording(dir).map(|_| ())
        } else {
            Ok(())
        }
    };
    let Some(truth) = &a.lockstep_truth else {
        return run(
            record::EXCITE,
            rig_file,
            port,
            None,
            &mut controller,
            &mut reference,
            a.duration_s,
            &out_dir,
            &mut (),
            &mut finish,
        )
        .map(|_| ());
    };
    super::recording::record_lockstep(
        record::EXCITE,
        rig_file,
        truth,
        a.seed,
        &out_dir,
        &[(rig_file, "rig")],
        &mut controller,
        &mut reference,
        a.duration_s,
        &mut finish,
    )
}
