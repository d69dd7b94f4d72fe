//! A run's trace as a rosbag2 recording, and back (docs/ros2.md has the table): one message per topic per
//! control tick, stamped with the trace's clock (`t`, the simulation's or the board's):
//!
//! | topic | type | from the trace |
//! |---|---|---|
//! | `/pneuflex/joint_states` | `sensor_msgs/msg/JointState` | per actuator: `x` (position), `x_dot` (velocity, when every actuator has it), `f_e` (effort) |
//! | `/pneuflex/pressures/<actuator>/a`, `/b` | `sensor_msgs/msg/FluidPressure` | `p_a`, `p_b` (Pa absolute) |
//! | `/pneuflex/valve_command` | `std_msgs/msg/Float64MultiArray` | `u`, one per actuator |
//! | `/pneuflex/force_reference` | `std_msgs/msg/Float64MultiArray` | `f_ref`, one per actuator |
//! | `/pneuflex/controller/<signal>` | `std_msgs/msg/Float64MultiArray` | every other signal (`x_r`, the controller's own, the plant's), one per actuator |
//!
//! A one-actuator trace has bare column names and its joint is `cylinder`; a trace of several has
//! `<actuator>.<signal>` columns and each joint is the actuator's name.
//!
//! A rig's trace with the board's record (`board_t` ... `applied_u`, docs/rig.md "Trace") is written on the
//! board's clock: the joint states and pressures are the board's samples at their `board_t` (`board_x`,
//! `board_f_e`, `board_p_a`, `board_p_b`), and `/pneuflex/valve_applied` holds each command the board
//! applied (`applied_u`) at its `applied_t`; the loop's own signals (valve command, force reference, the
//! others) stay at the loop's tick times `t`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::Ros2Error;
use crate::bag::{BagSummary, BagWriter, read_bag, topic_token};
use crate::msg::{
    Float64MultiArray, FluidPressure, Header, JointState, Message, Time, nanos_of_seconds,
};

/// The joint of a one-actuator trace.
pub const SINGLE_JOINT: &str = "cylinder";
/// The joint states' topic.
pub const JOINT_STATES: &str = "/pneuflex/joint_states";
/// The valve command's topic.
pub const VALVE_COMMAND: &str = "/pneuflex/valve_command";
/// The force reference's topic.
pub const FORCE_REFERENCE: &str = "/pneuflex/force_reference";
/// The valve commands the board applied, at the board's time (a rig's trace).
pub const VALVE_APPLIED: &str = "/pneuflex/valve_applied";

/// The board's record in a rig's trace: a sample (time, x, f_e, p_a, p_b) and an applied echo (time, duty)
/// per row, empty cells NaN.
const BOARD: [&str; 7] = [
    "board_t",
    "board_x",
    "board_f_e",
    "board_p_a",
    "board_p_b",
    "applied_t",
    "applied_u",
];

/// The signals with a topic of their own; the others go to `/pneuflex/controller/<signal>`.
const MAPPED: [&str; 7] = ["x", "x_dot", "f_e", "p_a", "p_b", "u", "f_ref"];

/// A chamber's pressure topic.
pub fn pressure_topic(actuator: &str, chamber: char) -> String {
    format!("/pneuflex/pressures/{}/{chamber}", topic_token(actuator))
}

/// A trace's columns by name (`t` first among them), and the actuators of a trace of several (empty: one
/// actuator, bare names).
#[derive(Clone, Debug, Default)]
pub struct TraceColumns<'a> {
    /// Name and values of each column, in the trace's order.
    pub columns: Vec<(&'a str, &'a [f64])>,
    /// The actuators' names, as the `<actuator>.` of their columns.
    pub actuators: Vec<String>,
}

impl<'a> TraceColumns<'a> {
    fn column(&self, name: &str) -> Option<&'a [f64]> {
        self.columns
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, v)| *v)
    }

    /// The joints' names and each one's column prefix.
    fn joints(&self) -> Vec<(String, String)> {
        if self.actuators.is_empty() {
            vec![(SINGLE_JOINT.into(), String::new())]
        } else {
            self.actuators
                .iter()
                .map(|a| (a.clone(), format!("{a}.")))
                .collect()
        }
    }
}

