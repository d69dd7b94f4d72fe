//! The node beside a loop ([`Bridge`]: publishes the rows, gives the commanded references) and `pneuflex
//! ros2` ([`run`]), built with the feature `ros2`.

use std::cell::RefCell;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::Duration;

use anyhow::{Context as _, anyhow, bail};
use pneuflex_control::{Setpoint, Signal, Sink};
use pneuflex_files::OutputDir;
use pneuflex_files::output::{Manifest, Partial, Writer};
use pneuflex_rig::clock::{Clock, WallClock};
use pneuflex_rig::rtloop::{TimingStats, check_duration};
use pneuflex_ros2::joint_commands::JointCommands;
use pneuflex_ros2::node::{NodeConfig, RosNode, TickValues, check_domain_id};
use pneuflex_ros2::trace_bag::SINGLE_JOINT;
use pneuflex_scene::{AnyScene, Plant};

use super::NodeOptions;
use crate::cmd::Exit;

/// What `pneuflex ros2` was given.
#[derive(Clone, Debug)]
pub struct Ros2Args {
    /// The scene file.
    pub scene: PathBuf,
    /// The run by name (None: the first).
    pub run: Option<String>,
    /// `--duration` (None: the scene's).
    pub duration_s: Option<f64>,
    /// Where the node joins and how long a command holds.
    pub node: NodeOptions,
    /// `--max-steps`, `--max-trace-mb`: what the run may cost.
    pub limits: pneuflex_scene::Limits,
    /// `--out`.
    pub out: Option<PathBuf>,
    /// `--quiet`.
    pub quiet: bool,
}

impl NodeOptions {
    /// The domain (`--domain-id`, else `ROS_DOMAIN_ID`, else 0) and whether on loopback alone; the command
    /// timeout checked. Errors name the option or variable.
    fn checked(&self) -> anyhow::Result<(u16, bool)> {
        if !(self.command_timeout_s.is_finite() && self.command_timeout_s > 0.0) {
            bail!(
                "--command-timeout: expected a time in seconds, finite and > 0; got {}",
                self.command_timeout_s
            );
        }
        let domain = match self.domain_id {
            Some(id) => check_domain_id(id).map_err(|e| anyhow!("--domain-id: {e}"))?,
            None => match std::env::var("ROS_DOMAIN_ID") {
                Ok(v) if !v.trim().is_empty() => v
                    .trim()
                    .parse::<u32>()
                    .map_err(|_| format!("not a whole number: {v:?}"))
                    .and_then(check_domain_id)
                    .map_err(|e| anyhow!("ROS_DOMAIN_ID: {e}"))?,
                _ => 0,
            },
        };
        let localhost =
            self.localhost || std::env::var("ROS_LOCALHOST_ONLY").is_ok_and(|v| v == "1");
        Ok((domain, localhost))
    }
}

/// A node beside a loop: it publishes the loop's rows ([`Publisher`]) and gives each actuator's reference,
/// the commanded force while commands arrive ([`Bridge::reference`]).
pub struct Bridge {
    node: RosNode,
    joints: Vec<String>,
    /// Where it joined, for the banner.
    pub domain: u16,
    /// On loopback alone.
    pub localhost: bool,
    commands: RefCell<Commands>,
}

/// The commands and what is counted of them.
struct Commands {
    table: JointCommands,
    drained_at: f64,
    counted_at: f64,
    ticks: u64,
    said: usize,
}

impl Bridge {
    /// Checks the options (before anything else is touched, so that a bad option fails at once).
    pub fn check(opts: &NodeOptions) -> anyhow::Result<()> {
        opts.checked().map(drop)
    }

    /// Joins the domain with the node for `joints` (their pressures published when `chambers`).
    pub fn start(opts: &NodeOptions, joints: Vec<String>, chambers: bool) -> anyhow::Result<Self> {
        let (domain, localhost) = opts.checked()?;
        let node = RosNode::new(&NodeConfig {
            domain_id: domain,
            localhost_only: localhost,
            joints: joints.clone(),
            chambers,
        })
        .context("starting the ROS 2 node")?;
        Ok(Self {
            node,
            domain,
            localhost,
            commands: RefCell::new(Commands {
                table: JointCommands::new(joints.clone(), opts.command_timeout_s),
                drained_at: f64::NAN,
                counted_at: f64::NAN,
                ticks: 0,
                said: 0,
            }),
            joints,
        })
    }

