//! Issues 12 and 24: one sink trait for every loop. The same `Sink` watches a run of the
//! scene runner (simulation) and a run of the rig's real-time loop (against the emulator, on a simulated
//! clock): both announce the same declared columns — the loop's, then the controller's (g, p, d for the
//! adaptive run) — and hand it one row per tick in that order.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use pneuflex::control::{Signal, Sink};
use pneuflex::rig::trace::TraceWriter;
use pneuflex::rig::{RigFile, rtloop, session};
use pneuflex::scene::{Scene, run_scene_observed};

#[derive(Default)]
struct Collect {
    columns: Vec<&'static str>,
    rows: Vec<Vec<f64>>,
    events: Vec<(f64, String)>,
    ended: usize,
}

/// A sink of rows: it watches any host, whatever the host shows of its world.
impl<W: ?Sized> Sink<W> for Collect {
    fn begin(&mut self, _run: &str, columns: &[Signal], _world: &W) {
        self.columns = columns.iter().map(|s| s.name).collect();
        self.rows.clear();
    }
    fn row(&mut self, values: &[f64], _world: &W) {
        assert_eq!(
            values.len(),
            self.columns.len(),
            "a row has one value per column"
        );
        self.rows.push(values.to_vec());
    }
    fn event(&mut self, t_s: f64, text: &str) {
        self.events.push((t_s, text.to_owned()));
    }
    fn end(&mut self, _why: Option<&str>) {
        self.ended += 1;
    }
}

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

#[test]
fn the_same_row_observer_watches_a_simulated_run_and_a_rig_run() {
    // Simulation: the adaptive run of paper-fig3 on the 1-DOF plant, shortened.
    let mut scene = Scene::load(&repo("scenes/paper-fig3.toml")).unwrap();
    scene.duration_s = 0.5;
    scene.metrics.clear();
    scene.claims.clear();
    scene.events.clear();
    scene.runs.retain(|r| r.name == "adaptive");
    let mut sim = Collect::default();
    let res = run_scene_observed(&scene, &mut |_| {}, &mut sim).unwrap();
    assert_eq!(sim.rows.len(), res[0].trace.len());
    assert_eq!(sim.ended, 1);

    // The rig: the same controller and references on the emulated board, stepped in lockstep.
    let (real, report, mut trace) = lockstep_rig_run(&scene, false);
    assert_eq!(real.rows.len() as u64, report.ticks);
    assert_eq!(real.ended, 1);

    // The same columns, declared once: the loop's, then the controller's; the simulated plant adds its
    // valve spool after them, the rig its link's quality.
    let loop_and_controller = [
        "t", "f_ref", "f_e", "x", "x_r", "p_a", "p_b", "u", "g", "p", "d",
    ];
    assert_eq!(
        &real.columns[..loop_and_controller.len()],
        loop_and_controller
    );
    assert_eq!(
        &real.columns[loop_and_controller.len()..],
        ["frames", "crc_errors", "seq_gaps", "period_error"]
    );
    // The link counted every sample the loop read (one per tick at the board's rate), with no CRC
    // error and no gap on the clean lockstep link.
    let last = real.rows.last().unwrap();
    let n = loop_and_controller.len();
    assert!(
        last[n] >= report.ticks as f64 - report.ticks_without_sample as f64,
        "{last:?}"
    );
    assert_eq!((last[n + 1], last[n + 2]), (0.0, 0.0));
    // The trace holds the loop's and the controller's columns only.
    let text = String::from_utf8(trace.get_mut().clone()).unwrap();
    let header = pneuflex::rig::trace::header_line(&text).unwrap();
    assert!(!header.contains("crc_errors"), "{header}");
    assert_eq!(
        &sim.columns[..loop_and_controller.len()],
        loop_and_controller
    );
    // Both start at t = 0 with the same reference.
    assert_eq!(real.rows[0][0], 0.0);
    assert_eq!(sim.rows[0][0], 0.0);
    assert_eq!(real.rows[0][1], sim.rows[0][1]);
}

/// A rig fault reaches the observers as an event (the live view's event log) at the tick it latched, and
/// the rows go on with the valve safe.
#[test]
fn a_rig_fault_is_an_event_for_the_observers() {
    let scene = Scene::load(&repo("scenes/paper-fig3.toml")).unwrap();
    // A signal before the first tick.
    let (seen, report, _) = lockstep_rig_run(&scene, true);
    let fault = report.fault.expect("the signal latches a fault");
    assert_eq!(fault.tick, 0);
    assert_eq!(seen.events.len(), 1, "{:?}", seen.events);
    let (t, text) = &seen.events[0];
    assert_eq!(*t, 0.0);
    assert!(
        text.contains("fault at tick 0") && text.contains("safe state"),
        "{text}"
    );
    // The loop ran on for post_fault_s with the valve safe, and every row reached the observer.
    assert_eq!(seen.rows.len() as u64, report.ticks);
    assert!(report.ticks > 1);
}

/// The scene's first run for 0.5 s on the emulated board stepped in lockstep, watched by a [`Collect`];
/// `stopped`: a signal arrived before the first tick.
fn lockstep_rig_run(
    scene: &Scene,
    stopped: bool,
) -> (Collect, rtloop::LoopReport, TraceWriter<Vec<u8>>) {
    let rig_file = repo("rigs/emulated.toml");
    let rig = RigFile::load(&rig_file).unwrap();
    let session::LockstepRig {
        rig: mut sup,
        mut clock,
        ..
    } = session::lockstep_rig(&rig, &rig_file).unwrap();
    let mut controller = scene.controller(0).unwrap();
    let setpoints = scene.setpoints().unwrap();
    let mut reference = |t: f64| setpoints.at(t);
    let mut trace = TraceWriter::new(Vec::new(), rig.rt.trace_flush_every).unwrap();
    let opts = session::run_options(&rig, 0.5);
    let stop = AtomicBool::new(stopped);
    let mut seen = Collect::default();
    let report = rtloop::run_observed(
        &mut sup,
        controller.as_mut(),
        &mut reference,
        &mut trace,
        &opts,
        &stop,
        &mut clock,
        &mut seen,
    )
    .unwrap();
    (seen, report, trace)
}
