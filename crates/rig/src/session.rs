//! Putting the layers together: the supervised rig stack from a rig file, and the emulator from a rig file.

use std::path::Path;
use std::sync::atomic::AtomicBool;

use pneuflex_control::{Controller, Setpoint};
use pneuflex_pneumatics::ActuatorSheet;

use crate::emulator::{Emulator, EmulatorHandle, PtyLink};
use crate::error::{ErrorKind, RigError};
use crate::plant::PneumaticPlant;
use crate::rig::{Calibrated, Limited, Watchdog};
use crate::rigfile::{EmulatorConfig, RigFile, RigFileError};
use crate::rtloop::{LoopReport, RunOptions, run_with_clock};
use crate::serial::{Link, SerialRig};
use crate::supervisor::Supervisor;
use crate::trace::{TraceSink, TraceWriter};

/// The full host-side stack: serial driver, watchdog, calibration, limits.
pub type RigStack<L> = Limited<Calibrated<Watchdog<SerialRig<L>>>>;

/// Wraps a connected serial driver in the watchdog, calibration and limit layers and a supervisor.
pub fn supervised<L: Link>(serial: SerialRig<L>, rig: &RigFile) -> Supervisor<RigStack<L>> {
    let stack = Limited::new(
        Calibrated::new(
            Watchdog::new(serial, &rig.watchdog),
            rig.cal(),
            rig.rt.velocity_cutoff_hz,
        ),
        rig.limits.clone(),
    );
    Supervisor::new(stack, rig.valve.safe_state)
}

/// Loop options from the rig file for a run of `duration_s`.
pub fn run_options(rig: &RigFile, duration_s: f64) -> RunOptions {
    RunOptions {
        rate_hz: rig.rt.rate_hz,
        spin_us: rig.rt.spin_us,
        duration_s,
        post_fault_s: rig.rt.post_fault_s,
        first_sample_timeout_s: (rig.link.handshake_timeout_ms as f64 * 1e-3).max(0.1),
    }
}

/// An `[emulator]` key of the rig file `file` that will not do (no position: the table is read, not its text).
fn invalid(file: &Path, key: &str, message: String) -> RigFileError {
    RigFileError::Invalid {
        file: file.to_path_buf(),
        at: None,
        key: key.into(),
        message,
    }
}

/// The emulator's plant from the rig file's `[emulator]` table (actuator sheet path relative to the rig file).
pub fn emulated_plant(rig: &RigFile, file: &Path) -> Result<PneumaticPlant, RigFileError> {
    let Some(e) = &rig.emulator else {
        return Err(invalid(
            file,
            "emulator",
            "missing: `pneuflex rig emulate` needs an [emulator] table".into(),
        ));
    };
    let Some(sheet) = &e.actuator else {
        return Err(invalid(
            file,
            "emulator.actuator",
            "missing: expected the path of an actuator sheet (e.g. ../pneumatics/paper-actuator.toml)".into(),
        ));
    };
    if e.environment.is_none() {
        return Err(invalid(
            file,
            "emulator.environment",
            "missing: the one-actuator emulator's contact spring (x_e_m, k_e_n_per_m); only a scene with \
             several actuators brings its own contacts"
                .into(),
        ));
    }
    let path = rig.resolve_path(sheet);
    let sheet = ActuatorSheet::load(&path)
        .map_err(|err| invalid(file, "emulator.actuator", err.to_string()))?;
    let model = sheet.model();
    let stroke = model.actuator.cylinder.stroke_m;
    if !(0.0..=stroke).contains(&e.x0_m) {
        return Err(invalid(
            file,
            "emulator.x0_m",
            format!("{} m is outside the stroke [0, {stroke}] m", e.x0_m),
        ));
    }
    Ok(PneumaticPlant::new(model, e.x0_m, e.supply_pa))
}

