//! A trace written as a bag and read back (the MCAP crate's reader underneath): one message per topic and
//! tick, the values as written; a rig's trace on the board's clock; a bag folder that cannot be written.

use pneuflex_ros2::bag::read_bag;
use pneuflex_ros2::msg::{Float64MultiArray, FluidPressure, JointState, Message};
use pneuflex_ros2::trace_bag::{JOINT_STATES, VALVE_APPLIED, VALVE_COMMAND};
use pneuflex_ros2::{TraceColumns, read_actuator_log, write_trace_bag};

/// Two actuators `a` and `b`, 50 ticks of 1 ms: values that differ per column, tick and actuator.
fn two_actuators() -> (Vec<String>, Vec<Vec<f64>>) {
    let signals = ["f_ref", "f_e", "x", "x_r", "p_a", "p_b", "u", "g", "x_dot"];
    let mut names = vec!["t".to_string()];
    let mut cols = vec![(0..50).map(|k| k as f64 * 1e-3).collect::<Vec<_>>()];
    for (j, a) in ["a", "b"].iter().enumerate() {
        for (i, s) in signals.iter().enumerate() {
            names.push(format!("{a}.{s}"));
            cols.push(
                (0..50)
                    .map(|k| (1 + i) as f64 * 1e3 + k as f64 + 0.5 * j as f64)
                    .collect(),
            );
        }
    }
    (names, cols)
}

#[test]
fn a_two_actuator_trace_reads_back_value_for_value() {
    let dir = tempfile::tempdir().unwrap();
    let (names, cols) = two_actuators();
    let col = |n: &str| &cols[names.iter().position(|m| m == n).unwrap()][..];
    let table = TraceColumns {
        columns: names
            .iter()
            .map(String::as_str)
            .zip(cols.iter().map(Vec::as_slice))
            .collect(),
        actuators: vec!["a".into(), "b".into()],
    };
    let bag_dir = dir.path().join("bag");
    let summary = write_trace_bag(&bag_dir, &table).unwrap();
    // joint states, 2 x 2 pressures, valve command, force reference, x_r, g: 9 topics of 50 messages.
    assert_eq!(summary.topics.len(), 9, "{:?}", summary.topics);
    assert!(summary.topics.iter().all(|(_, n)| *n == 50));
    assert_eq!(summary.message_count, 450);
    assert!(bag_dir.join("bag_0.mcap").is_file());
    let meta = std::fs::read_to_string(bag_dir.join("metadata.yaml")).unwrap();
    assert!(meta.contains("  message_count: 450\n"), "{meta}");
    assert!(meta.contains("    nanoseconds: 49000000\n"), "{meta}");

    let bag = read_bag(&bag_dir).unwrap();
    let states = bag.messages::<JointState>(JOINT_STATES).unwrap();
    assert_eq!(states.len(), 50);
    for (k, m) in states.iter().enumerate() {
        let s = JointState::decode(&m.data).unwrap();
        assert_eq!(s.name, ["a", "b"]);
        assert_eq!(m.t_ns, k as u64 * 1_000_000);
        assert_eq!(s.header.stamp.nanos().unwrap(), m.t_ns);
        assert_eq!(s.position, [col("a.x")[k], col("b.x")[k]]);
        assert_eq!(s.velocity, [col("a.x_dot")[k], col("b.x_dot")[k]]);
        assert_eq!(s.effort, [col("a.f_e")[k], col("b.f_e")[k]]);
    }
    let p = bag
        .messages::<FluidPressure>("/pneuflex/pressures/b/a")
        .unwrap();
    assert_eq!(
        FluidPressure::decode(&p[7].data).unwrap().fluid_pressure,
        col("b.p_a")[7]
    );
    let g = bag
        .messages::<Float64MultiArray>("/pneuflex/controller/g")
        .unwrap();
    assert_eq!(
        Float64MultiArray::decode(&g[3].data).unwrap().data,
        [col("a.g")[3], col("b.g")[3]]
    );
    // A topic of another type is refused by name.
    let e = bag
        .messages::<JointState>(VALVE_COMMAND)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("std_msgs/msg/Float64MultiArray, not sensor_msgs/msg/JointState"),
        "{e}"
    );

    // Actuator b as identification reads it.
    let log = read_actuator_log(&bag_dir, Some("b")).unwrap();
    // A bag's clock counts whole ns: t reads back to within half of one.
    assert!(
        log.t
            .iter()
            .zip(col("t"))
            .all(|(a, b)| (a - b).abs() <= 0.5e-9)
    );
    assert_eq!(log.u, col("b.u"));
    assert_eq!(log.x, col("b.x"));
    assert_eq!(log.p_b, col("b.p_b"));
    assert_eq!(log.f_e, col("b.f_e"));
    let e = read_actuator_log(&bag_dir, None).unwrap_err().to_string();
    assert!(e.contains("has the joints a, b: say which one"), "{e}");
}

