//! `pneuflex ros2 SCENE`: one run of a scene in real time as a native ROS 2 node (crates/ros2 `node`,
//! docs/ros2.md). The run is the scene's, through the one loop (`AnyScene::run_referenced`); a sink paces
//! each tick to the wall clock (it sleeps until the tick's time, then publishes it), and the reference takes
//! each actuator's commanded effort while commands arrive. The trace and summary.json are written as `run`
//! writes them, into a recording's directory (never replaced); a signal ends the run at the next tick and
//! keeps what ran in `DIR.partial`.

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

use super::Exit;

/// What `pneuflex ros2` was given.
#[derive(Clone, Debug)]
pub struct Ros2Args {
    /// The scene file.
    pub scene: PathBuf,
    /// The run by name (None: the first).
    pub run: Option<String>,
    /// `--duration` (None: the scene's).
    pub duration_s: Option<f64>,
    /// `--domain-id` (None: `ROS_DOMAIN_ID`, else 0).
    pub domain_id: Option<u32>,
    /// `--localhost`.
    pub localhost: bool,
    /// `--command-timeout`, s.
    pub command_timeout_s: f64,
    /// `--max-steps`, `--max-trace-mb`: what the run may cost.
    pub limits: pneuflex_scene::Limits,
    /// `--out`.
    pub out: Option<PathBuf>,
    /// `--quiet`.
    pub quiet: bool,
}

