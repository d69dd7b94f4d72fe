//! `pneuflex rig run` on a scene with several actuators (the gripper): the scene's run through the one loop
//! on an emulated board of two channels whose plant is the scene's own mechanism, in lockstep.

mod common;

use common::{col, pneuflex, read_trace, text};
use std::path::Path;
use std::process::{Command, Output};

fn rig_run(out: &Path, rig: &str, extra: &[&str]) -> Output {
    let mut args = vec![
        "rig",
        "run",
        "--rig",
        rig,
        "--scene",
        "scenes/gripper.toml",
        "--lockstep-truth",
        "pneumatics/gripper-finger.toml",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    pneuflex(&args)
}

/// The board run of the scene's own sheets writes both fingers' columns, the mechanism's summary and figure,
/// and follows the simulation of the same run: over the recorded second (the approach, contact, the squeeze)
/// each finger's force within 0.1 N RMS of `pneuflex run`'s, the difference the board's ADC noise and
/// velocity filter make. A second board run with the same seed is the same recording.
#[test]
fn the_gripper_on_a_board_of_two_channels_records_both_fingers_and_follows_its_simulation() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a");
    let o = rig_run(&a, "rigs/gripper.toml", &["--duration", "1"]);
    assert!(o.status.success(), "{}", text(&o));
    let (h, rows) = read_trace(&a.join("impedance").join("trace.csv"));
    for c in [
        "left.f_e",
        "left.x",
        "left.p_a",
        "left.u",
        "right.f_e",
        "right.x",
        "right.p_b",
        "board_t",
    ] {
        col(&h, c);
    }
    assert_eq!(rows.len(), 1001, "1 s at 1 ms");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(a.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["actuators"], serde_json::json!(["left", "right"]));
    assert_eq!(summary["runs"][0]["name"], "impedance");
    let png = std::fs::read(a.join("impedance").join("force.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let manifest = std::fs::read_to_string(a.join(".pneuflex-output.json")).unwrap();
    assert!(manifest.contains("\"truth\""), "{manifest}");

    let sim = dir.path().join("sim");
    let o = pneuflex(&[
        "run",
        "scenes/gripper.toml",
        "--out",
        sim.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let (hs, srows) = read_trace(&sim.join("impedance").join("trace.csv"));
    for finger in ["left", "right"] {
        let (i, j) = (
            col(&h, &format!("{finger}.f_e")),
            col(&hs, &format!("{finger}.f_e")),
        );
        let n = 1001;
        let rms = (rows[..n]
            .iter()
            .zip(&srows[..n])
            .map(|(b, s)| (b[i] - s[j]).powi(2))
            .sum::<f64>()
            / n as f64)
            .sqrt();
        let peak = srows[..n].iter().map(|s| s[j].abs()).fold(0.0, f64::max);
        assert!(
            peak > 4.0,
            "{finger}: the squeeze reached {peak} N by 0.3 s"
        );
        assert!(
            rms < 0.1,
            "{finger}: board run {rms:.4} N RMS from the simulation over the first 0.3 s"
        );
    }

    // `compare` on the recording: each finger's f_e and x RMS difference over the recorded second, as an
    // independent calculation from the two traces gives it.
    let cmp = dir.path().join("cmp");
    let log = a.join("impedance").join("trace.csv");
    let o = pneuflex(&[
        "compare",
        "scenes/gripper.toml",
        "--rig-log",
        log.to_str().unwrap(),
        "--out",
        cmp.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(cmp.join("compare.json")).unwrap()).unwrap();
    assert_eq!(report["samples"], 1001);
    for (k, finger) in ["left", "right"].iter().enumerate() {
        let got = &report["actuators"][k];
        assert_eq!(got["actuator"], *finger);
        for (c, key) in [("f_e", "f_e_rms_difference_n"), ("x", "x_rms_difference_m")] {
            let (i, j) = (
                col(&h, &format!("{finger}.{c}")),
                col(&hs, &format!("{finger}.{c}")),
            );
            let want = (rows
                .iter()
                .zip(&srows)
                .map(|(b, s)| (b[i] - s[j]).powi(2))
                .sum::<f64>()
                / rows.len() as f64)
                .sqrt();
            let v = got[key].as_f64().unwrap();
            assert!(
                (v - want).abs() <= 1e-9 * want.max(1e-9),
                "{finger} {key}: {v} vs {want}"
            );
        }
    }
    assert!(
        report["metrics"]
            .as_array()
            .unwrap()
            .iter()
            .any(|m| m["window"] == "squeeze"
                && m["actuator"] == "right"
                && m["metric"] == "rms_force_error_n")
    );
    assert_eq!(&std::fs::read(cmp.join("force.png")).unwrap()[1..4], b"PNG");
    // A simulation's trace is not a recording; a recording is not another scene's.
    let o = pneuflex(&[
        "compare",
        "scenes/gripper.toml",
        "--rig-log",
        sim.join("impedance").join("trace.csv").to_str().unwrap(),
    ]);
    assert!(
        !o.status.success() && text(&o).contains("a simulation's trace"),
        "{}",
        text(&o)
    );
    let o = pneuflex(&[
        "compare",
        "scenes/lever.toml",
        "--rig-log",
        log.to_str().unwrap(),
    ]);
    assert!(
        !o.status.success() && text(&o).contains("not of `lever`"),
        "{}",
        text(&o)
    );

    let b = dir.path().join("b");
    let o = rig_run(&b, "rigs/gripper.toml", &["--duration", "1"]);
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(
        std::fs::read(a.join("impedance").join("trace.csv")).unwrap(),
        std::fs::read(b.join("impedance").join("trace.csv")).unwrap(),
        "two lockstep runs with one seed"
    );
}

/// A fault on one channel (the right finger's load cell past its own limit) ends the run in that tick with
/// every valve safe; the recording is kept, marked, and the exit is non-zero.
#[test]
fn a_fault_on_one_finger_ends_the_run_and_keeps_the_recording() {
    let dir = tempfile::tempdir().unwrap();
    let rig =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("rigs/gripper.toml"))
            .unwrap();
    let rig = rig.replace(
        "[[channel]]\nname = \"right\"\n",
        "[[channel]]\nname = \"right\"\n[channel.limits]\nposition_m = [-0.001, 0.051]\nforce_n = [-5.0, 8.0]\n\
         pressure_pa = [60000.0, 800000.0]\nsupply_min_pa = 350000.0\n",
    );
    assert!(rig.contains("force_n = [-5.0, 8.0]"));
    let rig_path = dir.path().join("rig.toml");
    // The rig file's relative paths (sensor sheets) from its own folder.
    std::fs::write(
        &rig_path,
        rig.replace(
            "\"../pneumatics/",
            &format!("\"{}/pneumatics/", env!("CARGO_MANIFEST_DIR")),
        ),
    )
    .unwrap();
    let out = dir.path().join("out");
    let o = rig_run(&out, rig_path.to_str().unwrap(), &["--duration", "1"]);
    let all = text(&o);
    assert!(!o.status.success(), "{all}");
    assert!(all.contains("channel 1 (right)"), "{all}");
    assert!(
        all.contains("every valve was put in its safe state"),
        "{all}"
    );
    assert!(
        all.contains("force f_e = ") && all.contains("outside [-5, 8]"),
        "{all}"
    );
    let (h, rows) = read_trace(&out.join("impedance").join("trace.diverged.csv"));
    let f = col(&h, "right.f_e");
    let t = rows.last().unwrap()[0];
    assert!(
        t > 0.01 && t < 1.0,
        "the recording stops at the fault, t = {t} s"
    );
    assert!(
        rows.iter().any(|r| r[f] > 7.0),
        "the squeeze neared the limit"
    );
    assert!(out.join("summary.json").is_file());
}

/// What the command refuses, each naming the file and what to change.
#[test]
fn a_board_whose_channels_are_not_the_scenes_actuators_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let rig =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("rigs/gripper.toml"))
            .unwrap()
            .replace("name = \"right\"", "name = \"thumb\"")
            .replace(
                "\"../pneumatics/",
                &format!("\"{}/pneumatics/", env!("CARGO_MANIFEST_DIR")),
            );
    let rig_path = dir.path().join("rig.toml");
    std::fs::write(&rig_path, rig).unwrap();
    let out = dir.path().join("out");
    let o = rig_run(&out, rig_path.to_str().unwrap(), &[]);
    let all = text(&o);
    assert!(!o.status.success(), "{all}");
    assert!(
        all.contains("rig.toml") && all.contains("thumb") && all.contains("[[channel]]"),
        "{all}"
    );
    assert!(!out.exists(), "nothing written");

    let o = pneuflex(&[
        "rig",
        "run",
        "--rig",
        "rigs/gripper.toml",
        "--scene",
        "scenes/gripper.toml",
        "--port",
        "/dev/null",
    ]);
    let all = text(&o);
    assert!(!o.status.success(), "{all}");
    assert!(all.contains("--port") && all.contains("/dev/null"), "{all}");

    // --truth names an actuator of the scene.
    let o = rig_run(
        &out,
        "rigs/gripper.toml",
        &["--truth", "thumb=pneumatics/gripper-finger.toml"],
    );
    let all = text(&o);
    assert!(!o.status.success(), "{all}");
    assert!(
        all.contains("`thumb` is not an actuator") && all.contains("left, right"),
        "{all}"
    );
    assert!(!out.exists(), "nothing written");

    // The default rig file is the one-channel emulated rig: not this scene's board.
    let o = pneuflex(&[
        "rig",
        "run",
        "--scene",
        "scenes/gripper.toml",
        "--lockstep-truth",
        "pneumatics/gripper-finger.toml",
        "--out",
        out.to_str().unwrap(),
    ]);
    let all = text(&o);
    assert!(!o.status.success(), "{all}");
    assert!(
        all.contains("rigs/emulated.toml") && all.contains("[[channel]]"),
        "{all}"
    );
    assert!(!out.exists(), "nothing written");

    // A muscle's one pressure is not a board channel's two: refused, naming the actuator.
    let muscles = dir.path().join("muscles.toml");
    std::fs::write(
        &muscles,
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("rigs/gripper.toml"))
            .unwrap()
            .replace("name = \"left\"", "name = \"flexor\"")
            .replace("name = \"right\"", "name = \"extensor\"")
            .replace(
                "\"../pneumatics/",
                &format!("\"{}/pneumatics/", env!("CARGO_MANIFEST_DIR")),
            ),
    )
    .unwrap();
    let o = pneuflex(&[
        "rig",
        "run",
        "--rig",
        muscles.to_str().unwrap(),
        "--scene",
        "scenes/antagonist.toml",
        "--lockstep-truth",
        "pneumatics/festo-dmsp-10-muscle.toml",
        "--out",
        out.to_str().unwrap(),
    ]);
    let all = text(&o);
    assert!(
        !o.status.success() && all.contains("(flexor) is a muscle"),
        "{all}"
    );
    assert!(!out.exists(), "nothing written");

    // `compare` takes only a recording of the scene: a CSV from elsewhere is refused with what it needs.
    let log = dir.path().join("trace.csv");
    std::fs::write(&log, "t,left.f_e\n0,0\n").unwrap();
    let o = pneuflex(&[
        "compare",
        "scenes/gripper.toml",
        "--rig-log",
        log.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let all = text(&o);
    assert!(!o.status.success(), "{all}");
    assert!(all.contains("rig run --scene"), "{all}");
    assert!(!out.exists(), "nothing written");
}

/// The same scene in real time: `rig emulate --scene` serves the mechanism on a pseudo-terminal, `rig run
/// --port` drives it on the wall clock. Loose on purpose (the machine may be loaded: the watchdogs are widened
/// and nothing is timed): both fingers' columns for every tick, the squeeze reaching both pads, no fault.
#[test]
fn the_gripper_runs_in_real_time_on_an_emulated_board_of_two_channels() {
    use std::io::{BufRead, BufReader};
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let rig = std::fs::read_to_string(root.join("rigs/gripper.toml"))
        .unwrap()
        .replace(
            "\"../pneumatics/",
            &format!("\"{}/pneumatics/", root.display()),
        )
        .replace("handshake_timeout_ms = 500", "handshake_timeout_ms = 5000")
        .replace("timeout_ms = 20.0 ", "timeout_ms = 1000.0 ")
        .replace("board_watchdog_ms = 50 ", "board_watchdog_ms = 2000 ");
    assert!(rig.contains("timeout_ms = 1000.0") && rig.contains("board_watchdog_ms = 2000"));
    let rig_path = dir.path().join("rig.toml");
    std::fs::write(&rig_path, rig).unwrap();
    let mut emulator = Command::new(env!("CARGO_BIN_EXE_pneuflex"))
        .args(["rig", "emulate", "--rig", rig_path.to_str().unwrap()])
        .args(["--scene", "scenes/gripper.toml", "--duration", "60"])
        .current_dir(root)
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Kept open until the end: the emulator prints each run it serves.
    let mut said = BufReader::new(emulator.stdout.take().unwrap());
    let mut line = String::new();
    said.read_line(&mut line).unwrap();
    let pty = line
        .split_whitespace()
        .find(|w| w.starts_with("/dev/"))
        .unwrap_or_else(|| panic!("no pty in {line:?}"))
        .to_string();
    let out = dir.path().join("rt");
    let o = pneuflex(&[
        "rig",
        "run",
        "--rig",
        rig_path.to_str().unwrap(),
        "--scene",
        "scenes/gripper.toml",
        "--port",
        &pty,
        "--duration",
        "1",
        "--out",
        out.to_str().unwrap(),
    ]);
    let _ = emulator.kill();
    let _ = emulator.wait();
    drop(said);
    assert!(o.status.success(), "{}", text(&o));
    let (h, rows) = read_trace(&out.join("impedance").join("trace.csv"));
    assert_eq!(rows.len(), 1001);
    for finger in ["left", "right"] {
        let f = col(&h, &format!("{finger}.f_e"));
        let peak = rows.iter().map(|r| r[f]).fold(f64::MIN, f64::max);
        assert!(peak > 5.0, "{finger}: the squeeze reached {peak} N");
    }
}

/// `rig excite --scene`: every actuator its own excitation at once on the board, a recording `identify
/// --channel` reads and `compare` refuses as what it is.
#[test]
fn the_gripper_excited_on_its_board_gives_each_finger_its_own_signal() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ex");
    let o = pneuflex(&[
        "rig",
        "excite",
        "--rig",
        "rigs/gripper.toml",
        "--scene",
        "scenes/gripper.toml",
        "--lockstep-truth",
        "pneumatics/gripper-finger.toml",
        "--signal",
        "steps",
        "--duration",
        "2",
        "--centre",
        "0.02",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let trace = out.join("excite").join("trace.csv");
    let (h, rows) = read_trace(&trace);
    assert_eq!(rows.len(), 2001);
    let (l, r) = (col(&h, "left.u"), col(&h, "right.u"));
    let differ = rows
        .iter()
        .filter(|row| (row[l] - row[r]).abs() > 1e-6)
        .count();
    assert!(
        differ > 500,
        "each finger its own signal: {differ} of 2001 ticks differ"
    );
    let manifest = std::fs::read_to_string(out.join(".pneuflex-output.json")).unwrap();
    assert!(manifest.contains("\"rig excite\""), "{manifest}");
    let o = pneuflex(&[
        "compare",
        "scenes/gripper.toml",
        "--rig-log",
        trace.to_str().unwrap(),
    ]);
    assert!(
        !o.status.success() && text(&o).contains("an excitation log"),
        "{}",
        text(&o)
    );
}
