//! The standard messages a recording uses, with their `ros2msg` definitions as rosbag2 stores them in a
//! bag's schema: the type's own `.msg` text, then each type it uses after a line of 80 `=` and
//! `MSG: pkg/Type` (the definitions are those of ROS 2's common_interfaces and rcl_interfaces, Humble to
//! Jazzy, comments left out).
//!
//! Each type is also `serde`'s, field for field in the order of its definition, so a DDS library's CDR
//! serialiser (the node's, [`crate::node`]) writes the same bytes as [`Message::encode`] (a test checks it).

use serde::{Deserialize, Serialize};

use crate::Ros2Error;
use crate::cdr::{CdrReader, CdrWriter};

/// The line between a definition and the next type it uses.
const SEPARATOR: &str =
    "================================================================================";

const TIME_MSG: &str = "int32 sec\nuint32 nanosec\n";
const HEADER_MSG: &str = "builtin_interfaces/Time stamp\nstring frame_id\n";
const JOINT_STATE_MSG: &str = "std_msgs/Header header\n\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n";
const FLUID_PRESSURE_MSG: &str =
    "std_msgs/Header header\n\nfloat64 fluid_pressure\nfloat64 variance\n";
const FLOAT64_MULTI_ARRAY_MSG: &str = "std_msgs/MultiArrayLayout layout\nfloat64[] data\n";
const LAYOUT_MSG: &str = "std_msgs/MultiArrayDimension[] dim\nuint32 data_offset\n";
const DIMENSION_MSG: &str = "string label\nuint32 size\nuint32 stride\n";
const CLOCK_MSG: &str = "builtin_interfaces/Time clock\n";

/// A type's full definition: its text, then each dependency's after the separator.
fn definition(own: &str, uses: &[(&str, &str)]) -> String {
    let mut text = own.to_string();
    for (name, msg) in uses {
        text.push_str(&format!("\n{SEPARATOR}\nMSG: {name}\n{msg}"));
    }
    text
}

/// A message type a bag can hold.
pub trait Message: Sized {
    /// Its ROS 2 name, `pkg/msg/Type`.
    const TYPE: &'static str;
    /// Its `ros2msg` definition with its dependencies.
    fn definition() -> String;
    /// Its CDR bytes, encapsulation header first.
    fn encode(&self) -> Vec<u8>;
    /// Reads it from CDR bytes.
    fn decode(data: &[u8]) -> Result<Self, Ros2Error>;
}

/// `builtin_interfaces/msg/Time`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Time {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds within the second, [0, 1e9).
    pub nanosec: u32,
}

impl Time {
    /// A clock reading in nanoseconds.
    pub fn from_nanos(ns: u64) -> Result<Self, Ros2Error> {
        let sec = i32::try_from(ns / 1_000_000_000).map_err(|_| {
            Ros2Error::Time(format!(
                "{ns} ns: beyond builtin_interfaces/Time's int32 seconds"
            ))
        })?;
        Ok(Self {
            sec,
            nanosec: (ns % 1_000_000_000) as u32,
        })
    }

    /// The reading in nanoseconds (a negative time is refused).
    pub fn nanos(&self) -> Result<u64, Ros2Error> {
        if self.sec < 0 || self.nanosec >= 1_000_000_000 {
            return Err(Ros2Error::Time(format!(
                "stamp {} s {} ns: not a time since the clock's start",
                self.sec, self.nanosec
            )));
        }
        Ok(self.sec as u64 * 1_000_000_000 + self.nanosec as u64)
    }

    fn write(&self, w: &mut CdrWriter) {
        w.i32(self.sec);
        w.u32(self.nanosec);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, Ros2Error> {
        Ok(Self {
            sec: r.i32()?,
            nanosec: r.u32()?,
        })
    }
}

/// A time in seconds on a clock that starts at 0 (the simulation's, the board's) as whole nanoseconds, the
/// unit of a bag's log time and of a stamp.
pub fn nanos_of_seconds(t_s: f64) -> Result<u64, Ros2Error> {
    let ns = (t_s * 1e9).round();
    if !(ns.is_finite() && ns >= 0.0 && ns < 2f64.powi(63)) {
        return Err(Ros2Error::Time(format!(
            "t = {t_s} s: a bag's time is in [0, 292 years) of the clock"
        )));
    }
    Ok(ns as u64)
}

/// `rosgraph_msgs/msg/Clock`: the time a node that publishes `/clock` (a simulator) runs on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Clock {
    /// The time.
    pub clock: Time,
}

