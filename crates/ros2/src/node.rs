//! A native ROS 2 node without a ROS install (feature `node`: `ros2-client` on RustDDS, docs/ros2.md): the
//! topic interface of ros2_control's topic-based hardware interface. Every control tick it publishes
//!
//! | topic | type | holds |
//! |---|---|---|
//! | `/pneuflex/joint_states` | `sensor_msgs/msg/JointState` | per actuator: position x, velocity ẋ (when the plant has it), effort f_e |
//! | `/pneuflex/pressures/<joint>/a`, `/b` | `sensor_msgs/msg/FluidPressure` | p_a, p_b (Pa absolute), for a plant with chambers |
//! | `/pneuflex/force_reference` | `std_msgs/msg/Float64MultiArray` | the f_ref the controllers track, per actuator |
//! | `/pneuflex/valve_command` | `std_msgs/msg/Float64MultiArray` | u, per actuator |
//! | `/clock` | `rosgraph_msgs/msg/Clock` | the loop's time |
//!
//! stamped with the loop's time (the first tick is 0 s, as in a bag: [`crate::trace_bag`]), and takes the
//! `sensor_msgs/msg/JointState` commands on `/pneuflex/joint_commands` ([`JointCommands`]). The messages
//! are the types of [`crate::msg`], serialised by RustDDS through their `serde` derives.
//!
//! QoS: the publishers are reliable, volatile, keep-last 10, and never wait for a full send window (a
//! sample that finds one is counted, not waited for: the caller is a real-time loop); a reliable writer
//! reaches both reliable and best-effort readers (topic_based_ros2_control subscribes with the sensor-data
//! QoS, best effort). The subscription is best effort, keep-last 10, which matches reliable and
//! best-effort writers.

use std::net::{IpAddr, Ipv4Addr};
use std::sync::atomic::{AtomicU64, Ordering};

use ros2_client::dds::rustdds::DomainParticipantBuilder;
use ros2_client::qos::{Durability, History, Reliability, WhenFull};
use ros2_client::{
    Context, MessageTypeName, Name, Node, NodeName, NodeOptions, Publisher, QosProfile,
    Subscription,
};

use crate::Ros2Error;
use crate::joint_commands::JointCommands;
use crate::msg::{
    Clock, Float64MultiArray, FluidPressure, Header, JointState, Time, nanos_of_seconds,
};
use crate::trace_bag::{FORCE_REFERENCE, JOINT_STATES, VALVE_COMMAND, pressure_topic};

/// The node's name (namespace `/`).
pub const NODE_NAME: &str = "pneuflex";
/// The topic the commands arrive on.
pub const JOINT_COMMANDS: &str = "/pneuflex/joint_commands";
/// The clock's topic.
pub const CLOCK: &str = "/clock";
/// The largest DDS domain id: the RTPS port of domain d is 7400 + 250 d + ..., and it must stay below
/// 65536 (ROS 2 documents 0-101 as the ids safe from Linux's ephemeral ports, 0-232 as possible).
pub const MAX_DOMAIN_ID: u32 = 232;

/// Where the node joins: a DDS domain, on every network interface or on the loopback interface alone.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NodeConfig {
    /// The DDS domain (`ROS_DOMAIN_ID`).
    pub domain_id: u16,
    /// Discovery and traffic on the loopback interface alone (`ROS_LOCALHOST_ONLY=1`).
    pub localhost_only: bool,
    /// The joints' names, in the order of the values given to [`RosNode::publish`].
    pub joints: Vec<String>,
    /// Whether each joint has chambers whose pressures are published.
    pub chambers: bool,
}

/// Checks a domain id: 0 to [`MAX_DOMAIN_ID`].
pub fn check_domain_id(id: u32) -> Result<u16, String> {
    if id <= MAX_DOMAIN_ID {
        Ok(id as u16)
    } else {
        Err(format!(
            "a DDS domain id is 0 to {MAX_DOMAIN_ID} (its UDP ports are 7400 + 250 id + ...; ROS 2 advises 0 \
             to 101 on Linux), got {id}"
        ))
    }
}

/// One tick's values, per joint in [`NodeConfig::joints`]' order.
#[derive(Clone, Copy, Debug)]
pub struct TickValues<'a> {
    /// The loop's time, s.
    pub t_s: f64,
    /// Positions x, m.
    pub position: &'a [f64],
    /// Velocities ẋ, m/s (empty: the plant has none).
    pub velocity: &'a [f64],
    /// Contact forces f_e, N.
    pub effort: &'a [f64],
    /// Chamber pressures p_a, p_b, Pa absolute (empty without chambers).
    pub pressures: &'a [[f64; 2]],
    /// The force references f_ref, N.
    pub force_reference: &'a [f64],
    /// The valve commands u.
    pub valve_command: &'a [f64],
}