#[test]
fn a_rig_trace_is_written_on_the_boards_clock() {
    // 20 loop ticks; the board's sample j (time 3 s + j ms) recorded two rows late, sample 9 missing; the
    // command it applied at j ms echoed one row late.
    let n = 20;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
    let sample = |k: usize| (k >= 2 && k != 11).then(|| k - 2);
    let board_t: Vec<f64> = (0..n)
        .map(|k| sample(k).map_or(f64::NAN, |j| 3.0 + j as f64 * 1e-3))
        .collect();
    let board_x: Vec<f64> = (0..n)
        .map(|k| sample(k).map_or(f64::NAN, |j| j as f64 * 1e-4))
        .collect();
    let applied_t: Vec<f64> = (0..n)
        .map(|k| {
            if k >= 1 {
                3.0 + (k - 1) as f64 * 1e-3
            } else {
                f64::NAN
            }
        })
        .collect();
    let applied_u: Vec<f64> = (0..n)
        .map(|k| if k >= 1 { 0.01 * k as f64 } else { f64::NAN })
        .collect();
    let zero = vec![0.0; n];
    let p: Vec<f64> = vec![2e5; n];
    let table = TraceColumns {
        columns: vec![
            ("t", &t[..]),
            ("f_ref", &zero),
            ("f_e", &zero),
            ("x", &zero),
            ("x_r", &zero),
            ("p_a", &p),
            ("p_b", &p),
            ("u", &zero),
            ("board_t", &board_t),
            ("board_x", &board_x),
            ("board_f_e", &board_x),
            ("board_p_a", &board_x),
            ("board_p_b", &board_x),
            ("applied_t", &applied_t),
            ("applied_u", &applied_u),
        ],
        actuators: vec![],
    };
    let dir = tempfile::tempdir().unwrap();
    let bag_dir = dir.path().join("bag");
    write_trace_bag(&bag_dir, &table).unwrap();
    let bag = read_bag(&bag_dir).unwrap();
    assert_eq!(bag.messages::<JointState>(JOINT_STATES).unwrap().len(), 17);
    assert_eq!(
        bag.messages::<Float64MultiArray>(VALVE_APPLIED)
            .unwrap()
            .len(),
        19
    );
    assert_eq!(
        bag.messages::<Float64MultiArray>(VALVE_COMMAND)
            .unwrap()
            .len(),
        20
    );
    assert!(
        !bag.topics
            .keys()
            .any(|k| k.contains("board") || k.contains("applied_"))
    );
    let log = read_actuator_log(&bag_dir, None).unwrap();
    assert_eq!(log.joint, "cylinder");
    assert_eq!(log.t.len(), 17);
    assert_eq!(log.t[8], 3.008);
    assert_eq!(log.t[9], 3.010, "sample 9 is missing from the record");
    assert_eq!(log.x[9], 10.0 * 1e-4);
    assert!(log.u.is_empty());
    let applied = log.applied.unwrap();
    assert_eq!(applied.len(), 19);
    assert_eq!(applied[4], (3.004, 0.05));
}

