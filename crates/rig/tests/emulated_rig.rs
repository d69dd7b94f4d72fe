//! End to end: the controller drives the emulated rig through the serial protocol, the supervisor and the
//! trace; each injected fault puts the valve in its safe state and is latched.
//!
//! The emulator runs in lockstep with a simulated clock (`session::lockstep_emulator`, `SimClock`): the
//! board steps exactly once per sample period of the loop's clock, so the results do not depend on how fast
//! the machine is or how loaded it is. One test runs over a real pseudo-terminal on the wall clock, with
//! assertions that hold whatever the scheduling.

mod common;

use std::io;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use pneuflex_control::{
    Controller, ImpedanceController, Sensors, Setpoint, Telemetry, ValveCommand,
};
use pneuflex_rig::emulator::EmulatorLog;
use pneuflex_rig::plant::{EmulatedPlant, Environment, ValveDrive};
use pneuflex_rig::protocol::ValveMode;
use pneuflex_rig::rigfile::InjectedFault;
use pneuflex_rig::rtloop::{self, LoopReport};
use pneuflex_rig::trace::{self, TraceSink, TraceWriter};
use pneuflex_rig::{ErrorKind, RigFile, serial, session};

use common::FullDisk;

/// The emulated rig with its shipped watchdog times (20 ms timeout, 50 ms stale, 50 ms board watchdog):
/// in lockstep nothing is ever late, so the tests need no allowance for a loaded machine.
fn rig_with(faults: Vec<InjectedFault>, change_at_s: Option<f64>) -> RigFile {
    let mut rig = RigFile::load(&common::rig_path()).expect("rigs/emulated.toml loads");
    rig.rt.post_fault_s = 0.05;
    let e = rig.emulator.as_mut().unwrap();
    e.faults = faults;
    e.environment.as_mut().unwrap().change_at_s = change_at_s;
    rig
}

const X_D: f64 = 0.02;
const F_REF: f64 = 10.0;

fn setpoint(_t: f64) -> Setpoint {
    Setpoint {
        f_ref: F_REF,
        x_d: X_D,
    }
}

struct Run {
    report: LoopReport,
    rows: Vec<Vec<String>>,
    log: EmulatorLog,
    end: Option<String>,
}

/// Column of the fault field in these tests' traces (t … u, then the rig's own columns, fault last).
const FAULT: usize = 8 + pneuflex_files::output::RIG_TRACE_COLUMNS.len() - 1;

/// Parses a trace: data rows split into fields, and the end marker's text.
fn parse_trace(text: &str) -> (Vec<Vec<String>>, Option<String>) {
    let mut lines = text.lines().filter(|l| !l.starts_with("# pneuflex"));
    // The impedance controller records no signals of its own: the loop's columns, wall_time, fault.
    assert_eq!(lines.next(), Some(trace::header_for(&[]).as_str()));
    let (rows, end) = trace::data_lines(text);
    (
        rows.iter()
            .map(|l| l.split(',').map(str::to_string).collect())
            .collect(),
        end.map(str::to_string),
    )
}

/// Runs `ctrl` for `duration_s` against the lockstep emulator; `stop_at_s` sets the stop flag (as the
/// signal handler does) from the loop's own time, so the interrupt lands on a known tick.
fn run_lockstep<C: Controller>(
    rig: &RigFile,
    ctrl: &mut C,
    duration_s: f64,
    stop_at_s: Option<f64>,
) -> Run {
    let mut out = Vec::new();
    let (res, log) = run_lockstep_into(rig, ctrl, duration_s, stop_at_s, &mut out);
    let report = res.expect("the loop runs");
    let (rows, end) = parse_trace(&String::from_utf8(out).unwrap());
    Run {
        report,
        rows,
        log,
        end,
    }
}

