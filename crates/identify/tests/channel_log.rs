//! One actuator of a recording of several (`identify --channel NAME`, docs/identification.md "Several
//! actuators"): the log is `t` and that actuator's `NAME.u`, `NAME.x`, `NAME.p_a`, `NAME.p_b`, `NAME.f_e`;
//! without the option such a recording is refused naming its actuators; a tick that read no new sample
//! (`board_t` repeated) is not compared; errors name the file, the line and the column.

use std::path::Path;

use pneuflex_identify::IdentifyError;
use pneuflex_identify::log::{Log, LogLimits, parse_log, parse_log_formatted};
use pneuflex_identify::log_format::LogFormat;

const ROWS: usize = 30;

/// Actuator `a`'s (0: left, 1: right) signals at row k, SI: u, x, p_a, p_b, f_e.
fn signals(a: usize, k: usize) -> [f64; 5] {
    let k = k as f64;
    let s = 1.0 + a as f64;
    [
        0.01 * s * (0.3 * k).sin(),
        0.02 + 1e-4 * s * k,
        2e5 + 1e3 * s * k,
        3e5 - 5e2 * s * k,
        s * 0.5 * k,
    ]
}

/// A scene's recording as `rig run` writes it: per actuator f_ref, f_e, x, x_r, p_a, p_b, u, then board_t
/// (`board_t(k)`).
fn recording(board_t: impl Fn(usize) -> f64) -> String {
    let mut s = String::new();
    for a in ["left", "right"] {
        for c in ["f_ref", "f_e", "x", "x_r", "p_a", "p_b", "u"] {
            s += &format!("{a}.{c},");
        }
    }
    s = format!("t,{s}board_t\n");
    for k in 0..ROWS {
        s += &format!("{:?}", 0.001 * k as f64);
        for a in 0..2 {
            let [u, x, p_a, p_b, f_e] = signals(a, k);
            s += &format!(",10,{f_e:?},{x:?},0.03,{p_a:?},{p_b:?},{u:?}");
        }
        s += &format!(",{:?}\n", board_t(k));
    }
    s
}

fn read(text: &str, channel: Option<&str>) -> Result<Log, IdentifyError> {
    let format = match channel {
        Some(c) => LogFormat::channel(c).unwrap(),
        None => LogFormat::default(),
    };
    parse_log_formatted(
        Path::new("rec/trace.csv"),
        text,
        String::new(),
        &LogLimits::default(),
        &format,
    )
}

fn period(k: usize) -> f64 {
    0.001 * (k + 1) as f64
}

#[test]
fn each_actuator_reads_as_its_own_log() {
    let text = recording(period);
    for (a, name) in ["left", "right"].into_iter().enumerate() {
        let log = read(&text, Some(name)).unwrap();
        assert_eq!(log.len(), ROWS);
        for k in 0..ROWS {
            let [u, x, p_a, p_b, f_e] = signals(a, k);
            assert_eq!(log.t[k], 0.001 * k as f64);
            assert_eq!(
                [log.u[k], log.x[k], log.p_a[k], log.p_b[k], log.f_e[k]],
                [u, x, p_a, p_b, f_e],
                "{name} row {k}"
            );
        }
        assert!(log.measured.iter().all(|&m| m));
        let note = log.note.unwrap();
        assert!(
            note.contains(&format!("actuator `{name}`")) && note.contains("0 row(s)"),
            "{note}"
        );
    }
}

#[test]
fn a_recording_of_several_actuators_needs_the_channel_and_one_it_has() {
    let text = recording(period);
    let msg = |e: IdentifyError| e.to_string();
    let e = msg(parse_log(Path::new("rec/trace.csv"), &text, String::new()).unwrap_err());
    assert!(
        e.starts_with("rec/trace.csv:1:")
            && e.contains("several actuators (left, right)")
            && e.contains("--channel NAME"),
        "{e}"
    );
    let e = msg(read(&text, Some("middle")).unwrap_err());
    assert!(
        e.starts_with("rec/trace.csv:1:")
            && e.contains("no actuator `middle` in this recording; it has left, right"),
        "{e}"
    );
    // A one-actuator trace has no actuator's columns.
    let one = "t,u,x,p_a,p_b,f_e\n".to_string()
        + &(0..ROWS)
            .map(|k| format!("{},0,0.01,2e5,3e5,1\n", 0.001 * k as f64))
            .collect::<String>();
    let e = msg(read(&one, Some("left")).unwrap_err());
    assert!(
        e.contains("no actuator's columns") && e.contains("without --channel"),
        "{e}"
    );
    // A name that cannot be a column's prefix.
    for bad in ["", "left.u", "a,b", " left"] {
        assert!(LogFormat::channel(bad).is_err(), "{bad:?}");
    }
}

#[test]
fn a_tick_that_read_no_new_sample_is_not_compared_and_its_force_is_interpolated() {
    // Row 10's tick held row 9's sample (the board's time repeated).
    let text = recording(|k| period(if k == 10 { 9 } else { k }));
    let log = read(&text, Some("right")).unwrap();
    let unmeasured: Vec<usize> = (0..ROWS).filter(|&k| !log.measured[k]).collect();
    assert_eq!(unmeasured, vec![10]);
    // The contact force, an input of the replay, is the line between rows 9 and 11.
    let f = |k| signals(1, k)[4];
    assert!((log.f_e[10] - 0.5 * (f(9) + f(11))).abs() < 1e-12);
    assert!(log.note.unwrap().contains("1 row(s)"));
}

#[test]
fn bad_board_times_are_refused_at_their_line_and_column() {
    // Data row k is on line k + 2.
    let back = recording(|k| if k == 7 { 0.0 } else { period(k) });
    let e = read(&back, Some("left")).unwrap_err().to_string();
    assert!(
        e.starts_with("rec/trace.csv:9:")
            && e.contains("board_t")
            && e.contains("must not go back"),
        "{e}"
    );
    let nan = recording(|k| if k == 4 { f64::NAN } else { period(k) });
    let e = read(&nan, Some("left")).unwrap_err().to_string();
    assert!(
        e.starts_with("rec/trace.csv:6:") && e.contains("board_t") && e.contains("NaN"),
        "{e}"
    );
}
