//! The scene's figures of long traces: written, with the figures a scene's events call for.

use std::path::Path;

use pneuflex_scene::analysis::windows::compute_windows;
use pneuflex_scene::run::trace::Column;
use pneuflex_scene::{ControllerKind, RunResult, Scene, Trace};
use pneuflex_viz::{Format, write_figures};

fn column(name: &str, unit: &str) -> Column {
    Column {
        name: name.into(),
        unit: unit.into(),
        group: "loop".into(),
    }
}

/// A trace of `n` ticks at 1 ms: a PWM-like force on the scene's references.
fn synthetic_trace(n: usize) -> Trace {
    let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
    let f_ref: Vec<f64> = t
        .iter()
        .map(|&t| {
            if t < 3.0 {
                10.0
            } else {
                10.0 + 2.0 * (2.0 * std::f64::consts::PI * (t - 3.0)).sin()
            }
        })
        .collect();
    let f_e: Vec<f64> = t
        .iter()
        .zip(&f_ref)
        .map(|(&t, &f)| f + 1.3 * (2.0 * std::f64::consts::PI * 40.0 * t).sin())
        .collect();
    let x: Vec<f64> = f_e.iter().map(|f| 0.02 + f / 700.0).collect();
    let x_r: Vec<f64> = f_ref.iter().map(|f| 0.02 + f / 700.0).collect();
    let p = vec![3e5; n];
    let u = vec![0.0; n];
    Trace::from_columns(vec![
        (column("t", "s"), t),
        (column("f_ref", "N"), f_ref),
        (column("f_e", "N"), f_e),
        (column("x", "m"), x),
        (column("x_r", "m"), x_r),
        (column("p_a", "Pa"), p.clone()),
        (column("p_b", "Pa"), p),
        (column("u", "1"), u),
    ])
    .unwrap()
}

fn scene(file: &str) -> Scene {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    Scene::load(&root.join("scenes").join(file)).unwrap()
}

/// The impedance run of `sc` on a synthetic trace of `ticks` ticks, with its windows' metrics.
fn impedance_run(sc: &Scene, ticks: usize) -> RunResult {
    let trace = synthetic_trace(ticks);
    let pwm = pneuflex_scene::build_plant(sc).unwrap().pwm_period_s();
    let windows = compute_windows(sc, &trace, pwm);
    RunResult {
        name: "impedance".into(),
        controller: ControllerKind::Impedance,
        trace,
        windows,
        lyapunov: None,
        diverged: None,
        interrupted: None,
        warnings: Vec::new(),
        pwm_period_s: pwm,
    }
}

/// A fresh scratch directory, removed when the returned guard drops.
fn out_dir(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix(&format!("pneuflex-viz-{name}-"))
        .tempdir()
        .unwrap()
}

#[test]
fn figures_of_a_long_trace_are_written() {
    // 100 s at 1 ms (100,001 ticks) on the PWM scene: bands, means, the zoom with its settling marks.
    for (file, format) in [
        ("paper-fig3.toml", Format::Png),
        ("paper-fig3-ideal.toml", Format::Svg),
    ] {
        let sc = scene(file);
        let results = vec![impedance_run(&sc, 100_001)];
        let dir = out_dir(file);
        let dir = dir.path().to_path_buf();
        let written = write_figures(&dir, &sc, &results, format).unwrap();
        let names: Vec<String> = written
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        let ext = if format == Format::Png { "png" } else { "svg" };
        for f in ["force", "position", "event-0"] {
            assert!(names.contains(&format!("{f}.{ext}")), "{names:?}");
        }
        for p in &written {
            assert!(
                std::fs::metadata(p).unwrap().len() > 1000,
                "{}",
                p.display()
            );
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

/// A scene with an environment swap gets its Fig. 7 figure, with each run's settling time on it, and no
/// second zoom on the same window (`event-<i>`): paper-fig7-wood-to-iron writes force, position and
/// fig7-swap-0, and the swap figure carries the run's note for the 'swap' window.
#[test]
fn a_swap_has_one_figure_with_the_settling_times() {
    let sc = scene("paper-fig7-wood-to-iron.toml");
    let results = vec![impedance_run(&sc, 8_001)];
    let dir = out_dir("fig7-swap");
    let dir = dir.path().to_path_buf();
    let written = write_figures(&dir, &sc, &results, Format::Svg).unwrap();
    let mut names: Vec<String> = written
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["fig7-swap-0.svg", "force.svg", "position.svg"]);
    let svg = std::fs::read_to_string(dir.join("fig7-swap-0.svg")).unwrap();
    assert!(
        svg.contains("impedance: "),
        "no settling note on the swap figure"
    );
    assert!(
        svg.contains("window &apos;swap&apos;") || svg.contains("window 'swap'"),
        "the note names no window"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