fn run_lockstep_into<C: Controller, W: TraceSink>(
    rig: &RigFile,
    ctrl: &mut C,
    duration_s: f64,
    stop_at_s: Option<f64>,
    sink: W,
) -> (io::Result<LoopReport>, EmulatorLog) {
    let file = common::rig_path();
    let mut lockstep = session::lockstep_rig(rig, &file).expect("the emulator connects");
    let stop = AtomicBool::new(false);
    let mut reference = |t: f64| {
        if stop_at_s.is_some_and(|s| t >= s - 1e-9) {
            stop.store(true, Ordering::Relaxed);
        }
        setpoint(t)
    };
    let res = {
        let mut trace = TraceWriter::create(sink, rig.rt.trace_flush_every, "mem/trace.csv", &[])
            .expect("header");
        let opts = session::run_options(rig, duration_s);
        lockstep.run(ctrl, &mut reference, &mut trace, &opts, &stop)
    };
    // The supervisor parks the valve; the lockstep link lets the board take in the last frames.
    drop(lockstep.rig);
    let log = lockstep.log.lock().unwrap().clone();
    (res, log)
}

fn col(rows: &[Vec<String>], i: usize) -> Vec<f64> {
    rows.iter().map(|r| r[i].parse().unwrap()).collect()
}

/// The same plant and controller without the serial link: ideal sensors, no latency, no quantisation.
fn simulate(rig: &RigFile, duration_s: f64) -> Vec<(f64, f64)> {
    let file = common::rig_path();
    let mut plant = session::emulated_plant(rig, &file).unwrap();
    let e = rig.emulator.as_ref().unwrap();
    let env = Environment::from_config(e.environment.as_ref().unwrap());
    let mut ctrl = common::paper_controller();
    let dt = rig.dt();
    let sub = (dt / e.plant_dt_s).round() as usize;
    let h = dt / sub as f64;
    let mut out = Vec::new();
    for k in 0..(duration_s / dt).round() as usize {
        let t = k as f64 * dt;
        let s = plant.sample();
        let f_e = env.force(t, s.x);
        out.push((t, f_e));
        let sensors = Sensors {
            t,
            x: s.x,
            x_dot: s.x_dot,
            f_e,
            p_a: s.p_a,
            p_b: s.p_b,
        };
        let u = ctrl.update(&sensors, &setpoint(t), dt).u;
        for i in 0..sub {
            let ts = t + i as f64 * h;
            let f = env.force(ts, plant.sample().x);
            plant.step(ValveDrive::Run(u), -f, h);
        }
    }
    out
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    (s / n.max(1) as f64).sqrt()
}