#[test]
fn a_bag_folder_that_cannot_be_made_is_an_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("trace.csv");
    std::fs::write(&file, "not a folder").unwrap();
    let t = [0.0, 0.001];
    let table = TraceColumns {
        columns: vec![
            ("t", &t[..]),
            ("x", &t),
            ("f_e", &t),
            ("u", &t),
            ("f_ref", &t),
        ],
        actuators: vec![],
    };
    let inside_a_file = file.join("bag");
    let e = write_trace_bag(&inside_a_file, &table)
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with(&format!(
            "{}: cannot create the bag folder",
            inside_a_file.display()
        )),
        "{e}"
    );
    let exists = dir.path().join("old");
    std::fs::create_dir(&exists).unwrap();
    let e = write_trace_bag(&exists, &table).unwrap_err().to_string();
    assert!(
        e.contains("old: cannot create the bag folder: it exists already"),
        "{e}"
    );
    // A trace without a position has no joint state to write.
    let table = TraceColumns {
        columns: vec![("t", &t[..])],
        actuators: vec![],
    };
    let e = write_trace_bag(&dir.path().join("new"), &table)
        .unwrap_err()
        .to_string();
    assert!(e.contains("the trace has no column `x`"), "{e}");
    assert!(!dir.path().join("new").exists());
}

#[test]
fn a_folder_without_metadata_is_not_a_bag() {
    let dir = tempfile::tempdir().unwrap();
    let e = read_bag(dir.path()).unwrap_err().to_string();
    assert!(
        e.contains("metadata.yaml: cannot read (a rosbag2 folder has one)"),
        "{e}"
    );
}

#[test]
fn a_plant_without_chambers_has_no_pressure_topics() {
    let dir = tempfile::tempdir().unwrap();
    let t = [0.0, 0.001, 0.002];
    let none = [f64::NAN; 3];
    let table = TraceColumns {
        columns: vec![
            ("t", &t[..]),
            ("f_ref", &t),
            ("f_e", &t),
            ("x", &t),
            ("p_a", &none),
            ("p_b", &none),
            ("u", &t),
        ],
        actuators: vec![],
    };
    let s = write_trace_bag(&dir.path().join("bag"), &table).unwrap();
    let topics: Vec<&str> = s.topics.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        topics,
        [JOINT_STATES, VALVE_COMMAND, "/pneuflex/force_reference"]
    );
}

/// A bag as a robot's `ros2 bag record --storage-preset-profile zstd_fast` may leave it: zstd chunks.
#[test]
fn a_bag_of_zstd_chunks_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("robot_0.mcap");
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .compression(Some(mcap::Compression::Zstd))
        .create(std::io::BufWriter::new(
            std::fs::File::create(&file).unwrap(),
        ))
        .unwrap();
    let schema = w
        .add_schema(
            JointState::TYPE,
            "ros2msg",
            JointState::definition().as_bytes(),
        )
        .unwrap();
    let channel = w
        .add_channel(schema, JOINT_STATES, "cdr", &Default::default())
        .unwrap();
    for k in 0..100u32 {
        let m = JointState {
            name: vec!["j".into()],
            position: vec![f64::from(k)],
            ..JointState::default()
        };
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: k,
            log_time: u64::from(k) * 1_000_000,
            publish_time: u64::from(k) * 1_000_000,
        };
        w.write_to_known_channel(&header, &m.encode()).unwrap();
    }
    w.finish().unwrap();
    drop(w);
    std::fs::write(
        dir.path().join("metadata.yaml"),
        "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: mcap\n  relative_file_paths:\n    - robot_0.mcap\n",
    )
    .unwrap();
    let bag = read_bag(dir.path()).unwrap();
    let states = bag.messages::<JointState>(JOINT_STATES).unwrap();
    assert_eq!(states.len(), 100);
    assert_eq!(
        JointState::decode(&states[42].data).unwrap().position,
        [42.0]
    );
}
