//! Recordings read back with Rerun's own decoder, and the sink errors.

use std::net::TcpListener;
use std::time::{Duration, Instant};

use pneuflex_rerun::{
    ChamberSample, Clock, Contact, EventLevel, LinkShape, RecorderOptions, RerunError, RunRecorder,
    Sink, paths,
};
use pneuflex_scene::plants::VisualShape;

mod common;
use common::{read_back, temp_dir};

/// Records `steps` steps of a small scene the way the run loop does.
fn record(rec: &mut RunRecorder, steps: usize, dt: f64) {
    rec.log_link_shape(&LinkShape {
        entity: paths::link("flange"),
        shape: VisualShape::Cylinder {
            radius_m: 0.03,
            half_length_m: 0.005,
        },
        colour: [200, 200, 200, 255],
    })
    .unwrap();
    rec.log_link_shape(&LinkShape {
        entity: paths::link("block"),
        shape: VisualShape::Box {
            half_extents_m: [0.05, 0.05, 0.05],
        },
        colour: [90, 90, 90, 255],
    })
    .unwrap();
    // A mesh (a URDF mesh's convex hull): a tetrahedron.
    rec.log_link_shape(&LinkShape {
        entity: paths::link("wedge"),
        shape: VisualShape::Mesh {
            vertices_m: vec![
                [0.0; 3],
                [0.02, 0.0, 0.0],
                [0.0, 0.02, 0.0],
                [0.0, 0.0, 0.02],
            ],
            triangles: vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
        },
        colour: [120, 90, 60, 255],
    })
    .unwrap();
    rec.set_chamber_bore(0.032).unwrap();
    rec.register_series(paths::VALVE_U, "u [-]", [0, 200, 0, 255], 1.5)
        .unwrap();
    rec.log_event(0.0, EventLevel::Info, "start").unwrap();
    for k in 0..steps {
        let t = k as f64 * dt;
        let x = 0.01 * (t * 3.0).sin();
        rec.log_scalars(
            t,
            &[
                (paths::F_REF, 20.0),
                (paths::F_E, 20.0 * (1.0 - (-t).exp())),
                (paths::X, x),
                (paths::X_R, 0.0),
                (paths::P_A, 3e5),
                (paths::P_B, 2e5),
            ],
        )
        .unwrap();
        rec.set_link_pose(
            t,
            &paths::link("flange"),
            [0.0, 0.0, x],
            [0.0, 0.0, 0.0, 1.0],
        )
        .unwrap();
        let contact = (k % 2 == 0).then_some(Contact {
            point_m: [0.0, 0.0, x],
            force_n: [0.0, 0.0, -20.0],
            arrow_from_m: [0.0, 0.03, x],
        });
        rec.log_contact(t, contact.as_ref()).unwrap();
        rec.log_chambers(
            t,
            &ChamberSample {
                length_a_m: 0.05 + x,
                pressure_a_pa: 3e5,
                length_b_m: 0.05 - x,
                pressure_b_pa: 2e5,
            },
        )
        .unwrap();
    }
    rec.log_event(steps as f64 * dt, EventLevel::Warn, "end")
        .unwrap();
}

