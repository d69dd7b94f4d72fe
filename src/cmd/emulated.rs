//! An emulated board as the `rig emulate` commands serve it (one channel, or a scene of several): what it
//! hides from the host, and the wait until Ctrl-C or its duration, saying each run a host starts.

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use pneuflex_rig::session;

/// What `rig emulate --truth` hides from the host: the plant's actuator sheet, the noise seed and a
/// transport delay (docs/identification.md).
#[derive(Clone, Debug, Default)]
pub struct Hidden {
    /// Actuator sheet the plant runs instead of the rig file's `emulator.actuator`.
    pub truth: Option<std::path::PathBuf>,
    /// Sensor-noise seed instead of `emulator.seed`.
    pub seed: Option<u64>,
    /// Transport delay of valve commands, s.
    pub delay_s: Option<f64>,
}

/// Serves an emulated board until Ctrl-C, `duration_s` or the board's end, saying each run a host starts, then
/// what the board did.
pub fn serve(
    handle: pneuflex_rig::emulator::EmulatorHandle,
    name: &str,
    port: Option<&str>,
    duration_s: Option<f64>,
) -> anyhow::Result<()> {
    let stop = session::install_ctrl_c()?;
    match &handle.path {
        Some(p) => outln!(
            "emulating rig `{name}` on {}  (connect with: pneuflex rig run --port {} ...; Ctrl-C stops)",
            p.display(),
            p.display()
        ),
        None => outln!(
            "emulating rig `{name}` on {}  (Ctrl-C stops)",
            port.unwrap_or("")
        ),
    }
    let start = Instant::now();
    let mut runs = 0;
    while !stop.load(Ordering::Relaxed)
        && !handle.is_finished()
        && duration_s.is_none_or(|d| start.elapsed().as_secs_f64() < d)
    {
        std::thread::sleep(Duration::from_millis(20));
        // Each host connection (its Config) starts a run from the rig file's initial state.
        let now = handle.runs();
        if now > runs {
            runs = now;
            outln!("run {runs}: a host connected; the plant starts from its initial state");
        }
    }
    let log = handle.stop();
    outln!(
        "emulator stopped: {} runs, {} samples sent, {} valve commands received, {} board-watchdog trips{}",
        log.runs,
        log.samples_sent,
        log.commands.len(),
        log.board_watchdog_trips,
        log.ended.map(|e| format!(" ({e})")).unwrap_or_default()
    );
    Ok(())
}
