//! The output pipeline: what a complete and a stopped simulation leave, and where nothing is written.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicUsize;

use pneuflex_outputs::{Outcome, Outputs, OutputsError, Simulate, simulate_into};
use pneuflex_scene::Scene;

fn scene_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paper-fig3-ideal.toml")
}

#[test]
fn a_complete_simulation_commits_traces_summary_figures_and_manifest() {
    let tmp = tempfile::tempdir().unwrap();
    let dest = tmp.path().join("out");
    let scene = Scene::load(&scene_path()).unwrap();
    let outputs = Outputs::stage(&scene, &scene_path(), &dest, "run", &[]).unwrap();
    let sim = simulate_into(&scene, outputs, Simulate::default(), &mut |_| {}, &mut ()).unwrap();
    assert_eq!(sim.outcome, Outcome::Committed(dest.clone()));
    assert!(sim.summary.complete);
    for r in &scene.runs {
        let trace = std::fs::read_to_string(dest.join(&r.name).join("trace.csv")).unwrap();
        // One row per tick and the header: the trace is the run's, written in full.
        let result = sim.results.iter().find(|x| x.name == r.name).unwrap();
        assert_eq!(trace.lines().count(), result.trace.t().len() + 1);
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dest.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["complete"], true);
    assert!(dest.join("force.png").is_file());
    let manifest = std::fs::read_to_string(dest.join(".pneuflex-output.json")).unwrap();
    assert!(manifest.contains("\"run\""), "{manifest}");
}

#[test]
fn a_stopped_simulation_is_a_partial_and_the_destination_is_untouched() {
    let tmp = tempfile::tempdir().unwrap();
    let dest = tmp.path().join("out");
    let scene = Scene::load(&scene_path()).unwrap();
    // A signal before the first tick (SIGTERM = 15): the first run stops at once, the others never start.
    let stop = AtomicUsize::new(15);
    let outputs = Outputs::stage(&scene, &scene_path(), &dest, "run", &[]).unwrap();
    let how = Simulate {
        stop: Some(&stop),
        ..Simulate::default()
    };
    let sim = simulate_into(&scene, outputs, how, &mut |_| {}, &mut ()).unwrap();
    let Outcome::Partial(stopped) = sim.outcome else {
        panic!("a stopped simulation was committed")
    };
    assert_eq!(stopped.reason, "SIGTERM");
    assert!(!dest.exists(), "the destination was written");
    let summary = std::fs::read_to_string(stopped.to.join("summary.json")).unwrap();
    assert!(summary.contains("\"complete\": false"), "{summary}");
    // No figures of an incomplete command.
    assert!(!stopped.to.join("force.png").exists());
}

#[test]
fn a_recording_file_inside_the_destination_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let dest = tmp.path().join("out");
    let scene = Scene::load(&scene_path()).unwrap();
    let outputs = Outputs::stage(&scene, &scene_path(), &dest, "run", &[]).unwrap();
    let e = outputs
        .refuse_inside(&dest.join("a.rrd"), "--rerun save")
        .unwrap_err();
    assert!(matches!(e, OutputsError::Inside { .. }));
    assert!(e.to_string().contains("--rerun save"), "{e}");
    outputs
        .refuse_inside(&tmp.path().join("a.rrd"), "--rerun save")
        .unwrap();
}

#[test]
fn the_scene_file_is_never_an_output() {
    let scene = Scene::load(&scene_path()).unwrap();
    let scenes = scene_path().parent().unwrap().to_path_buf();
    let e = Outputs::stage(&scene, &scene_path(), &scenes, "run", &[])
        .err()
        .expect("the scenes folder was accepted as an output directory");
    assert!(e.to_string().contains("scenes"), "{e}");
}
