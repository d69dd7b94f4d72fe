//! Processor-in-the-loop (PIL): a scene run's controller executes in the firmware on an emulated Cortex-M4F
//! (QEMU `mps2-an386`, [`qemu`]), the scene's plant on the host, in lockstep: the scene runner calls
//! [`FirmwareController::update`] once per tick, which sends the tick's sensors over the emulated UART and
//! waits for the board's valve command. The same run is simulated on the host, and the two traces are
//! compared tick by tick ([`Comparison`]). docs/firmware.md.

pub mod controller;
pub mod link;
pub mod mechanism;
pub mod observe;
pub mod qemu;

use std::path::Path;

use pneuflex_scene::analysis::adaptation::{lyapunov_summary, pinned_parameters};
use pneuflex_scene::analysis::windows::compute_windows;
use pneuflex_scene::{RunResult, Scene, build_plant, run_scene};

pub use controller::{Cost, FirmwareController};
pub use link::{Link, LinkStats};
pub use pneuflex_protocol::ctrl::SafePayload;

/// Why a PIL run could not be done.
#[derive(Debug, thiserror::Error)]
pub enum PilError {
    /// QEMU is missing (the message says how to install it).
    #[error("{0}")]
    NoQemu(String),
    /// The firmware image is missing, or the firmware went safe or panicked during the run.
    #[error("firmware: {0}")]
    Firmware(String),
    /// The link failed (QEMU exited, no answer, write error).
    #[error("link: {0}")]
    Link(String),
    /// The board refused the setup, or the run cannot be set up.
    #[error("setup: {0}")]
    Setup(String),
    /// The scene.
    #[error(transparent)]
    Scene(#[from] pneuflex_scene::SceneError),
    /// A signal came while the host waited for the board (before any tick, or in one).
    #[error("stopped by a signal while waiting for the board")]
    Stopped,
    /// A signal stopped the run: what the board ran until then.
    #[error("interrupted: {}", .0.interrupted.as_deref().unwrap_or("by a signal"))]
    Interrupted(Box<RunResult>),
}

/// The board's watchdog in a PIL run, ms of virtual time. Generous: the host computes the plant between
/// two ticks while the board's clock runs on (one virtual ns per emulated instruction); a real board with a
/// real-time host would use a few control periods.
pub const PIL_WATCHDOG_MS: u16 = 2000;

/// Tolerance for "the same command": |Δu| ≤ 1e-9 (the firmware and the host compute in IEEE-754 f64 with
/// the same code; a difference shows where they do not).
pub const U_TOLERANCE: f64 = 1e-9;

/// Tick-by-tick comparison of the firmware's run with the host's simulation of the same run.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Comparison {
    /// Ticks compared (the shorter trace).
    pub ticks: usize,
    /// Ticks in the firmware run and in the host run.
    pub ticks_firmware: usize,
    /// See `ticks_firmware`.
    pub ticks_host: usize,
    /// max |u_firmware - u_host|.
    pub max_abs_du: f64,
    /// max |f_e,firmware - f_e,host|, N.
    pub max_abs_dfe_n: f64,
    /// max |x_r,firmware - x_r,host|, m.
    pub max_abs_dxr_m: f64,
    /// First tick where |Δu| > [`U_TOLERANCE`] (None: never).
    pub first_divergent_tick: Option<usize>,
    /// Ticks whose every recorded value is bit-identical in both traces.
    pub bit_identical_ticks: usize,
    /// Each of the controller's own signals (as `Controller::signals()` declares them; g, p, d for the
    /// adaptive controller), compared over the same ticks.
    pub controller_signals: Vec<SignalComparison>,
    /// Ticks where the board's own setpoint differed from the host's.
    pub setpoint_mismatches: u64,
    /// Per metric window: RMS force error of the firmware and the host run, N.
    pub rms_force_error_n: Vec<(String, Option<f64>, Option<f64>)>,
    /// Whether every metric of summary.json is equal in both runs.
    pub metrics_equal: bool,
}

/// One controller signal of the firmware run against the host run.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SignalComparison {
    /// The signal's declared name.
    pub name: String,
    /// Its declared unit.
    pub unit: String,
    /// max |firmware - host| (infinite where one is NaN and the other not).
    pub max_abs_diff: f64,
    /// Ticks where both values are bit-identical.
    pub bit_identical_ticks: usize,
}