    /// `node /pneuflex on DDS domain 7 (loopback only), 1 joint(s) (cylinder)`.
    pub fn banner(&self) -> String {
        format!(
            "node /{} on DDS domain {}{}, {} joint(s) ({})",
            pneuflex_ros2::node::NODE_NAME,
            self.domain,
            if self.localhost {
                " (loopback only)"
            } else {
                ""
            },
            self.joints.len(),
            self.joints.join(", ")
        )
    }

    /// Actuator `i`'s setpoint at `t`: `scheduled` with the commanded force while a command for it is in
    /// force. The first call of a tick takes every command that arrived since the last tick.
    pub fn reference(&self, i: usize, t: f64, scheduled: Setpoint) -> Setpoint {
        let mut c = self.commands.borrow_mut();
        if i == 0 && t != c.drained_at {
            c.drained_at = t;
            match self.node.take_commands(&mut c.table, t) {
                Ok(notes) => {
                    for n in notes {
                        // A sender that keeps sending bad commands is said a few times, not every tick.
                        if c.said < 5 {
                            errln!("warning: t = {t:.3} s: {n}");
                        }
                        c.said += 1;
                    }
                }
                Err(e) => errln!("warning: t = {t:.3} s: {e}"),
            }
        }
        match c.table.effort(i, t) {
            Some(f_ref) => {
                // A tick with a command for any actuator, counted once.
                if t != c.counted_at {
                    c.counted_at = t;
                    c.ticks += 1;
                }
                Setpoint { f_ref, ..scheduled }
            }
            None => scheduled,
        }
    }

    /// `joint commands: 3 received, 0 refused, in force at 1200 ticks`.
    pub fn commands_report(&self) -> String {
        let c = self.commands.borrow();
        format!(
            "joint commands: {} received, {} refused, in force at {} ticks",
            c.table.received, c.table.refused, c.ticks
        )
    }

    /// A publisher of the loop's rows.
    pub fn publisher(&self) -> Publisher<'_> {
        Publisher::new(&self.node, self.joints.len())
    }
}

/// Runs the node; see the module's doc.
pub fn run(a: &Ros2Args) -> anyhow::Result<()> {
    let mut scene = AnyScene::load(&a.scene)?;
    let index = match &a.run {
        None => 0,
        Some(name) => scene.run_index(name)?,
    };
    let run_name = scene.runs()[index].name.clone();
    if let Some(d) = a.duration_s {
        check_duration(d).map_err(|e| anyhow!("--duration: {}", e.message))?;
        scene.set_duration(d);
    }
    Bridge::check(&a.node)?;
    scene.keep_only_run(index);
    // The trace is kept in memory (written at the end, as `run` writes it): bounded as `run`'s are.
    scene.check_budget(&a.limits)?;
    let (joints, chambers) = joints_of(&scene)?;
    let dt = scene.dt_s();

    // The output is staged before the node joins: a bad --out fails at once.
    let dest = match &a.out {
        Some(d) => d.clone(),
        None => pneuflex_files::output::fresh_destination(
            &Path::new("out").join("ros2").join(scene.name()),
        ),
    };
    let inputs = scene.input_files(&a.scene);
    let protect: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let stage = OutputDir::create(&dest, &protect, Writer::recording("ros2"))?;
    let stop = crate::cmd::stop_flag()?;

    let bridge = Bridge::start(&a.node, joints, chambers)?;
    if !a.quiet {
        outln!(
            "{}: scene `{}`, run `{run_name}`, {:.0} Hz for {} s (Ctrl-C ends it)",
            bridge.banner(),
            scene.name(),
            1.0 / dt,
            scene.duration_s()
        );
    }
    let mut sink = NodeSink {
        publisher: bridge.publisher(),
        clock: WallClock::new(Duration::ZERO),
        dt,
        lateness: TimingStats::default(),
        late: 0,
    };
    let result = scene.run_referenced(
        0,
        &mut |i, t, scheduled| bridge.reference(i, t, scheduled),
        &mut sink,
        Some(&stop),
    )?;
    let report = format!("{}; {}", sink.report(), bridge.commands_report());
    drop(sink);
    drop(bridge);

    let runs = [result];
    scene.write_results(stage.path(), &runs)?;
    let manifest = Manifest::new("ros2", env!("CARGO_PKG_VERSION"), scene.input_digests());
    let r = &runs[0];
    let time_reached_s = r.trace.t().last().copied().unwrap_or(0.0);
    outln!(
        "{} ticks to t = {time_reached_s:.3} s; {report}",
        r.trace.len()
    );
    let signal = stop.load(Ordering::Relaxed);
    if signal != 0 {
        let reason = pneuflex_scene::signal_name(signal);
        let to = stage.commit_partial(
            manifest,
            Partial {
                reason: reason.clone(),
                time_reached_s,
                done: None,
            },
        )?;
        return Err(Exit {
            code: 128 + signal.clamp(1, 64) as u8,
            message: format!(
                "{reason}: the node stopped at t = {time_reached_s:.3} s; the trace is in {} (marked incomplete \
                 in its manifest)",
                to.display()
            ),
        }
        .into());
    }
    let dest = stage.commit(manifest)?;
    if !a.quiet {
        outln!("outputs in {}", dest.display());
    }
    crate::cmd::fail_on_divergence([(r.name.as_str(), r.diverged.as_deref())], &dest)
}

