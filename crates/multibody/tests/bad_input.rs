//! Bad input gives a MultibodyError naming the file and the element (issue 4, item 7).

use std::path::{Path, PathBuf};

use pneuflex_multibody::{CarriageRig, MultibodyError, RigConfig};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn rig_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../urdf/rig.urdf")
}

fn build_err(path: &Path, cfg: &RigConfig) -> (MultibodyError, String) {
    match CarriageRig::from_urdf(path, cfg) {
        Ok(_) => panic!("{} should be rejected", path.display()),
        Err(e) => {
            let msg = e.to_string();
            (e, msg)
        }
    }
}

#[test]
fn urdf_that_does_not_parse() {
    let p = fixture("not_xml.urdf");
    let (e, msg) = build_err(&p, &RigConfig::paper_rig());
    assert!(matches!(e, MultibodyError::Parse { .. }), "{msg}");
    assert!(msg.contains("not_xml.urdf"), "{msg}");
}

/// A missing file is an input error naming it, with the OS error printed once (no `source()` repeating it).
#[test]
fn missing_file_is_an_input_error_naming_it() {
    let p = fixture("no_such_file.urdf");
    let (e, msg) = build_err(&p, &RigConfig::paper_rig());
    assert!(matches!(e, MultibodyError::Input(_)), "{msg}");
    assert!(msg.contains("no_such_file.urdf: cannot read: "), "{msg}");
    assert!(std::error::Error::source(&e).is_none(), "{msg}");
}

#[test]
fn configured_link_missing_from_urdf() {
    let mut cfg = RigConfig::paper_rig();
    cfg.flange_link = "piston_rod".into();
    let (e, msg) = build_err(&rig_path(), &cfg);
    assert!(matches!(e, MultibodyError::MissingLink { .. }), "{msg}");
    assert!(
        msg.contains("rig.urdf") && msg.contains("piston_rod") && msg.contains("flange_link"),
        "{msg}"
    );
}

#[test]
fn configured_joint_missing_from_urdf() {
    let mut cfg = RigConfig::paper_rig();
    cfg.materials[1].mount_joint = "steel_mount".into();
    let (e, msg) = build_err(&rig_path(), &cfg);
    assert!(matches!(e, MultibodyError::MissingJoint { .. }), "{msg}");
    assert!(
        msg.contains("rig.urdf") && msg.contains("steel_mount"),
        "{msg}"
    );
}

#[test]
fn zero_length_joint_axis() {
    let p = fixture("zero_axis.urdf");
    let (e, msg) = build_err(&p, &RigConfig::paper_rig());
    assert!(matches!(e, MultibodyError::BadJoint { .. }), "{msg}");
    assert!(
        msg.contains("zero_axis.urdf") && msg.contains("flange_slide") && msg.contains("axis"),
        "{msg}"
    );
}

#[test]
fn zero_mass_on_a_moving_link() {
    let p = fixture("zero_mass.urdf");
    let (e, msg) = build_err(&p, &RigConfig::paper_rig());
    assert!(matches!(e, MultibodyError::BadInertial { .. }), "{msg}");
    assert!(
        msg.contains("zero_mass.urdf") && msg.contains("'flange'") && msg.contains("mass"),
        "{msg}"
    );
}

#[test]
fn negative_mass() {
    let p = fixture("negative_mass.urdf");
    let (e, msg) = build_err(&p, &RigConfig::paper_rig());
    assert!(matches!(e, MultibodyError::BadInertial { .. }), "{msg}");
    assert!(
        msg.contains("negative_mass.urdf") && msg.contains("'flange'") && msg.contains("-0.3"),
        "{msg}"
    );
}

#[test]
fn inertia_not_positive_definite() {
    let p = fixture("bad_inertia.urdf");
    let (e, msg) = build_err(&p, &RigConfig::paper_rig());
    assert!(matches!(e, MultibodyError::BadInertial { .. }), "{msg}");
    assert!(
        msg.contains("bad_inertia.urdf")
            && msg.contains("'flange'")
            && msg.contains("positive definite"),
        "{msg}"
    );
}