/// Writes `trace` as a rosbag2 folder `dir` (which must not exist).
pub fn write_trace_bag(dir: &Path, trace: &TraceColumns<'_>) -> Result<BagSummary, Ros2Error> {
    let missing = |what: String| Ros2Error::Bag {
        path: dir.to_path_buf(),
        message: format!("the trace has no column `{what}`"),
    };
    let t = trace.column("t").ok_or_else(|| missing("t".into()))?;
    let joints = trace.joints();
    let need = |prefix: &str, s: &str| {
        trace
            .column(&format!("{prefix}{s}"))
            .ok_or_else(|| missing(format!("{prefix}{s}")))
    };
    struct Joint<'a> {
        x: &'a [f64],
        x_dot: Option<&'a [f64]>,
        f_e: &'a [f64],
        u: &'a [f64],
        f_ref: &'a [f64],
        p: Option<(&'a [f64], &'a [f64])>,
    }
    let cols: Vec<Joint<'_>> = joints
        .iter()
        .map(|(_, p)| {
            // A column of no values (the ideal plant's pressures) is none.
            let opt = |s: &str| {
                trace
                    .column(&format!("{p}{s}"))
                    .filter(|v| v.iter().any(|x| !x.is_nan()))
            };
            Ok(Joint {
                x: need(p, "x")?,
                x_dot: opt("x_dot"),
                f_e: need(p, "f_e")?,
                u: need(p, "u")?,
                f_ref: need(p, "f_ref")?,
                p: opt("p_a").zip(opt("p_b")),
            })
        })
        .collect::<Result<_, Ros2Error>>()?;
    // The other signals: name -> one column per joint (None where a joint lacks it, written as NaN).
    let mut signals: Vec<(String, Vec<Option<&[f64]>>)> = Vec::new();
    for (name, values) in &trace.columns {
        if *name == "t" {
            continue;
        }
        let (joint, signal) = match joints
            .iter()
            .position(|(_, p)| !p.is_empty() && name.starts_with(p.as_str()))
        {
            Some(j) => (Some(j), &name[joints[j].1.len()..]),
            None if trace.actuators.is_empty() => (Some(0), *name),
            None => (None, *name),
        };
        if joint.is_some() && MAPPED.contains(&signal) {
            continue;
        }
        let i = match signals.iter().position(|(s, _)| s == signal) {
            Some(i) => i,
            None => {
                signals.push((signal.to_string(), vec![None; joints.len().max(1)]));
                signals.len() - 1
            }
        };
        signals[i].1[joint.unwrap_or(0)] = Some(values);
    }

    let board: Option<Vec<&[f64]>> = (trace.actuators.is_empty())
        .then(|| {
            BOARD
                .iter()
                .map(|c| trace.column(c))
                .collect::<Option<Vec<_>>>()
        })
        .flatten();
    if board.is_some() {
        signals.retain(|(s, _)| !BOARD.contains(&s.as_str()));
    }

    let mut bag = BagWriter::create(dir)?;
    let joint_states = bag.topic::<JointState>(JOINT_STATES)?;
    let pressures = joints
        .iter()
        .zip(&cols)
        .filter(|(_, c)| c.p.is_some() || board.is_some())
        .map(|((name, _), _)| {
            Ok((
                bag.topic::<FluidPressure>(&pressure_topic(name, 'a'))?,
                bag.topic::<FluidPressure>(&pressure_topic(name, 'b'))?,
            ))
        })
        .collect::<Result<Vec<_>, Ros2Error>>()?;
    let valve = bag.topic::<Float64MultiArray>(VALVE_COMMAND)?;
    let applied = match board {
        Some(_) => Some(bag.topic::<Float64MultiArray>(VALVE_APPLIED)?),
        None => None,
    };
    let force_ref = bag.topic::<Float64MultiArray>(FORCE_REFERENCE)?;
    let signal_topics = signals
        .iter()
        .map(|(s, _)| {
            bag.topic::<Float64MultiArray>(&format!("/pneuflex/controller/{}", topic_token(s)))
        })
        .collect::<Result<Vec<_>, Ros2Error>>()?;
    let names: Vec<String> = joints.iter().map(|(n, _)| n.clone()).collect();
    let with_velocity = cols.iter().all(|c| c.x_dot.is_some());

    // What is written, in time order: (ns, what, row). The board's record lags the loop's rows.
    #[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
    enum Item {
        Sample,
        Applied,
        Tick,
    }
    let mut items: Vec<(u64, Item, usize)> = Vec::with_capacity(t.len() * 3);
    for (k, &tk) in t.iter().enumerate() {
        items.push((nanos_of_seconds(tk)?, Item::Tick, k));
        if let Some(b) = &board {
            if b[0][k].is_finite() {
                items.push((nanos_of_seconds(b[0][k])?, Item::Sample, k));
            }
            if b[5][k].is_finite() {
                items.push((nanos_of_seconds(b[5][k])?, Item::Applied, k));
            }
        }
    }
    if board.is_some() {
        items.sort();
    }
    let header = |ns: u64| -> Result<Header, Ros2Error> {
        Ok(Header {
            stamp: Time::from_nanos(ns)?,
            frame_id: String::new(),
        })
    };
    for (ns, item, k) in items {
        // The sample of the state and pressures: the loop's row, or the board's record.
        let sample = match (item, &board) {
            (Item::Tick, None) => Some(
                cols.iter()
                    .map(|c| {
                        (
                            c.x[k],
                            c.x_dot.map(|v| v[k]),
                            c.f_e[k],
                            c.p.map(|(a, b)| (a[k], b[k])),
                        )
                    })
                    .collect::<Vec<_>>(),
            ),
            (Item::Sample, Some(b)) => {
                Some(vec![(b[1][k], None, b[2][k], Some((b[3][k], b[4][k])))])
            }
            _ => None,
        };
        if let Some(sample) = sample {
            let state = JointState {
                header: header(ns)?,
                name: names.clone(),
                position: sample.iter().map(|s| s.0).collect(),
                velocity: if with_velocity && board.is_none() {
                    sample.iter().map(|s| s.1.unwrap_or(f64::NAN)).collect()
                } else {
                    Vec::new()
                },
                effort: sample.iter().map(|s| s.2).collect(),
            };
            bag.write(joint_states, ns, &state)?;
            for ((a, b), (pa, pb)) in pressures.iter().zip(sample.iter().filter_map(|s| s.3)) {
                for (topic, p) in [(*a, pa), (*b, pb)] {
                    let msg = FluidPressure {
                        header: header(ns)?,
                        fluid_pressure: p,
                        variance: 0.0,
                    };
                    bag.write(topic, ns, &msg)?;
                }
            }
        }
        if let (Item::Applied, Some(b), Some(topic)) = (item, &board, applied) {
            bag.write(topic, ns, &Float64MultiArray::per_actuator(vec![b[6][k]]))?;
        }
        if item != Item::Tick {
            continue;
        }
        let per = |f: &dyn Fn(&Joint<'_>) -> f64| {
            Float64MultiArray::per_actuator(cols.iter().map(f).collect())
        };
        bag.write(valve, ns, &per(&|c| c.u[k]))?;
        bag.write(force_ref, ns, &per(&|c| c.f_ref[k]))?;
        for (topic, (_, values)) in signal_topics.iter().zip(&signals) {
            let data = values
                .iter()
                .map(|v| v.map_or(f64::NAN, |v| v[k]))
                .collect();
            bag.write(*topic, ns, &Float64MultiArray::per_actuator(data))?;
        }
    }
    bag.finish()
}