/// The joints' names (a one-actuator scene's is `cylinder`, as in a bag) and whether every actuator has
/// chambers whose pressures are published (a plant built to look: its initial p_a and p_b are numbers).
fn joints_of(scene: &AnyScene) -> anyhow::Result<(Vec<String>, bool)> {
    Ok(match scene {
        AnyScene::One(s) => {
            let plant = pneuflex_scene::build_plant(s)?;
            let p = plant.sense();
            (
                vec![SINGLE_JOINT.to_string()],
                p.p_a.is_finite() && p.p_b.is_finite(),
            )
        }
        AnyScene::Mechanism(m) => {
            let plant = pneuflex_scene::mechanism::MechanismPlant::new(m)?;
            let names = plant.actuator_names().to_vec();
            let chambers = (0..names.len()).all(|i| {
                let p = plant.sense_actuator(i);
                p.p_a.is_finite() && p.p_b.is_finite()
            });
            (names, chambers)
        }
    })
}

/// Where an actuator's signals sit in the row.
#[derive(Clone, Copy, Debug, Default)]
struct Columns {
    f_ref: usize,
    f_e: usize,
    x: usize,
    p_a: usize,
    p_b: usize,
    u: usize,
}

/// Publishes the loop's rows: finds each actuator's columns at the run's start (bare names for one
/// actuator, `<actuator>.<signal>` for several), then publishes each row given to it. A sink of rows alone
/// for the rig's loop (no velocity: the rig's row has none); the simulation's [`NodeSink`] adds the plant's.
pub struct Publisher<'a> {
    node: &'a RosNode,
    columns: Vec<Columns>,
    position: Vec<f64>,
    velocity: Vec<f64>,
    effort: Vec<f64>,
    pressures: Vec<[f64; 2]>,
    force_reference: Vec<f64>,
    valve_command: Vec<f64>,
    /// Rows not published, and the last reason.
    errors: (u64, Option<String>),
    /// How long publishing a row took, s.
    cost: TimingStats,
}

impl<'a> Publisher<'a> {
    fn new(node: &'a RosNode, joints: usize) -> Self {
        Self {
            node,
            columns: vec![Columns::default(); joints],
            position: vec![0.0; joints],
            velocity: Vec::new(),
            effort: vec![0.0; joints],
            pressures: vec![[0.0; 2]; joints],
            force_reference: vec![0.0; joints],
            valve_command: vec![0.0; joints],
            errors: (0, None),
            cost: TimingStats::default(),
        }
    }

    fn find_columns(&mut self, columns: &[Signal]) {
        let one = self.columns.len() == 1 && !columns.iter().any(|c| c.name.ends_with(".f_e"));
        // A plant of several names its columns by actuator, in the order of the joints.
        let names: Vec<String> = if one {
            vec![String::new()]
        } else {
            columns
                .iter()
                .filter_map(|c| c.name.strip_suffix(".f_e").map(str::to_string))
                .collect()
        };
        let find = |actuator: &str, s: &str| {
            let name = if one {
                s.to_string()
            } else {
                format!("{actuator}.{s}")
            };
            columns.iter().position(|c| c.name == name).unwrap_or(0)
        };
        for (col, a) in self.columns.iter_mut().zip(&names) {
            *col = Columns {
                f_ref: find(a, "f_ref"),
                f_e: find(a, "f_e"),
                x: find(a, "x"),
                p_a: find(a, "p_a"),
                p_b: find(a, "p_b"),
                u: find(a, "u"),
            };
        }
    }