/// A `package://` mesh (a ROS package path) is refused naming the URDF, the link and the fix (meshes that
/// load: tests/mesh.rs).
#[test]
fn a_package_mesh_path_is_refused_with_the_fix() {
    let p = fixture("mesh.urdf");
    let (e, msg) = build_err(&p, &RigConfig::paper_rig());
    assert!(matches!(e, MultibodyError::BadGeometry { .. }), "{msg}");
    assert!(
        msg.contains("mesh.urdf")
            && msg.contains("'flange'")
            && msg.contains("package://rig/flange.stl")
            && msg.contains("relative to the URDF"),
        "{msg}"
    );
}

#[test]
fn non_positive_dt_and_stiffness_are_rejected() {
    let mut cfg = RigConfig::paper_rig();
    cfg.dt_s = 0.0;
    let (e, _) = build_err(&rig_path(), &cfg);
    assert!(matches!(e, MultibodyError::BadConfig { field: "dt_s", .. }));
    let mut cfg = RigConfig::paper_rig();
    cfg.materials[0].params.stiffness_n_per_m = f64::NAN;
    let (e, _) = build_err(&rig_path(), &cfg);
    assert!(matches!(
        e,
        MultibodyError::BadConfig {
            field: "stiffness_n_per_m",
            ..
        }
    ));
}

#[test]
fn two_materials_on_one_mount_are_rejected() {
    let mut cfg = RigConfig::paper_rig();
    let mut soft = cfg.materials[0].clone();
    soft.name = "soft wood".into();
    cfg.materials.push(soft);
    let (e, msg) = build_err(&rig_path(), &cfg);
    assert!(
        matches!(
            e,
            MultibodyError::BadConfig {
                field: "materials.mount_joint",
                ..
            }
        ),
        "{msg}"
    );
    assert!(
        msg.contains("wood_mount") && msg.contains("soft wood"),
        "{msg}"
    );
}

/// A copy of the shipped rig.urdf with `from` replaced by `to` (which must occur), in a scratch directory.
/// The directory is removed when the returned guard drops.
fn rig_variant(case: &str, from: &str, to: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::Builder::new()
        .prefix(&format!("pneuflex-multibody-{case}-"))
        .tempdir()
        .unwrap();
    let text = std::fs::read_to_string(rig_path()).unwrap();
    assert!(text.contains(from), "rig.urdf lacks {from:?}");
    let p = dir.path().join("rig.urdf");
    std::fs::write(&p, text.replacen(from, to, 1)).unwrap();
    (dir, p)
}

/// 1-based line of the first line of `path` containing `needle`.
fn line_of(path: &Path, needle: &str) -> usize {
    let text = std::fs::read_to_string(path).unwrap();
    1 + text.lines().position(|l| l.contains(needle)).unwrap()
}

/// Builds on a thread; the error within 5 s (a hang or an unbounded read fails the test).
fn build_err_within_5_s(path: PathBuf) -> (MultibodyError, String) {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(build_err(&path, &RigConfig::paper_rig()));
    });
    rx.recv_timeout(std::time::Duration::from_secs(5))
        .expect("building did not finish within 5 s")
}

/// Issue 11: 20,000 nested elements aborted the process with a stack overflow inside urdf-rs; now an
/// error naming the file, the line and the element, found before urdf-rs parses anything.
#[test]
fn deeply_nested_urdf_is_an_error_not_a_stack_overflow() {
    let depth = 20_000;
    let (_scratch, p) = rig_variant(
        "deep",
        "<link name=\"flange\">",
        &format!(
            "<link name=\"flange\">\n{}{}",
            "<deep>".repeat(depth),
            "</deep>".repeat(depth)
        ),
    );
    let line = line_of(&p, "<deep>");
    let (e, msg) = build_err(&p, &RigConfig::paper_rig());
    assert!(matches!(e, MultibodyError::Element { .. }), "{msg}");
    assert!(
        msg.starts_with(&format!(
            "{}:{line}: <deep>: elements nested deeper than 64 levels",
            p.display()
        )),
        "{msg}"
    );
    assert!(msg.contains("(in link 'flange')"), "{msg}");
}

/// Issue 11: `<mass value="heavy"/>` gave `custom: invalid float literal`; now file, line, element, key.
#[test]
fn non_numeric_mass_names_file_line_and_element() {
    let (_scratch, p) = rig_variant("heavy", "<mass value=\"0.60\"/>", "<mass value=\"heavy\"/>");
    let line = line_of(&p, "heavy");
    let (e, msg) = build_err(&p, &RigConfig::paper_rig());
    assert!(matches!(e, MultibodyError::Element { .. }), "{msg}");
    assert_eq!(
        msg,
        format!(
            "{}:{line}: <mass value=\"heavy\">: value: expected a finite number, got \"heavy\" (in link 'flange')",
            p.display()
        )
    );
}

