//! Issue 11: hostile and implausible scenes. Every error names the file, the line and the key that is to
//! blame; implausible but legal parameters are warned about before the run, and a run whose state becomes
//! physically impossible stops as diverged instead of writing an impossible trace.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use pneuflex_scene::analysis::advice;
use pneuflex_scene::{Limits, Plant, RunOptions, Scene, Sink, run_scene, run_scene_with};

fn shipped(name: &str) -> (String, PathBuf) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(name);
    (std::fs::read_to_string(&path).unwrap(), path)
}

fn load(text: &str, path: &Path) -> Result<Scene, String> {
    Scene::from_toml_str(text, path, path.parent().unwrap()).map_err(|e| e.to_string())
}

fn err(name: &str, from: &str, to: &str) -> String {
    let (text, path) = shipped(name);
    assert!(text.contains(from), "{from:?} not in {name}");
    load(&text.replacen(from, to, 1), &path).expect_err("bad scene accepted")
}

fn line_of(name: &str, needle: &str) -> usize {
    let (text, _) = shipped(name);
    text.lines().position(|l| l.contains(needle)).unwrap() + 1
}

#[test]
fn a_toml_syntax_error_names_the_line() {
    let e = err("paper-fig3.toml", "[environment]", "[environment");
    let line = line_of("paper-fig3.toml", "[environment]");
    assert!(e.contains(&format!("paper-fig3.toml:{line}:")), "{e}");
}

#[test]
fn a_fractional_substeps_is_blamed_on_substeps_not_on_plant() {
    let e = err("paper-fig3.toml", "substeps = 10", "substeps = 10.5");
    let line = line_of("paper-fig3.toml", "substeps = 10");
    assert!(
        e.contains(&format!(":{line}:")) && e.contains("plant.substeps: invalid type"),
        "{e}"
    );
}

#[test]
fn a_huge_duration_is_blamed_on_duration() {
    let e = err(
        "paper-fig3-ideal.toml",
        "duration_s = 10.0",
        "duration_s = 1e9",
    );
    assert!(e.contains(": duration_s: must be at most"), "{e}");
}

#[test]
fn an_event_after_the_end_is_refused() {
    let e = err("paper-fig3-ideal.toml", "t_s = 6.0", "t_s = 1e9");
    assert!(
        e.contains("events[0].t_s: the event would never happen"),
        "{e}"
    );
}

#[test]
fn a_newer_schema_version_is_refused_and_the_current_one_accepted() {
    let (text, path) = shipped("paper-fig3-ideal.toml");
    let e = load(&format!("schema_version = 2\n{text}"), &path).unwrap_err();
    assert!(
        e.contains(":1:")
            && e.contains("schema_version: this pneuflex reads scene schema version 1"),
        "{e}"
    );
    load(&format!("schema_version = 1\n{text}"), &path).unwrap();
}

