//! Hostile inputs to `pneuflex run`, one test per class, written from the scene contracts in docs/scenes.md
//! and docs/multibody.md: a several-actuator scene is held to the one-actuator scene's checks (a blown-up run
//! stops as diverged, every inner step counts against `--max-steps`, `--format` is obeyed; the first signal
//! stopping it is `cli_mechanism.rs`' SIGINT test), a command that takes one actuator refuses such a scene
//! with the reason, and a controller gain that only makes an on/off switch is refused by file, line and key.

use std::path::{Path, PathBuf};

mod common;
use common::{repo, run, s};

/// A copy of the shipped scene `name` in `dir` with `edit` applied to its text (each pair replaces the
/// first occurrence of the left by the right, which must be there), its relative paths pointing back
/// into the repository.
fn scene_copy(dir: &Path, name: &str, edits: &[(&str, &str)]) -> PathBuf {
    let text = std::fs::read_to_string(repo().join("scenes").join(name)).unwrap();
    let mut text = text
        .replace("\"../urdf/", &format!("\"{}/urdf/", repo().display()))
        .replace(
            "\"../pneumatics/",
            &format!("\"{}/pneumatics/", repo().display()),
        );
    for (from, to) in edits {
        assert!(text.contains(from), "{name} has no `{from}`");
        text = text.replacen(from, to, 1);
    }
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// The summary.json of a finished output directory.
fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}

#[test]
fn a_blown_up_several_actuator_run_stops_as_diverged_and_fails() {
    // A 1e12 N/m pad on the lever: the explicit pad blows the mechanism up within a few ticks.
    let d = tempfile::tempdir().unwrap();
    let scene = scene_copy(
        d.path(),
        "lever.toml",
        &[("stiffness_n_per_m = 5000.0", "stiffness_n_per_m = 1e12")],
    );
    let out = d.path().join("out");
    let r = run(&["run", "-q", s(&scene), "--out", s(&out)], d.path());
    r.refused(&["diverged", "impedance"]);
    let sum = summary(&out);
    let why = sum["runs"][0]["diverged"]
        .as_str()
        .unwrap_or_else(|| panic!("not marked diverged: {sum}"));
    assert!(
        why.contains("elbow_cylinder")
            && (why.contains("chamber pressure")
                || why.contains("|f_e|")
                || why.contains("non-finite")),
        "{why}"
    );
    // The trace ends at the divergence: no row holds a chamber above twice the supply (0.6 MPa here).
    assert!(
        !out.join("impedance/trace.csv").exists(),
        "a diverged run's trace is not trace.csv"
    );
    let trace = std::fs::read_to_string(out.join("impedance/trace.diverged.csv")).unwrap();
    let mut lines = trace.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let p_a = head
        .iter()
        .position(|c| *c == "elbow_cylinder.p_a")
        .unwrap();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert!(rows.len() < 6001, "the run went on: {} rows", rows.len());
    // Only the last row (the one that broke the invariant) may be beyond the limit.
    for r in &rows[..rows.len() - 1] {
        assert!(r[p_a] <= 2.0 * 0.7e6, "p_a = {} before the stop", r[p_a]);
    }
}

#[test]
fn inner_steps_beyond_the_budget_are_refused_before_anything_runs() {
    let d = tempfile::tempdir().unwrap();
    // Out of their ranges: named by key and line, nothing staged.
    for (key, now, value) in [
        ("chamber_substeps", "10", "1000000000"),
        ("solver_iterations", "2", "1000000000"),
        ("chamber_substeps", "10", "0"),
    ] {
        let scene = scene_copy(
            d.path(),
            "gripper.toml",
            &[(&format!("{key} = {now}"), &format!("{key} = {value}"))],
        );
        let out = d.path().join("out");
        let r = run(&["run", "-q", s(&scene), "--out", s(&out)], d.path());
        r.refused(&[key, "gripper.toml:"]);
        assert!(!out.exists(), "{key} = {value}: output written");
    }
    // Within their ranges but beyond the step budget: each inner loop counts, the key that costs most is
    // named with the flag that raises the limit.
    let scene = scene_copy(
        d.path(),
        "gripper.toml",
        &[("chamber_substeps = 10", "chamber_substeps = 1000")],
    );
    let out = d.path().join("out");
    let r = run(
        &[
            "run",
            "-q",
            s(&scene),
            "--out",
            s(&out),
            "--max-steps",
            "1000000",
        ],
        d.path(),
    );
    r.refused(&["chamber_substeps", "--max-steps", "inner steps"]);
    assert!(!out.exists());
}

#[test]
fn a_several_actuator_scene_obeys_format() {
    let d = tempfile::tempdir().unwrap();
    let scene = scene_copy(d.path(), "cross-slide.toml", &[]);
    for format in ["svg", "pdf"] {
        let out = d.path().join(format);
        let r = run(
            &["run", "-q", s(&scene), "--out", s(&out), "--format", format],
            d.path(),
        );
        assert_eq!(r.code, Some(0), "{}", r.stderr);
        let figure = out.join("impedance").join(format!("force.{format}"));
        let bytes = std::fs::read(&figure).unwrap_or_else(|e| panic!("{}: {e}", figure.display()));
        let magic: &[u8] = if format == "svg" { b"<svg" } else { b"%PDF" };
        assert!(
            bytes.windows(magic.len()).take(200).any(|w| w == magic),
            "{} is not {format}",
            figure.display()
        );
        assert!(
            !out.join("impedance/force.png").exists(),
            "a PNG beside the {format}"
        );
    }
}

