//! A recording judged as the scene's run (`rig run --scene` writes this beside its trace): the same
//! metrics as the simulation of that run when the trace is the simulation's, the fault and signal cases,
//! and a trace that cannot be read leaves the recording as it was.

use std::path::{Path, PathBuf};

use pneuflex_outputs::{RecordingEnd, judge_recording};
use pneuflex_scene::{Scene, run_scene};
use pneuflex_viz::Format;

fn scene() -> Scene {
    let p: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paper-fig3.toml");
    Scene::load(&p).unwrap()
}

fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}

/// The adaptive run simulated; its trace written as a recording's `trace.csv` in a fresh directory.
fn recorded(scene: &Scene) -> (tempfile::TempDir, pneuflex_scene::RunResult, usize) {
    let i = scene.run_index("adaptive").unwrap();
    let sim = run_scene(&scene.one_run(i, scene.duration_s), &mut |_| {})
        .unwrap()
        .remove(0);
    let dir = tempfile::tempdir().unwrap();
    let mut f = std::fs::File::create(dir.path().join("trace.csv")).unwrap();
    sim.trace.write_csv(&mut f).unwrap();
    (dir, sim, i)
}

/// The same JSON, numbers within 1e-12 relative (a trace read back from CSV can differ in the last bit).
fn assert_close(a: &serde_json::Value, b: &serde_json::Value, at: &str) {
    use serde_json::Value::*;
    match (a, b) {
        (Number(x), Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            assert!(
                (x - y).abs() <= 1e-12 * x.abs().max(y.abs()),
                "{at}: {x} vs {y}"
            );
        }
        (Array(x), Array(y)) => {
            assert_eq!(x.len(), y.len(), "{at}");
            for (k, (x, y)) in x.iter().zip(y).enumerate() {
                assert_close(x, y, &format!("{at}[{k}]"));
            }
        }
        (Object(x), Object(y)) => {
            assert_eq!(
                x.keys().collect::<Vec<_>>(),
                y.keys().collect::<Vec<_>>(),
                "{at}"
            );
            for (k, v) in x {
                assert_close(v, &y[k], &format!("{at}.{k}"));
            }
        }
        _ => assert_eq!(a, b, "{at}"),
    }
}

/// [`judge_recording`] of a complete recording of `sim`.
fn judge(dir: &tempfile::TempDir, scene: &Scene, i: usize, sim: &pneuflex_scene::RunResult) {
    judge_recording(
        dir.path(),
        scene,
        i,
        RecordingEnd::Complete,
        sim.pwm_period_s,
        Format::Png,
    )
    .unwrap();
}

#[test]
fn a_recording_of_the_simulated_run_is_judged_as_the_simulation_judged_it() {
    let scene = scene();
    let (dir, sim, i) = recorded(&scene);
    judge(&dir, &scene, i, &sim);
    let s = summary(dir.path());
    assert_eq!(s["complete"], true);
    let run = &s["runs"][0];
    assert_eq!(
        (run["name"].as_str(), run["trace"].as_str()),
        (Some("adaptive"), Some("trace.csv"))
    );
    // Every window's metrics as the simulation computed them, to the last digits the CSV carries.
    let want = serde_json::to_value(&sim.windows).unwrap();
    assert_close(&run["windows"], &want, "windows");
    assert_eq!(
        run["windows"].as_array().unwrap().len(),
        scene.metrics.len()
    );
    assert_eq!(run["lyapunov"]["non_increasing"], true);
    // The projection-bound warnings the simulation gives.
    assert_eq!(
        run["warnings"],
        serde_json::to_value(&sim.warnings).unwrap()
    );
    assert!(
        s.get("claims")
            .is_none_or(|c| c.as_array().is_some_and(Vec::is_empty)),
        "claims compare two runs: none on one recording"
    );
    assert!(dir.path().join("force.png").is_file());
}

#[test]
fn a_recording_cut_short_keeps_only_the_windows_it_covers() {
    let scene = scene();
    let (dir, sim, i) = recorded(&scene);
    // The first 4 s of it: 4000 ticks (header and rows up to t = 3.999 s) cover 4 s.
    let path = dir.path().join("trace.csv");
    let text = std::fs::read_to_string(&path).unwrap();
    let cut: Vec<&str> = text.lines().take(1 + 4000).collect();
    std::fs::write(&path, cut.join("\n") + "\n").unwrap();
    judge(&dir, &scene, i, &sim);
    let s = summary(dir.path());
    let names: Vec<&str> = s["runs"][0]["windows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w["name"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        ["step"],
        "only the step window (2.5–3 s) ends by 4 s"
    );
    assert_eq!(s["duration_s"], 4.0);
}

#[test]
fn a_fault_or_a_signal_is_said_and_draws_no_figures() {
    let scene = scene();
    for (end, key) in [
        (
            RecordingEnd::Fault("the rig run ended on a fault: link lost (tick 12)".into()),
            "reason",
        ),
        (
            RecordingEnd::Interrupted("stopped by SIGINT".into()),
            "interrupted",
        ),
    ] {
        let (dir, sim, i) = recorded(&scene);
        let why = match &end {
            RecordingEnd::Fault(w) | RecordingEnd::Interrupted(w) => w.clone(),
            RecordingEnd::Complete => unreachable!(),
        };
        judge_recording(dir.path(), &scene, i, end, sim.pwm_period_s, Format::Png).unwrap();
        let s = summary(dir.path());
        assert_eq!(s["runs"][0][key].as_str(), Some(why.as_str()));
        assert!(s["runs"][0]["windows"].as_array().unwrap().is_empty());
        assert!(!dir.path().join("force.png").exists());
        if key == "interrupted" {
            assert_eq!(s["complete"], false);
        } else {
            assert_eq!(s["runs"][0]["diverged"], true);
        }
    }
}

#[test]
fn a_trace_that_cannot_be_read_back_leaves_the_recording_as_it_was() {
    let scene = scene();
    let dir = tempfile::tempdir().unwrap();
    let bad = "t,f_ref,f_e,x,x_r,p_a,p_b,u\n0,10,0,0,0,1e5,1e5,0\n0.001,10,oops,0,0,1e5,1e5,0\n";
    std::fs::write(dir.path().join("trace.csv"), bad).unwrap();
    let e = judge_recording(
        dir.path(),
        &scene,
        0,
        RecordingEnd::Complete,
        None,
        Format::Png,
    )
    .unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("trace.csv") && msg.contains("oops"), "{msg}");
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left, ["trace.csv"]);
    assert_eq!(
        std::fs::read_to_string(dir.path().join("trace.csv")).unwrap(),
        bad
    );
}
