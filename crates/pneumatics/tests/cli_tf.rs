//! The `pneuflex tf` command body (src/cmd/tf.rs of the root package), compiled against this crate.
#[path = "../../../src/cmd/tf.rs"]
mod tf;

use std::path::Path;

fn data(p: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(p)
}

/// JSON output has k_n, omega_n, xi_n in SI and agrees with the library's eq. (17) values; the table
/// names every quantity with its unit; a scene naming the sheet gives the same numbers.
#[test]
fn tf_json_and_table() {
    let sheet = data("pneumatics/paper-actuator.toml");
    let out = tf::tf(&sheet, true).unwrap();
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let model = pneuflex_pneumatics::ActuatorSheet::load(&sheet)
        .unwrap()
        .model();
    let (_, expected) = model.transfer_function_mid_stroke().unwrap();
    assert!((v["omega_n"].as_f64().unwrap() / expected.omega_n - 1.0).abs() < 1e-12);
    assert!((v["xi_n"].as_f64().unwrap() / expected.xi_n - 1.0).abs() < 1e-12);
    assert!((v["k_n"].as_f64().unwrap() / expected.k_n - 1.0).abs() < 1e-12);
    assert_eq!(v["den"].as_array().unwrap().len(), 4);
    let table = tf::tf(&sheet, false).unwrap();
    for key in [
        "K_n",
        "omega_n",
        "xi_n",
        "rad/s",
        "m/(Pa s)",
        "a3 (s^3)",
        "a1 (s^1) = beta_n",
    ] {
        assert!(table.contains(key), "table lacks {key}:\n{table}");
    }
    let scene = data("scenes/paper-fig3.toml");
    if scene.exists() {
        let s: serde_json::Value = serde_json::from_str(&tf::tf(&scene, true).unwrap()).unwrap();
        assert_eq!(s["omega_n"], v["omega_n"]);
    }
    eprintln!("{table}");
}

/// A bad sheet is an error naming the file, not a panic.
#[test]
fn tf_bad_file_is_an_error() {
    let err = tf::tf(&data("pneumatics/no-such-sheet.toml"), false).unwrap_err();
    assert!(format!("{err:#}").contains("no-such-sheet.toml"));
}

/// Issue 11: `tf` with a missing component named the missing file but not the key naming it, and printed
/// the OS error twice under anyhow's `{:#}`. Now: sheet:line: key: file: cannot read: <OS error>, once.
#[test]
fn tf_missing_component_names_sheet_line_and_key_and_the_os_error_once() {
    let dir = std::env::temp_dir().join(format!("pneuflex-cli-tf-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    for e in std::fs::read_dir(data("pneumatics")).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, dir.join(p.file_name().unwrap())).unwrap();
    }
    let sheet = dir.join("paper-actuator.toml");
    let text = std::fs::read_to_string(&sheet).unwrap();
    std::fs::write(
        &sheet,
        text.replace("\"a05ps25x-5-2-valve.toml\"", "\"nope.toml\""),
    )
    .unwrap();
    let line = 1 + text.lines().position(|l| l.starts_with("valve =")).unwrap();
    let err = format!("{:#}", tf::tf(&sheet, false).unwrap_err());
    let os = std::io::Error::from(std::io::ErrorKind::NotFound).to_string();
    let want = format!(
        "{}:{line}: components.valve: {}: cannot read: ",
        sheet.display(),
        dir.join("nope.toml").display()
    );
    assert!(err.starts_with(&want), "{err}\nwanted {want}...");
    assert_eq!(err.matches("No such file").count(), 1, "{err} ({os})");

    // A scene naming a missing sheet is blamed on its plant.actuator line.
    let scene = dir.join("scene.toml");
    std::fs::write(
        &scene,
        "name = \"s\"\n\n[plant]\nkind = \"pneumatic\"\nactuator = \"gone.toml\"\n",
    )
    .unwrap();
    let err = format!("{:#}", tf::tf(&scene, false).unwrap_err());
    assert!(
        err.starts_with(&format!(
            "{}:5: plant.actuator: {}: cannot read: ",
            scene.display(),
            dir.join("gone.toml").display()
        )),
        "{err}"
    );
    assert_eq!(err.matches("No such file").count(), 1, "{err}");
}
