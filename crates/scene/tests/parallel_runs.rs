//! Issue 14 item 2: the runs of a scene execute in parallel when nothing observes them, with the same
//! results, byte for byte, as one after another (the path an observer gets); progress still rises to 1;
//! a stop flag set before the command starts no run.

use std::path::Path;
use std::sync::atomic::AtomicUsize;

use pneuflex_scene::{
    Limits, Plant, RunOptions, RunResult, Scene, Sink, run_scene, run_scene_observed,
    run_scene_with,
};

fn scene(file: &str) -> Scene {
    Scene::load(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../scenes")
            .join(file),
    )
    .unwrap()
}

/// Watches (so the runs go one after another) without doing anything.
struct Watching;
impl Sink<dyn Plant> for Watching {}

/// Everything a run writes or reports, as text (NaN-safe: the trace as its CSV bytes).
fn fingerprint(results: &[RunResult]) -> Vec<String> {
    results
        .iter()
        .map(|r| {
            let mut csv = Vec::new();
            r.trace.write_csv(&mut csv).unwrap();
            format!(
                "{} {:?} {:?} {:?} {:?} {:?}\n{}",
                r.name,
                r.windows,
                r.lyapunov,
                r.diverged,
                r.interrupted,
                r.warnings,
                String::from_utf8(csv).unwrap()
            )
        })
        .collect()
}

#[test]
fn parallel_runs_equal_sequential_ones_and_report_progress() {
    for file in ["paper-fig3-ideal.toml", "paper-fig3-linear.toml"] {
        let s = scene(file);
        let mut seen = Vec::new();
        let parallel = run_scene(&s, &mut |f| seen.push(f)).unwrap();
        let sequential = run_scene_observed(&s, &mut |_| {}, &mut Watching).unwrap();
        assert_eq!(parallel.len(), s.runs.len());
        assert!(
            fingerprint(&parallel) == fingerprint(&sequential),
            "{file}: parallel and sequential runs differ"
        );
        assert!(seen.windows(2).all(|w| w[0] <= w[1]), "{file}: {seen:?}");
        assert_eq!(seen.last(), Some(&1.0), "{file}");
        assert!(seen.len() > 10, "{file}: {} progress reports", seen.len());
    }
}

#[test]
fn a_stop_flag_set_before_starts_no_run() {
    let s = scene("paper-fig3-ideal.toml");
    let stop = AtomicUsize::new(15);
    let opts = RunOptions {
        limits: Limits::default(),
        stop: Some(&stop),
        on_run: None,
    };
    let r = run_scene_with(&s, &opts, &mut |_| {}, &mut ()).unwrap();
    assert!(r.is_empty(), "{} runs", r.len());
}

/// `RunOptions::on_run` (how `pneuflex run` writes each trace while the other runs simulate) is called
/// once per run with the trace, metrics and warnings the command returns, in parallel and one after
/// another; the adaptive run's Lyapunov check (a job of its own in parallel) is in the result.
#[test]
fn every_run_is_handed_over_once_with_its_final_trace() {
    let s = scene("paper-fig3-ideal.toml");
    for watched in [false, true] {
        let handed = std::sync::Mutex::new(Vec::new());
        let on_run = |r: &RunResult| handed.lock().unwrap().push(r.clone());
        let opts = RunOptions {
            on_run: Some(&on_run),
            ..RunOptions::default()
        };
        let results = if watched {
            run_scene_with(&s, &opts, &mut |_| {}, &mut Watching).unwrap()
        } else {
            run_scene_with(&s, &opts, &mut |_| {}, &mut ()).unwrap()
        };
        let mut handed = handed.into_inner().unwrap();
        assert_eq!(handed.len(), results.len(), "watched {watched}");
        handed.sort_by_key(|h| results.iter().position(|r| r.name == h.name));
        for (h, r) in handed.iter_mut().zip(&results) {
            // Handed over before the Lyapunov check is attached; everything else is final.
            h.lyapunov = r.lyapunov;
            assert_eq!(
                fingerprint(std::slice::from_ref(h)),
                fingerprint(std::slice::from_ref(r))
            );
        }
        let adaptive = results.iter().find(|r| r.name == "adaptive").unwrap();
        assert!(
            adaptive.lyapunov.is_some(),
            "watched {watched}: no Lyapunov check"
        );
    }
}
