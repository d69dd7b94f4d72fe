//! `--mcap` (docs/ros2.md): `run` writes each run's trace also as a rosbag2 folder `<run>/bag/` whose
//! messages hold the trace's values (read back through the MCAP crate's reader), one joint state a tick;
//! `identify` fits a bag of `rig excite --mcap` to the same estimates as its trace.csv.

use std::path::Path;
use std::process::Command;

use pneuflex::scene::Trace;
use pneuflex_ros2::bag::read_bag;
use pneuflex_ros2::msg::{Float64MultiArray, FluidPressure, JointState, Message};

fn pneuflex(args: &[&str]) -> std::process::Output {
    let o = Command::new(env!("CARGO_BIN_EXE_pneuflex"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("runs");
    assert!(
        o.status.success(),
        "pneuflex {args:?}:\n{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

fn trace(dir: &Path) -> Trace {
    Trace::from_csv(
        &std::fs::read_to_string(dir.join("trace.csv")).unwrap(),
        &[],
    )
    .unwrap()
}

/// Topic `name`'s Float64MultiArray values, one vector a message.
fn arrays(bag: &pneuflex_ros2::BagContents, name: &str) -> Vec<Vec<f64>> {
    bag.messages::<Float64MultiArray>(name)
        .unwrap()
        .iter()
        .map(|m| Float64MultiArray::decode(&m.data).unwrap().data)
        .collect()
}

#[test]
fn paper_fig3_has_one_joint_state_a_tick_with_the_traces_values() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("fig3");
    pneuflex(&[
        "run",
        "scenes/paper-fig3.toml",
        "--out",
        out.to_str().unwrap(),
        "--quiet",
        "--mcap",
    ]);
    let manifest = std::fs::read_to_string(out.join(".pneuflex-output.json")).unwrap();
    for run in ["impedance", "adaptive", "frozen_means", "frozen_bounds"] {
        let tr = trace(&out.join(run));
        let bag = read_bag(&out.join(run).join("bag")).unwrap();
        let states = bag
            .messages::<JointState>("/pneuflex/joint_states")
            .unwrap();
        assert_eq!(states.len(), tr.len(), "{run}: one joint state a tick");
        for (k, m) in states.iter().enumerate() {
            let s = JointState::decode(&m.data).unwrap();
            assert_eq!(s.name, ["cylinder"]);
            assert!(
                (m.t_ns as f64 * 1e-9 - tr.t()[k]).abs() < 1e-9,
                "{run} tick {k}"
            );
            assert_eq!(s.header.stamp.nanos().unwrap(), m.t_ns);
            assert_eq!(
                (s.position[0], s.effort[0]),
                (tr.x()[k], tr.f_e()[k]),
                "{run} tick {k}"
            );
            assert!(s.velocity.is_empty(), "the 1-DOF plant records no velocity");
        }
        for (chamber, column) in [('a', tr.p_a()), ('b', tr.p_b())] {
            let p: Vec<f64> = bag
                .messages::<FluidPressure>(&format!("/pneuflex/pressures/cylinder/{chamber}"))
                .unwrap()
                .iter()
                .map(|m| FluidPressure::decode(&m.data).unwrap().fluid_pressure)
                .collect();
            assert_eq!(p, column, "{run} p_{chamber}");
        }
        let one = |v: Vec<Vec<f64>>| v.into_iter().map(|d| d[0]).collect::<Vec<_>>();
        assert_eq!(one(arrays(&bag, "/pneuflex/valve_command")), tr.u());
        assert_eq!(one(arrays(&bag, "/pneuflex/force_reference")), tr.f_ref());
        assert_eq!(one(arrays(&bag, "/pneuflex/controller/x_r")), tr.x_r());
        if run == "adaptive" {
            assert_eq!(
                one(arrays(&bag, "/pneuflex/controller/g")),
                tr.column("g").unwrap()
            );
        }
        // Committed with the run's other files.
        assert!(
            manifest.contains(&format!("\"{run}/bag/bag_0.mcap\"")),
            "{manifest}"
        );
        assert!(manifest.contains(&format!("\"{run}/bag/metadata.yaml\"")));
    }
}

#[test]
fn a_scene_of_two_actuators_has_two_joints_a_state_with_their_velocities() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cross");
    pneuflex(&[
        "run",
        "scenes/cross-slide.toml",
        "--out",
        out.to_str().unwrap(),
        "--quiet",
        "--mcap",
    ]);
    // A trace of several actuators has `<actuator>.<signal>` columns: read as a table.
    let text = std::fs::read_to_string(out.join("impedance/trace.csv")).unwrap();
    let mut lines = text.lines();
    let names: Vec<&str> = lines.next().unwrap().split(',').collect();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    let col = |n: &str, k: usize| rows[k][names.iter().position(|m| *m == n).unwrap()];
    let bag = read_bag(&out.join("impedance").join("bag")).unwrap();
    let states = bag
        .messages::<JointState>("/pneuflex/joint_states")
        .unwrap();
    assert_eq!(states.len(), rows.len());
    for (k, m) in states.iter().enumerate() {
        let s = JointState::decode(&m.data).unwrap();
        assert_eq!(s.name, ["press", "push"]);
        let c = |n: &str| col(n, k);
        assert_eq!(s.position, [c("press.x"), c("push.x")]);
        assert_eq!(s.velocity, [c("press.x_dot"), c("push.x_dot")]);
        assert_eq!(s.effort, [c("press.f_e"), c("push.f_e")]);
    }
    let u = arrays(&bag, "/pneuflex/valve_command");
    assert_eq!(u[100], [col("press.u", 100), col("push.u", 100)]);
}

#[test]
fn identify_fits_a_bag_of_rig_excite_as_it_fits_its_trace() {
    let dir = tempfile::tempdir().unwrap();
    let d = |p: &str| dir.path().join(p).to_str().unwrap().to_string();
    // The emulator hides the shipped sheet; 3 s of PRBS in lockstep.
    pneuflex(&[
        "rig",
        "excite",
        "--rig",
        "rigs/emulated.toml",
        "--lockstep-truth",
        "pneumatics/paper-actuator.toml",
        "--seed",
        "3",
        "--duration",
        "3",
        "--out",
        &d("ex"),
        "--mcap",
    ]);
    let fit = |log: &str, out: &str| {
        pneuflex(&[
            "identify",
            "--log",
            log,
            "--actuator",
            "pneumatics/paper-actuator.toml",
            "--free",
            "valve.sonic_conductance_m3_per_s_pa,mechanics.moving_mass_kg",
            "--out",
            out,
        ]);
        let r: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(Path::new(out).join("report.json")).unwrap(),
        )
        .unwrap();
        r
    };
    let csv = fit(&d("ex/trace.csv"), &d("fit-csv"));
    let bag = fit(&d("ex/bag"), &d("fit-bag"));
    assert_eq!(csv["fit"]["estimates"], bag["fit"]["estimates"]);
    assert_eq!(csv["logs"][0]["rows"], bag["logs"][0]["rows"]);
    assert_eq!(csv["logs"][0]["note"], bag["logs"][0]["note"]);
    assert_eq!(csv["model_check"], bag["model_check"]);
    assert_eq!(csv["fit"]["estimates"].as_array().unwrap().len(), 2);
}

#[test]
fn identify_refuses_a_folder_that_is_not_a_bag_naming_what_is_missing() {
    let dir = tempfile::tempdir().unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_pneuflex"))
        .args([
            "identify",
            "--log",
            dir.path().to_str().unwrap(),
            "--actuator",
        ])
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("pneumatics/paper-actuator.toml"))
        .args(["--free", "mechanics.moving_mass_kg", "--out"])
        .arg(dir.path().join("fit"))
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(&format!(
            "{}: cannot read (a rosbag2 folder has one)",
            dir.path().join("metadata.yaml").display()
        )),
        "{err}"
    );
    assert!(!dir.path().join("fit").exists());
}

