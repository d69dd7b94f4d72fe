//! Bad input gives a MultibodyError naming the file and the element (issue 4, item 7).

use std::path::{Path, PathBuf};

use pneuflex_multibody::{MultibodyConfig, MultibodyError, RigWorld};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn rig_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../urdf/rig.urdf")
}

fn build_err(path: &Path, cfg: &MultibodyConfig) -> (MultibodyError, String) {
    match RigWorld::from_urdf(path, cfg) {
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
    let (e, msg) = build_err(&p, &MultibodyConfig::paper_rig());
    assert!(matches!(e, MultibodyError::Parse { .. }), "{msg}");
    assert!(msg.contains("not_xml.urdf"), "{msg}");
}

#[test]
fn missing_file_is_a_parse_error_naming_it() {
    let p = fixture("no_such_file.urdf");
    let (e, msg) = build_err(&p, &MultibodyConfig::paper_rig());
    assert!(matches!(e, MultibodyError::Parse { .. }), "{msg}");
    assert!(msg.contains("no_such_file.urdf"), "{msg}");
}

#[test]
fn configured_link_missing_from_urdf() {
    let mut cfg = MultibodyConfig::paper_rig();
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
    let mut cfg = MultibodyConfig::paper_rig();
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
    let (e, msg) = build_err(&p, &MultibodyConfig::paper_rig());
    assert!(matches!(e, MultibodyError::BadJoint { .. }), "{msg}");
    assert!(
        msg.contains("zero_axis.urdf") && msg.contains("flange_slide") && msg.contains("axis"),
        "{msg}"
    );
}

#[test]
fn zero_mass_on_a_moving_link() {
    let p = fixture("zero_mass.urdf");
    let (e, msg) = build_err(&p, &MultibodyConfig::paper_rig());
    assert!(matches!(e, MultibodyError::BadInertial { .. }), "{msg}");
    assert!(
        msg.contains("zero_mass.urdf") && msg.contains("'flange'") && msg.contains("mass"),
        "{msg}"
    );
}

#[test]
fn negative_mass() {
    let p = fixture("negative_mass.urdf");
    let (e, msg) = build_err(&p, &MultibodyConfig::paper_rig());
    assert!(matches!(e, MultibodyError::BadInertial { .. }), "{msg}");
    assert!(
        msg.contains("negative_mass.urdf") && msg.contains("'flange'") && msg.contains("-0.3"),
        "{msg}"
    );
}

#[test]
fn inertia_not_positive_definite() {
    let p = fixture("bad_inertia.urdf");
    let (e, msg) = build_err(&p, &MultibodyConfig::paper_rig());
    assert!(matches!(e, MultibodyError::BadInertial { .. }), "{msg}");
    assert!(
        msg.contains("bad_inertia.urdf")
            && msg.contains("'flange'")
            && msg.contains("positive definite"),
        "{msg}"
    );
}

#[test]
fn mesh_collision_is_unsupported() {
    let p = fixture("mesh.urdf");
    let (e, msg) = build_err(&p, &MultibodyConfig::paper_rig());
    assert!(matches!(e, MultibodyError::BadGeometry { .. }), "{msg}");
    assert!(
        msg.contains("mesh.urdf") && msg.contains("'flange'") && msg.contains("unsupported"),
        "{msg}"
    );
}

#[test]
fn non_positive_dt_and_stiffness_are_rejected() {
    let mut cfg = MultibodyConfig::paper_rig();
    cfg.dt_s = 0.0;
    let (e, _) = build_err(&rig_path(), &cfg);
    assert!(matches!(e, MultibodyError::BadConfig { field: "dt_s", .. }));
    let mut cfg = MultibodyConfig::paper_rig();
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
    let mut cfg = MultibodyConfig::paper_rig();
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
