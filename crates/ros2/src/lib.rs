//! ROS 2 without a ROS install (docs/ros2.md): the standard messages a recording of pneuflex uses in CDR
//! ([`cdr`], [`msg`]), rosbag2 folders in MCAP storage written and read ([`bag`]), and a run's trace as
//! such a bag and back ([`trace_bag`]); with the feature `node`, a native ROS 2 node ([`node`]) and the
//! commands it takes ([`joint_commands`]).

pub mod bag;
pub mod cdr;
pub mod joint_commands;
pub mod msg;
#[cfg(feature = "node")]
pub mod node;
pub mod trace_bag;

pub use bag::{BagContents, BagSummary, BagWriter, read_bag};
pub use trace_bag::{ActuatorLog, TraceColumns, read_actuator_log, write_trace_bag};

use std::path::PathBuf;

/// What went wrong writing or reading a bag.
#[derive(Debug, thiserror::Error)]
pub enum Ros2Error {
    /// A file or folder could not be written or read.
    #[error("{}: cannot {what}: {source}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// What was tried.
        what: &'static str,
        /// The OS's reason.
        source: std::io::Error,
    },
    /// The MCAP container.
    #[error("{}: {source}", path.display())]
    Mcap {
        /// The MCAP file.
        path: PathBuf,
        /// The MCAP library's reason.
        source: mcap::McapError,
    },
    /// A bag that is not one of a pneuflex recording's shape.
    #[error("{}: {message}", path.display())]
    Bag {
        /// The bag.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A message's bytes.
    #[error("CDR: {0}")]
    Cdr(String),
    /// A time that a bag cannot hold.
    #[error("time: {0}")]
    Time(String),
    /// A topic name.
    #[error("topic {0}")]
    Topic(String),
    /// The DDS middleware (joining a domain, creating a node or a topic).
    #[error("ROS 2: {0}")]
    Dds(String),
}
