//! `pneuflex rig emulate` and `pneuflex rig run` (`rig excite` is in excite.rs, `rig pil` in pil.rs).

use std::path::Path;
use std::time::Duration;

use anyhow::{anyhow, bail};
use pneuflex_control::{Controller, Setpoint};
use pneuflex_outputs::{RecordingEnd, judge_recording};
use pneuflex_rig::clock::WallClock;
use pneuflex_rig::record;
use pneuflex_rig::rtloop::{LoopReport, check_duration};
use pneuflex_rig::{RigFile, serial, session};
#[cfg(feature = "ros2")]
use pneuflex_ros2::trace_bag::SINGLE_JOINT;

/// `pneuflex rig emulate <rig.toml> [--port <tty>] [--duration <s>]`: runs the rig file's emulated plant in
/// real time behind a new pseudo-terminal (its path is printed) or on a given serial port, until Ctrl-C or
/// `duration_s`. Faults listed in the rig file's `[emulator].faults` are injected.
pub fn emulate(
    rig_file: &Path,
    scene: Option<&Path>,
    port: Option<&str>,
    duration_s: Option<f64>,
    hidden: &super::emulated::Hidden,
) -> anyhow::Result<()> {
    if let Some(d) = duration_s {
        check_duration(d).map_err(|e| anyhow!("--duration: {}", e.message))?;
    }
    // A scene of several actuators: its mechanism is the board's plant (`rig_mechanism`).
    if let Some(scene) = scene {
        return super::rig_mechanism::emulate(rig_file, scene, port, duration_s, hidden);
    }
    let mut rig = RigFile::load(rig_file)?;
    if let Some(truth) = &hidden.truth {
        session::hide_truth(&mut rig, rig_file, truth, hidden.seed, hidden.delay_s)?;
    } else if hidden.seed.is_some() || hidden.delay_s.is_some() {
        bail!("--seed and --delay apply to a hidden truth: give --truth <actuator-sheet.toml>");
    }
    let handle = match port {
        Some(p) => session::spawn_port_emulator(&rig, rig_file, p)?,
        None => session::spawn_pty_emulator(&rig, rig_file)?,
    };
    super::emulated::serve(handle, &rig.name, port, duration_s)
}

/// `pneuflex rig run --rig <rig.toml> [--port <tty>] --scene <scene.toml> [--out DIR]`: runs `controller`
/// against the reference on the rig (real or emulated) for `duration_s`, writing `out_dir/trace.csv` and
/// its manifest. The rig is connected before anything is written; the output is staged beside `out_dir`
/// and renamed into place (crates/rig `record`). SIGINT, SIGTERM, SIGHUP, any rig fault, a controller panic
/// or NaN puts the valve in its safe state and ends the run `loop.post_fault_s` later. Returns the loop
/// report; an error (non-zero exit) if the run ended on a fault or a signal (then the output is committed
/// as `<out_dir>.partial`).
#[allow(clippy::too_many_arguments)]
pub fn run(
    command: &'static str,
    rig_file: &Path,
    port: Option<&str>,
    scene: Option<&Path>,
    controller: &mut dyn Controller,
    reference: &mut dyn FnMut(f64) -> Setpoint,
    duration_s: f64,
    out_dir: &Path,
    observer: &mut dyn pneuflex_control::Sink<()>,
    finish: record::Finish<'_>,
) -> anyhow::Result<LoopReport> {
    check_duration(duration_s).map_err(|e| anyhow!("--duration: {}", e.message))?;
    let rig = RigFile::load(rig_file)?;
    let stop = session::install_ctrl_c()?;
    let mut inputs = vec![(rig_file, "rig")];
    if let Some(s) = scene {
        inputs.push((s, "scene"));
    }
    outln!(
        "running on `{}` at {} Hz for {duration_s} s; output: {}",
        port.unwrap_or(&rig.link.port),
        rig.rt.rate_hz,
        out_dir.display()
    );
    let mut clock = WallClock::new(Duration::from_micros(rig.rt.spin_us));
    let rec = record::record_observed(
        command,
        &rig,
        || serial::connect(&rig, rig_file, port),
        out_dir,
        &inputs,
        controller,
        reference,
        duration_s,
        &stop,
        &mut clock,
        observer,
        finish,
    )?;
    super::recording::finished(&rec)?;
    Ok(rec.report)
}