/// The outcome of one PIL run.
pub struct PilRun {
    /// The run with the controller on the board (trace, metrics).
    pub firmware: RunResult,
    /// The same run simulated on the host.
    pub host: RunResult,
    /// The two compared.
    pub comparison: Comparison,
    /// Link counters.
    pub link: LinkStats,
    /// The controller update's cost on the board.
    pub cost: Cost,
    /// The board's report when the host parked the valve at the end (stack high-water mark).
    pub end: SafePayload,
}

/// Runs run `index` of `scene` with its controller in the firmware `elf` on the emulated board, then the same
/// run on the host, and compares them. A link or firmware error is an Err (no half result).
pub fn run_pil(
    scene: &Scene,
    index: usize,
    elf: &Path,
    progress: &mut dyn FnMut(f64),
) -> Result<PilRun, PilError> {
    run_pil_observed(scene, index, elf, progress, &mut (), None)
}

fn is_set(stop: &Option<std::sync::Arc<std::sync::atomic::AtomicUsize>>) -> bool {
    stop.as_ref()
        .is_some_and(|s| s.load(std::sync::atomic::Ordering::Relaxed) != 0)
}

/// [`run_pil`] with an observer of the firmware run's rows, which also get the link's quality and the
/// board's update cost ([`observe::PIL_SIGNALS`]); the observer sees the run tick by tick as it happens.
pub fn run_pil_observed(
    scene: &Scene,
    index: usize,
    elf: &Path,
    progress: &mut dyn FnMut(f64),
    observer: &mut dyn pneuflex_control::Sink<()>,
    stop: Option<std::sync::Arc<std::sync::atomic::AtomicUsize>>,
) -> Result<PilRun, PilError> {
    qemu::check_firmware(elf)?;
    let run = scene
        .runs
        .get(index)
        .ok_or_else(|| PilError::Setup(format!("no run {index}")))?;
    let setup = controller::setup_of(run)?;
    let setpoints = scene.setpoints()?;
    // The host controller of the same kind declares the recorded signals (g, p, d for adaptive).
    let signals = scene.controller(index)?.signals();

    let (mut board, stdin, stdout) = qemu::Board::start(elf)?;
    let mut link = Link::new(stdin, stdout);
    link.stop = stop.clone();
    controller::start(&mut link, &setup, &setpoints, scene.dt_s, PIL_WATCHDOG_MS)
        .map_err(|e| if is_set(&stop) { PilError::Stopped } else { e })?;
    let mut fw = FirmwareController::new(link, signals);
    let mut plant = build_plant(scene)?;
    let live = fw.live();
    let mut rows = observe::LinkRows::new(observer, live);
    let mut firmware = pneuflex_scene::run::simulate_stoppable(
        scene,
        index,
        plant.as_mut(),
        &mut fw,
        &setpoints,
        progress,
        &mut rows,
        stop.as_deref(),
    )?;
    // simulate_observed leaves the run's end to its caller (run_scene_with calls it).
    pneuflex_control::Sink::<dyn pneuflex_scene::Plant>::end(
        &mut rows,
        firmware
            .diverged
            .as_deref()
            .or(firmware.interrupted.as_deref()),
    );
    if let Some(e) = fw.error.take() {
        let exited = board
            .exited()
            .map(|s| format!(" (QEMU: {s})"))
            .unwrap_or_default();
        return Err(match e {
            PilError::Link(m) => PilError::Link(format!("{m}{exited}")),
            e => e,
        });
    }
    // A signal: at the next tick (the run comes back interrupted), or while the host waited for the
    // board in a tick (the link gave up at once).
    if firmware.interrupted.is_some() || is_set(&stop) {
        drop(board);
        if firmware.interrupted.is_none() {
            let t = firmware.trace.t().last().copied().unwrap_or(0.0);
            firmware.interrupted = Some(format!("stopped by a signal at t = {t} s"));
        }
        return Err(PilError::Interrupted(Box::new(firmware)));
    }
    let end = fw.finish()?;
    drop(board);
    let pwm = firmware.pwm_period_s;
    if firmware.diverged.is_none() {
        firmware.windows = compute_windows(scene, &firmware.trace, pwm);
    }
    if firmware.is_adaptive() {
        firmware.lyapunov = lyapunov_summary(scene, run);
    }
    firmware.warnings = pinned_parameters(run, &firmware.trace);

    let host = host_run(scene, index)?;
    let comparison = compare(&firmware, &host, signals, fw.setpoint_mismatches.0);
    Ok(PilRun {
        firmware,
        host,
        comparison,
        link: fw.link_stats(),
        cost: fw.cost(),
        end,
    })
}

