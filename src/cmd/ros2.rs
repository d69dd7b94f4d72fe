//! `pneuflex ros2 SCENE`: one run of a scene in real time as a native ROS 2 node (crates/ros2 `node`,
//! docs/ros2.md). The run is the scene's, through the one loop (`AnyScene::run_referenced`); a sink paces
//! each tick to the wall clock (it sleeps until the tick's time, then publishes it), and the reference takes
//! each actuator's commanded effort while commands arrive. The trace and summary.json are written as `run`
//! writes them, into a recording's directory (never replaced); a signal ends the run at the next tick and
//! keeps what ran in `DIR.partial`. `rig run --ros2` puts the same node beside the rig's real-time loop.

#[cfg(feature = "ros2")]
mod node;
#[cfg(feature = "ros2")]
pub use node::{Bridge, Ros2Args, run};

/// `--domain-id`, `--localhost`, `--command-timeout`: where a node joins and how long a command holds
/// (`pneuflex ros2`, `rig run --ros2`).
#[derive(Clone, Debug)]
// Without the feature only `rig run --ros2`'s refusal holds it.
#[cfg_attr(not(feature = "ros2"), allow(dead_code))]
pub struct NodeOptions {
    /// `--domain-id` (None: `ROS_DOMAIN_ID`, else 0).
    pub domain_id: Option<u32>,
    /// `--localhost` (or `ROS_LOCALHOST_ONLY=1`).
    pub localhost: bool,
    /// `--command-timeout`, s.
    pub command_timeout_s: f64,
}