#[test]
fn a_gain_that_only_switches_the_valve_is_refused_by_file_line_and_key() {
    let d = tempfile::tempdir().unwrap();
    for (from, to, key) in [
        ("kp_per_m = 10.0", "kp_per_m = 1e300", "kp_per_m"),
        ("ki_per_m_s = 20.0", "ki_per_m_s = 1e12", "ki_per_m_s"),
        ("kd_s_per_m = 0.0", "kd_s_per_m = 1e5", "kd_s_per_m"),
    ] {
        let scene = scene_copy(d.path(), "paper-fig3.toml", &[(from, to)]);
        let out = d.path().join("out");
        let r = run(&["run", "-q", s(&scene), "--out", s(&out)], d.path());
        r.refused(&[key, "paper-fig3.toml:", "runs[0]"]);
        assert!(!out.exists());
        // The same gain on a several-actuator scene.
        let scene = scene_copy(d.path(), "gripper.toml", &[(from, to)]);
        let r = run(&["run", "-q", s(&scene), "--out", s(&out)], d.path());
        r.refused(&[key, "gripper.toml:"]);
        assert!(!out.exists());
    }
}

#[test]
fn a_non_finite_or_negative_threshold_is_refused() {
    let d = tempfile::tempdir().unwrap();
    for (table, key) in [
        (
            "[divergence]\nmax_abs_force_n = nan\n",
            "divergence.max_abs_force_n",
        ),
        (
            "[divergence]\nmax_abs_position_m = -1.0\n",
            "divergence.max_abs_position_m",
        ),
    ] {
        let text = format!("{table}\n");
        let scene = scene_copy(
            d.path(),
            "gripper.toml",
            &[("[[actuators]]", &format!("{text}[[actuators]]"))],
        );
        let out = d.path().join("out");
        let r = run(&["run", "-q", s(&scene), "--out", s(&out)], d.path());
        r.refused(&[key, "gripper.toml:"]);
        assert!(!out.exists());
    }
}

#[test]
fn an_absurd_stiffness_ends_as_a_refusal_or_a_divergence_never_a_hang() {
    // 1e300 N/m on the 1-DOF plant: the loop analysis of the warnings (a NaN map's eigenvalues) once spun
    // forever after the runs had ended, deaf to signals. Now: a readable warning, the runs diverge, exit 1.
    let d = tempfile::tempdir().unwrap();
    let scene = scene_copy(
        d.path(),
        "paper-fig3.toml",
        &[("stiffness_n_per_m = 700.0", "stiffness_n_per_m = 1e300")],
    );
    let out = d.path().join("out");
    let r = run(&["run", "-q", s(&scene), "--out", s(&out)], d.path());
    r.refused(&["diverged", "environment.stiffness_n_per_m", "1.000e300 N/m"]);
    assert!(
        r.stderr.lines().all(|l| l.len() < 1000),
        "a message line of over 1000 characters:\n{}",
        r.stderr
    );
}

#[test]
fn sweep_and_tune_take_a_several_actuator_scene() {
    let d = tempfile::tempdir().unwrap();
    let lever = scene_copy(d.path(), "lever.toml", &[]);
    let out = d.path().join("sweep");
    let r = run(
        &[
            "sweep",
            "-q",
            s(&lever),
            "--set",
            "contacts[press].stiffness_n_per_m=3000,8000",
            "--set",
            "actuators[elbow_cylinder].x_d_m=0.01,0.02",
            "--format",
            "svg",
            "--out",
            s(&out),
        ],
        d.path(),
    );
    r.accepted();
    let table = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    let header = table.lines().next().unwrap();
    assert!(
        header.contains(",press.elbow_cylinder.rms_force_error_n,")
            && header.contains(",sine.force_imbalance_n"),
        "{header}"
    );
    // 4 points x 1 run, each simulated to the end.
    assert_eq!(
        table.lines().filter(|l| l.contains(",ok,")).count(),
        4,
        "{table}"
    );
    let svg = std::fs::read_dir(&out)
        .unwrap()
        .filter_map(|e| e.ok())
        .find(|e| e.file_name().to_string_lossy().ends_with(".svg"))
        .expect("a heatmap in svg");
    assert!(
        std::fs::read_to_string(svg.path())
            .unwrap()
            .contains("<svg")
    );
    let out = d.path().join("tune");
    let r = run(
        &[
            "tune",
            "-q",
            s(&lever),
            "--free",
            "runs[impedance].impedance.b_d_ns_per_m=[50,400]",
            "--budget",
            "3",
            "--population",
            "3",
            "--out",
            s(&out),
        ],
        d.path(),
    );
    r.accepted();
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        report.contains("sine.elbow_cylinder.rms_force_error_n"),
        "{report}"
    );
    // Three candidates may not beat the start: then the report says the start is kept, and no copy is written.
    let kept = report.contains("the start is kept");
    assert_eq!(out.join("lever-tuned.toml").exists(), !kept, "{report}");
}