/// Issue 11: a vector with the wrong count or a non-finite entry is reported at its element.
#[test]
fn malformed_vectors_name_file_line_and_element() {
    for (case, from, to, what) in [
        (
            "axis",
            "<axis xyz=\"1 0 0\"/>",
            "<axis xyz=\"1 0\"/>",
            "xyz: expected 3 finite numbers",
        ),
        (
            "box",
            "<box size=\"0.01 0.04 0.04\"/>",
            "<box size=\"0.01 0.04 inf\"/>",
            "size: expected 3 finite numbers",
        ),
        (
            "inertia",
            "ixx=\"1.6e-04\"",
            "ixx=\"1.6e-04kg\"",
            "ixx: expected a finite number",
        ),
    ] {
        let (_scratch, p) = rig_variant(case, from, to);
        let line = line_of(&p, to);
        let (e, msg) = build_err(&p, &RigConfig::paper_rig());
        assert!(matches!(e, MultibodyError::Element { .. }), "{msg}");
        assert!(
            msg.starts_with(&format!("{}:{line}: <", p.display())) && msg.contains(what),
            "{msg}"
        );
    }
}

/// Issue 11: an inertia that breaks the triangle inequality (positive definite, but no rigid body has it)
/// was accepted; now an error naming the link.
#[test]
fn inertia_breaking_the_triangle_inequality_names_the_link() {
    let (_scratch, p) = rig_variant(
        "triangle",
        "ixx=\"1.6e-04\" ixy=\"0\" ixz=\"0\" iyy=\"8.5e-05\"",
        "ixx=\"1.6e-03\" ixy=\"0\" ixz=\"0\" iyy=\"8.5e-05\"",
    );
    let (e, msg) = build_err(&p, &RigConfig::paper_rig());
    assert!(matches!(e, MultibodyError::BadInertial { .. }), "{msg}");
    assert!(
        msg.contains("'flange'") && msg.contains("triangle inequality"),
        "{msg}"
    );
}

/// Issue 11: `/dev/zero` as the URDF was read without bound; now refused before it is opened.
#[cfg(unix)]
#[test]
fn device_as_urdf_is_refused() {
    let (e, msg) = build_err_within_5_s(PathBuf::from("/dev/zero"));
    assert!(matches!(e, MultibodyError::Input(_)), "{msg}");
    assert!(
        msg.contains("/dev/zero: not a regular file (a character device)"),
        "{msg}"
    );
}

/// Issue 11: a FIFO as the URDF blocked forever in open(); now refused after a stat.
#[cfg(unix)]
#[test]
fn fifo_as_urdf_does_not_block() {
    let dir = tempfile::Builder::new()
        .prefix("pneuflex-multibody-fifo-")
        .tempdir()
        .unwrap();
    let fifo = dir.path().join("rig.urdf");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success());
    if !made {
        eprintln!("mkfifo unavailable; skipped");
        return;
    }
    let (e, msg) = build_err_within_5_s(fifo);
    assert!(matches!(e, MultibodyError::Input(_)), "{msg}");
    assert!(msg.contains("not a regular file (a FIFO)"), "{msg}");
}

/// Nesting up to the limit (64 levels, here inside a link's extension element) still parses and builds:
/// the limit refuses only what urdf-rs could not take.
#[test]
fn nesting_at_the_limit_is_accepted() {
    // robot > link > 62 levels = 64.
    let n = pneuflex_multibody::urdf_scan::MAX_DEPTH - 2;
    let (_scratch, p) = rig_variant(
        "at-limit",
        "<link name=\"flange\">",
        &format!(
            "<link name=\"flange\">\n{}{}",
            "<ext>".repeat(n),
            "</ext>".repeat(n)
        ),
    );
    CarriageRig::from_urdf(&p, &RigConfig::paper_rig()).unwrap();
    let (_scratch, p) = rig_variant(
        "over-limit",
        "<link name=\"flange\">",
        &format!(
            "<link name=\"flange\">\n{}{}",
            "<ext>".repeat(n + 1),
            "</ext>".repeat(n + 1)
        ),
    );
    let (e, msg) = build_err(&p, &RigConfig::paper_rig());
    assert!(matches!(e, MultibodyError::Element { .. }), "{msg}");
}
