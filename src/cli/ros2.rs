//! `pneuflex ros2`'s arguments.

use std::path::PathBuf;

use clap::Args;

#[cfg(feature = "ros2")]
use crate::cmd;

/// Run a scene in real time as a native ROS 2 node (no ROS install; docs/ros2.md): publishes
/// /pneuflex/joint_states, the chamber pressures, the force reference, the valve command and /clock every
/// control tick; the efforts on /pneuflex/joint_commands replace the force reference while they arrive
/// (ros2_control's topic-based hardware interface). Ends after --duration or on Ctrl-C; the trace and
/// summary.json go to out/ros2/<scene>/ (a recording: never replaced).
#[derive(Args)]
pub struct Ros2 {
    /// A scene file (scenes/*.toml), one actuator or several.
    pub scene: PathBuf,
    /// Name of the scene's run whose controllers run (default: the first).
    #[arg(long)]
    pub run: Option<String>,
    /// Run length in seconds (default: the scene's duration).
    #[arg(long, value_name = "S")]
    pub duration: Option<f64>,
    #[command(flatten)]
    pub node: NodeFlags,
    #[command(flatten)]
    pub limits: crate::cli::simulate::RunLimits,
    /// Output directory (default: out/ros2/<scene name>/, or the first free <name>-2, -3, ...).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print only the final report.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Where the node joins and how long a command holds (`ros2`, `rig run --ros2`).
#[derive(Args)]
pub struct NodeFlags {
    /// DDS domain, 0 to 232 (default: ROS_DOMAIN_ID, else 0).
    #[arg(long, value_name = "N")]
    pub domain_id: Option<u32>,
    /// Discovery and traffic on the loopback interface alone, as ROS_LOCALHOST_ONLY=1 (which also sets it).
    #[arg(long)]
    pub localhost: bool,
    /// How long a joint's commanded effort stays in force after it arrived, s (default 0.5); then the
    /// scene's own reference applies again.
    #[arg(long, value_name = "S")]
    pub command_timeout: Option<f64>,
}

impl NodeFlags {
    /// Whether any was given.
    pub fn given(&self) -> bool {
        self.domain_id.is_some() || self.localhost || self.command_timeout.is_some()
    }

    /// The options, the defaults where a flag is absent.
    pub fn options(&self) -> crate::cmd::ros2::NodeOptions {
        crate::cmd::ros2::NodeOptions {
            domain_id: self.domain_id,
            localhost: self.localhost,
            command_timeout_s: self.command_timeout.unwrap_or(0.5),
        }
    }
}

impl Ros2 {
    #[cfg(not(feature = "ros2"))]
    pub fn call(self) -> anyhow::Result<()> {
        anyhow::bail!(
            "ros2 {}: this pneuflex was built without the `ros2` feature (a default one): build it with \
             `cargo build --features ros2`",
            self.scene.display()
        )
    }

    #[cfg(feature = "ros2")]
    pub fn call(self) -> anyhow::Result<()> {
        cmd::ros2::run(&cmd::ros2::Ros2Args {
            scene: self.scene,
            run: self.run,
            duration_s: self.duration,
            node: self.node.options(),
            limits: self.limits.limits(),
            out: self.out,
            quiet: self.quiet,
        })
    }
}
