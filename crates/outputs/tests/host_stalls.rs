//! Host stalls are not the plant's oscillation: a rig recording is judged on the board's own record (its
//! samples on its clock), and the host loop's stalls are counted in `summary.json` `rig`, apart from the
//! plant's verdict. The recordings here are the simulated run of `scenes/paper-fig3.toml` written as a rig
//! trace: the board's record the simulation's samples, the loop's columns perturbed as a stalled host's are
//! (a tick late, then the newest sample read at once and repeated while the loop catches up).

use std::path::{Path, PathBuf};

use pneuflex_outputs::{RecordingEnd, RecordingJudged, judge_recording};
use pneuflex_scene::{RunResult, Scene, run_scene};
use pneuflex_viz::Format;

const DT: f64 = 0.001;
/// The board's clock at the run's first sample (it runs from power-up, not from the run).
const BOARD_T0: f64 = 0.123;
/// The Unix time of tick 0.
const WALL0: f64 = 1_796_000_000.0;

fn scene() -> Scene {
    let p: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paper-fig3.toml");
    Scene::load(&p).unwrap()
}

/// The impedance run of paper-fig3, simulated (the plant the recordings stand for).
fn simulated(scene: &Scene) -> RunResult {
    run_scene(&scene.one_run(0, scene.duration_s), &mut |_| {})
        .unwrap()
        .remove(0)
}

/// What a recording's two records hold, one entry per tick / sample period.
struct Recording {
    /// The loop's contact force column (what the controller saw).
    host_f_e: Vec<f64>,
    /// Each tick's start, s after tick 0's.
    host_start: Vec<f64>,
    /// The board's record: its contact force at each sample period (None: missing from the record).
    board_f_e: Vec<Option<f64>>,
    /// The board's sample times, s on its clock.
    board_t: Vec<f64>,
}

impl Recording {
    /// A host that kept time, and the board's record of the simulation's samples.
    fn clean(sim: &RunResult) -> Self {
        let f = sim.trace.f_e().to_vec();
        let n = f.len();
        Self {
            host_f_e: f.clone(),
            host_start: (0..n).map(|k| k as f64 * DT).collect(),
            board_f_e: f.into_iter().map(Some).collect(),
            board_t: (0..n).map(|k| BOARD_T0 + k as f64 * DT).collect(),
        }
    }

    /// The host stalls `g` periods before tick `k`: tick k starts `g` periods late and reads the newest
    /// sample (k + g); the ticks after it run back to back until the loop is on time again, with no new
    /// sample (they repeat it). The board's record is untouched: the board sampled on.
    fn stall(&mut self, k: usize, g: usize) {
        let newest = self.board_f_e[k + g].unwrap();
        for i in 0..=g {
            // Back to back, 50 µs apart, until the schedule catches up.
            self.host_start[k + i] =
                ((k + g) as f64 * DT + i as f64 * 50e-6).max((k + i) as f64 * DT);
            self.host_f_e[k + i] = newest;
        }
    }

    /// Writes it as `rig run` does (trace schema 2) into `dir/trace.csv`: `sim`'s loop columns with the
    /// host's contact force, the board's record, the ticks' wall times.
    fn write(&self, sim: &RunResult, dir: &Path) {
        let cols = sim.trace.columns();
        let mut out = String::from("# pneuflex 0.1.0, trace schema 2\n");
        let names: Vec<&str> = cols.iter().map(|c| c.name.as_str()).collect();
        out += &names.join(",");
        out +=
            ",board_t,board_x,board_f_e,board_p_a,board_p_b,applied_t,applied_u,wall_time,fault\n";
        let x = sim.trace.x();
        let data: Vec<&[f64]> = cols
            .iter()
            .map(|c| sim.trace.column(&c.name).unwrap())
            .collect();
        for k in 0..sim.trace.len() {
            for (j, c) in cols.iter().enumerate() {
                let v = if c.name == "f_e" {
                    self.host_f_e[k]
                } else {
                    data[j][k]
                };
                if j > 0 {
                    out.push(',');
                }
                out += &format!("{v}");
            }
            match self.board_f_e[k] {
                Some(f) => {
                    out += &format!(",{:.6},{},{f},2e5,2e5", self.board_t[k], x[k]);
                }
                None => out += ",,,,,",
            }
            out += &format!(",{:.6},0.1", self.board_t[k]);
            out += &format!(",{:.6},\n", WALL0 + self.host_start[k]);
        }
        out += &format!("# end: complete, {} rows\n", sim.trace.len());
        std::fs::write(dir.join("trace.csv"), out).unwrap();
    }
}

fn judge(dir: &Path, scene: &Scene, sim: &RunResult) -> RecordingJudged {
    judge_recording(
        dir,
        scene,
        0,
        RecordingEnd::Complete,
        sim.pwm_period_s,
        Format::Png,
    )
    .unwrap()
}

fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}

/// The event window (the stiffness change, 6–10 s) of a summary.
fn event(s: &serde_json::Value) -> &serde_json::Value {
    let w = s["runs"][0]["windows"].as_array().unwrap();
    &w.iter().find(|w| w["kind"] == "event").unwrap()["event"]
}

#[test]
fn a_stalled_host_is_reported_and_not_judged_as_the_plants_oscillation() {
    let scene = scene();
    let sim = simulated(&scene);
    let sim_event = sim.windows.iter().find_map(|w| w.event.clone()).unwrap();
    assert!(sim_event.settled, "the simulated plant settles");
    let mut rec = Recording::clean(&sim);
    // 9 ms stalls every 55 ms from the stiffness change to the end (72 of them; the loaded host had
    // 147 gaps of 4–9 ms): enough for the loop's columns alone to read as an oscillation.
    let stalls: Vec<usize> = (6000..9950).step_by(55).collect();
    for &k in &stalls {
        rec.stall(k, 9);
    }
    let dir = tempfile::tempdir().unwrap();
    rec.write(&sim, dir.path());
    let judged = judge(dir.path(), &scene, &sim);
    let s = summary(dir.path());
    // The plant's verdict is the board's record's: the simulation's own.
    let e = event(&s);
    assert_eq!(e["settled"], true, "{e}");
    assert!(e.get("oscillation").is_none(), "{e}");
    assert_eq!(e["settling_time_s"].as_f64(), sim_event.settling_time_s);
    assert_eq!(s["rig"]["judged_on"], "board");
    // The stalls, counted apart: how many, the longest, when.
    let h = &s["rig"]["host_stalls"];
    assert_eq!(h["count"].as_u64(), Some(stalls.len() as u64), "{h}");
    assert!(
        (h["longest_s"].as_f64().unwrap() - 0.010).abs() < 2e-6,
        "{h}"
    );
    let at = h["longest"][0]["at_s"].as_f64().unwrap();
    assert!(
        stalls.iter().any(|&k| (k as f64 * DT - at).abs() < 1e-9),
        "{at} is not a stalled tick"
    );
    assert!(
        h["late_ticks"].as_u64().unwrap() >= stalls.len() as u64,
        "{h}"
    );
    // The host's own columns would have read an oscillation: the test would fail on them.
    assert_eq!(judged.host_verdicts.len(), 1, "{:?}", judged.host_verdicts);
    let v = &judged.host_verdicts[0];
    assert!(
        v.contains("stiffness_change")
            && v.contains("the loop's own columns read not settled: sustained oscillation")
            && v.contains(&format!("{} stalls", stalls.len())),
        "{v}"
    );
    assert_eq!(s["runs"][0]["warnings"][0].as_str(), Some(v.as_str()));
}

#[test]
fn a_plant_that_oscillates_on_the_boards_record_is_judged_oscillating() {
    let scene = scene();
    let sim = simulated(&scene);
    let mut rec = Recording::clean(&sim);
    // A 9 Hz, 2 N oscillation of the contact force after the stiffness change, in both records, on a host
    // that kept time.
    for k in 6000..rec.board_f_e.len() {
        let w = 2.0 * (std::f64::consts::TAU * 9.0 * k as f64 * DT).sin();
        rec.host_f_e[k] += w;
        rec.board_f_e[k] = rec.board_f_e[k].map(|f| f + w);
    }
    let dir = tempfile::tempdir().unwrap();
    rec.write(&sim, dir.path());
    let judged = judge(dir.path(), &scene, &sim);
    let s = summary(dir.path());
    let e = event(&s);
    assert_eq!(e["settled"], false, "{e}");
    let f = e["oscillation"]["frequency_hz"].as_f64().unwrap();
    assert!((f - 9.0).abs() < 0.5, "{e}");
    assert!(
        e["not_settled"]
            .as_str()
            .unwrap()
            .starts_with("sustained oscillation at "),
        "{e}"
    );
    assert_eq!(s["rig"]["host_stalls"]["count"], 0);
    assert!(
        judged.host_verdicts.is_empty(),
        "{:?}",
        judged.host_verdicts
    );
}

/// Sets the cell of `column` on data row `k` of `dir/trace.csv` to `value`; returns the file's line number.
fn edit_cell(dir: &Path, k: usize, column: &str, value: &str) -> usize {
    let path = dir.join("trace.csv");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let j = lines[1].split(',').position(|c| c == column).unwrap();
    // Line 1 is the comment, line 2 the header: row k is line k + 3, index k + 2.
    let mut cells: Vec<String> = lines[k + 2].split(',').map(String::from).collect();
    cells[j] = value.into();
    lines[k + 2] = cells.join(",");
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    k + 3
}