#[test]
fn a_scene_that_is_a_directory_or_a_fifo_is_a_clear_error_not_a_hang() {
    let e = Scene::load(Path::new(env!("CARGO_MANIFEST_DIR")))
        .unwrap_err()
        .to_string();
    assert!(e.contains("not a regular file (a directory)"), "{e}");
    let dir = std::env::temp_dir().join(format!("pneuflex-fifo-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let fifo = dir.join("scene.toml");
    let _ = std::fs::remove_file(&fifo);
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if made.is_ok_and(|s| s.success()) {
        let e = Scene::load(&fifo).unwrap_err().to_string();
        assert!(e.contains("not a regular file (a FIFO)"), "{e}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn runs_beyond_the_step_and_memory_limits_are_refused_with_the_number_and_the_flag() {
    let (text, path) = shipped("paper-fig7-wood-to-iron.toml");
    // Whatever step the shipped file states.
    let line = text
        .lines()
        .find(|l| l.starts_with("physics_dt_s"))
        .unwrap();
    let s = load(&text.replacen(line, "physics_dt_s = 1e-12", 1), &path).unwrap();
    let e = s.check_budget(&Limits::default()).unwrap_err().to_string();
    assert!(
        e.contains("plant.physics_dt_s") && e.contains("--max-steps"),
        "{e}"
    );
    let (text, path) = shipped("paper-fig3.toml");
    let s = load(
        &text.replacen("duration_s = 10.0", "duration_s = 1e5", 1),
        &path,
    )
    .unwrap();
    let e = run_scene(&s, &mut |_| {}).unwrap_err().to_string();
    assert!(e.contains("MiB") && e.contains("--max-trace-mb"), "{e}");
    // The default limits leave every shipped scene alone.
    for name in [
        "paper-fig2.toml",
        "paper-fig3.toml",
        "paper-fig3-ideal.toml",
        "paper-fig3-multibody.toml",
        "paper-fig7-wood-to-iron.toml",
    ] {
        let (text, path) = shipped(name);
        load(&text, &path)
            .unwrap()
            .check_budget(&Limits::default())
            .unwrap();
    }
}

#[test]
fn shipped_scenes_get_no_warning() {
    for name in [
        "paper-fig2.toml",
        "paper-fig3.toml",
        "paper-fig3-ideal.toml",
        "paper-fig3-multibody.toml",
        "paper-fig7-wood-to-iron.toml",
    ] {
        let (text, path) = shipped(name);
        let w = advice::warnings(&load(&text, &path).unwrap());
        assert!(w.is_empty(), "{name}: {w:?}");
    }
}

fn pneumatic_with(from: &str, to: &str, duration: &str) -> Scene {
    let (text, path) = shipped("paper-fig3.toml");
    let text = text
        .replacen(from, to, 1)
        .replacen("duration_s = 10.0", duration, 1);
    // Metric windows beyond a shortened run would be refused; drop them.
    let text = match text.find("[[metrics]]") {
        Some(i) => text[..i].to_string(),
        None => text,
    };
    load(&text, &path).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn a_stiffness_beyond_the_step_is_warned_about_and_stops_as_diverged() {
    let s = pneumatic_with(
        "stiffness_n_per_m = 700.0",
        "stiffness_n_per_m = 1e12",
        "duration_s = 7.0",
    );
    let w = advice::warnings(&s);
    assert!(
        w.iter()
            .any(|w| w.key == "environment.stiffness_n_per_m"
                && w.message.contains("plant.substeps >=")),
        "{w:?}"
    );
    for r in run_scene(&s, &mut |_| {}).unwrap() {
        let why = r
            .diverged
            .unwrap_or_else(|| panic!("run {} exited as if fine", r.name));
        assert!(why.contains("at t ="), "{why}");
        // Nothing impossible was recorded before the stop: pressures stay absolute and bounded. (A frozen
        // run whose source diverged did not run: its trace is empty.)
        let last_ok = r.trace.p_a().len().saturating_sub(1);
        for &p in &r.trace.p_a()[..last_ok] {
            assert!(p > 0.0 && p < 2.0 * 6.0e5, "{p}");
        }
    }
}

#[test]
fn a_control_period_the_chambers_cannot_follow_is_warned_about_and_stops_as_diverged() {
    let s = pneumatic_with("dt_s = 0.001", "dt_s = 0.5", "duration_s = 7.0");
    let w = advice::warnings(&s);
    assert!(w.iter().any(|w| w.key == "plant.substeps"), "{w:?}");
    for r in run_scene(&s, &mut |_| {}).unwrap() {
        let why = r
            .diverged
            .unwrap_or_else(|| panic!("run {} exited as if fine", r.name));
        assert!(
            why.contains("chamber") || why.contains("piston") || why.contains("non-finite"),
            "{why}"
        );
    }
}

/// Sets the stop flag (as the signal handler would) once simulated time passes `at_s`.
struct StopAt<'a> {
    flag: &'a AtomicUsize,
    at_s: f64,
}

impl Sink<dyn Plant> for StopAt<'_> {
    fn row(&mut self, values: &[f64], _plant: &dyn Plant) {
        if values[pneuflex_control::signal::index::T] >= self.at_s {
            self.flag.store(15, Ordering::Relaxed);
        }
    }
}

#[test]
fn a_stop_request_ends_the_run_at_the_next_tick_and_starts_no_other() {
    let (text, path) = shipped("paper-fig3-ideal.toml");
    let s = load(&text, &path).unwrap();
    let flag = AtomicUsize::new(0);
    let opts = RunOptions {
        limits: Limits::default(),
        stop: Some(&flag),
        on_run: None,
    };
    let res = run_scene_with(
        &s,
        &opts,
        &mut |_| {},
        &mut StopAt {
            flag: &flag,
            at_s: 1.0,
        },
    )
    .unwrap();
    assert_eq!(res.len(), 1, "the second run must not start");
    let why = res[0].interrupted.as_deref().unwrap();
    assert!(why.starts_with("SIGTERM at t = 1.0"), "{why}");
    assert!((res[0].trace.t().last().unwrap() - 1.0).abs() < 1e-9);
    assert!(res[0].windows.is_empty(), "no metrics on a cut trace");
    let summary = pneuflex_scene::summary(&s, &res);
    assert!(!summary.complete);
    assert!(
        summary
            .inputs
            .iter()
            .any(|i| i.role == "scene" && i.sha256.len() == 64)
    );
}

#[test]
fn gains_past_the_inner_loops_margin_are_warned_about_with_the_kp_that_keeps_it() {
    let (text, path) = shipped("paper-fig3-proportional.toml");
    let s = load(&text.replace("kp_per_m = 7.0", "kp_per_m = 12.0"), &path).unwrap();
    let w = advice::warnings(&s);
    assert!(
        w.iter()
            .any(|w| w.key == "runs[0].inner.kp_per_m" && w.message.contains("may limit-cycle")),
        "{w:?}"
    );
}

/// A mount whose damping the solver substep cannot represent (k h > 0.9 c: Rapier's implicit spring adds
/// k h, and only 0.9 c of it is taken back) is warned about, naming the material and the step that would
/// give its damping: the realistic iron (2e7 N/m, 400 N s/m) at h = 0.1 ms / 2; the Fig. 7 rig's wood and
/// iron (700 and 1400 N/m, 2 N s/m at h = 2 ms / 2) are not.
#[test]
fn a_mount_damping_the_substep_cannot_give_is_warned_about() {
    let (text, path) = shipped("paper-fig7-realistic.toml");
    let w = advice::warnings(&load(&text, &path).unwrap());
    let mounts: Vec<_> = w
        .iter()
        .filter(|w| w.message.contains("its mount is damped"))
        .collect();
    assert_eq!(mounts.len(), 1, "{w:?}");
    assert_eq!(mounts[0].key, "plant.physics_dt_s");
    assert!(
        mounts[0].message.contains("material `iron`"),
        "{}",
        mounts[0]
    );
    assert!(
        mounts[0]
            .message
            .contains("damped with 1040 N s/m, not 400"),
        "{}",
        mounts[0]
    );
    assert!(
        mounts[0].message.contains("physics_dt_s <= 3.600e-5 s"),
        "{}",
        mounts[0]
    );
    let (text, path) = shipped("paper-fig7-wood-to-iron.toml");
    let w = advice::warnings(&load(&text, &path).unwrap());
    assert!(
        w.iter().all(|w| !w.message.contains("its mount is damped")),
        "{w:?}"
    );
}
