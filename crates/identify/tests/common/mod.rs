//! Logs from the emulated rig with a hidden truth, run in lockstep with a simulated clock (as
//! crates/rig/tests/emulated_rig.rs does), so that nothing depends on the machine's speed.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use pneuflex_identify::excite::{Excitation, Exciter, Signal};
use pneuflex_identify::fit::{Estimate, FitOptions};
use pneuflex_identify::params::{Key, Offsets};
use pneuflex_identify::perturb::Perturbed;
use pneuflex_identify::replay::{Prepared, ReplayOptions};
use pneuflex_identify::request::Request;
use pneuflex_pneumatics::OneDofModel;
use pneuflex_rig::trace::TraceWriter;
use pneuflex_rig::{RigFile, session};

/// The shipped sheets the tests edit.
pub const CYL: &str = "smc-mqm16-cylinder.toml";
pub const VALVE: &str = "a05ps25x-5-2-valve.toml";
pub const ACT: &str = "paper-actuator.toml";

/// The shipped actuator sheet's friction lines, which the friction truths replace.
pub const SMOOTH: &str = "friction = \"smooth\"              # \"smooth\" (tanh) or \"stick_slip\" (Karnopp + Stribeck)\n\
                          coulomb_n = 0.6                  # low-friction MQM seals plus guide\n\
                          smooth_velocity_m_per_s = 0.002";

/// The keys the usual truths perturb: C, b, both dead volumes, Coulomb friction and the moving mass.
pub const USUAL_KEYS: [Key; 6] = [
    Key::SonicConductance,
    Key::CriticalRatio,
    Key::DeadVolumeA,
    Key::DeadVolumeB,
    Key::Coulomb,
    Key::MovingMass,
];

/// The workspace root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The emulated rig file.
pub fn rig_path() -> PathBuf {
    root().join("rigs/emulated.toml")
}

/// The shipped actuator sheet.
pub fn shipped() -> PathBuf {
    root().join("pneumatics").join(ACT)
}

/// Seeded steps of 0.15 s about a piston centred at 25 mm: the free-motion excitation the truths are
/// recovered from.
pub fn steps(seed: u64) -> Excitation {
    Excitation {
        signal: Signal::Steps { hold_s: 0.15, seed },
        amplitude: 0.05,
        bias: 0.0,
        centre_m: 0.025,
        centring_per_m: 15.0,
        ramp_s: 1.0,
    }
}

/// Steps with the piston held on its stop (bias -0.9, no centring): pressure transients and no motion, so
/// nothing to identify the mass from.
pub fn held_steps() -> Excitation {
    Excitation {
        signal: Signal::Steps {
            hold_s: 0.1,
            seed: 4,
        },
        amplitude: 0.1,
        bias: -0.9,
        centre_m: 0.0,
        centring_per_m: 0.0,
        ramp_s: 0.0,
    }
}

/// The names `--free` takes for `keys`.
pub fn names(keys: &[Key]) -> Vec<String> {
    keys.iter().map(|k| k.name().to_string()).collect()
}

/// A request to fit `free` of `actuator` from `logs`, a quarter of each log held out, everything else as
/// `identify` defaults it.
pub fn request(logs: Vec<PathBuf>, actuator: PathBuf, free: Vec<String>) -> Request {
    Request {
        logs,
        actuator,
        free,
        bounds: vec![],
        limits: Default::default(),
        log_format: Default::default(),
        figure_format: Default::default(),
        validation_fraction: 0.25,
        options: FitOptions::default(),
    }
}

/// Pressure and position RMS of `model`'s replay of `p` against the log, Pa and m.
pub fn rms_of(p: &Prepared, model: &OneDofModel) -> [f64; 2] {
    let pred = p.replay(
        model,
        &Offsets::default(),
        &ReplayOptions::default(),
        p.log.len(),
    );
    let (mut sp, mut sx) = (0.0, 0.0);
    for &k in &p.compared {
        sp += (pred.p_a[k] - p.log.p_a[k]).powi(2) + (pred.p_b[k] - p.log.p_b[k]).powi(2);
        sx += (pred.x[k] - p.log.x[k]).powi(2);
    }
    let n = p.compared.len() as f64;
    [(sp / (2.0 * n)).sqrt(), (sx / n).sqrt()]
}

