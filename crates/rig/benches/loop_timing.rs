//! Loop timing at the rig file's rate (1 kHz) against the emulator over a pty: period error p50/p99/max,
//! overruns, host time per tick in I/O and in the controller. Not a criterion bench: the quantity is the
//! behaviour of a real-time loop over wall time, not the cost of a function.
//!
//! `cargo bench -p pneuflex-rig --bench loop_timing` (PNEUFLEX_BENCH_SECONDS sets the length, default 15 s;
//! PNEUFLEX_BENCH_SPIN_US overrides `loop.spin_us`; PNEUFLEX_BENCH_TIMEOUT_MS the watchdogs, default 1000 ms).

#[path = "../tests/common/mod.rs"]
mod common;

use std::path::Path;
use std::sync::atomic::AtomicBool;

use pneuflex_control::Setpoint;
use pneuflex_rig::rtloop;
use pneuflex_rig::trace::TraceWriter;
use pneuflex_rig::{RigFile, serial, session};

fn main() {
    let secs: f64 = std::env::var("PNEUFLEX_BENCH_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(15.0);
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../rigs/emulated.toml");
    let mut rig = RigFile::load(&file).expect("rigs/emulated.toml");
    if let Some(s) = std::env::var("PNEUFLEX_BENCH_SPIN_US")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        rig.rt.spin_us = s;
    }
    rig.emulator
        .as_mut()
        .unwrap()
        .environment
        .as_mut()
        .unwrap()
        .change_at_s = Some(secs / 2.0);
    // Measure timing over the whole run: a late tick on a loaded machine would otherwise end it on the 5 ms
    // rig watchdog (the number of such would-be trips is what `ticks without a new sample` hints at).
    let wd_ms: f64 = std::env::var("PNEUFLEX_BENCH_TIMEOUT_MS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1000.0);
    rig.watchdog.timeout_ms = wd_ms;
    rig.watchdog.board_watchdog_ms = wd_ms.min(60000.0) as u16;
    let emu = session::spawn_pty_emulator(&rig, &file).expect("emulator");
    let port = emu.path.clone().unwrap();
    let link = serial::connect(&rig, &file, Some(port.to_str().unwrap())).expect("connect");
    let mut sup = session::supervised(link, &rig);
    let mut ctrl = common::paper_controller();
    let mut reference = |_t: f64| Setpoint {
        f_ref: 10.0,
        x_d: 0.02,
    };
    let mut trace = TraceWriter::new(std::io::sink(), rig.rt.trace_flush_every).unwrap();
    let opts = session::run_options(&rig, secs);
    let stop = AtomicBool::new(false);
    println!(
        "loop timing: {} Hz for {secs} s against the pty emulator (spin {} µs)",
        rig.rt.rate_hz, rig.rt.spin_us
    );
    let report = rtloop::run(
        &mut sup,
        &mut ctrl,
        &mut reference,
        &mut trace,
        &opts,
        &stop,
    )
    .unwrap();
    drop(sup);
    let log = emu.stop();
    println!("{report}");
    println!(
        "emulator: {} samples sent, {} commands received, {} tx drops",
        log.samples_sent,
        log.commands.len(),
        log.tx_dropped
    );
}