/// `pneuflex rig run --scene <scene.toml>`: the controller and reference of one of the scene's runs (by name,
/// or the first) on the rig, for the scene's duration unless `duration_s` is given. Output in
/// `out/rig/<scene>/<run>/` unless `out` is given.
#[allow(clippy::too_many_arguments)]
pub fn run_scene(
    rig_file: &Path,
    port: Option<&str>,
    lockstep: Option<(&Path, u64)>,
    truths: &[String],
    scene_path: &Path,
    run_name: Option<&str>,
    duration_s: Option<f64>,
    out: Option<&Path>,
    rerun: Option<&[String]>,
    figures: pneuflex_viz::Format,
    mcap: bool,
    ros2: Option<&super::ros2::NodeOptions>,
) -> anyhow::Result<()> {
    // A scene of several actuators: the board's channels through the one loop (`rig_mechanism`).
    if pneuflex_files::read_text(scene_path, pneuflex_files::InputKind::Scene)
        .is_ok_and(|t| pneuflex_scene::mechanism::MechanismScene::is_mechanism(&t))
    {
        if ros2.is_some() {
            bail!("--ros2: a scene with several actuators on a board is not bridged to ROS 2 yet");
        }
        if let Some(words) = rerun {
            bail!(
                "--rerun {}: a scene with several actuators on a board shows no live view yet",
                words.join(" ")
            );
        }
        return super::rig_mechanism::run(
            rig_file, port, lockstep, truths, scene_path, run_name, duration_s, out, figures, mcap,
        );
    }
    if let Some(t) = truths.first() {
        bail!(
            "--truth {t}: names an actuator's truth on a scene of several actuators; this scene has one"
        );
    }
    if let Some(d) = duration_s {
        check_duration(d).map_err(|e| anyhow!("--duration: {}", e.message))?;
    }
    let rig = RigFile::load(rig_file)?;
    let scene = pneuflex_scene::Scene::load(scene_path)?;
    session::check_scene_rate(scene.dt_s, scene_path, &rig, rig_file)?;
    let index = match run_name {
        None => 0,
        Some(name) => scene.run_index(name)?,
    };
    let mut controller = scene.controller(index)?;
    let setpoints = scene.setpoints()?;
    #[cfg(not(feature = "ros2"))]
    if ros2.is_some() {
        bail!("--ros2: this pneuflex was built without the `ros2` feature (a default one)");
    }
    #[cfg(feature = "ros2")]
    if let Some(o) = ros2 {
        super::ros2::Bridge::check(o)?;
        if lockstep.is_some() {
            bail!("--ros2: bridges a real-time run; a --lockstep-truth run is not one");
        }
    }
    let out_dir = match out {
        Some(dir) => dir.to_path_buf(),
        // A recording is never replaced: a second one goes beside the first (`<run>-2`, ...).
        None => pneuflex_files::output::fresh_destination(
            &Path::new("out")
                .join("rig")
                .join(&scene.name)
                .join(&scene.runs[index].name),
        ),
    };
    let duration = match duration_s {
        Some(d) => d,
        None => {
            let d = scene.duration_s;
            check_duration(d)
                .map_err(|e| anyhow!("{}: `duration_s`: {}", scene_path.display(), e.message))?;
            d
        }
    };
    // The live view: the same entity paths as `run`, on the wall clock; checked before the rig is touched.
    let pwm_period_s = pneuflex_scene::build_plant(&scene)?.pwm_period_s();
    let mut live = super::live::LiveSink::parse(rerun, "rig run")?.view(
        &format!("rig/{}/{}", scene.name, scene.runs[index].name),
        &scene.runs[index].name,
        1,
        super::live::Timeline::Wall,
        scene.dt_s,
        pwm_period_s,
    )?;
    // The recording judged as the scene's run (summary.json, figures) before it is committed.
    let mut analyse = |dir: &Path, report: &LoopReport| {
        let end = match &report.fault {
            None => RecordingEnd::Complete,
            Some(f) => {
                let why = format!(
                    "the rig run ended on a fault: {}: {} (tick {})",
                    f.kind, f.message, f.tick
                );
                if f.kind == pneuflex_rig::ErrorKind::Interrupted {
                    RecordingEnd::Interrupted(why)
                } else {
                    RecordingEnd::Fault(why)
                }
            }
        };
        // `--mcap`: the bag first, removed again if the judging fails (this leaves no file of its own then).
        if mcap {
            super::bag::write_recording(dir)?;
        }
        let judged =
            judge_recording(dir, &scene, index, end, pwm_period_s, figures).map_err(|e| {
                let _ = std::fs::remove_dir_all(dir.join(super::bag::BAG_DIR));
                e.to_string()
            })?;
        // The host's timing, said apart from the plant's verdict (summary.json `rig`).
        if let Some(rig) = &judged.rig {
            match &rig.host_stalls {
                Some(s) if s.count > 0 => errln!(
                    "host: {} stalls of the loop (a tick starting over half a period late), the longest \
                     {:.1} ms at t = {:.3} s; {} ticks late",
                    s.count,
                    1e3 * s.longest_s,
                    s.longest.first().map_or(0.0, |l| l.at_s),
                    s.late_ticks
                ),
                Some(_) => errln!("host: no stalls of the loop"),
                None => {}
            }
            if judged.windows_judged {
                errln!("judged on {}", rig.note);
            }
        }
        for v in &judged.host_verdicts {
            errln!("note: {v}");
        }
        Ok(())
    };
    if let Some((truth, seed)) = lockstep {
        if rerun.is_some() {
            bail!("--rerun: shows a real-time run; a --lockstep-truth run is not one");
        }
        let mut reference = |t: f64| setpoints.at(t);
        return super::recording::record_lockstep(
            record::COMMAND,
            rig_file,
            truth,
            seed,
            &out_dir,
            &[(rig_file, "rig"), (scene_path, "scene")],
            controller.as_mut(),
            &mut reference,
            duration,
            &mut analyse,
        );
    }
    // `--ros2`: the node beside the loop, joined before the rig is connected; the commanded force replaces
    // the scene's reference while commands arrive, and every traced row is published.
    #[cfg(feature = "ros2")]
    let bridge = match ros2 {
        Some(o) => {
            let b = super::ros2::Bridge::start(o, vec![SINGLE_JOINT.to_string()], true)?;
            outln!("{}: bridging the rig run", b.banner());
            Some(b)
        }
        None => None,
    };
    #[cfg(feature = "ros2")]
    let mut reference = |t: f64| match &bridge {
        Some(b) => b.reference(0, t, setpoints.at(t)),
        None => setpoints.at(t),
    };
    #[cfg(not(feature = "ros2"))]
    let mut reference = |t: f64| setpoints.at(t);
    #[cfg(feature = "ros2")]
    let mut publisher = bridge.as_ref().map(super::ros2::Bridge::publisher);
    #[cfg(feature = "ros2")]
    let mut both;
    #[cfg(feature = "ros2")]
    let observer: &mut dyn pneuflex_control::Sink<()> = match publisher.as_mut() {
        Some(p) => {
            both = Both(live.observer(), p);
            &mut both
        }
        None => live.observer(),
    };
    #[cfg(not(feature = "ros2"))]
    let observer = live.observer();
    let result = run(
        record::COMMAND,
        rig_file,
        port,
        Some(scene_path),
        controller.as_mut(),
        &mut reference,
        duration,
        &out_dir,
        observer,
        &mut analyse,
    )
    .map(|_| ());
    #[cfg(feature = "ros2")]
    if let Some(b) = &bridge {
        let what = publisher.as_ref().map(|p| p.report()).unwrap_or_default();
        errln!("ros2: {}{what}", b.commands_report());
    }
    // The recording is safe on disk whatever the view did: a logging error is a warning.
    match live.finish() {
        Ok(Some(rows)) => errln!("rerun: {rows} ticks logged"),
        Ok(None) => {}
        Err(e) => errln!("warning: the Rerun view is incomplete: {e:#}"),
    }
    result
}

/// Two sinks of the rig's rows, each called in turn (the live view and the ROS 2 node).
#[cfg(feature = "ros2")]
struct Both<'a, 'b>(
    &'a mut dyn pneuflex_control::Sink<()>,
    &'b mut dyn pneuflex_control::Sink<()>,
);

#[cfg(feature = "ros2")]
impl pneuflex_control::Sink<()> for Both<'_, '_> {
    fn begin(&mut self, run: &str, columns: &[pneuflex_control::Signal], world: &()) {
        self.0.begin(run, columns, world);
        self.1.begin(run, columns, world);
    }
    fn row(&mut self, values: &[f64], world: &()) {
        self.0.row(values, world);
        self.1.row(values, world);
    }
    fn event(&mut self, t_s: f64, text: &str) {
        self.0.event(t_s, text);
        self.1.event(t_s, text);
    }
    fn end(&mut self, why: Option<&str>) {
        self.0.end(why);
        self.1.end(why);
    }
}