/// Prints a fitted key against its truth: shipped, truth, fitted (its error) and the 95 % interval.
pub fn show_estimate(what: &str, c: &Perturbed, e: &Estimate) {
    eprintln!(
        "{what}{}: shipped {:e} truth {:e} fitted {:e} ({:+.3} %) 95 % [{:e}, {:e}]",
        e.key,
        c.shipped,
        c.truth,
        e.value,
        100.0 * (e.value / c.truth - 1.0),
        e.ci95[0],
        e.ci95[1]
    );
}

/// Whether the truth of `c` is inside the 95 % interval of its estimate `e`.
pub fn inside(c: &Perturbed, e: &Estimate) -> bool {
    e.ci95[0] <= c.truth && c.truth <= e.ci95[1]
}

/// Asserts the truth of `c` is inside the 95 % interval of its estimate `e` (`what` prefixes the message).
pub fn assert_inside(what: &str, c: &Perturbed, e: &Estimate) {
    assert!(
        inside(c, e),
        "{what}{}: truth {:e} outside the 95 % interval [{:e}, {:e}]",
        e.key,
        c.truth,
        e.ci95[0],
        e.ci95[1]
    );
}

/// A fresh scratch directory, removed when the returned guard drops.
pub fn scratch(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix(&format!("pneuflex-identify-{name}-"))
        .tempdir()
        .unwrap()
}

/// Records `duration_s` of `excitation` on the emulated rig whose plant runs the actuator sheet `truth`
/// (noise seed `seed`; contact with the block at `x_e_m`, or free motion when `None`), and writes the trace
/// to `out`. Returns the trace text.
pub fn record(
    truth: &Path,
    seed: u64,
    excitation: Excitation,
    duration_s: f64,
    x_e_m: Option<f64>,
    out: &Path,
) -> String {
    record_delayed(truth, seed, excitation, duration_s, x_e_m, None, out)
}

/// [`record`] with a transport delay of the valve commands.
pub fn record_delayed(
    truth: &Path,
    seed: u64,
    excitation: Excitation,
    duration_s: f64,
    x_e_m: Option<f64>,
    delay_s: Option<f64>,
    out: &Path,
) -> String {
    let file = rig_path();
    let mut rig = RigFile::load(&file).expect("rigs/emulated.toml loads");
    session::hide_truth(&mut rig, &file, truth, Some(seed), delay_s).expect("truth sheet loads");
    {
        let e = rig.emulator.as_mut().unwrap();
        e.faults.clear();
        let env = e.environment.as_mut().expect("the rig file's environment");
        env.change_at_s = None;
        // Free motion: the block beyond the stroke.
        env.x_e_m = x_e_m.unwrap_or(1.0);
    }
    let mut lockstep = session::lockstep_rig(&rig, &file).expect("the emulator connects");
    let stop = AtomicBool::new(false);
    let mut ctrl = Exciter::new(excitation);
    let mut reference = |_t: f64| pneuflex_control::Setpoint::default();
    let mut buf = Vec::new();
    {
        let mut trace =
            TraceWriter::create(&mut buf, rig.rt.trace_flush_every, "mem/trace.csv", &[])
                .expect("header");
        let opts = session::run_options(&rig, duration_s);
        let report = lockstep
            .run(&mut ctrl, &mut reference, &mut trace, &opts, &stop)
            .expect("the loop runs");
        if report.fault.is_some() {
            let t = String::from_utf8_lossy(trace.get_mut()).into_owned();
            for l in t.lines().skip(2).step_by(5).take(0) {
                eprintln!("{l}");
            }
        }
        assert!(
            report.fault.is_none(),
            "excitation faulted: {:?}",
            report.fault
        );
    }
    drop(lockstep);
    let text = String::from_utf8(buf).unwrap();
    std::fs::write(out, &text).unwrap();
    text
}

/// The shipped sheets copied into `dir` with `edits` applied (file, text to replace, replacement; an empty
/// `from` appends); the actuator sheet's path.
pub fn sheets(dir: &Path, edits: &[(&str, &str, &str)]) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let src = root().join("pneumatics");
    for e in std::fs::read_dir(&src).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "toml") {
            std::fs::copy(&p, dir.join(p.file_name().unwrap())).unwrap();
        }
    }
    for (file, from, to) in edits {
        let path = dir.join(file);
        let text = std::fs::read_to_string(&path).unwrap();
        let text = if from.is_empty() {
            format!("{text}\n{to}\n")
        } else {
            assert!(text.contains(from), "{file} lacks {from:?}");
            text.replacen(from, to, 1)
        };
        std::fs::write(&path, text).unwrap();
    }
    dir.join(ACT)
}