/// The scene reduced to run `index` (what the outputs of a PIL run describe). Its claims compare runs with
/// each other, so they go too.
pub fn single_run_scene(scene: &Scene, index: usize) -> Scene {
    scene.one_run(index, scene.duration_s)
}

fn host_run(scene: &Scene, index: usize) -> Result<RunResult, PilError> {
    let one = single_run_scene(scene, index);
    let mut r = run_scene(&one, &mut |_| {})?;
    r.pop()
        .ok_or_else(|| PilError::Setup("the host simulation returned no run".into()))
}

/// Compares two runs of the same scene tick by tick; `signals` are the controller's own.
pub fn compare(
    fw: &RunResult,
    host: &RunResult,
    signals: &[pneuflex_control::Signal],
    setpoint_mismatches: u64,
) -> Comparison {
    compare_actuator(fw, host, signals, setpoint_mismatches, "")
}

/// [`compare`] of one actuator's columns in the traces of a scene of several (`prefix` its name and a dot:
/// `left.u`); a tick is bit-identical when every column of the trace is.
pub fn compare_actuator(
    fw: &RunResult,
    host: &RunResult,
    signals: &[pneuflex_control::Signal],
    setpoint_mismatches: u64,
    prefix: &str,
) -> Comparison {
    let col = |r: &RunResult, n: &str| {
        r.trace
            .column(&format!("{prefix}{n}"))
            .map(<[f64]>::to_vec)
            .unwrap_or_default()
    };
    let (u1, u2) = (col(fw, "u"), col(host, "u"));
    let (f1, f2) = (col(fw, "f_e"), col(host, "f_e"));
    let (x1, x2) = (col(fw, "x_r"), col(host, "x_r"));
    let ticks = fw.trace.len().min(host.trace.len());
    let max_abs = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| {
                let d = (x - y).abs();
                if d.is_nan() { f64::INFINITY } else { d }
            })
            .fold(0.0_f64, f64::max)
    };
    let first_divergent_tick = u1.iter().zip(&u2).position(|(a, b)| {
        let d = (a - b).abs();
        d.is_nan() || d > U_TOLERANCE
    });
    let names: Vec<String> = fw
        .trace
        .columns()
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    let bit_identical_ticks = (0..ticks)
        .filter(|&k| {
            names.iter().all(|n| {
                let a = fw.trace.column(n).map(|c| c[k].to_bits());
                let b = host.trace.column(n).map(|c| c[k].to_bits());
                a == b
            })
        })
        .count();
    let controller_signals = signals
        .iter()
        .map(|sig| {
            let (a, b) = (col(fw, sig.name), col(host, sig.name));
            let n = a.len().min(b.len()).min(ticks);
            SignalComparison {
                name: sig.name.to_string(),
                unit: sig.unit.to_string(),
                // A column missing on one side compares as NaN against the other: not identical.
                max_abs_diff: if a.len() < ticks || b.len() < ticks {
                    f64::INFINITY
                } else {
                    max_abs(&a[..n], &b[..n])
                },
                bit_identical_ticks: (0..n).filter(|&k| a[k].to_bits() == b[k].to_bits()).count(),
            }
        })
        .collect();
    let rms_force_error_n = fw
        .windows
        .iter()
        .map(|w| {
            let h = host.window(&w.name).map(|h| h.rms_force_error_n);
            (w.name.clone(), Some(w.rms_force_error_n), h)
        })
        .collect();
    Comparison {
        ticks,
        ticks_firmware: fw.trace.len(),
        ticks_host: host.trace.len(),
        max_abs_du: max_abs(&u1, &u2),
        max_abs_dfe_n: max_abs(&f1, &f2),
        max_abs_dxr_m: max_abs(&x1, &x2),
        first_divergent_tick,
        bit_identical_ticks,
        controller_signals,
        setpoint_mismatches,
        rms_force_error_n,
        metrics_equal: fw.windows == host.windows && fw.diverged == host.diverged,
    }
}
