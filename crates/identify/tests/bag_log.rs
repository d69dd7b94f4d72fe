//! A rosbag2 recording as a log (`identify --log BAG`, docs/ros2.md): the trace's values, row for row, and a
//! bad value refused naming the joint state it is in.

use pneuflex_identify::IdentifyError;
use pneuflex_identify::log::LogLimits;
use pneuflex_identify::log_bag::read_bag_log;

fn read_log(
    p: &std::path::Path,
) -> Result<pneuflex_identify::log_rows::Log, pneuflex_identify::IdentifyError> {
    read_bag_log(p, &LogLimits::default())
}
use pneuflex_ros2::{TraceColumns, write_trace_bag};

/// 40 ticks of 1 ms of a plausible cylinder; `x[bad]` set to `bad_x` when given.
fn bag(dir: &std::path::Path, bad: Option<(usize, f64)>) -> std::path::PathBuf {
    let n = 40;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
    let u: Vec<f64> = (0..n).map(|k| 0.01 * (k % 7) as f64).collect();
    let mut x: Vec<f64> = (0..n).map(|k| 0.02 + 1e-5 * k as f64).collect();
    if let Some((k, v)) = bad {
        x[k] = v;
    }
    let p_a: Vec<f64> = (0..n).map(|k| 3e5 + 100.0 * k as f64).collect();
    let p_b: Vec<f64> = (0..n).map(|k| 4e5 - 50.0 * k as f64).collect();
    let f_e: Vec<f64> = (0..n).map(|k| 0.1 * k as f64).collect();
    let path = dir.join("bag");
    let table = TraceColumns {
        columns: vec![
            ("t", &t[..]),
            ("f_ref", &f_e),
            ("f_e", &f_e),
            ("x", &x),
            ("p_a", &p_a),
            ("p_b", &p_b),
            ("u", &u),
        ],
        actuators: vec![],
    };
    write_trace_bag(&path, &table).unwrap();
    path
}

#[test]
fn a_bag_is_read_as_the_trace_it_was_written_from() {
    let dir = tempfile::tempdir().unwrap();
    let log = read_log(&bag(dir.path(), None)).unwrap();
    assert_eq!(log.len(), 40);
    assert_eq!(log.x[17], 0.02 + 1e-5 * 17.0);
    assert_eq!(log.u[5], 0.05);
    assert_eq!(log.p_b[39], 4e5 - 50.0 * 39.0);
    assert_eq!(log.f_e[3], 0.1 * 3.0);
    assert!((log.t[9] - 0.009).abs() <= 0.5e-9);
    assert!(log.note.is_none(), "{:?}", log.note);
    assert_eq!(log.sha256.len(), 64);
}

#[test]
fn a_bad_value_is_refused_naming_the_joint_state() {
    let dir = tempfile::tempdir().unwrap();
    let e = read_log(&bag(dir.path(), Some((12, 50.0)))).unwrap_err();
    let IdentifyError::Log {
        line,
        column,
        message,
        ..
    } = &e
    else {
        panic!("{e}");
    };
    assert_eq!(*line, None);
    assert_eq!(column.as_deref(), Some("x"));
    assert!(
        message.starts_with("joint state 13: 50: outside"),
        "{message}"
    );
}
