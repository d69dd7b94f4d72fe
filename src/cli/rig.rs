//! The real-rig commands' arguments (`rig emulate`, `rig pil`, `rig excite`, `rig run`), handed to
//! `cmd::rig` and `cmd::pil`.

use std::path::PathBuf;

use clap::{Args, Subcommand};

use crate::cmd;

/// The `rig` subcommands.
#[derive(Subcommand)]
pub enum RigCommand {
    Emulate(Emulate),
    Pil(Pil),
    Excite(Excite),
    Run(Run),
}

impl RigCommand {
    pub fn call(self) -> anyhow::Result<()> {
        match self {
            RigCommand::Emulate(a) => a.call(),
            RigCommand::Pil(a) => a.call(),
            RigCommand::Excite(a) => a.call(),
            RigCommand::Run(a) => a.call(),
        }
    }
}

/// Emulate the rig's I/O board: the 1-DOF pneumatic plant in real time behind a pseudo-terminal (or a port).
#[derive(Args)]
pub struct Emulate {
    /// Rig file (rigs/*.toml): protocol, calibration, plant and fault injection.
    #[arg(long, default_value = "rigs/emulated.toml")]
    pub rig: PathBuf,
    /// Serve this serial port instead of a new pseudo-terminal.
    #[arg(long)]
    pub port: Option<String>,
    /// A scene with several actuators whose mechanism (URDF, contacts, events) is the board's plant, one
    /// channel per actuator (the rig file's [[channel]]s); --truth hides a sheet as every actuator's.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Stop after this many seconds (default: until Ctrl-C).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Hide a truth: the plant runs this actuator sheet (and its supply), which the host does not know.
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// Sensor-noise seed (with --truth; default: the rig file's emulator.seed).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Transport delay of valve commands in seconds, whole sample periods (with --truth).
    #[arg(long)]
    pub delay: Option<f64>,
}

/// Processor-in-the-loop: a scene's controllers in the firmware on an emulated Cortex-M4F (QEMU
/// mps2-an386), the plant simulated in lockstep, compared tick by tick with the host (docs/firmware.md).
#[derive(Args)]
pub struct Pil {
    /// Scene file (scenes/*.toml).
    #[arg(long)]
    pub scene: PathBuf,
    /// Name of the scene's run (default: every run).
    #[arg(long)]
    pub run: Option<String>,
    /// Firmware ELF (default: firmware/target/thumbv7em-none-eabihf/release/pneuflex-firmware).
    #[arg(long)]
    pub firmware: Option<PathBuf>,
    /// Output directory (default: out/pil/<scene name>/).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Log each run live to Rerun on the simulated timeline: `save <file.rrd>` (one file per run),
    /// `spawn` or `connect <url>`. Needs the `rerun` feature.
    #[arg(long, num_args = 1..=2, value_names = ["MODE", "TARGET"])]
    pub rerun: Option<Vec<String>>,
    /// The figures' format: png (default), svg or pdf.
    #[arg(long, value_enum, default_value_t = crate::cli::FigureFormat::Png)]
    pub format: crate::cli::FigureFormat,
}

/// Excite the valve for identification (docs/identification.md): a PRBS, chirp or steps plus a weak
/// centring term, under the supervisor's limits, logged like `rig run`.
#[derive(Args)]
pub struct Excite {
    /// Serial port of the I/O board (default: the rig file's link.port).
    #[arg(long)]
    pub port: Option<String>,
    /// Rig file (rigs/*.toml).
    #[arg(long, default_value = "rigs/emulated.toml")]
    pub rig: PathBuf,
    /// prbs, chirp or steps.
    #[arg(long, default_value = "steps")]
    pub signal: String,
    /// Amplitude of the signal, command units (0-1).
    #[arg(long, default_value_t = 0.05)]
    pub amplitude: f64,
    /// Length, s.
    #[arg(long, default_value_t = 10.0)]
    pub duration: f64,
    /// Centre position the centring term holds, m.
    #[arg(long, default_value_t = 0.025)]
    pub centre: f64,
    /// Centring gain, 1/m (0: none, the piston walks into a stop or rests on the block).
    #[arg(long, default_value_t = 15.0)]
    pub centring: f64,
    /// Command bias.
    #[arg(long, default_value_t = 0.0)]
    pub bias: f64,
    /// PRBS bit / step hold time, s (chirp: ignored).
    #[arg(long, default_value_t = 0.15)]
    pub hold: f64,
    /// Seed of the PRBS / step levels.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output directory for trace.csv (default: out/rig/excite/<signal>/).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Instead of --port: the rig file's emulator in lockstep with a simulated clock (not real time),
    /// hiding this actuator sheet; --seed also seeds its sensor noise. For CI and worked examples.
    #[arg(long, conflicts_with = "port")]
    pub lockstep_truth: Option<PathBuf>,
    /// A scene with several actuators ([[actuators]]): every actuator excited at once, each its own signal
    /// (--seed + its index), on the rig file's board of one [[channel]] per actuator (docs/rig.md).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Also write the recording as a rosbag2 folder `bag/` beside trace.csv (MCAP storage, CDR, on the
    /// trace's clock; docs/ros2.md): `identify --log DIR/bag` reads it.
    #[arg(long)]
    pub mcap: bool,
}