impl Message for Clock {
    const TYPE: &'static str = "rosgraph_msgs/msg/Clock";

    fn definition() -> String {
        definition(CLOCK_MSG, &[("builtin_interfaces/Time", TIME_MSG)])
    }

    fn encode(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        self.clock.write(&mut w);
        w.finish()
    }

    fn decode(data: &[u8]) -> Result<Self, Ros2Error> {
        let mut r = CdrReader::new(data)?;
        Ok(Self {
            clock: Time::read(&mut r)?,
        })
    }
}

/// `std_msgs/msg/Header`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header {
    /// When the values were read.
    pub stamp: Time,
    /// The frame they are in (empty: none).
    pub frame_id: String,
}

impl Header {
    fn write(&self, w: &mut CdrWriter) {
        self.stamp.write(w);
        w.string(&self.frame_id);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, Ros2Error> {
        Ok(Self {
            stamp: Time::read(r)?,
            frame_id: r.string()?,
        })
    }
}

/// `sensor_msgs/msg/JointState`: for a prismatic joint position in m, velocity in m/s, effort in N. An
/// array may be empty (not measured); a non-empty one has an entry per name.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct JointState {
    /// Stamp and frame.
    pub header: Header,
    /// The joints' names.
    pub name: Vec<String>,
    /// Positions.
    pub position: Vec<f64>,
    /// Velocities.
    pub velocity: Vec<f64>,
    /// Efforts.
    pub effort: Vec<f64>,
}

impl Message for JointState {
    const TYPE: &'static str = "sensor_msgs/msg/JointState";

    fn definition() -> String {
        definition(
            JOINT_STATE_MSG,
            &[
                ("std_msgs/Header", HEADER_MSG),
                ("builtin_interfaces/Time", TIME_MSG),
            ],
        )
    }

    fn encode(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        self.header.write(&mut w);
        w.strings(&self.name);
        w.f64s(&self.position);
        w.f64s(&self.velocity);
        w.f64s(&self.effort);
        w.finish()
    }

    fn decode(data: &[u8]) -> Result<Self, Ros2Error> {
        let mut r = CdrReader::new(data)?;
        let m = Self {
            header: Header::read(&mut r)?,
            name: r.strings()?,
            position: r.f64s()?,
            velocity: r.f64s()?,
            effort: r.f64s()?,
        };
        for (what, v) in [
            ("position", &m.position),
            ("velocity", &m.velocity),
            ("effort", &m.effort),
        ] {
            if !v.is_empty() && v.len() != m.name.len() {
                return Err(Ros2Error::Cdr(format!(
                    "a JointState of {} names with {} {what} entries",
                    m.name.len(),
                    v.len()
                )));
            }
        }
        Ok(m)
    }
}

/// `sensor_msgs/msg/FluidPressure`: absolute pressure, Pa.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FluidPressure {
    /// Stamp and frame.
    pub header: Header,
    /// Absolute pressure, Pa.
    pub fluid_pressure: f64,
    /// Its variance, Pa² (0: unknown).
    pub variance: f64,
}

impl Message for FluidPressure {
    const TYPE: &'static str = "sensor_msgs/msg/FluidPressure";

    fn definition() -> String {
        definition(
            FLUID_PRESSURE_MSG,
            &[
                ("std_msgs/Header", HEADER_MSG),
                ("builtin_interfaces/Time", TIME_MSG),
            ],
        )
    }

    fn encode(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        self.header.write(&mut w);
        w.f64(self.fluid_pressure);
        w.f64(self.variance);
        w.finish()
    }

    fn decode(data: &[u8]) -> Result<Self, Ros2Error> {
        let mut r = CdrReader::new(data)?;
        Ok(Self {
            header: Header::read(&mut r)?,
            fluid_pressure: r.f64()?,
            variance: r.f64()?,
        })
    }
}

/// `std_msgs/msg/MultiArrayDimension`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct MultiArrayDimension {
    /// What the dimension counts.
    pub label: String,
    /// Its length.
    pub size: u32,
    /// Elements per step of the dimension above.
    pub stride: u32,
}

/// `std_msgs/msg/Float64MultiArray`: here one value per actuator, in the order of the JointState's names,
/// one dimension labelled `actuator`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Float64MultiArray {
    /// The dimensions (`std_msgs/MultiArrayLayout` dim).
    pub dim: Vec<MultiArrayDimension>,
    /// `std_msgs/MultiArrayLayout` data_offset.
    pub data_offset: u32,
    /// The values.
    pub data: Vec<f64>,
}