    /// Publishes one row; `velocity(i)` is actuator `i`'s, when there is one.
    fn publish(&mut self, values: &[f64], velocity: Option<&dyn Fn(usize) -> f64>) {
        for (i, c) in self.columns.iter().enumerate() {
            self.position[i] = values[c.x];
            self.effort[i] = values[c.f_e];
            self.pressures[i] = [values[c.p_a], values[c.p_b]];
            self.force_reference[i] = values[c.f_ref];
            self.valve_command[i] = values[c.u];
        }
        self.velocity.clear();
        if let Some(v) = velocity {
            self.velocity.extend((0..self.columns.len()).map(v));
        }
        let started = std::time::Instant::now();
        let published = self.node.publish(&TickValues {
            t_s: values[0],
            position: &self.position,
            velocity: &self.velocity,
            effort: &self.effort,
            pressures: &self.pressures,
            force_reference: &self.force_reference,
            valve_command: &self.valve_command,
        });
        self.cost.push(started.elapsed().as_secs_f64());
        if let Err(e) = published {
            self.errors.0 += 1;
            self.errors.1 = Some(e.to_string());
        }
    }

    /// What publishing cost and what did not go out, in words, each part after `; `.
    pub fn report(&self) -> String {
        let c = self.cost.percentiles();
        let mut s = format!(
            "; publishing a tick took median {:.0} µs, p99 {:.0} µs",
            1e6 * c.p50,
            1e6 * c.p99
        );
        let dropped = self.node.dropped();
        if dropped > 0 {
            s.push_str(&format!(
                "; {dropped} samples not sent (a full send window)"
            ));
        }
        if let (n, Some(e)) = &self.errors {
            s.push_str(&format!("; {n} ticks not published, the last: {e}"));
        }
        s
    }
}

/// The rig's loop: its rows as they are traced (the loop paces itself).
impl Sink<()> for Publisher<'_> {
    fn begin(&mut self, _run: &str, columns: &[Signal], _world: &()) {
        self.find_columns(columns);
    }

    fn row(&mut self, values: &[f64], _world: &()) {
        self.publish(values, None);
    }
}

/// The simulation's side of the node: at each row, waits for the tick's time on the wall clock, then
/// publishes the tick with the plant's velocities; keeps how late the ticks were.
struct NodeSink<'a> {
    publisher: Publisher<'a>,
    clock: WallClock,
    dt: f64,
    lateness: TimingStats,
    /// Ticks published over half a period after their time.
    late: u64,
}

impl NodeSink<'_> {
    /// The timing in words.
    fn report(&self) -> String {
        let p = self.lateness.percentiles();
        format!(
            "publish after the tick's time: median {:.0} µs, p99 {:.0} µs, max {:.1} ms; {} late ticks (over half a \
             period){}",
            1e6 * p.p50,
            1e6 * p.p99,
            1e3 * p.max,
            self.late,
            self.publisher.report()
        )
    }
}

impl Sink<dyn Plant + '_> for NodeSink<'_> {
    fn begin(&mut self, _run: &str, columns: &[Signal], _world: &(dyn Plant + '_)) {
        self.publisher.find_columns(columns);
        // The wall clock starts with the first tick. Sleeps only: a spinning wait would take a core from
        // the DDS threads and the subscribers.
        self.clock = WallClock::new(Duration::ZERO);
    }

    fn row(&mut self, values: &[f64], world: &(dyn Plant + '_)) {
        let t = values[0];
        self.clock.wait_until(t);
        let late = self.clock.now() - t;
        self.lateness.push(late);
        if late > 0.5 * self.dt {
            self.late += 1;
        }
        // The trace of a one-actuator plant has no velocity: the plant's own, as it senses it.
        self.publisher
            .publish(values, Some(&|i| world.sense_actuator(i).x_dot));
    }
}