#[test]
fn saved_recording_reads_back_with_one_row_per_step_and_a_footer() {
    let dir = temp_dir("save");
    let dir = dir.path().to_path_buf();
    let file = dir.join("run.rrd");
    let steps = 1000;
    // A batch size that does not divide the step count exercises full and partial batches.
    let opts = RecorderOptions {
        batch_rows: 300,
        ..RecorderOptions::default()
    };
    let mut rec =
        RunRecorder::with_options("pneuflex-test", "save", &Sink::Save(file.clone()), opts)
            .unwrap();
    record(&mut rec, steps, 1e-3);
    rec.finish().unwrap();

    // Read immediately after finish(): the file must already be complete (footer present).
    let back = read_back(&file);
    assert!(back.bytes > 0);
    assert!(
        back.has_footer,
        "finish() returned before the footer was written"
    );
    let rows = |e: &str, tl: &str| {
        back.rows_on
            .get(&(e.to_owned(), tl.to_owned()))
            .copied()
            .unwrap_or(0)
    };
    for p in [
        paths::F_REF,
        paths::F_E,
        paths::X,
        paths::X_R,
        paths::P_A,
        paths::P_B,
    ] {
        assert_eq!(rows(&format!("/{p}"), "sim_time"), steps, "{p}");
    }
    // Registered but never logged: present as a static style, no samples.
    assert_eq!(rows(&format!("/{}", paths::VALVE_U), "sim_time"), 0);
    assert!(
        back.static_entities
            .contains(&format!("/{}", paths::VALVE_U))
    );
    let flange = format!("/{}", paths::link("flange"));
    assert_eq!(rows(&flange, "sim_time"), steps);
    assert!(back.static_entities.contains(&flange));
    assert!(
        back.static_entities
            .contains(&format!("/{}", paths::link("wedge"))),
        "the mesh link is in the recording"
    );
    assert_eq!(
        rows(&format!("/{}", paths::CONTACT_FORCE), "sim_time"),
        steps
    );
    assert_eq!(rows(&format!("/{}", paths::CHAMBER_A), "sim_time"), steps);
    assert_eq!(rows(&format!("/{}", paths::CHAMBER_B), "sim_time"), steps);
    assert_eq!(rows(&format!("/{}", paths::EVENTS), "sim_time"), 2);
    // Nothing of ours on the rig timeline in a simulation recording.
    assert_eq!(rows(&format!("/{}", paths::F_E), "wall_time"), 0);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn wall_clock_recording_uses_the_same_paths_on_wall_time() {
    let dir = temp_dir("wall");
    let dir = dir.path().to_path_buf();
    let file = dir.join("rig.rrd");
    let opts = RecorderOptions {
        clock: Clock::Wall,
        ..RecorderOptions::default()
    };
    let mut rec =
        RunRecorder::with_options("pneuflex-test", "rig", &Sink::Save(file.clone()), opts).unwrap();
    let t0 = pneuflex_rerun::wall_clock_s();
    for k in 0..50 {
        rec.log_scalars(t0 + k as f64 * 1e-3, &[(paths::F_E, k as f64)])
            .unwrap();
    }
    rec.finish().unwrap();
    let back = read_back(&file);
    let f_e = format!("/{}", paths::F_E);
    assert_eq!(
        back.rows_on.get(&(f_e.clone(), "wall_time".into())),
        Some(&50)
    );
    assert_eq!(back.rows_on.get(&(f_e, "sim_time".into())), None);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn save_into_missing_directory_names_the_path_and_creates_nothing() {
    let dir = temp_dir("missing");
    let dir = dir.path().to_path_buf();
    let missing = dir.join("no/such/dir");
    let file = missing.join("run.rrd");
    let err = RunRecorder::new("pneuflex-test", "missing", &Sink::Save(file.clone()))
        .err()
        .expect("must fail");
    assert!(
        matches!(&err, RerunError::SaveDirMissing { dir, .. } if *dir == missing),
        "{err}"
    );
    assert!(
        err.to_string().contains(&missing.display().to_string()),
        "{err}"
    );
    assert!(!dir.join("no").exists(), "nothing may be created");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn save_onto_a_directory_is_rejected() {
    let dir = temp_dir("isdir");
    let dir = dir.path().to_path_buf();
    let err = RunRecorder::new("pneuflex-test", "isdir", &Sink::Save(dir.clone()))
        .err()
        .expect("must fail");
    assert!(matches!(err, RerunError::SaveCreate { .. }), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn connect_where_nothing_listens_fails_fast_with_the_address() {
    // Take a free port from the OS, then close it so that nothing listens there.
    let port = {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().port()
    };
    let url = format!("rerun+http://127.0.0.1:{port}/proxy");
    let started = Instant::now();
    let err = RunRecorder::new("pneuflex-test", "refused", &Sink::Connect(url.clone()))
        .err()
        .expect("must fail");
    // Bounded by the probe timeout inside the recorder, not by this test.
    assert!(
        started.elapsed() < Duration::from_secs(10),
        "took {:?}",
        started.elapsed()
    );
    assert!(matches!(err, RerunError::ConnectFailed { .. }), "{err}");
    assert!(
        err.to_string().contains(&format!("127.0.0.1:{port}")),
        "{err}"
    );
}

#[test]
fn connect_with_a_malformed_address_is_a_bad_url() {
    let err = RunRecorder::new("pneuflex-test", "bad", &Sink::Connect("ftp://x:1".into()))
        .err()
        .expect("must fail");
    assert!(matches!(err, RerunError::BadUrl { .. }), "{err}");
}

#[test]
fn invalid_shapes_and_options_are_rejected() {
    let dir = temp_dir("shape");
    let dir = dir.path().to_path_buf();
    let mut rec =
        RunRecorder::new("pneuflex-test", "shape", &Sink::Save(dir.join("s.rrd"))).unwrap();
    for shape in [
        VisualShape::Sphere { radius_m: 0.0 },
        VisualShape::Sphere { radius_m: f64::NAN },
        VisualShape::Box {
            half_extents_m: [0.1, -0.1, 0.1],
        },
        VisualShape::Cylinder {
            radius_m: 0.1,
            half_length_m: f64::INFINITY,
        },
        // A mesh with a vertex that is not finite, and one whose triangle indexes past its vertices.
        VisualShape::Mesh {
            vertices_m: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, f64::NAN, 0.0]],
            triangles: vec![[0, 1, 2]],
        },
        VisualShape::Mesh {
            vertices_m: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            triangles: vec![[0, 1, 3]],
        },
    ] {
        let err = rec
            .log_link_shape(&LinkShape {
                entity: "world/links/x".into(),
                shape: shape.clone(),
                colour: [0, 0, 0, 255],
            })
            .unwrap_err();
        assert!(
            matches!(err, RerunError::BadShape { .. }),
            "{shape:?}: {err}"
        );
    }
    assert!(rec.set_chamber_bore(-1.0).is_err());
    rec.finish().unwrap();
    let opts = RecorderOptions {
        batch_rows: 0,
        ..RecorderOptions::default()
    };
    let err = RunRecorder::with_options("t", "t", &Sink::Save(dir.join("o.rrd")), opts)
        .err()
        .unwrap();
    assert!(matches!(err, RerunError::BadOption { .. }), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A rig run's rows as `rig run --rerun` hands them over: the loop's signals, the adaptive controller's,
/// the link's quality.
#[test]
fn a_row_observer_shows_a_rig_run_on_the_wall_clock_with_the_runs_paths_and_the_link() {
    use pneuflex_control::{LOOP_SIGNALS, Signal};
    use pneuflex_rerun::RowRecorder;
    let dir = temp_dir("rows");
    let dir = dir.path().to_path_buf();
    let file = dir.join("rig.rrd");
    let own = [
        Signal {
            name: "g",
            unit: "m",
            group: "adaptive",
            description: "g",
        },
        Signal {
            name: "crc_errors",
            unit: "1",
            group: "link",
            description: "frames dropped for a bad CRC",
        },
        Signal {
            name: "period_error",
            unit: "s",
            group: "timing",
            description: "period error",
        },
    ];
    let columns: Vec<Signal> = LOOP_SIGNALS.iter().chain(&own).copied().collect();
    let mut rec = RowRecorder::new(
        Sink::Save(file.clone()),
        "rig/test/adaptive",
        Clock::Wall,
        1e-3,
        None,
    )
    .unwrap();
    let before = pneuflex_rerun::wall_clock_s();
    <RowRecorder as pneuflex_control::Sink<()>>::begin(&mut rec, "rig", &columns, &());
    let n = 250;
    for k in 0..n {
        let mut row = vec![0.0; columns.len()];
        row[0] = k as f64 * 1e-3;
        row[2] = 10.0;
        row[columns.len() - 2] = (k / 100) as f64;
        // A tick without a value (NaN) is not drawn.
        row[columns.len() - 1] = if k == 7 { f64::NAN } else { 2e-5 };
        <RowRecorder as pneuflex_control::Sink<()>>::row(&mut rec, &row, &());
    }
    <RowRecorder as pneuflex_control::Sink<()>>::event(
        &mut rec,
        0.2,
        "fault at tick 200: link lost; the valve is in its safe state",
    );
    <RowRecorder as pneuflex_control::Sink<()>>::end(&mut rec, None);
    assert_eq!(rec.finish().unwrap(), n);
    let back = read_back(&file);
    assert!(back.has_active_blueprint(), "the layout is sent and active");
    assert_eq!(back.rows(&format!("/{}", paths::F_E), "wall_time"), n);
    assert_eq!(back.rows(&format!("/{}", paths::F_E), "sim_time"), 0);
    assert_eq!(back.rows("/signals/link/crc_errors", "wall_time"), n);
    assert_eq!(
        back.rows("/signals/timing/period_error", "wall_time"),
        n - 1
    );
    assert_eq!(back.rows("/signals/adaptive/g", "wall_time"), n);
    assert_eq!(back.rows(&format!("/{}", paths::EVENTS), "wall_time"), 1);
    // The timeline is the wall clock at the run's start plus the tick time.
    assert!(pneuflex_rerun::wall_clock_s() >= before);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_row_observer_refuses_a_save_path_in_a_missing_directory_before_the_run() {
    let dir = temp_dir("rows-missing");
    let dir = dir.path().to_path_buf();
    let file = dir.join("no/such/dir/rig.rrd");
    let err = pneuflex_rerun::RowRecorder::new(Sink::Save(file), "rig", Clock::Wall, 1e-3, None)
        .err()
        .expect("must fail");
    assert!(err.to_string().contains("no/such/dir"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}