/// The node, its publishers and its subscription.
pub struct RosNode {
    joints: Vec<String>,
    joint_states: Publisher<JointState>,
    pressures: Vec<[Publisher<FluidPressure>; 2]>,
    force_reference: Publisher<Float64MultiArray>,
    valve_command: Publisher<Float64MultiArray>,
    clock: Publisher<Clock>,
    commands: Subscription<JointState>,
    /// Samples a publisher could not send (a full send window).
    dropped: AtomicU64,
    // Last: the publishers and the subscription go before their node and its participant.
    _node: Node,
}

fn dds<E: std::fmt::Display>(what: &str) -> impl Fn(E) -> Ros2Error + '_ {
    move |e| Ros2Error::Dds(format!("{what}: {e}"))
}

impl RosNode {
    /// Joins the domain and creates the node `/pneuflex` with its topics.
    pub fn new(cfg: &NodeConfig) -> Result<Self, Ros2Error> {
        let mut participant = DomainParticipantBuilder::new(cfg.domain_id);
        if cfg.localhost_only {
            participant = participant.with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)]);
        }
        let participant = participant
            .build()
            .map_err(dds(&format!("joining DDS domain {}", cfg.domain_id)))?;
        let context =
            Context::from_domain_participant(participant).map_err(dds("the ROS 2 context"))?;
        let mut node = context
            .new_node(
                NodeName::new("/", NODE_NAME).map_err(dds("the node's name"))?,
                NodeOptions::new().enable_rosout(false),
            )
            .map_err(dds("creating the node"))?;
        let publish = QosProfile::publisher_default()
            .reliability(Reliability::Reliable {
                when_full: WhenFull::Fail,
            })
            .durability(Durability::Volatile)
            .history(History::KeepLast { depth: 10 });
        let subscribe = QosProfile::subscription_default()
            .reliability(Reliability::BestEffort)
            .history(History::KeepLast { depth: 10 });
        fn topic(
            node: &mut Node,
            name: &str,
            ty: (&str, &str),
            qos: &QosProfile,
        ) -> Result<ros2_client::dds::rustdds::Topic, Ros2Error> {
            let n = Name::parse(name).map_err(|e| Ros2Error::Topic(format!("{name}: {e}")))?;
            node.create_topic(&n, MessageTypeName::new(ty.0, ty.1), qos)
                .map_err(dds(name))
        }
        fn publisher<M: serde::Serialize>(
            node: &mut Node,
            name: &str,
            ty: (&str, &str),
            qos: &QosProfile,
        ) -> Result<Publisher<M>, Ros2Error> {
            let t = topic(node, name, ty, qos)?;
            node.create_publisher(&t, Some(qos.clone()))
                .map_err(dds(name))
        }
        const JOINT_STATE: (&str, &str) = ("sensor_msgs", "JointState");
        const MULTI_ARRAY: (&str, &str) = ("std_msgs", "Float64MultiArray");
        let joint_states = publisher(&mut node, JOINT_STATES, JOINT_STATE, &publish)?;
        let pressures = if cfg.chambers {
            cfg.joints
                .iter()
                .map(|j| {
                    let mut p = |c| {
                        publisher(
                            &mut node,
                            &pressure_topic(j, c),
                            ("sensor_msgs", "FluidPressure"),
                            &publish,
                        )
                    };
                    Ok([p('a')?, p('b')?])
                })
                .collect::<Result<Vec<_>, Ros2Error>>()?
        } else {
            Vec::new()
        };
        let force_reference = publisher(&mut node, FORCE_REFERENCE, MULTI_ARRAY, &publish)?;
        let valve_command = publisher(&mut node, VALVE_COMMAND, MULTI_ARRAY, &publish)?;
        let clock = publisher(&mut node, CLOCK, ("rosgraph_msgs", "Clock"), &publish)?;
        let commands_topic = topic(&mut node, JOINT_COMMANDS, JOINT_STATE, &subscribe)?;
        let commands = node
            .create_subscription(&commands_topic, Some(subscribe.clone()))
            .map_err(dds(JOINT_COMMANDS))?;
        Ok(Self {
            joints: cfg.joints.clone(),
            joint_states,
            pressures,
            force_reference,
            valve_command,
            clock,
            commands,
            dropped: AtomicU64::new(0),
            _node: node,
        })
    }

    /// Publishes one tick: the joint states, the pressures, the force references, the valve commands and
    /// the clock, all stamped `v.t_s`. A sample that finds a full send window is counted
    /// ([`RosNode::dropped`]), not waited for.
    pub fn publish(&self, v: &TickValues<'_>) -> Result<(), Ros2Error> {
        let stamp = Time::from_nanos(nanos_of_seconds(v.t_s)?)?;
        let header = Header {
            stamp,
            frame_id: String::new(),
        };
        // Each publish that failed (a full send window; nothing else fails without a closed participant).
        let mut failed = u64::from(
            self.joint_states
                .publish(JointState {
                    header: header.clone(),
                    name: self.joints.clone(),
                    position: v.position.to_vec(),
                    velocity: v.velocity.to_vec(),
                    effort: v.effort.to_vec(),
                })
                .is_err(),
        );
        for (pair, p) in self.pressures.iter().zip(v.pressures) {
            for (publisher, &pressure) in pair.iter().zip(p) {
                let m = FluidPressure {
                    header: header.clone(),
                    fluid_pressure: pressure,
                    variance: 0.0,
                };
                failed += u64::from(publisher.publish(m).is_err());
            }
        }
        let per = |v: &[f64]| Float64MultiArray::per_actuator(v.to_vec());
        failed += u64::from(
            self.force_reference
                .publish(per(v.force_reference))
                .is_err(),
        );
        failed += u64::from(self.valve_command.publish(per(v.valve_command)).is_err());
        failed += u64::from(self.clock.publish(Clock { clock: stamp }).is_err());
        if failed > 0 {
            self.dropped.fetch_add(failed, Ordering::Relaxed);
        }
        Ok(())
    }

    /// Takes every command that arrived since the last call into `commands`, as arrived at `now_s`;
    /// returns what was ignored, each said once ([`JointCommands::take`]).
    pub fn take_commands(
        &self,
        commands: &mut JointCommands,
        now_s: f64,
    ) -> Result<Vec<String>, Ros2Error> {
        let mut said = Vec::new();
        // Bounded: a flood of commands cannot hold the tick.
        for _ in 0..64 {
            match self.commands.take() {
                Ok(Some((msg, _))) => said.extend(commands.take(&msg, now_s)),
                Ok(None) => break,
                // A sample that does not decode as a JointState.
                Err(e) => {
                    commands.refused += 1;
                    said.push(format!("{JOINT_COMMANDS}: a sample that is not read: {e}"));
                }
            }
        }
        Ok(said)
    }

    /// Samples not sent because a send window was full.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::{Message, MultiArrayDimension};
    use ros2_client::dds::rustdds::CDRSerializerAdapter;
    use ros2_client::dds::rustdds::no_key::SerializerAdapter;

    /// RustDDS's CDR of each message (what the node sends) is the bytes of [`Message::encode`] after its
    /// encapsulation header (what a bag holds, laid out by hand in msg.rs's tests).
    #[test]
    fn the_wire_bytes_are_the_bags() {
        fn same<M: Message + serde::Serialize>(m: &M) {
            let wire = CDRSerializerAdapter::<M>::to_bytes(m).unwrap();
            let ours = m.encode();
            assert_eq!(&ours[..4], &[0, 1, 0, 0]);
            assert_eq!(&wire[..], &ours[4..], "{}", M::TYPE);
        }
        let header = Header {
            stamp: Time {
                sec: 3,
                nanosec: 250_000_000,
            },
            frame_id: "base".into(),
        };
        same(&JointState {
            header: header.clone(),
            name: vec!["left".into(), "right".into()],
            position: vec![0.01, 0.02],
            velocity: vec![],
            effort: vec![-3.5, 60.0],
        });
        same(&FluidPressure {
            header,
            fluid_pressure: 6.2e5,
            variance: 0.0,
        });
        same(&Float64MultiArray {
            dim: vec![MultiArrayDimension {
                label: "actuator".into(),
                size: 3,
                stride: 3,
            }],
            data_offset: 0,
            data: vec![0.5, -1.0, 0.25],
        });
        same(&Clock {
            clock: Time { sec: 7, nanosec: 1 },
        });
    }

    #[test]
    fn a_domain_id_past_232_is_refused() {
        assert_eq!(check_domain_id(0), Ok(0));
        assert_eq!(check_domain_id(232), Ok(232));
        assert!(check_domain_id(233).unwrap_err().contains("0 to 232"));
    }
}