#[test]
fn sample_periods_missing_from_the_boards_record_are_counted_and_bridged() {
    let scene = scene();
    let sim = simulated(&scene);
    let sim_event = sim.windows.iter().find_map(|w| w.event.clone()).unwrap();
    let mut rec = Recording::clean(&sim);
    for k in [1500, 7001, 7002, 8500] {
        rec.board_f_e[k] = None;
    }
    let dir = tempfile::tempdir().unwrap();
    rec.write(&sim, dir.path());
    let judged = judge(dir.path(), &scene, &sim);
    assert!(judged.windows_judged);
    let s = summary(dir.path());
    assert_eq!(s["rig"]["judged_on"], "board");
    let note = s["rig"]["note"].as_str().unwrap();
    assert!(
        note.contains(&format!("{} sample periods", sim.trace.len()))
            && note.contains("4 missing from it"),
        "{note}"
    );
    let e = event(&s);
    assert_eq!(e["settled"], true, "{e}");
    let ts = e["settling_time_s"].as_f64().unwrap();
    assert!(
        (ts - sim_event.settling_time_s.unwrap()).abs() < 0.01,
        "{ts}"
    );
}

#[test]
fn a_board_record_off_the_loops_grid_is_not_used_and_the_summary_says_why() {
    let scene = scene();
    let sim = simulated(&scene);
    let sim_event = sim.windows.iter().find_map(|w| w.event.clone()).unwrap();
    // Each spoils the record before it is written, or the file after; returns what the note must say.
    type Spoil = fn(&mut Recording) -> String;
    type SpoilFile = fn(&Path) -> String;
    let cases: [(&str, Option<Spoil>, Option<SpoilFile>); 4] = [
        (
            "a clock that goes back",
            None,
            Some(|dir| {
                let line = edit_cell(dir, 5000, "board_t", "0.200000");
                format!("line {line}: `board_t` 0.2 does not follow")
            }),
        ),
        (
            "another sample period",
            Some(|rec| {
                for (k, t) in rec.board_t.iter_mut().enumerate() {
                    *t = BOARD_T0 + 2.0 * k as f64 * DT;
                }
                "the board samples every 0.002 s and the loop runs every 0.001 s".into()
            }),
            None,
        ),
        (
            "a sample between two periods",
            None,
            Some(|dir| {
                // Row 5000's sample at 5000.5 periods.
                let t = format!("{:.6}", BOARD_T0 + 5.0005);
                let line = edit_cell(dir, 5000, "board_t", &t);
                format!(
                    "line {line}: `board_t` 5.1235 is 0.50 periods off the board's 0.001 s grid"
                )
            }),
        ),
        (
            "no record at all",
            Some(|rec| {
                rec.board_f_e.iter_mut().for_each(|f| *f = None);
                "the trace holds no board record".into()
            }),
            None,
        ),
    ];
    for (what, spoil, spoil_file) in cases {
        let mut rec = Recording::clean(&sim);
        let dir = tempfile::tempdir().unwrap();
        let mut why = spoil.map(|f| f(&mut rec)).unwrap_or_default();
        rec.write(&sim, dir.path());
        if let Some(f) = spoil_file {
            why = f(dir.path());
        }
        judge(dir.path(), &scene, &sim);
        let s = summary(dir.path());
        assert_eq!(s["rig"]["judged_on"], "host", "{what}");
        let note = s["rig"]["note"].as_str().unwrap();
        assert!(
            note.starts_with("the loop's columns") && note.contains(&why),
            "{what}: {note}\nwanted: {why}"
        );
        // Judged as before on the loop's columns (here the simulation's own), the stalls still counted.
        let e = event(&s);
        assert_eq!(
            e["settling_time_s"].as_f64(),
            sim_event.settling_time_s,
            "{what}"
        );
        assert_eq!(s["rig"]["host_stalls"]["count"], 0, "{what}");
    }
}

#[test]
fn a_rig_column_that_is_not_a_number_names_the_line_and_leaves_the_recording_as_it_was() {
    let scene = scene();
    let sim = simulated(&scene);
    for (column, value) in [
        ("board_t", "12abc"),
        ("board_f_e", "nan?"),
        ("wall_time", "yesterday"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        Recording::clean(&sim).write(&sim, dir.path());
        let line = edit_cell(dir.path(), 4321, column, value);
        let before = std::fs::read(dir.path().join("trace.csv")).unwrap();
        let e = judge_recording(
            dir.path(),
            &scene,
            0,
            RecordingEnd::Complete,
            sim.pwm_period_s,
            Format::Png,
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("trace.csv")
                && e.contains(&format!(
                    "line {line}: column `{column}`: `{value}` is not a number"
                )),
            "{e}"
        );
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(left, ["trace.csv"], "{column}");
        assert_eq!(std::fs::read(dir.path().join("trace.csv")).unwrap(), before);
    }
}
