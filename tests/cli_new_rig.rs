//! `pneuflex new rig` from the command line: datasheet values with units to a rig directory that `run`
//! takes as it is; bad values refused with the option named, a non-zero exit and nothing written.

use std::process::Command;

fn pneuflex(args: &[&str], cwd: &std::path::Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_pneuflex"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("runs")
}

#[test]
fn a_rig_from_datasheet_values_runs_in_two_commands() {
    let tmp = tempfile::tempdir().unwrap();
    let out = pneuflex(
        &[
            "new",
            "rig",
            "my-rig",
            "--bore",
            "25mm",
            "--stroke",
            "100mm",
            "--supply",
            "6bar",
            "--valve-flow",
            "300l/min",
        ],
        tmp.path(),
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("gains: kp ="), "{stdout}");
    let readme = std::fs::read_to_string(tmp.path().join("my-rig/README.md")).unwrap();
    assert!(
        readme.contains("`--rod`: 10 mm, the ISO 6432 rod"),
        "{readme}"
    );
    assert!(readme.contains("QN 300 l/min"), "{readme}");
    for f in [
        "scene.toml",
        "rig.toml",
        "pneumatics/actuator.toml",
        "pneumatics/valve.toml",
    ] {
        assert!(tmp.path().join("my-rig").join(f).is_file(), "{f}");
    }
    let run = pneuflex(&["run", "my-rig/scene.toml", "--quiet"], tmp.path());
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        !stderr.contains("warning: my-rig/scene.toml"),
        "a generated scene has no loop warning: {stderr}"
    );
    let summary = std::fs::read_to_string(tmp.path().join("out/my-rig/summary.json")).unwrap();
    assert!(summary.contains("\"claims\""), "{summary}");
}

#[test]
fn bad_datasheet_values_name_their_option_and_write_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    for (args, expect) in [
        (
            vec!["--bore", "25", "--stroke", "100mm"],
            "--bore 25: give a unit",
        ),
        (
            vec!["--bore", "25mm", "--stroke", "100mm", "--supply", "6atm"],
            "unknown unit `atm`",
        ),
        (
            vec![
                "--bore",
                "25mm",
                "--stroke",
                "100mm",
                "--position-range",
                "75mm",
            ],
            "--position-range: 75.0 mm is shorter than the 100.0 mm stroke",
        ),
        (
            vec!["--iso-bore", "30", "--stroke", "100mm"],
            "--iso-bore 30: not a bore of ISO 6432 or ISO 15552",
        ),
        (
            vec!["--bore", "25mm", "--stroke", "100mm", "--valve-c", "fast"],
            "--valve-c fast",
        ),
    ] {
        let mut a = vec!["new", "rig", "x"];
        a.extend(args.iter());
        let out = pneuflex(&a, tmp.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{a:?}: {stderr}");
        assert!(stderr.contains(expect), "{a:?}: {stderr}");
    }
    assert!(
        std::fs::read_dir(tmp.path()).unwrap().next().is_none(),
        "nothing written"
    );
}