/// Hides a truth in the emulator of `rig` (`pneuflex rig emulate --truth`): its plant runs the actuator sheet
/// `sheet` (validated here; errors name the sheet and the key) with the sheet's supply pressure (a rig
/// measures its supply, so the host may know it), `seed` for the sensor noise and `transport_delay_s`
/// between a command reaching the board and the valve applying it. The host is told none of it.
pub fn hide_truth(
    rig: &mut RigFile,
    file: &Path,
    sheet: &Path,
    seed: Option<u64>,
    transport_delay_s: Option<f64>,
) -> Result<(), RigFileError> {
    let truth = ActuatorSheet::load(sheet)
        .map_err(|err| invalid(file, "emulator.actuator (--truth)", err.to_string()))?;
    let Some(e) = rig.emulator.as_mut() else {
        return Err(invalid(
            file,
            "emulator",
            "missing: `pneuflex rig emulate --truth` needs an [emulator] table".into(),
        ));
    };
    // An absolute path: `RigFile::resolve_path` joins it to the rig file's folder unchanged.
    let abs = std::path::absolute(sheet).unwrap_or_else(|_| sheet.to_path_buf());
    e.actuator = Some(abs);
    e.supply_pa = truth.supply.supply.supply_pressure_pa;
    if let Some(s) = seed {
        e.seed = s;
    }
    if let Some(d) = transport_delay_s {
        if !(d.is_finite() && (0.0..=1.0).contains(&d)) {
            return Err(invalid(
                file,
                "emulator.transport_delay_s (--delay)",
                format!("expected 0..=1 s, got {d}"),
            ));
        }
        e.transport_delay_s = d;
    }
    Ok(())
}

/// The emulator's plant and its `[emulator]` table, for starting it.
fn plant_and_config(
    rig: &RigFile,
    file: &Path,
) -> Result<(PneumaticPlant, EmulatorConfig), RigError> {
    let plant =
        emulated_plant(rig, file).map_err(|e| RigError::new(ErrorKind::Io, e.to_string()))?;
    let cfg = rig
        .emulator
        .clone()
        .ok_or_else(|| RigError::new(ErrorKind::Io, "no [emulator] table"))?;
    Ok((plant, cfg))
}

/// Starts the emulator of `rig` behind a new pseudo-terminal; the handle carries the path to open.
pub fn spawn_pty_emulator(rig: &RigFile, file: &Path) -> Result<EmulatorHandle, RigError> {
    let (plant, cfg) = plant_and_config(rig, file)?;
    let link = PtyLink::open()?;
    let path = link.path.clone();
    Ok(Emulator::new(plant, link, rig.cal(), cfg).spawn(Some(path)))
}

/// The number of the last SIGINT, SIGTERM or SIGHUP that [`install_ctrl_c`]'s handler saw (0: none).
static LAST_SIGNAL: std::sync::OnceLock<std::sync::Arc<std::sync::atomic::AtomicUsize>> =
    std::sync::OnceLock::new();

/// Installs a handler for SIGINT (Ctrl-C), SIGTERM and SIGHUP that sets the returned flag; the loop polls it
/// every tick and latches an `Interrupted` fault, which puts the valve in its safe state in that tick and
/// syncs the trace. A second signal does not end the process: the recording is committed first.
/// [`last_signal`] tells which signal came (for the exit code, 128 + the signal).
pub fn install_ctrl_c() -> Result<std::sync::Arc<std::sync::atomic::AtomicBool>, RigError> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let flag = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let number = LAST_SIGNAL
        .get_or_init(|| std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0)))
        .clone();
    let err = |e: std::io::Error| {
        RigError::new(
            ErrorKind::Io,
            format!("cannot install the SIGINT/SIGTERM/SIGHUP handler: {e}"),
        )
    };
    for sig in [SIGINT, SIGTERM, SIGHUP] {
        signal_hook::flag::register(sig, flag.clone()).map_err(err)?;
        signal_hook::flag::register_usize(sig, number.clone(), sig as usize).map_err(err)?;
    }
    Ok(flag)
}

/// The number of the last signal the handler of [`install_ctrl_c`] saw (0: none yet).
pub fn last_signal() -> usize {
    LAST_SIGNAL
        .get()
        .map_or(0, |n| n.load(std::sync::atomic::Ordering::Relaxed))
}

/// Starts the emulator of `rig` serving an existing serial port (e.g. one end of a null-modem pair).
pub fn spawn_port_emulator(
    rig: &RigFile,
    file: &Path,
    port: &str,
) -> Result<EmulatorHandle, RigError> {
    let (plant, cfg) = plant_and_config(rig, file)?;
    let link = serialport::new(port, rig.link.baud)
        .timeout(std::time::Duration::ZERO)
        .open()
        .map_err(|e| RigError::new(ErrorKind::LinkLost, format!("cannot open `{port}`: {e}")))?;
    Ok(Emulator::new(plant, link, rig.cal(), cfg).spawn(None))
}

/// The host end of the link to the one-channel emulated board of a pneumatic plant, in lockstep.
pub type PneumaticLockstep =
    crate::emulator::LockstepLink<crate::emulator::Board<PneumaticPlant, crate::emulator::MemLink>>;

