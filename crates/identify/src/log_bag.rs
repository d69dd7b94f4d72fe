//! A rosbag2 recording as a log (`identify --log BAG`, docs/ros2.md): the folder (or its `.mcap` file) that
//! `run --mcap` and `rig excite --mcap` write, read through crates/ros2 with its topics mapped as a trace's
//! columns are: `t` the joint states' stamps, `x` and `f_e` the joint's position and effort, `p_a` and `p_b`
//! its `/pneuflex/pressures/<joint>/{a,b}`, `u` `/pneuflex/valve_command` at the same stamp. A rig's bag
//! (the board's samples, `/pneuflex/valve_applied` with the commands the board applied) is laid on the
//! board's sample grid as its trace.csv is (crate::board_time), so the two give the same log.

use std::path::Path;

use crate::IdentifyError;
use crate::board_time::{BoardColumns, RecordedSample, on_board_grid};
use crate::log::{LogLimits, parse_log_limited};
use crate::log_rows::Log;

/// Any log `identify --log` takes: a rosbag2 recording (`--mcap`: its topics are the columns) or a text log
/// in `format`.
pub fn read_any_log(
    path: &Path,
    limits: &LogLimits,
    format: &crate::log_format::LogFormat,
) -> Result<Log, IdentifyError> {
    if !is_bag(path) {
        return crate::log::read_log_formatted(path, limits, format);
    }
    if !format.own_trace {
        return Err(IdentifyError::Input(format!(
            "{}: a bag's topics are read as docs/ros2.md maps them; --log-format is for text logs",
            path.display()
        )));
    }
    if let Some(name) = &format.channel {
        return Err(IdentifyError::Input(format!(
            "{}: --channel {name} picks an actuator's columns of a recording's trace.csv; a bag of several \
             joints is not read by identify (give the recording's trace.csv)",
            path.display()
        )));
    }
    read_bag_log(path, limits)
}

/// Whether `path` is a bag: a folder, or an `.mcap` file.
pub fn is_bag(path: &Path) -> bool {
    path.is_dir() || path.extension().is_some_and(|e| e == "mcap")
}

/// Reads the bag at `path` as a log (its only joint), checked as a trace is: `limits`, increasing time,
/// finite plausible values, no gap; an error names the joint state (1-based) it is about.
pub fn read_bag_log(path: &Path, limits: &LogLimits) -> Result<Log, IdentifyError> {
    let input = |e: pneuflex_ros2::Ros2Error| IdentifyError::Input(e.to_string());
    let bag = pneuflex_ros2::read_actuator_log(path, None).map_err(input)?;
    let mut hasher = pneuflex_files::provenance::Sha256Hasher::new();
    for f in pneuflex_ros2::bag::bag_files(path).map_err(input)? {
        let bytes = std::fs::read(&f)
            .map_err(|e| IdentifyError::Input(format!("{}: cannot read: {e}", f.display())))?;
        hasher.update(&bytes);
    }
    let sha256 = hasher.finish();
    let n = bag.t.len();
    if n > limits.max_rows {
        return Err(IdentifyError::Input(format!(
            "{}: {n} joint states: more than {} rows; cut the bag, or raise --max-rows",
            path.display(),
            limits.max_rows
        )));
    }
    // A message's place in place of a line.
    let at_message = |e: IdentifyError| match e {
        IdentifyError::Log {
            file,
            line,
            column,
            message,
        } => IdentifyError::Log {
            file,
            line: None,
            column,
            message: match line {
                Some(l) => format!("joint state {l}: {message}"),
                None => message,
            },
        },
        other => other,
    };
    let Some(applied) = bag.applied else {
        // One row a tick: the same checks as a trace's rows, on the same numbers (shortest round trip).
        let mut text = String::with_capacity(n * 100);
        text.push_str("t,u,x,p_a,p_b,f_e\n");
        for k in 0..n {
            text.push_str(&format!(
                "{},{},{},{},{},{}\n",
                bag.t[k], bag.u[k], bag.x[k], bag.p_a[k], bag.p_b[k], bag.f_e[k]
            ));
        }
        text.push_str("# end: the bag's last joint state\n");
        // Line k + 2 of the text is joint state k + 1.
        return parse_log_limited(path, &text, sha256, limits).map_err(|e| match e {
            IdentifyError::Log {
                line: Some(l),
                file,
                column,
                message,
            } => at_message(IdentifyError::Log {
                file,
                line: Some(l - 1),
                column,
                message,
            }),
            other => at_message(other),
        });
    };
    let span = bag.t.last().zip(bag.t.first()).map_or(0.0, |(b, a)| b - a);
    if span > limits.max_span_s {
        return Err(IdentifyError::Input(format!(
            "{}: the joint states span {span} s, more than {} s; cut the bag, or raise --max-log-s",
            path.display(),
            limits.max_span_s
        )));
    }
    let board = BoardColumns {
        samples: (0..n)
            .map(|k| RecordedSample {
                t: bag.t[k],
                x: bag.x[k],
                f_e: bag.f_e[k],
                p_a: bag.p_a[k],
                p_b: bag.p_b[k],
                line: k + 1,
            })
            .collect(),
        applied,
    };
    let host = Log {
        path: path.to_path_buf(),
        sha256,
        t: Vec::new(),
        u: Vec::new(),
        x: Vec::new(),
        p_a: Vec::new(),
        p_b: Vec::new(),
        f_e: Vec::new(),
        measured: Vec::new(),
        note: None,
    };
    match on_board_grid(&host, &board).map_err(at_message)? {
        Some((grid, _)) => Ok(grid),
        None => Err(IdentifyError::Input(format!(
            "{}: /pneuflex/valve_applied holds no command the board applied: nothing to replay",
            path.display()
        ))),
    }
}
