//! `pneuflex ros2` (docs/ros2.md) without a peer: a short run on the loopback interface writes its trace and
//! summary as `run` does, into a recording that is never replaced; Ctrl-C ends it at the next tick and keeps
//! the trace in `DIR.partial`; bad input is refused before the node joins a domain or anything is written.
//! The node against another DDS (Cyclone) is scripts/check_ros2_node.py.

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn pneuflex(args: &[&str], env: &[(&str, &str)]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pneuflex"))
        .args(args)
        .env_remove("ROS_DOMAIN_ID")
        .envs(env.iter().copied())
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("runs")
}

/// A domain of this test process's own (the tests of this file run at once: each adds its offset).
fn domain(offset: u32) -> String {
    (101 + (std::process::id() % 40) * 3 + offset).to_string()
}

fn rows(trace: &Path) -> usize {
    std::fs::read_to_string(trace)
        .unwrap()
        .lines()
        .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()))
        .count()
}

#[test]
fn a_short_run_writes_its_trace_into_a_recording() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("node");
    let o = pneuflex(
        &[
            "ros2",
            "scenes/paper-fig3.toml",
            "--run",
            "adaptive",
            "--duration",
            "0.3",
            "--domain-id",
            &domain(0),
            "--localhost",
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ],
        &[],
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(stdout.contains("301 ticks to t = 0.300 s"), "{stdout}");
    assert!(stdout.contains("joint commands: 0 received"), "{stdout}");
    assert_eq!(rows(&out.join("adaptive").join("trace.csv")), 301);
    let summary = std::fs::read_to_string(out.join("summary.json")).unwrap();
    assert!(summary.contains("\"adaptive\"") && !summary.contains("\"impedance\""));
    let manifest = std::fs::read_to_string(out.join(".pneuflex-output.json")).unwrap();
    assert!(manifest.contains("\"command\": \"ros2\""), "{manifest}");
    assert!(manifest.contains("\"recording\": true"), "{manifest}");
    // A recording is never replaced.
    let again = pneuflex(
        &[
            "ros2",
            "scenes/paper-fig3.toml",
            "--duration",
            "0.1",
            "--domain-id",
            &domain(0),
            "--localhost",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert!(!again.status.success());
    assert_eq!(rows(&out.join("adaptive").join("trace.csv")), 301);
}

#[test]
fn ctrl_c_keeps_what_ran_in_the_partial() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("node");
    let child = Command::new(env!("CARGO_BIN_EXE_pneuflex"))
        .args([
            "ros2",
            "scenes/gripper.toml",
            "--duration",
            "30",
            "--domain-id",
            &domain(1),
            "--localhost",
            "--out",
            out.to_str().unwrap(),
        ])
        .env_remove("ROS_DOMAIN_ID")
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The node has started when its staged output exists; then it runs a moment longer.
    let started = Instant::now();
    while started.elapsed() < Duration::from_secs(20)
        && !std::fs::read_dir(dir.path()).unwrap().any(|e| {
            e.unwrap()
                .file_name()
                .to_string_lossy()
                .starts_with(".node.partial-")
        })
    {
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(700));
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let o = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(130), "{stderr}");
    assert!(
        stderr.contains("SIGINT: the node stopped at t = "),
        "{stderr}"
    );
    let partial = dir.path().join("node.partial");
    let trace = partial.join("impedance").join("trace.interrupted.csv");
    let n = rows(&trace);
    assert!((2..30_000).contains(&n), "{n} rows");
    assert!(!out.exists());
    // Both joints' columns, as `run` writes a mechanism's trace (an interrupted run's name).
    let header = std::fs::read_to_string(&trace).unwrap();
    assert!(header.contains("left.f_e") && header.contains("right.f_e"));
}

#[test]
fn bad_input_is_refused_before_the_node_starts() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("node");
    let out = out.to_str().unwrap();
    // Arguments (before --out), the environment, what the error says.
    type Case<'a> = (&'a [&'a str], &'a [(&'a str, &'a str)], &'a str);
    let cases: [Case<'_>; 9] = [
        (&["ros2", "scenes/no-such.toml"], &[], "no-such.toml"),
        (
            &["ros2", "scenes/paper-fig3.toml", "--run", "pid"],
            &[],
            "no run named \"pid\"",
        ),
        (
            &["ros2", "scenes/paper-fig3.toml", "--domain-id", "233"],
            &[],
            "--domain-id: a DDS domain id is 0 to 232",
        ),
        (
            &["ros2", "scenes/paper-fig3.toml"],
            &[("ROS_DOMAIN_ID", "seven")],
            "ROS_DOMAIN_ID: not a whole number: \"seven\"",
        ),
        (
            &["ros2", "scenes/paper-fig3.toml", "--duration", "0"],
            &[],
            "--duration: expected a duration in seconds",
        ),
        (
            &["ros2", "scenes/paper-fig3.toml", "--command-timeout", "0"],
            &[],
            "--command-timeout: expected a time in seconds",
        ),
        (
            &[
                "rig",
                "run",
                "--scene",
                "scenes/paper-fig3.toml",
                "--lockstep-truth",
                "pneumatics/paper-actuator.toml",
                "--ros2",
            ],
            &[],
            "--ros2: bridges a real-time run",
        ),
        (
            &[
                "rig",
                "run",
                "--scene",
                "scenes/paper-fig3.toml",
                "--domain-id",
                "3",
            ],
            &[],
            "--domain-id, --localhost and --command-timeout apply to --ros2",
        ),
        (
            &["rig", "run", "--scene", "scenes/gripper.toml", "--ros2"],
            &[],
            "--ros2: a scene with several actuators on a board is not bridged",
        ),
    ];
    for (args, env, want) in cases {
        let mut all = args.to_vec();
        all.extend_from_slice(&["--out", out]);
        let o = pneuflex(&all, env);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(stderr.contains(want), "{args:?}: {stderr}");
        assert!(!Path::new(out).exists(), "{args:?} wrote {out}");
    }
}
