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
            header.starts_with("t,left.f_r,left.f_e,left.x,"),
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
    assert!(
        stderr.contains("lever.toml:17:")
            && stderr.contains("actuators[0].anchors.retracted_length_m"),
        "{stderr}"
    );
    assert!(
        stderr.contains("apart in the URDF's zero configuration"),
        "{stderr}"
    );
    assert!(!out.exists(), "an output was left behind");
}
