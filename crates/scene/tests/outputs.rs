//! Outputs: trace.csv and summary.json written through a staging directory; diverged runs stop, are marked
//! and never written as if they succeeded.

use std::path::Path;

use pneuflex_files::OutputDir;
use pneuflex_files::output::{Manifest, Writer};
use pneuflex_scene::{Scene, run_scene, write_results};

fn stage(dest: &Path) -> OutputDir {
    OutputDir::create(dest, &[], Writer::simulation("test")).unwrap()
}

fn manifest() -> Manifest {
    Manifest::new("test", "0", vec![])
}

fn scene(extra: &str) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paper-fig3-ideal.toml");
    let text = std::fs::read_to_string(&path).unwrap() + extra;
    Scene::from_toml_str(&text, &path, path.parent().unwrap()).unwrap_or_else(|e| panic!("{e}"))
}

/// A fresh scratch directory, removed when the returned guard drops.
fn tmp(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix(&format!("pneuflex-scene-test-{name}-"))
        .tempdir()
        .unwrap()
}

#[test]
fn traces_and_summary_are_written_and_read_back() {
    let s = scene("");
    let res = run_scene(&s, &mut |_| {}).unwrap();
    let scratch = tmp("ok");
    let dest = scratch.path().join("paper-fig3-ideal");
    let stage = stage(&dest);
    let staged = stage.path().to_path_buf();
    write_results(stage.path(), &s, &res).unwrap();
    assert!(
        !dest.exists(),
        "nothing appears under the final name before commit"
    );
    stage.commit(manifest()).unwrap();
    assert!(!staged.exists());
    let csv = std::fs::read_to_string(dest.join("adaptive/trace.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next().unwrap(), "t,f_ref,f_e,x,x_r,p_a,p_b,u,g,p,d");
    assert_eq!(csv.lines().count(), s.n_steps() + 2);
    // Values read back bit for bit (row 5000 = t 5 s).
    let row: Vec<&str> = csv.lines().nth(5001).unwrap().split(',').collect();
    let r = &res.iter().find(|r| r.name == "adaptive").unwrap().trace;
    assert_eq!(row[0].parse::<f64>().unwrap(), r.t()[5000]);
    assert_eq!(row[2].parse::<f64>().unwrap(), r.f_e()[5000]);
    assert_eq!(row[8].parse::<f64>().unwrap(), r.column("g").unwrap()[5000]);
    assert_eq!(row[5], "", "the ideal plant has no chamber pressures");
    let imp = std::fs::read_to_string(dest.join("impedance/trace.csv")).unwrap();
    assert_eq!(imp.lines().next().unwrap(), "t,f_ref,f_e,x,x_r,p_a,p_b,u");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dest.join("summary.json")).unwrap()).unwrap();
    let runs = summary["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2);
    for (run, r) in runs.iter().zip(&res) {
        assert_eq!(run["diverged"], false);
        let sine = run["windows"]
            .as_array()
            .unwrap()
            .iter()
            .find(|w| w["name"] == "sine")
            .unwrap();
        assert_eq!(
            sine["rms_force_error_n"].as_f64().unwrap(),
            r.window("sine").unwrap().rms_force_error_n
        );
    }
    assert!(runs[1]["lyapunov"]["non_increasing"].as_bool().unwrap());
    let _ = std::fs::remove_dir_all(dest.parent().unwrap());
}

#[test]
fn a_runaway_run_stops_and_is_marked_diverged() {
    // A force limit below the 10 N reference: both runs must stop at the crossing, not run on.
    let s = scene("\n[divergence]\nmax_abs_force_n = 5.0\n");
    let res = run_scene(&s, &mut |_| {}).unwrap();
    for r in &res {
        let reason = r.diverged.as_deref().expect("marked diverged");
        assert!(reason.contains("divergence.max_abs_force_n"), "{reason}");
        assert!(r.trace.len() < s.n_steps() + 1, "stopped early");
        let last = *r.trace.f_e().last().unwrap();
        assert!(
            last > 5.0
                && r.trace.f_e()[..r.trace.len() - 1]
                    .iter()
                    .all(|f| f.abs() <= 5.0)
        );
        assert!(r.windows.is_empty(), "no metrics for a diverged run");
    }
    let scratch = tmp("div");
    let dest = scratch.path().join("x");
    let stage = stage(&dest);
    write_results(stage.path(), &s, &res).unwrap();
    stage.commit(manifest()).unwrap();
    assert!(
        !dest.join("impedance/trace.csv").exists(),
        "a diverged trace is never written as trace.csv"
    );
    assert!(dest.join("impedance/trace.diverged.csv").exists());
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dest.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["runs"][0]["diverged"], true);
    assert!(
        summary["runs"][0]["reason"]
            .as_str()
            .unwrap()
            .contains("max_abs_force_n")
    );
    let _ = std::fs::remove_dir_all(dest.parent().unwrap());
}

#[test]
fn an_uncommitted_staging_directory_is_removed() {
    let scratch = tmp("drop");
    let dest = scratch.path().join("x");
    let staged = {
        let stage = stage(&dest);
        std::fs::write(stage.path().join("half.csv"), "t\n").unwrap();
        stage.path().to_path_buf()
    };
    assert!(!staged.exists() && !dest.exists());
    let _ = std::fs::remove_dir_all(dest.parent().unwrap());
}

/// Counts what it sees, to check that observers fan out.
#[derive(Default)]
struct Count {
    runs: usize,
    steps: usize,
    last_t: f64,
}

impl<W: ?Sized> pneuflex_scene::Sink<W> for Count {
    fn begin(&mut self, _run: &str, _columns: &[pneuflex_control::Signal], _: &W) {
        self.runs += 1;
    }
    fn row(&mut self, values: &[f64], _: &W) {
        self.steps += 1;
        self.last_t = values[pneuflex_control::signal::index::T];
    }
}

#[test]
fn every_observer_sees_every_tick_of_every_run() {
    let s = scene("");
    let (mut a, mut b) = (Count::default(), Count::default());
    let mut all = pneuflex_scene::Sinks(vec![&mut a, &mut b]);
    let res = pneuflex_scene::run_scene_observed(&s, &mut |_| {}, &mut all).unwrap();
    let rows: usize = res.iter().map(|r| r.trace.len()).sum();
    for c in [&a, &b] {
        assert_eq!((c.runs, c.steps), (2, rows));
        assert_eq!(c.last_t, s.duration_s);
    }
}
