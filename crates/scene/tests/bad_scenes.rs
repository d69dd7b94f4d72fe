//! Bad scene files give clear errors naming the file and the key path, never a panic.

use std::path::{Path, PathBuf};

use pneuflex_scene::{Scene, SceneError};

fn good_text() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paper-fig3-ideal.toml");
    std::fs::read_to_string(path).unwrap()
}

fn load_err(text: &str) -> String {
    let file = PathBuf::from("scenes/x.toml");
    match Scene::from_toml_str(text, &file, Path::new("scenes")) {
        Ok(_) => panic!("bad scene accepted"),
        Err(e) => {
            let msg = e.to_string();
            assert!(
                msg.starts_with("scenes/x.toml:"),
                "message does not name the file: {msg}"
            );
            msg
        }
    }
}

#[test]
fn the_good_scene_loads() {
    Scene::from_toml_str(
        &good_text(),
        Path::new("scenes/x.toml"),
        Path::new("scenes"),
    )
    .unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn unknown_key_is_rejected() {
    let text = good_text().replace(
        "stiffness_n_per_m = 700.0",
        "stiffness_n_per_m = 700.0\nstifness = 1.0",
    );
    let msg = load_err(&text);
    assert!(
        msg.contains("environment") && msg.contains("unknown field `stifness`"),
        "{msg}"
    );
}

#[test]
fn missing_field_is_rejected() {
    let text = good_text().replacen("impedance = { m_d_kg = 2.0, ", "impedance = { ", 1);
    let msg = load_err(&text);
    assert!(
        msg.contains("runs[0].impedance") && msg.contains("missing field `m_d_kg`"),
        "{msg}"
    );
}

#[test]
fn negative_stiffness_is_rejected() {
    let text = good_text().replace("stiffness_n_per_m = 700.0", "stiffness_n_per_m = -700.0");
    let msg = load_err(&text);
    assert_eq!(
        msg,
        "scenes/x.toml:17:21: environment.stiffness_n_per_m: must be >= 0, got -700"
    );
}

#[test]
fn nan_is_rejected() {
    let text = good_text().replace("amplitude_n = 2.0", "amplitude_n = nan");
    let msg = load_err(&text);
    assert_eq!(
        msg,
        "scenes/x.toml:32:15: reference.force[1].amplitude_n: must be a finite number, got NaN"
    );
}

#[test]
fn negative_event_stiffness_is_rejected() {
    let text = good_text().replace("stiffness_n_per_m = 1400.0", "stiffness_n_per_m = -1.0");
    assert_eq!(
        load_err(&text),
        "scenes/x.toml:39:21: events[0].stiffness_n_per_m: must be >= 0, got -1"
    );
}

#[test]
fn missing_file_names_the_file() {
    match Scene::load(Path::new("scenes/does-not-exist.toml")) {
        Err(e @ SceneError::Input(_)) => {
            assert!(e.to_string().contains("scenes/does-not-exist.toml"), "{e}")
        }
        other => panic!("expected an I/O error, got {other:?}"),
    }
}

#[test]
fn missing_actuator_sheet_is_an_error_not_a_panic() {
    let text = good_text().replace(
        "kind = \"ideal\"\nomega_rad_per_s = 200.0",
        "kind = \"pneumatic\"\nactuator = \"nowhere.toml\"\n#",
    );
    let text = text.replace("zeta = 1.0\nx0_m = 0.0\n", "");
    let scene = Scene::from_toml_str(&text, Path::new("scenes/x.toml"), Path::new("/nonexistent"))
        .unwrap_or_else(|e| panic!("{e}"));
    let err = pneuflex_scene::run_scene(&scene, &mut |_| {})
        .expect_err("missing actuator sheet accepted");
    let msg = err.to_string();
    assert!(
        msg.starts_with("scenes/x.toml:12:12: plant.actuator: ") && msg.contains("nowhere.toml"),
        "{msg}"
    );
}

#[test]
fn controller_parameters_are_checked_by_the_control_crate_and_blamed_on_their_key() {
    let text = good_text().replacen("kp_per_m = ", "kp_per_m = -", 1);
    let msg = load_err(&text);
    assert!(
        msg.contains(": runs[0].inner.kp_per_m: must be >= 0, got -"),
        "{msg}"
    );
    let text = good_text().replacen("[runs.inner]", "[runs.inner]\nu_max = 2.0", 1);
    if text != good_text() {
        let msg = load_err(&text);
        assert!(
            msg.contains("runs[0].inner.u_max: must be in [-1, 1], got 2"),
            "{msg}"
        );
    }
}

#[test]
fn a_run_is_picked_by_name_with_the_names_in_the_error() {
    let s = Scene::from_toml_str(
        &good_text(),
        Path::new("scenes/x.toml"),
        Path::new("scenes"),
    )
    .unwrap();
    assert_eq!(s.run_index("adaptive").unwrap(), 1);
    let e = s.run_index("adaptiv").unwrap_err().to_string();
    assert!(
        e.contains("no run named \"adaptiv\"") && e.contains("\"impedance\", \"adaptive\""),
        "{e}"
    );
}
