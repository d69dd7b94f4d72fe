//! SIGTERM and SIGHUP are handled exactly like Ctrl-C (SIGINT): the handler sets the stop flag, the loop
//! commands the safe state in the tick that sees it, writes the fault row and ends the trace with its end
//! marker. Its own test binary: a process installs the handler once. Without the handler for SIGTERM and
//! SIGHUP (ctrlc's `termination` feature) this test process would be killed.

mod common;

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use pneuflex_control::Setpoint;
use pneuflex_rig::protocol::ValveMode;
use pneuflex_rig::trace::{self, TraceWriter};
use pneuflex_rig::{ErrorKind, RigFile, session};

#[test]
fn sigterm_sighup_and_sigint_stop_the_run_safely() {
    let file = common::rig_path();
    let rig = RigFile::load(&file).unwrap();
    let stop = session::install_ctrl_c().expect("handler");
    for sig in ["TERM", "HUP", "INT"] {
        stop.store(false, Ordering::SeqCst);
        let mut lockstep = session::lockstep_rig(&rig, &file).unwrap();
        let mut ctrl = common::paper_controller();
        let flag = stop.clone();
        let mut sent = false;
        let mut reference = |t: f64| {
            if t >= 0.25 && !sent {
                sent = true;
                // The real signal, to this process; wait (wall clock) until the handler thread has run.
                let ok = std::process::Command::new("kill")
                    .arg(format!("-{sig}"))
                    .arg(std::process::id().to_string())
                    .status()
                    .unwrap()
                    .success();
                assert!(ok, "kill -{sig}");
                let t0 = Instant::now();
                while !flag.load(Ordering::SeqCst) && t0.elapsed() < Duration::from_secs(30) {
                    std::thread::sleep(Duration::from_millis(1));
                }
            }
            Setpoint {
                f_ref: 10.0,
                x_d: 0.02,
            }
        };
        let mut out = Vec::new();
        let report = {
            let mut trace = TraceWriter::new(&mut out, rig.rt.trace_flush_every).unwrap();
            let opts = session::run_options(&rig, 1.0);
            lockstep
                .run(&mut ctrl, &mut reference, &mut trace, &opts, &stop)
                .unwrap()
        };
        drop(lockstep.rig);
        let f = report.fault.expect("stopped");
        assert_eq!(f.kind, ErrorKind::Interrupted, "SIG{sig}");
        assert_eq!(f.tick, 251, "SIG{sig}: seen at the start of the next tick");
        // The host sent the safe state in the tick that saw the signal, and only safe states after.
        let log = lockstep.log.lock().unwrap();
        let first_safe = log.commands.iter().position(|c| c.mode.is_safe()).unwrap();
        assert_eq!(log.commands[first_safe].tick, 251, "SIG{sig}");
        assert_eq!(log.commands[first_safe].mode, ValveMode::SafeVent);
        assert!(log.commands[first_safe..].iter().all(|c| c.mode.is_safe()));
        let text = String::from_utf8(out).unwrap();
        let (rows, end) = trace::data_lines(&text);
        assert!(
            rows[251].contains(",interrupted: stopped by a signal"),
            "SIG{sig}"
        );
        assert_eq!(
            end,
            Some(format!("interrupted, {} rows", rows.len()).as_str())
        );
    }
}