/// The emulator of `rig` on an in-memory link, stepped in lockstep with `clock` (see
/// [`crate::emulator::lockstep`]); with [`serial::connect_link`] and [`crate::rtloop::run_with_clock`] on the
/// same clock, a run does not depend on the machine's speed.
pub fn lockstep_emulator(
    rig: &RigFile,
    file: &Path,
    clock: crate::clock::SimClock,
) -> Result<
    (
        PneumaticLockstep,
        std::sync::Arc<std::sync::Mutex<crate::emulator::EmulatorLog>>,
    ),
    RigError,
> {
    let (plant, cfg) = plant_and_config(rig, file)?;
    Ok(crate::emulator::lockstep(plant, rig.cal(), cfg, clock))
}

/// The rig file's emulator in lockstep (see [`lockstep_emulator`]), connected over the serial protocol and
/// behind the supervisor, with the clock a loop must run on (`rtloop::run_with_clock`) and the emulator's log.
pub struct LockstepRig {
    /// The supervised rig.
    pub rig: Supervisor<RigStack<PneumaticLockstep>>,
    /// The simulated clock the emulator steps with.
    pub clock: crate::clock::SimClock,
    /// What the emulated board saw and did.
    pub log: std::sync::Arc<std::sync::Mutex<crate::emulator::EmulatorLog>>,
}

impl LockstepRig {
    /// Runs the loop on this rig and the clock its emulator steps with ([`crate::rtloop::run_with_clock`]).
    pub fn run(
        &mut self,
        controller: &mut (impl Controller + ?Sized),
        reference: &mut dyn FnMut(f64) -> Setpoint,
        trace: &mut TraceWriter<impl TraceSink>,
        opts: &RunOptions,
        stop: &AtomicBool,
    ) -> std::io::Result<LoopReport> {
        run_with_clock(
            &mut self.rig,
            controller,
            reference,
            trace,
            opts,
            stop,
            &mut self.clock,
        )
    }
}

/// [`LockstepRig`] for `rig` (read from `file`): the emulator, the handshake, the supervisor.
pub fn lockstep_rig(rig: &RigFile, file: &Path) -> Result<LockstepRig, RigError> {
    let mut clock = crate::clock::SimClock::new();
    let (link, log) = lockstep_emulator(rig, file, clock.clone())?;
    let serial = crate::serial::connect_link(link, rig, &mut clock)?;
    Ok(LockstepRig {
        rig: supervised(serial, rig),
        clock,
        log,
    })
}

/// A scene whose control period is not the rig's: both files and both keys named.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error(
    "{}: `dt_s` = {scene_dt_s} s differs from the rig's control period: {}: `loop.rate_hz` = {rate_hz} Hz, i.e. dt = {} s; set the scene's dt_s = {} or the rig's loop.rate_hz = {}",
    scene_file.display(), rig_file.display(), 1.0 / rate_hz, 1.0 / rate_hz, 1.0 / scene_dt_s
)]
pub struct RateMismatch {
    /// The scene file.
    pub scene_file: std::path::PathBuf,
    /// Its `dt_s`, s.
    pub scene_dt_s: f64,
    /// The rig file.
    pub rig_file: std::path::PathBuf,
    /// Its `loop.rate_hz`, Hz.
    pub rate_hz: f64,
}

/// A scene's step `dt_s` must be the rig's control period 1/`loop.rate_hz` (docs/rig.md): the controller's
/// gains and filters were tuned for its dt, and the rig runs at its own rate.
pub fn check_scene_rate(
    scene_dt_s: f64,
    scene_file: &Path,
    rig: &RigFile,
    rig_file: &Path,
) -> Result<(), RateMismatch> {
    let dt = rig.dt();
    if (scene_dt_s - dt).abs() <= 1e-9 * dt {
        return Ok(());
    }
    Err(RateMismatch {
        scene_file: scene_file.to_path_buf(),
        scene_dt_s,
        rig_file: rig_file.to_path_buf(),
        rate_hz: rig.rt.rate_hz,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scene_dt_other_than_the_rig_period_names_both_keys() {
        let file = crate::rigfile::tests::rigs_dir().join("emulated.toml");
        let rig = RigFile::parse(crate::rigfile::tests::EMULATED, &file).unwrap();
        let scene = Path::new("scenes/s.toml");
        assert!(check_scene_rate(0.001, scene, &rig, &file).is_ok());
        let m = check_scene_rate(0.01, scene, &rig, &file)
            .unwrap_err()
            .to_string();
        assert!(
            m.contains("scenes/s.toml")
                && m.contains("`dt_s` = 0.01")
                && m.contains("emulated.toml")
                && m.contains("`loop.rate_hz` = 1000"),
            "{m}"
        );
    }
}
