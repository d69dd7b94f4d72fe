//! Logs from the emulated rig with a hidden truth, run in lockstep with a simulated clock (as
//! crates/rig/tests/emulated_rig.rs does), so that nothing depends on the machine's speed.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use pneuflex_identify::excite::{Excitation, Exciter};
use pneuflex_rig::trace::TraceWriter;
use pneuflex_rig::{RigFile, rtloop, session};

/// The workspace root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The emulated rig file.
pub fn rig_path() -> PathBuf {
    root().join("rigs/emulated.toml")
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
        e.environment.change_at_s = None;
        // Free motion: the block beyond the stroke.
        e.environment.x_e_m = x_e_m.unwrap_or(1.0);
    }
    let session::LockstepRig {
        rig: mut sup,
        mut clock,
        ..
    } = session::lockstep_rig(&rig, &file).expect("the emulator connects");
    let stop = AtomicBool::new(false);
    let mut ctrl = Exciter::new(excitation);
    let mut reference = |_t: f64| pneuflex_control::Setpoint::default();
    let mut buf = Vec::new();
    {
        let mut trace =
            TraceWriter::create(&mut buf, rig.rt.trace_flush_every, "mem/trace.csv", &[])
                .expect("header");
        let opts = session::run_options(&rig, duration_s);
        let report = rtloop::run_with_clock(
            &mut sup,
            &mut ctrl,
            &mut reference,
            &mut trace,
            &opts,
            &stop,
            &mut clock,
        )
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
    drop(sup);
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
    dir.join("paper-actuator.toml")
}