/// The domain: `--domain-id`, else `ROS_DOMAIN_ID`, else 0.
fn domain_id(given: Option<u32>) -> anyhow::Result<u16> {
    match given {
        Some(id) => check_domain_id(id).map_err(|e| anyhow!("--domain-id: {e}")),
        None => match std::env::var("ROS_DOMAIN_ID") {
            Ok(v) if !v.trim().is_empty() => v
                .trim()
                .parse::<u32>()
                .map_err(|_| format!("not a whole number: {v:?}"))
                .and_then(check_domain_id)
                .map_err(|e| anyhow!("ROS_DOMAIN_ID: {e}")),
            _ => Ok(0),
        },
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
    if !(a.command_timeout_s.is_finite() && a.command_timeout_s > 0.0) {
        bail!(
            "--command-timeout: expected a time in seconds, finite and > 0; got {}",
            a.command_timeout_s
        );
    }
    let domain = domain_id(a.domain_id)?;
    let localhost = a.localhost || std::env::var("ROS_LOCALHOST_ONLY").is_ok_and(|v| v == "1");
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
    let stop = super::stop_flag()?;

    let node = RosNode::new(&NodeConfig {
        domain_id: domain,
        localhost_only: localhost,
        joints: joints.clone(),
        chambers,
    })
    .context("starting the ROS 2 node")?;
    if !a.quiet {
        outln!(
            "node /{} on DDS domain {domain}{}: scene `{}`, run `{run_name}`, {} joint(s) ({}), {:.0} Hz for {} s \
             (Ctrl-C ends it)",
            pneuflex_ros2::node::NODE_NAME,
            if localhost { " (loopback only)" } else { "" },
            scene.name(),
            joints.len(),
            joints.join(", "),
            1.0 / dt,
            scene.duration_s()
        );
    }

    let mut commands = JointCommands::new(joints.clone(), a.command_timeout_s);
    let mut commanded_ticks = 0u64;
    let (mut drained_at, mut counted_at) = (f64::NAN, f64::NAN);
    let mut said = 0usize;
    let mut reference = |i: usize, t: f64, scheduled: Setpoint| -> Setpoint {
        // Once a tick, before the first actuator's controller: every command that arrived since.
        if i == 0 && t != drained_at {
            drained_at = t;
            match node.take_commands(&mut commands, t) {
                Ok(notes) => {
                    for n in notes {
                        // A sender that keeps sending bad commands is said a few times, not every tick.
                        if said < 5 {
                            errln!("warning: t = {t:.3} s: {n}");
                        }
                        said += 1;
                    }
                }
                Err(e) => errln!("warning: t = {t:.3} s: {e}"),
            }
        }
        match commands.effort(i, t) {
            Some(f_ref) => {
                // A tick with a command for any actuator, counted once.
                if t != counted_at {
                    counted_at = t;
                    commanded_ticks += 1;
                }
                Setpoint { f_ref, ..scheduled }
            }
            None => scheduled,
        }
    };
    let mut sink = NodeSink::new(&node, dt, joints.len());
    let result = scene.run_referenced(0, &mut reference, &mut sink, Some(&stop))?;
    let report = sink.report();
    drop(sink);
    let received = (commands.received, commands.refused);
    drop(node);

    let runs = [result];
    scene.write_results(stage.path(), &runs)?;
    let manifest = Manifest::new("ros2", env!("CARGO_PKG_VERSION"), scene.input_digests());
    let r = &runs[0];
    let time_reached_s = r.trace.t().last().copied().unwrap_or(0.0);
    outln!(
        "{} ticks to t = {time_reached_s:.3} s; {report}; joint commands: {} received, {} refused, in force at {} \
         ticks",
        r.trace.len(),
        received.0,
        received.1,
        commanded_ticks
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
    super::fail_on_divergence([(r.name.as_str(), r.diverged.as_deref())], &dest)
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

/// The node's side of the loop: at each row, waits for the tick's time on the wall clock, then publishes
/// the tick; keeps how late the ticks were.
struct NodeSink<'a> {
    node: &'a RosNode,
    clock: WallClock,
    dt: f64,
    columns: Vec<Columns>,
    position: Vec<f64>,
    velocity: Vec<f64>,
    effort: Vec<f64>,
    pressures: Vec<[f64; 2]>,
    force_reference: Vec<f64>,
    valve_command: Vec<f64>,
    lateness: TimingStats,
    /// Ticks published over half a period after their time.
    late: u64,
    /// The latest publish error, and how many.
    errors: (u64, Option<String>),
}

impl<'a> NodeSink<'a> {
    fn new(node: &'a RosNode, dt: f64, joints: usize) -> Self {
        Self {
            node,
            // Sleeps only: a spinning wait would take a core from the DDS threads and the subscribers.
            clock: WallClock::new(Duration::ZERO),
            dt,
            columns: vec![Columns::default(); joints],
            position: vec![0.0; joints],
            velocity: vec![0.0; joints],
            effort: vec![0.0; joints],
            pressures: vec![[0.0; 2]; joints],
            force_reference: vec![0.0; joints],
            valve_command: vec![0.0; joints],
            lateness: TimingStats::default(),
            late: 0,
            errors: (0, None),
        }
    }

    /// The timing in words.
    fn report(&self) -> String {
        let p = self.lateness.percentiles();
        let mut s = format!(
            "publish after the tick's time: median {:.0} µs, p99 {:.0} µs, max {:.1} ms; {} late ticks (over half a \
             period)",
            1e6 * p.p50,
            1e6 * p.p99,
            1e3 * p.max,
            self.late
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

impl Sink<dyn Plant + '_> for NodeSink<'_> {
    fn begin(&mut self, _run: &str, columns: &[Signal], _world: &(dyn Plant + '_)) {
        let one = self.columns.len() == 1 && !columns.iter().any(|c| c.name.ends_with(".f_e"));
        let find = |actuator: &str, s: &str| {
            let name = if one {
                s.to_string()
            } else {
                format!("{actuator}.{s}")
            };
            columns.iter().position(|c| c.name == name).unwrap_or(0)
        };
        let names: Vec<String> = if one {
            vec![String::new()]
        } else {
            // A plant of several names its columns by actuator, in the order of the joints.
            let mut names = Vec::new();
            for c in columns {
                if let Some(a) = c.name.strip_suffix(".f_e") {
                    names.push(a.to_string());
                }
            }
            names
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
        // The wall clock starts with the first tick.
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
        for (i, c) in self.columns.iter().enumerate() {
            self.position[i] = values[c.x];
            // The trace of a one-actuator plant has no velocity: the plant's own, as it senses it.
            self.velocity[i] = world.sense_actuator(i).x_dot;
            self.effort[i] = values[c.f_e];
            self.pressures[i] = [values[c.p_a], values[c.p_b]];
            self.force_reference[i] = values[c.f_ref];
            self.valve_command[i] = values[c.u];
        }
        let published = self.node.publish(&TickValues {
            t_s: t,
            position: &self.position,
            velocity: &self.velocity,
            effort: &self.effort,
            pressures: &self.pressures,
            force_reference: &self.force_reference,
            valve_command: &self.valve_command,
        });
        if let Err(e) = published {
            self.errors.0 += 1;
            self.errors.1 = Some(e.to_string());
        }
    }
}