#[test]
fn force_tracks_reference_through_wood_to_iron() {
    // Wood (700 N/m) for 1.5 s, then iron (1400 N/m); 3 s in all.
    let duration = 3.0;
    let rig = rig_with(vec![], Some(1.5));
    let mut ctrl = common::paper_controller();
    let run = run_lockstep(&rig, &mut ctrl, duration, None);
    assert!(
        run.report.fault.is_none(),
        "unexpected fault: {}",
        run.report
    );
    let n = (duration * rig.rt.rate_hz).round() as usize;
    assert_eq!(run.rows.len(), n, "one trace row per tick");
    assert_eq!(run.end, Some(format!("complete, {n} rows")));
    // Lockstep: a new sample every tick but tick 0, which uses the one the loop waited for.
    assert_eq!(run.report.ticks_without_sample, 1);
    let t = col(&run.rows, 0);
    let f_e = col(&run.rows, 2);
    let sim = simulate(&rig, duration);
    // Tracking error RMS over the settled part of each environment: wood 0.8–1.5 s, iron 2.3–3.0 s.
    let window = |a: f64, b: f64, f: &[f64]| {
        rms(t
            .iter()
            .zip(f)
            .filter(|(t, _)| **t >= a && **t < b)
            .map(|(_, f)| f - F_REF))
    };
    let sim_f: Vec<f64> = sim.iter().map(|s| s.1).collect();
    let (rig_wood, rig_iron) = (window(0.8, 1.5, &f_e), window(2.3, 3.0, &f_e));
    let (sim_wood, sim_iron) = (window(0.8, 1.5, &sim_f), window(2.3, 3.0, &sim_f));
    eprintln!(
        "RMS(f_e - f_ref): rig wood {rig_wood:.3} N, iron {rig_iron:.3} N; simulation wood {sim_wood:.3} N, iron {sim_iron:.3} N"
    );
    eprintln!("{}", run.report);
    // Tolerance (docs/rig.md): the simulation's own tracking error plus what the link adds — load-cell
    // quantisation and noise (0.2 mN/count, negligible), one sample of latency, the velocity from quantised
    // position — bounded by 0.5 N RMS, i.e. 5 % of the 10 N level. In lockstep the run is deterministic.
    assert!(
        rig_wood <= sim_wood + 0.5,
        "wood: rig {rig_wood} vs simulation {sim_wood}"
    );
    assert!(
        rig_iron <= sim_iron + 0.5,
        "iron: rig {rig_iron} vs simulation {sim_iron}"
    );
    // And both settle on the reference on average (the RMS above is mostly the 40 Hz PWM ripple, which
    // doubles with the stiffness): the tolerance is not a free pass.
    let mean = |a: f64, b: f64, f: &[f64]| {
        let v: Vec<f64> = t
            .iter()
            .zip(f)
            .filter(|(t, _)| **t >= a && **t < b)
            .map(|(_, f)| *f)
            .collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    for (name, f) in [("rig", &f_e), ("simulation", &sim_f)] {
        for (a, b) in [(0.8, 1.5), (2.3, 3.0)] {
            let m = mean(a, b, f);
            eprintln!("{name} mean f_e over [{a}, {b}) s: {m:.3} N");
            assert!(
                (m - F_REF).abs() < 1.0,
                "{name} mean f_e {m} over [{a}, {b})"
            );
        }
    }
}

/// Checks the common fault contract and returns the fault tick.
fn check_fault(run: &Run, kind: ErrorKind, dt: f64, check_valve: bool) -> usize {
    let f = run
        .report
        .fault
        .as_ref()
        .unwrap_or_else(|| panic!("expected a {kind} fault; {}", run.report));
    assert_eq!(f.kind, kind, "{}", f.message);
    let kf = f.tick as usize;
    // The trace holds every tick up to and including the fault, at t = k·dt, none missing.
    assert!(
        run.rows.len() > kf,
        "trace has {} rows, fault at {kf}",
        run.rows.len()
    );
    for (k, r) in run.rows.iter().enumerate().take(kf + 1) {
        let t: f64 = r[0].parse().unwrap();
        assert!((t - k as f64 * dt).abs() < 1e-9, "row {k} has t = {t}");
        let healthy = r[FAULT].is_empty();
        assert_eq!(healthy, k < kf, "row {k}: fault column `{}`", r[FAULT]);
    }
    // Latched: every row after the fault still says so, and the host commands u = 0 (safe).
    for r in &run.rows[kf..] {
        assert!(
            r[FAULT].starts_with(kind.name()),
            "latched fault column `{}`",
            r[FAULT]
        );
        assert_eq!(r[7], "0");
    }
    if check_valve {
        // The board received the safe state for tick kf or kf + 1 (within 2 ticks), and nothing else after.
        let after: Vec<_> = run
            .log
            .commands
            .iter()
            .filter(|c| c.tick as usize >= kf)
            .collect();
        let first = after
            .first()
            .expect("the board received commands after the fault");
        assert!(
            first.tick as usize <= kf + 1,
            "first command after the fault is for tick {}",
            first.tick
        );
        assert!(
            after.iter().all(|c| c.mode == ValveMode::SafeVent),
            "all commands from tick {kf} on are safe"
        );
        // Healthy commands before the fault were Run.
        assert!(
            run.log
                .commands
                .iter()
                .filter(|c| (c.tick as usize) < kf)
                .all(|c| c.mode == ValveMode::Run)
        );
    }
    kf
}

/// Runs 1 s with `fault` injected at 0.3 s; returns the fault tick.
fn fault_run(fault: InjectedFault, kind: ErrorKind) -> usize {
    let mut rig = rig_with(vec![fault], None);
    if let InjectedFault::Stall { at_s, for_s } = fault {
        // Keep the host running until the board wakes up and takes in the safe commands.
        rig.rt.post_fault_s = at_s + for_s - 0.3 + 0.1;
    }
    let mut ctrl = common::paper_controller();
    let run = run_lockstep(&rig, &mut ctrl, 1.0, None);
    let check_valve = !matches!(fault, InjectedFault::CloseLink { .. });
    let kf = check_fault(&run, kind, rig.dt(), check_valve);
    // Detected after the injection (experiment time starts with the first Run command, at tick 0).
    let f = run.report.fault.as_ref().unwrap();
    assert!(
        f.host_time_s >= 0.3 - 0.002,
        "fault at host time {} s",
        f.host_time_s
    );
    assert_eq!(
        run.end,
        Some(format!("fault {}, {} rows", kind.name(), run.rows.len()))
    );
    kf
}

#[test]
fn dropped_frames_trip_the_watchdog() {
    // Last sample at 0.3 s; no sample for more than timeout_ms = 20 ms: tripped at 0.321 s.
    let kf = fault_run(InjectedFault::DropFrames { at_s: 0.3 }, ErrorKind::Timeout);
    assert!((320..=322).contains(&kf), "fault tick {kf}");
}

#[test]
fn corrupted_crcs_trip_the_crc_threshold() {
    fault_run(InjectedFault::CorruptCrc { at_s: 0.3 }, ErrorKind::Crc);
}

#[test]
fn a_stalled_board_trips_the_watchdog() {
    // 250 ms of silence: longer than the 20 ms watchdog.
    fault_run(
        InjectedFault::Stall {
            at_s: 0.3,
            for_s: 0.25,
        },
        ErrorKind::Timeout,
    );
}

#[test]
fn a_stuck_sensor_is_stale() {
    fault_run(InjectedFault::StuckSensor { at_s: 0.3 }, ErrorKind::Stale);
}

#[test]
fn supply_loss_trips_the_supply_limit() {
    fault_run(InjectedFault::SupplyLoss { at_s: 0.3 }, ErrorKind::Limit);
}

#[test]
fn a_closed_link_is_link_lost() {
    fault_run(InjectedFault::CloseLink { at_s: 0.3 }, ErrorKind::LinkLost);
}

/// The controller of the other tests, misbehaving from 0.3 s on.
struct Misbehaving {
    inner: ImpedanceController,
    panic: bool,
}

impl Controller for Misbehaving {
    fn update(&mut self, s: &Sensors, sp: &Setpoint, dt: f64) -> ValveCommand {
        if s.t >= 0.3 {
            if self.panic {
                panic!("injected controller panic");
            }
            return ValveCommand { u: f64::NAN };
        }
        self.inner.update(s, sp, dt)
    }
    fn telemetry(&self) -> Telemetry {
        self.inner.telemetry()
    }
    fn reset(&mut self) {
        self.inner.reset()
    }
}

#[test]
fn a_nan_command_and_a_controller_panic_go_safe() {
    for (panic, kind) in [(false, ErrorKind::NotANumber), (true, ErrorKind::Panic)] {
        let rig = rig_with(vec![], None);
        let mut ctrl = Misbehaving {
            inner: common::paper_controller(),
            panic,
        };
        let run = run_lockstep(&rig, &mut ctrl, 1.0, None);
        let kf = check_fault(&run, kind, rig.dt(), true);
        assert_eq!(kf, 300, "the misbehaving update is caught in its own tick");
    }
}

#[test]
fn a_stop_signal_and_a_crossed_limit_go_safe() {
    // The signal handler's flag, set at t = 0.4 s (tick 400): the loop sees it at the start of tick 401 and
    // commands the safe state in that tick.
    let rig = rig_with(vec![], None);
    let mut ctrl = common::paper_controller();
    let run = run_lockstep(&rig, &mut ctrl, 1.5, Some(0.4));
    let kf = check_fault(&run, ErrorKind::Interrupted, rig.dt(), true);
    assert_eq!(kf, 401);
    assert_eq!(
        run.end,
        Some(format!("interrupted, {} rows", run.rows.len()))
    );
    assert_eq!(
        run.rows.len(),
        401 + 50 + 1,
        "post_fault_s = 50 ms of rows after the fault row"
    );

    // A position limit inside the travel to the 10 N contact (x ≈ 34 mm at 700 N/m).
    let mut rig = rig_with(vec![], None);
    rig.limits.position_m = [-0.001, 0.025];
    let mut ctrl = common::paper_controller();
    let run = run_lockstep(&rig, &mut ctrl, 2.0, None);
    let kf = check_fault(&run, ErrorKind::Limit, rig.dt(), true);
    let x = col(&run.rows, 3);
    assert!(
        x[kf - 1] <= 0.025,
        "the last healthy sample was inside the limit"
    );
}

#[test]
fn a_full_disk_goes_safe_first_then_names_the_trace_and_leaves_no_half_line() {
    let rig = rig_with(vec![], None);
    let mut ctrl = common::paper_controller();
    let mut disk = FullDisk {
        data: Vec::new(),
        room: 40_000,
    };
    let (res, log) = run_lockstep_into(&rig, &mut ctrl, 2.0, None, &mut disk);
    let e = res.expect_err("the disk fills up");
    assert!(e.to_string().contains("mem/trace.csv"), "{e}");
    assert_eq!(e.kind(), io::ErrorKind::StorageFull);
    let text = String::from_utf8(disk.data).unwrap();
    assert!(text.ends_with('\n'), "no half line");
    let (rows, end) = trace::data_lines(&text);
    assert_eq!(end, None, "a cut trace has no end marker");
    assert!(
        rows.len() >= 100,
        "{} rows before the disk filled",
        rows.len()
    );
    // The failing flush happens in the tick of the row that completes a buffer (every 100 rows), after that
    // tick's Run command: the safe command for the same tick follows it, then only safe ones.
    let first_safe = log
        .commands
        .iter()
        .position(|c| c.mode.is_safe())
        .expect("a safe command reached the board");
    let k = log.commands[first_safe].tick;
    assert_eq!(k as usize % 100, 99, "failed on the flush of rows ..{k}");
    assert!(
        log.commands[..first_safe]
            .iter()
            .all(|c| c.mode == ValveMode::Run)
    );
    assert_eq!(log.commands[first_safe - 1].tick, k);
    assert!(log.commands[first_safe..].iter().all(|c| c.mode.is_safe()));
}

/// The trace writer alone on a full disk (the loop's side is the test above).
#[test]
fn a_full_disk_leaves_no_half_line_and_names_the_file() {
    // Fill at every byte offset of the third flush: the file must always end with a whole row.
    let values: Vec<[f64; 8]> = (0..100)
        .map(|k| [k as f64 * 1e-3, 10.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
        .collect();
    let row = |k: u64| trace::TraceRow {
        values: &values[k as usize],
        ..trace::TraceRow::default()
    };
    for room in 150..400 {
        let mut disk = FullDisk {
            room,
            ..FullDisk::default()
        };
        let mut w = TraceWriter::create(&mut disk, 2, "/data/run/trace.csv", &[]).unwrap();
        w.columns(&[]).unwrap();
        let mut err = None;
        for k in 0..40 {
            if let Err(e) = w.row(&row(k)) {
                err = Some(e);
                break;
            }
        }
        let e = err.expect("the disk fills up");
        assert!(e.to_string().contains("/data/run/trace.csv"), "{e}");
        assert_eq!(e.kind(), io::ErrorKind::StorageFull);
        assert!(
            w.row(&row(99)).is_err(),
            "nothing is written after a failure"
        );
        assert!(w.finish("complete").is_err());
        drop(w);
        let t = String::from_utf8(disk.data.clone()).unwrap();
        assert!(t.ends_with('\n'), "room {room}: half line in {t:?}");
        for l in trace::data_lines(&t).0 {
            assert_eq!(
                l.split(',').count(),
                trace::header_for(&[]).split(',').count()
            );
        }
        assert_eq!(
            trace::data_lines(&t).1,
            None,
            "a cut trace has no end marker"
        );
    }
}

#[test]
fn durations_that_are_not_finite_positive_and_bounded_are_refused() {
    let rig = rig_with(vec![], None);
    for d in [f64::NAN, -1.0, 0.0, 1e10, f64::INFINITY] {
        let mut ctrl = common::paper_controller();
        let (res, log) = run_lockstep_into(&rig, &mut ctrl, d, None, Vec::new());
        let e = res.expect_err("refused");
        assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
        assert!(e.to_string().contains("duration"), "{e}");
        assert!(
            log.commands.iter().all(|c| c.mode.is_safe()),
            "{d}: no Run command was sent"
        );
    }
}

/// The wall-clock path over a real pseudo-terminal: the emulator on its own thread. Only what holds
/// whatever the scheduling is asserted: watchdogs are 1 s, the limits wide (tracking is not tested here),
/// and the stop lands on the tick that sees it.
#[test]
fn over_a_pty_a_stop_goes_safe_and_the_board_gets_only_safe_commands_after() {
    let mut rig = rig_with(vec![], None);
    rig.watchdog.timeout_ms = 1000.0;
    rig.watchdog.stale_ms = 0.0;
    rig.watchdog.board_watchdog_ms = 2000;
    // On the wall clock a late host loop lets the real-time plant overshoot: only the stop may end the run.
    rig.limits.position_m = [-1.0, 1.0];
    rig.limits.force_n = [-1e6, 1e6];
    rig.limits.pressure_pa = [0.0, 1e8];
    rig.limits.supply_min_pa = 0.0;
    let file = common::rig_path();
    let emu = session::spawn_pty_emulator(&rig, &file).expect("emulator starts");
    let port = emu.path.clone().unwrap();
    let serial = serial::connect(&rig, &file, Some(port.to_str().unwrap())).expect("connects");
    let mut sup = session::supervised(serial, &rig);
    let stop = Arc::new(AtomicBool::new(false));
    let mut reference = |t: f64| {
        if t >= 0.2 {
            stop.store(true, Ordering::Relaxed);
        }
        setpoint(t)
    };
    let mut out = Vec::new();
    let report = {
        let mut trace = TraceWriter::new(&mut out, rig.rt.trace_flush_every).unwrap();
        let opts = session::run_options(&rig, 1.0);
        let mut ctrl = common::paper_controller();
        rtloop::run(
            &mut sup,
            &mut ctrl,
            &mut reference,
            &mut trace,
            &opts,
            &stop,
        )
        .unwrap()
    };
    drop(sup);
    let f = report.fault.clone().expect("interrupted");
    assert_eq!(f.kind, ErrorKind::Interrupted, "{}", f.message);
    assert_eq!(f.tick, 201);
    // Wait (wall clock, generously) until the board has read a command from the fault tick on.
    let t0 = Instant::now();
    while !emu.log().commands.iter().any(|c| c.tick as u64 >= f.tick)
        && t0.elapsed() < Duration::from_secs(30)
    {
        std::thread::sleep(Duration::from_millis(10));
    }
    let log = emu.stop();
    let (rows, end) = parse_trace(&String::from_utf8(out).unwrap());
    let run = Run {
        report,
        rows,
        log,
        end,
    };
    check_fault(&run, ErrorKind::Interrupted, rig.dt(), true);
    assert_eq!(
        run.end,
        Some(format!("interrupted, {} rows", run.rows.len()))
    );
}

#[test]
fn an_unopenable_port_names_the_file_and_field() {
    let rig = rig_with(vec![], None);
    let e = serial::connect(&rig, &common::rig_path(), None)
        .err()
        .expect("/dev/null is no serial port");
    let m = e.to_string();
    assert!(
        m.contains("emulated.toml") && m.contains("link.port") && m.contains("/dev/null"),
        "{m}"
    );
    let e = serial::connect(&rig, &common::rig_path(), Some("/dev/ttyNOPE9"))
        .err()
        .unwrap();
    let m = e.to_string();
    assert!(m.contains("--port") && m.contains("/dev/ttyNOPE9"), "{m}");
}
