//! `record`: the output directory of a rig run. Connect before writing; never touch an existing output on a
//! failed connect; a signal commits a marked partial beside the previous output; provenance in the trace
//! header and the manifest. The emulator runs in lockstep with a simulated clock.

mod common;

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

use pneuflex_control::Setpoint;
use pneuflex_files::output::read_manifest;
use pneuflex_rig::clock::SimClock;
use pneuflex_rig::record::{self, RecordError, Recording};
use pneuflex_rig::trace;
use pneuflex_rig::{RigError, RigFile, serial, session};

/// A fresh scratch directory, removed when the returned guard drops.
fn scratch(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix(&format!("pneuflex-record-{name}-"))
        .tempdir()
        .unwrap()
}

/// Records `duration_s` into `out`; `stop_at_s` sets the stop flag as the signal handler would; with
/// `fail_connect` the connection fails.
fn record_into(
    out: &Path,
    duration_s: f64,
    stop_at_s: Option<f64>,
    fail_connect: bool,
) -> (Result<Recording, RecordError>, bool) {
    let rig = RigFile::load(&common::rig_path()).unwrap();
    let file = common::rig_path();
    let mut clock = SimClock::new();
    let mut c2 = clock.clone();
    let mut connected = false;
    let connect = || {
        connected = true;
        if fail_connect {
            return Err(RigError::new(
                pneuflex_rig::ErrorKind::LinkLost,
                "cannot open serial port `/dev/nope`",
            ));
        }
        let (link, _log) = session::lockstep_emulator(&rig, &file, c2.clone())?;
        serial::connect_link(link, &rig, &mut c2)
    };
    let stop = AtomicBool::new(false);
    let mut reference = |t: f64| {
        if stop_at_s.is_some_and(|s| t >= s) {
            stop.store(true, Ordering::Relaxed);
        }
        Setpoint {
            f_ref: 10.0,
            x_d: 0.02,
        }
    };
    let res = record::record(
        record::COMMAND,
        &rig,
        connect,
        out,
        &[(&file, "rig")],
        &mut common::paper_controller(),
        &mut reference,
        duration_s,
        &stop,
        &mut clock,
    );
    (res, connected)
}

#[test]
fn a_run_writes_trace_with_provenance_end_marker_and_manifest() {
    let d = scratch("ok");
    let d = d.path().to_path_buf();
    let out = d.join("D");
    let (res, _) = record_into(&out, 0.5, None, false);
    let rec = res.unwrap();
    assert_eq!(rec.dir, out);
    assert!(!rec.partial);
    let text = std::fs::read_to_string(out.join("trace.csv")).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        format!("# pneuflex {}, trace schema 2", env!("CARGO_PKG_VERSION"))
    );
    let input = lines.next().unwrap();
    let sha = pneuflex_files::InputDigest::of_file(&common::rig_path(), "rig")
        .unwrap()
        .sha256;
    assert!(
        input.starts_with("# input rig ")
            && input.ends_with(&format!("emulated.toml sha256 {sha}")),
        "{input}"
    );
    assert_eq!(lines.next(), Some(trace::header_for(&[]).as_str()));
    let (rows, end) = trace::data_lines(&text);
    assert_eq!(rows.len(), 500);
    assert_eq!(end, Some("complete, 500 rows"));
    let m = read_manifest(&out).unwrap();
    assert_eq!((m.command.as_str(), m.complete), ("rig run", true));
    assert_eq!(m.files, vec!["trace.csv".to_string()]);
    assert_eq!(m.inputs[0].sha256, sha);
}

#[test]
fn a_failed_connect_never_touches_an_existing_trace() {
    let d = scratch("connect");
    let d = d.path().to_path_buf();
    let out = d.join("D");
    record_into(&out, 0.2, None, false).0.unwrap();
    let before = std::fs::read(out.join("trace.csv")).unwrap();
    assert!(!before.is_empty());
    // A recording is never replaced: a second one into the same directory is refused before connecting.
    let (res, connected) = record_into(&out, 0.2, None, false);
    let e = res.unwrap_err();
    assert!(!connected, "refused before the rig is touched");
    assert!(e.to_string().contains("rig recording"), "{e}");
    assert_eq!(std::fs::read(out.join("trace.csv")).unwrap(), before);
    // A failed connect into a new directory writes nothing.
    let (res, connected) = record_into(&d.join("E"), 0.2, None, true);
    let e = res.unwrap_err();
    assert!(connected);
    assert!(matches!(e, RecordError::Connect(_)), "{e}");
    assert!(e.to_string().contains("/dev/nope"), "{e}");
    assert_eq!(std::fs::read(out.join("trace.csv")).unwrap(), before);
    // Nothing staged or left beside it.
    let names: Vec<String> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, vec!["D".to_string()]);
}

#[test]
fn a_directory_with_user_files_is_refused_before_connecting() {
    let d = scratch("foreign");
    let d = d.path().to_path_buf();
    let out = d.join("D");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("trace.csv"), "my own data\n").unwrap();
    let (res, connected) = record_into(&out, 0.2, None, false);
    let e = res.unwrap_err();
    assert!(!connected, "refused before the rig is touched");
    assert!(e.to_string().contains("trace.csv"), "{e}");
    assert_eq!(
        std::fs::read_to_string(out.join("trace.csv")).unwrap(),
        "my own data\n"
    );
}

#[test]
fn a_signal_commits_a_marked_partial_and_leaves_an_earlier_recording_untouched() {
    let d = scratch("signal");
    let d = d.path().to_path_buf();
    let out = d.join("D");
    record_into(&out, 0.2, None, false).0.unwrap();
    let before = std::fs::read(out.join("trace.csv")).unwrap();
    let (res, _) = record_into(&d.join("E"), 1.0, Some(0.3), false);
    let rec = res.unwrap();
    assert!(rec.partial);
    assert_eq!(rec.dir, d.join("E.partial"));
    assert_eq!(std::fs::read(out.join("trace.csv")).unwrap(), before);
    let text = std::fs::read_to_string(rec.dir.join("trace.csv")).unwrap();
    let (rows, end) = trace::data_lines(&text);
    // Fault at tick 301 (the flag is seen at the start of the next tick), then post_fault_s = 0.2 s.
    assert_eq!(rows.len(), 301 + 200 + 1);
    assert!(
        rows[301].ends_with(",interrupted: stopped by a signal (SIGINT/Ctrl-C; SIGTERM or SIGHUP)")
    );
    assert_eq!(end, Some("interrupted, 502 rows"));
    let m = read_manifest(&rec.dir).unwrap();
    assert!(!m.complete);
    let p = m.partial.unwrap();
    assert!(p.reason.contains("SIGTERM"), "{}", p.reason);
    assert!((p.time_reached_s - 0.502).abs() < 1e-9);
}

#[test]
fn a_bad_duration_is_refused_before_connecting() {
    let d = scratch("duration");
    let d = d.path().to_path_buf();
    for dur in [f64::NAN, -1.0, 0.0, 1e10] {
        let (res, connected) = record_into(&d.join("D"), dur, None, false);
        let e = res.unwrap_err();
        assert!(!connected);
        assert!(
            matches!(e, RecordError::Duration(_)) && e.to_string().contains("--duration"),
            "{e}"
        );
    }
    assert_eq!(std::fs::read_dir(&d).unwrap().count(), 0, "nothing created");
}