/// Run one of a scene's controllers on a rig, real or emulated, with the safety supervisor.
#[derive(Args)]
pub struct Run {
    /// Serial port of the I/O board (default: the rig file's link.port).
    #[arg(long)]
    pub port: Option<String>,
    /// Scene whose controller and reference schedule to run.
    #[arg(long)]
    pub scene: PathBuf,
    /// Rig file (rigs/*.toml): port, calibration, limits, safe state, watchdog.
    #[arg(long, default_value = "rigs/emulated.toml")]
    pub rig: PathBuf,
    /// Name of the scene's run to use (default: the first).
    #[arg(long)]
    pub run: Option<String>,
    /// Run length in seconds (default: the scene's duration).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Instead of --port: the rig file's emulator in lockstep with a simulated clock (not real time),
    /// hiding this actuator sheet (`perturb` writes one); --seed seeds its sensor noise. For CI and
    /// worked examples: the same recording every time.
    #[arg(long, conflicts_with = "port")]
    pub lockstep_truth: Option<PathBuf>,
    /// Seed of the lockstep emulator's sensor noise.
    #[arg(long, default_value_t = 1, requires = "lockstep_truth")]
    pub seed: u64,
    /// On a scene of several actuators: NAME=SHEET hides SHEET as actuator NAME's truth instead of
    /// --lockstep-truth's (repeat per actuator).
    #[arg(long = "truth", value_name = "NAME=SHEET", requires = "lockstep_truth")]
    pub truths: Vec<String>,
    /// Output directory for trace.csv (default: out/rig/<scene>/<run>/).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Show the run live in Rerun on the wall-clock timeline, with the same entity paths as `run`
    /// plus the link's quality: `save <file.rrd>`, `spawn` (start a viewer) or `connect <url>`.
    /// Needs the `rerun` feature.
    #[arg(long, num_args = 1..=2, value_names = ["MODE", "TARGET"])]
    pub rerun: Option<Vec<String>>,
    /// The figures' format: png (default), svg or pdf.
    #[arg(long, value_enum, default_value_t = crate::cli::FigureFormat::Png)]
    pub format: crate::cli::FigureFormat,
    /// Also write the recording as a rosbag2 folder `bag/` beside trace.csv (MCAP storage, CDR, on the
    /// board's clock; docs/ros2.md).
    #[arg(long)]
    pub mcap: bool,
    /// Bridge the run to ROS 2 as `pneuflex ros2` does (docs/ros2.md): every tick's joint state, pressures,
    /// force reference, valve command and /clock published; the efforts on /pneuflex/joint_commands replace
    /// the force reference while they arrive, the supervisor in charge as ever. A scene of one actuator.
    #[arg(long)]
    pub ros2: bool,
    #[command(flatten)]
    pub node: crate::cli::ros2::NodeFlags,
}

impl Emulate {
    pub fn call(self) -> anyhow::Result<()> {
        cmd::rig::emulate(
            &self.rig,
            self.scene.as_deref(),
            self.port.as_deref(),
            self.duration,
            &cmd::emulated::Hidden {
                truth: self.truth,
                seed: self.seed,
                delay_s: self.delay,
            },
        )
    }
}

impl Pil {
    pub fn call(self) -> anyhow::Result<()> {
        cmd::pil::pil(
            &self.scene,
            self.run.as_deref(),
            self.firmware.as_deref(),
            self.out.as_deref(),
            self.rerun.as_deref(),
            self.format.into(),
        )
    }
}

impl Excite {
    pub fn call(self) -> anyhow::Result<()> {
        cmd::excite::excite(
            &self.rig,
            self.port.as_deref(),
            &cmd::excitation::ExciteArgs {
                signal: self.signal,
                amplitude: self.amplitude,
                duration_s: self.duration,
                centre_m: self.centre,
                centring_per_m: self.centring,
                bias: self.bias,
                hold_s: self.hold,
                seed: self.seed,
                lockstep_truth: self.lockstep_truth,
                mcap: self.mcap,
                scene: self.scene,
            },
            self.out.as_deref(),
        )
    }
}

impl Run {
    pub fn call(self) -> anyhow::Result<()> {
        if !self.ros2 && self.node.given() {
            anyhow::bail!("--domain-id, --localhost and --command-timeout apply to --ros2");
        }
        let node = self.ros2.then(|| self.node.options());
        cmd::rig::run_scene(
            &self.rig,
            self.port.as_deref(),
            self.lockstep_truth.as_deref().map(|t| (t, self.seed)),
            &self.truths,
            &self.scene,
            self.run.as_deref(),
            self.duration,
            self.out.as_deref(),
            self.rerun.as_deref(),
            self.format.into(),
            self.mcap,
            node.as_ref(),
        )
    }
}