#[test]
fn rig_run_writes_the_boards_record_on_its_clock() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("rr");
    pneuflex(&[
        "rig",
        "run",
        "--scene",
        "scenes/paper-fig3.toml",
        "--lockstep-truth",
        "pneumatics/paper-actuator.toml",
        "--duration",
        "1",
        "--out",
        out.to_str().unwrap(),
        "--mcap",
    ]);
    let text = std::fs::read_to_string(out.join("trace.csv")).unwrap();
    let tr = Trace::from_csv(&text, &["wall_time", "fault"]).unwrap();
    let bag = read_bag(&out.join("bag")).unwrap();
    let states = bag
        .messages::<JointState>("/pneuflex/joint_states")
        .unwrap();
    // One joint state per board sample, at its board_t, with its readings.
    let board_t = tr.column("board_t").unwrap();
    let samples: Vec<usize> = (0..tr.len()).filter(|&k| board_t[k].is_finite()).collect();
    assert_eq!(states.len(), samples.len());
    for (m, &k) in states.iter().zip(&samples) {
        let s = JointState::decode(&m.data).unwrap();
        assert!((m.t_ns as f64 * 1e-9 - board_t[k]).abs() < 1e-9);
        assert_eq!(s.position, [tr.column("board_x").unwrap()[k]]);
        assert_eq!(s.effort, [tr.column("board_f_e").unwrap()[k]]);
    }
    let applied_u = tr.column("applied_u").unwrap();
    let echoes: Vec<f64> = applied_u
        .iter()
        .copied()
        .filter(|u| u.is_finite())
        .collect();
    let applied: Vec<f64> = arrays(&bag, "/pneuflex/valve_applied")
        .into_iter()
        .map(|d| d[0])
        .collect();
    assert_eq!(applied, echoes);
    // The loop's own command, one a tick.
    assert_eq!(arrays(&bag, "/pneuflex/valve_command").len(), tr.len());
}