/// What identification reads of one actuator from a bag: the columns of a trace (docs/identification.md).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ActuatorLog {
    /// The bag.
    pub path: PathBuf,
    /// The joint read.
    pub joint: String,
    /// Time, s (the joint states' stamps).
    pub t: Vec<f64>,
    /// Valve command.
    pub u: Vec<f64>,
    /// Position, m.
    pub x: Vec<f64>,
    /// Chamber pressures, Pa absolute.
    pub p_a: Vec<f64>,
    /// Chamber pressures, Pa absolute.
    pub p_b: Vec<f64>,
    /// Contact force, N.
    pub f_e: Vec<f64>,
    /// A rig's bag: the commands the board applied, (board time s, duty), from `/pneuflex/valve_applied`;
    /// the rows are then the board's samples and `u` is empty (the valve's command is these).
    pub applied: Option<Vec<(f64, f64)>>,
}

/// Reads actuator `joint` (None: the bag's only joint) of a bag written as [`write_trace_bag`] writes
/// it: a row per joint state, the valve command and the pressures of the same time stamp.
pub fn read_actuator_log(path: &Path, joint: Option<&str>) -> Result<ActuatorLog, Ros2Error> {
    let bag = read_bag(path)?;
    let err = |message: String| Ros2Error::Bag {
        path: path.to_path_buf(),
        message,
    };
    let states = bag.messages::<JointState>(JOINT_STATES)?;
    let first = JointState::decode(
        &states
            .first()
            .ok_or_else(|| err(format!("no message on {JOINT_STATES}")))?
            .data,
    )?;
    let index = match joint {
        Some(j) => first.name.iter().position(|n| n == j),
        None if first.name.len() == 1 => Some(0),
        None => None,
    }
    .ok_or_else(|| {
        err(format!(
            "{JOINT_STATES} has the joints {}: {}",
            first.name.join(", "),
            match joint {
                Some(j) => format!("no `{j}`"),
                None => "say which one".into(),
            }
        ))
    })?;
    let name = first.name[index].clone();
    // Each other topic by its time stamp (log time), ns.
    let by_time = |topic: &str, value: &dyn Fn(&[u8]) -> Result<f64, Ros2Error>| {
        bag.topics
            .get(topic)
            .ok_or_else(|| err(format!("no topic `{topic}`")))?
            .1
            .iter()
            .map(|m| Ok((m.t_ns, value(&m.data)?)))
            .collect::<Result<BTreeMap<u64, f64>, Ros2Error>>()
    };
    let entry = |topic: &str| {
        let topic = topic.to_string();
        move |d: &[u8]| {
            Float64MultiArray::decode(d)?
                .data
                .get(index)
                .copied()
                .ok_or_else(|| Ros2Error::Cdr(format!("{topic}: fewer values than joints")))
        }
    };
    // A rig's bag: the board's applied commands; otherwise the loop's command of each tick.
    let applied = match bag.topics.contains_key(VALVE_APPLIED) {
        true => Some(
            bag.messages::<Float64MultiArray>(VALVE_APPLIED)?
                .iter()
                .map(|m| Ok((seconds(m.t_ns), entry(VALVE_APPLIED)(&m.data)?)))
                .collect::<Result<Vec<_>, Ros2Error>>()?,
        ),
        false => None,
    };
    let u = match applied {
        Some(_) => BTreeMap::new(),
        None => {
            bag.messages::<Float64MultiArray>(VALVE_COMMAND)?;
            by_time(VALVE_COMMAND, &entry(VALVE_COMMAND))?
        }
    };
    let pressure = |chamber| {
        let topic = pressure_topic(&name, chamber);
        bag.messages::<FluidPressure>(&topic)?;
        by_time(&topic, &|d: &[u8]| {
            Ok(FluidPressure::decode(d)?.fluid_pressure)
        })
    };
    let (p_a, p_b) = (pressure('a')?, pressure('b')?);
    let mut log = ActuatorLog {
        path: path.to_path_buf(),
        joint: name.clone(),
        applied: applied.clone(),
        ..ActuatorLog::default()
    };
    for m in states {
        let s = JointState::decode(&m.data)?;
        if s.name != first.name {
            return Err(err(format!(
                "{JOINT_STATES} at {} ns: joints {} where the first message has {}",
                m.t_ns,
                s.name.join(", "),
                first.name.join(", ")
            )));
        }
        let ns = s.header.stamp.nanos()?;
        let at = |what: &str, map: &BTreeMap<u64, f64>| {
            map.get(&ns).copied().ok_or_else(|| {
                err(format!(
                    "no {what} message at t = {} s, the stamp of a joint state",
                    ns as f64 * 1e-9
                ))
            })
        };
        log.t.push(seconds(ns));
        if applied.is_none() {
            log.u.push(at(VALVE_COMMAND, &u)?);
        }
        log.p_a.push(at(&pressure_topic(&name, 'a'), &p_a)?);
        log.p_b.push(at(&pressure_topic(&name, 'b'), &p_b)?);
        log.x.push(
            *s.position
                .get(index)
                .ok_or_else(|| err(format!("{JOINT_STATES}: no position")))?,
        );
        log.f_e.push(
            *s.effort
                .get(index)
                .ok_or_else(|| err(format!("{JOINT_STATES}: no effort")))?,
        );
    }
    Ok(log)
}

/// Nanoseconds as seconds, correctly rounded (a time written as `0.001000` reads back as `0.001` does).
fn seconds(ns: u64) -> f64 {
    ns as f64 / 1e9
}
