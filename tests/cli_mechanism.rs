//! `pneuflex run` on a scene with several actuators: what it writes, and what it refuses.

use std::path::Path;
use std::process::Command;

fn pneuflex(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_pneuflex"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("runs")
}

#[test]
fn a_gripper_run_writes_prefixed_traces_a_summary_with_claims_and_a_figure_per_run() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("grip");
    let o = pneuflex(&["run", "scenes/gripper.toml", "--out", out.to_str().unwrap()]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(stdout.contains("[holds] on the foam object"), "{stdout}");
    for run in ["impedance", "adaptive"] {
        let trace = std::fs::read_to_string(out.join(run).join("trace.csv")).unwrap();
        let header = trace.lines().next().unwrap();
        assert!(
            header.starts_with("t,left.f_ref,left.f_e,left.x,left.x_r,left.p_a,left.p_b,left.u,"),
            "{header}"
        );
        assert!(header.contains(",right.f_e,"), "{header}");
        // 8 s at 1 ms: 8001 rows and the header.
        assert_eq!(trace.lines().count(), 8002);
        let png = std::fs::read(out.join(run).join("force.png")).unwrap();
        assert_eq!(&png[1..4], b"PNG");
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["actuators"], serde_json::json!(["left", "right"]));
    assert_eq!(summary["claims"].as_array().unwrap().len(), 4);
    let manifest = std::fs::read_to_string(out.join(".pneuflex-output.json")).unwrap();
    assert!(manifest.contains("gripper-finger.toml") && manifest.contains("gripper.urdf"));
}

#[test]
fn a_mechanism_scene_with_a_bad_key_fails_naming_it_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join("scenes/lever.toml"))
        .unwrap()
        .replace("\"../", &format!("\"{}/", root.display()))
        .replace("retracted_length_m = 0.2 }", "retracted_length_m = 0.5 }");
    let scene = dir.path().join("lever.toml");
    std::fs::write(&scene, text).unwrap();
    let out = dir.path().join("out");
    let o = pneuflex(&[
        "run",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    // The line of the key as the file has it.
    let line = 1 + std::fs::read_to_string(&scene)
        .unwrap()
        .lines()
        .position(|l| l.contains("retracted_length_m = 0.5"))
        .unwrap();
    assert!(
        stderr.contains(&format!("lever.toml:{line}:"))
            && stderr.contains("actuators[0].anchors.retracted_length_m"),
        "{stderr}"
    );
    assert!(
        stderr.contains("apart in the URDF's zero configuration"),
        "{stderr}"
    );
    assert!(!out.exists(), "an output was left behind");
}

#[test]
fn sigint_keeps_what_ran_as_a_partial_output_and_exits_130() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    // A long gripper run, so that the signal lands mid-run.
    let text = std::fs::read_to_string(root.join("scenes/gripper.toml"))
        .unwrap()
        .replace("\"../", &format!("\"{}/", root.display()))
        .replace("duration_s = 8.0", "duration_s = 400.0");
    let scene = dir.path().join("long.toml");
    std::fs::write(&scene, text).unwrap();
    let out = dir.path().join("out");
    let child = Command::new(env!("CARGO_BIN_EXE_pneuflex"))
        .args([
            "run",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Until the staging directory exists (the run has started), then the signal.
    let started = std::time::Instant::now();
    while !std::fs::read_dir(dir.path())
        .unwrap()
        .flatten()
        .any(|e| e.file_name().to_string_lossy().contains("out."))
    {
        assert!(
            started.elapsed().as_secs() < 60,
            "the run never staged its output"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    std::thread::sleep(std::time::Duration::from_millis(300));
    let pid = child.id().to_string();
    assert!(
        Command::new("kill")
            .args(["-INT", &pid])
            .status()
            .unwrap()
            .success()
    );
    let o = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(130), "{stderr}");
    assert!(
        stderr.contains("SIGINT") && stderr.contains("out.partial"),
        "{stderr}"
    );
    assert!(!out.exists(), "the destination was written");
    let manifest =
        std::fs::read_to_string(dir.path().join("out.partial/.pneuflex-output.json")).unwrap();
    assert!(manifest.contains("\"complete\": false") && manifest.contains("SIGINT"));
    // The cut run's trace is never named as a whole run's.
    assert!(
        dir.path()
            .join("out.partial/impedance/trace.interrupted.csv")
            .exists()
    );
    assert!(!dir.path().join("out.partial/impedance/trace.csv").exists());
}

#[test]
fn a_mechanism_run_beyond_the_step_or_trace_limits_is_refused_before_it_starts() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = pneuflex(&[
        "run",
        "scenes/gripper.toml",
        "--out",
        out.to_str().unwrap(),
        "--max-steps",
        "1000",
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        stderr.contains("gripper.toml:")
            && stderr.contains("chamber_substeps")
            // 8001 ticks x 8 physics steps x (2 solver iterations + 10 chamber substeps x 2 actuators).
            && stderr.contains("--max-steps 1408176"),
        "{stderr}"
    );
    let o = pneuflex(&[
        "run",
        "scenes/gripper.toml",
        "--out",
        out.to_str().unwrap(),
        "--max-trace-mb",
        "1",
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        stderr.contains("duration_s") && stderr.contains("--max-trace-mb"),
        "{stderr}"
    );
    assert!(!out.exists(), "an output was written");
}
