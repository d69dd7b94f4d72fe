//! PIL for a scene of several actuators (issue 43): one firmware runs one controller per actuator, each on its
//! own channel of the board (docs/protocol.md §5, "Several controllers"), over one link; the scene's mechanism
//! runs on the host in lockstep through the one loop, and the same run is simulated on the host. Each
//! actuator's valve commands, forces and controller signals are compared tick by tick.

use std::cell::RefCell;
use std::path::Path;
use std::rc::Rc;

use pneuflex_control::{Controller, Signal};
use pneuflex_protocol::{Message, ValveMode, ValvePayload};
use pneuflex_scene::RunResult;
use pneuflex_scene::mechanism::plant::loop_events;
use pneuflex_scene::mechanism::{MechanismPlant, MechanismScene, run_all, summarise};
use pneuflex_scene::run::{RunPlan, simulate_run};

use crate::controller::{self, Cost, FirmwareController, await_safe};
use crate::link::{Link, LinkStats};
use crate::{Comparison, PIL_WATCHDOG_MS, PilError, SafePayload, compare_actuator, qemu};

/// The outcome of one PIL run of a scene of several actuators.
pub struct MechanismPilRun {
    /// The run with every controller on the board.
    pub firmware: RunResult,
    /// The same run simulated on the host.
    pub host: RunResult,
    /// Each actuator's name and its comparison (its own columns).
    pub actuators: Vec<(String, Comparison, Cost)>,
    /// Whether every window metric of the two runs' summaries is equal.
    pub metrics_equal: bool,
    /// The link's counters.
    pub link: LinkStats,
    /// Each channel's report when the host parked the valves (the last one's stack high-water mark is the
    /// board's).
    pub ends: Vec<SafePayload>,
}

/// Runs run `index` of `scene` with each actuator's controller on its channel of the firmware `elf`, then the
/// same run on the host, and compares them.
pub fn run_pil_mechanism(
    scene: &MechanismScene,
    index: usize,
    elf: &Path,
    progress: &mut dyn FnMut(f64),
    stop: Option<std::sync::Arc<std::sync::atomic::AtomicUsize>>,
) -> Result<MechanismPilRun, PilError> {
    qemu::check_firmware(elf)?;
    let n = scene.actuators.len();
    if index >= scene.runs.len() {
        return Err(PilError::Setup(format!("no run {index}")));
    }
    let host_controllers = scene.run_controllers(index)?;
    let signals: Vec<&'static [Signal]> = host_controllers.iter().map(|c| c.signals()).collect();
    let schedules = MechanismPlant::new(scene)?.schedules().to_vec();

    let (mut board, stdin, stdout) = qemu::Board::start(elf)?;
    let mut link = Link::new(stdin, stdout);
    link.stop = stop.clone();
    let link = Rc::new(RefCell::new(link));
    for (i, schedule) in schedules.iter().enumerate() {
        let run = scene.actuator_run(index, i);
        let setup = controller::setup_of(&run)?;
        let mut l = link.borrow_mut();
        l.send(&Message::CtrlChannel(i as u8))?;
        controller::start(&mut l, &setup, schedule, scene.dt_s, PIL_WATCHDOG_MS).map_err(|e| {
            match e {
                PilError::Setup(m) => PilError::Setup(format!(
                    "actuator `{}` (channel {i}): {m}",
                    scene.actuators[i].name
                )),
                e => e,
            }
        })?;
    }
    let mut fws: Vec<FirmwareController> = (0..n)
        .map(|i| FirmwareController::on_channel(link.clone(), i as u8, signals[i]))
        .collect();
    let mut plant = MechanismPlant::new(scene)?;
    let events = loop_events(scene);
    let invalid = |key: &str, message: String| scene.invalid(key, message);
    let spec = &scene.runs[index];
    let plan = RunPlan {
        name: &spec.name,
        controller: spec.controller,
        dt_s: scene.dt_s,
        n_steps: scene.n_steps(),
        events: &events,
        divergence: &scene.divergence,
        invalid: &invalid,
    };
    let mut each: Vec<&mut dyn Controller> =
        fws.iter_mut().map(|c| c as &mut dyn Controller).collect();
    let mut firmware = simulate_run(
        &plan,
        &mut plant,
        &mut each,
        &mut |i, t| schedules[i].at(t),
        progress,
        &mut (),
        stop.as_deref(),
    )?;
    drop(each);
    for fw in &mut fws {
        if let Some(e) = fw.error.take() {
            let exited = board
                .exited()
                .map(|s| format!(" (QEMU: {s})"))
                .unwrap_or_default();
            return Err(match e {
                PilError::Link(m) => PilError::Link(format!("{m}{exited}")),
                e => e,
            });
        }
    }
    if firmware.interrupted.is_some() {
        drop(board);
        return Err(PilError::Interrupted(Box::new(firmware)));
    }
    // One safe command reaches every channel addressed; each answers with its Safe frame.
    let ends = {
        let mut l = link.borrow_mut();
        l.send(&Message::Valve(ValvePayload {
            tick: 0,
            duty_q15: 0,
            mode: ValveMode::SafeVent,
        }))?;
        (0..n)
            .map(|_| await_safe(&mut l).map(|(s, _)| s))
            .collect::<Result<Vec<_>, _>>()?
    };
    drop(board);

    let mut one = scene.clone();
    one.runs = vec![spec.clone()];
    let host = run_all(&one, &mut |_| {}, None, &mut ())?
        .pop()
        .ok_or_else(|| PilError::Setup("the host simulation returned no run".into()))?;
    firmware.pwm_period_s = host.pwm_period_s;
    let actuators = scene
        .actuators
        .iter()
        .enumerate()
        .map(|(i, a)| {
            let c = compare_actuator(
                &firmware,
                &host,
                signals[i],
                fws[i].setpoint_mismatches.0,
                &format!("{}.", a.name),
            );
            (a.name.clone(), c, fws[i].cost())
        })
        .collect();
    let (s_fw, s_host) = (
        summarise(&one, std::slice::from_ref(&firmware)),
        summarise(&one, std::slice::from_ref(&host)),
    );
    let metrics_equal = s_fw.runs == s_host.runs;
    let link = link.borrow().stats();
    Ok(MechanismPilRun {
        firmware,
        host,
        actuators,
        metrics_equal,
        link,
        ends,
    })
}