impl Float64MultiArray {
    /// One value per actuator.
    pub fn per_actuator(data: Vec<f64>) -> Self {
        Self {
            dim: vec![MultiArrayDimension {
                label: "actuator".into(),
                size: data.len() as u32,
                stride: data.len() as u32,
            }],
            data_offset: 0,
            data,
        }
    }
}

impl Message for Float64MultiArray {
    const TYPE: &'static str = "std_msgs/msg/Float64MultiArray";

    fn definition() -> String {
        definition(
            FLOAT64_MULTI_ARRAY_MSG,
            &[
                ("std_msgs/MultiArrayLayout", LAYOUT_MSG),
                ("std_msgs/MultiArrayDimension", DIMENSION_MSG),
            ],
        )
    }

    fn encode(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        w.len(self.dim.len());
        for d in &self.dim {
            w.string(&d.label);
            w.u32(d.size);
            w.u32(d.stride);
        }
        w.u32(self.data_offset);
        w.f64s(&self.data);
        w.finish()
    }

    fn decode(data: &[u8]) -> Result<Self, Ros2Error> {
        let mut r = CdrReader::new(data)?;
        let n = r.len(13)?;
        let dim = (0..n)
            .map(|_| {
                Ok(MultiArrayDimension {
                    label: r.string()?,
                    size: r.u32()?,
                    stride: r.u32()?,
                })
            })
            .collect::<Result<_, Ros2Error>>()?;
        Ok(Self {
            dim,
            data_offset: r.u32()?,
            data: r.f64s()?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bytes of a JointState of one joint laid out by hand from the CDR rules (cdr.rs): stamp 1 s
    /// 2 ns (body bytes 0-8), frame "" (length 1, NUL, 3 pad: 8-16), name count 1 and "cyl" (length 4,
    /// 4 bytes: 16-28), position count 1 (28-32) and its float (32-40, 8-aligned already), velocity count
    /// 0 (40-44), effort count 1 (44-48) and its float (48-56).
    #[test]
    fn a_joint_state_has_the_layout_of_the_cdr_rules() {
        let m = JointState {
            header: Header {
                stamp: Time { sec: 1, nanosec: 2 },
                frame_id: String::new(),
            },
            name: vec!["cyl".into()],
            position: vec![0.25],
            velocity: vec![],
            effort: vec![-3.0],
        };
        let mut want: Vec<u8> = vec![0, 1, 0, 0];
        want.extend([1, 0, 0, 0, 2, 0, 0, 0]); // stamp
        want.extend([1, 0, 0, 0, 0, 0, 0, 0]); // frame_id "": length 1, NUL, pad to 4
        want.extend([1, 0, 0, 0, 4, 0, 0, 0, b'c', b'y', b'l', 0]); // name
        want.extend([1, 0, 0, 0]); // position count
        want.extend(0.25f64.to_le_bytes());
        want.extend([0, 0, 0, 0]); // velocity: no entries
        want.extend([1, 0, 0, 0]); // effort count
        want.extend((-3.0f64).to_le_bytes());
        assert_eq!(m.encode(), want);
        assert_eq!(JointState::decode(&want).unwrap(), m);
    }

    #[test]
    fn the_definitions_name_each_type_they_use_once() {
        let d = JointState::definition();
        assert!(d.starts_with("std_msgs/Header header\n"));
        assert_eq!(d.matches("MSG: ").count(), 2);
        assert!(d.contains(&format!(
            "{SEPARATOR}\nMSG: builtin_interfaces/Time\nint32 sec"
        )));
        let m = Float64MultiArray::per_actuator(vec![0.5, -0.25]);
        assert_eq!(Float64MultiArray::decode(&m.encode()).unwrap(), m);
        let p = FluidPressure {
            fluid_pressure: 6e5,
            ..FluidPressure::default()
        };
        assert_eq!(FluidPressure::decode(&p.encode()).unwrap(), p);
    }

    #[test]
    fn seconds_become_whole_nanoseconds() {
        assert_eq!(nanos_of_seconds(0.001).unwrap(), 1_000_000);
        assert_eq!(nanos_of_seconds(9.999).unwrap(), 9_999_000_000);
        assert!(nanos_of_seconds(-0.001).is_err());
        assert_eq!(
            Time::from_nanos(2_500_000_001).unwrap(),
            Time {
                sec: 2,
                nanosec: 500_000_001
            }
        );
    }
}
