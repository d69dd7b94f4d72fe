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
