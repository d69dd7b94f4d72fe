//! `pneuflex tf` as a user meets it: the built binary, its stdout, stderr and exit status.
//! (Moved from crates/pneumatics/tests, which compiled src/cmd/tf.rs into that crate through a `#[path]`.)

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// `pneuflex tf <file> [--json]`.
fn tf(file: &Path, json: bool) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_pneuflex"));
    c.arg("tf").arg(file);
    if json {
        c.arg("--json");
    }
    c.output().unwrap()
}

/// Stdout of a command that must succeed.
fn ok(o: Output) -> String {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout).unwrap()
}

/// The error message of a command that must fail: stderr without main's `error: ` prefix.
fn err(o: Output) -> String {
    assert!(
        !o.status.success(),
        "succeeded: {}",
        String::from_utf8_lossy(&o.stdout)
    );
    let e = String::from_utf8(o.stderr).unwrap();
    e.strip_prefix("error: ")
        .unwrap_or(&e)
        .trim_end()
        .to_string()
}

/// JSON output has k_n, omega_n, xi_n in SI and agrees with the library's eq. (17) values; the table
/// names every quantity with its unit; a scene naming the sheet gives the same numbers.
#[test]
fn tf_json_and_table() {
    let sheet = repo("pneumatics/paper-actuator.toml");
    let v: serde_json::Value = serde_json::from_str(&ok(tf(&sheet, true))).unwrap();
    let model = pneuflex::pneumatics::ActuatorSheet::load(&sheet)
        .unwrap()
        .model();
    let (_, expected) = model.transfer_function_mid_stroke().unwrap();
    assert!((v["omega_n"].as_f64().unwrap() / expected.omega_n - 1.0).abs() < 1e-12);
    assert!((v["xi_n"].as_f64().unwrap() / expected.xi_n - 1.0).abs() < 1e-12);
    assert!((v["k_n"].as_f64().unwrap() / expected.k_n - 1.0).abs() < 1e-12);
    assert_eq!(v["den"].as_array().unwrap().len(), 4);
    let table = ok(tf(&sheet, false));
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
    let scene = repo("scenes/paper-fig3.toml");
    let s: serde_json::Value = serde_json::from_str(&ok(tf(&scene, true))).unwrap();
    assert_eq!(s["omega_n"], v["omega_n"]);
}

/// A bad sheet is an error naming the file and a non-zero exit, not a panic.
#[test]
fn tf_bad_file_is_an_error() {
    let o = tf(&repo("pneumatics/no-such-sheet.toml"), false);
    assert_eq!(o.status.code(), Some(1), "{o:?}");
    assert!(err(o).contains("no-such-sheet.toml"));
}

/// Issue 11: `tf` with a missing component named the missing file but not the key naming it, and printed
/// the OS error twice under anyhow's `{:#}`. Now: sheet:line: key: file: cannot read: <OS error>, once.
#[test]
fn tf_missing_component_names_sheet_line_and_key_and_the_os_error_once() {
    let dir = std::env::temp_dir().join(format!("pneuflex-cli-tf-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    for e in std::fs::read_dir(repo("pneumatics")).unwrap() {
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
    let (i, l) = text
        .lines()
        .enumerate()
        .find(|(_, l)| l.starts_with("valve ="))
        .unwrap();
    // Errors point at the value: line:column.
    let line = format!("{}:{}", i + 1, l.find('"').unwrap() + 1);
    let e = err(tf(&sheet, false));
    let os = std::io::Error::from(std::io::ErrorKind::NotFound).to_string();
    let want = format!(
        "{}:{line}: components.valve: {}: cannot read: ",
        sheet.display(),
        dir.join("nope.toml").display()
    );
    assert!(e.starts_with(&want), "{e}\nwanted {want}...");
    assert_eq!(e.matches("No such file").count(), 1, "{e} ({os})");

    // A scene naming a missing sheet is blamed on its plant.actuator line.
    let scene = dir.join("scene.toml");
    std::fs::write(
        &scene,
        "name = \"s\"\n\n[plant]\nkind = \"pneumatic\"\nactuator = \"gone.toml\"\n",
    )
    .unwrap();
    let e = err(tf(&scene, false));
    assert!(
        e.starts_with(&format!(
            "{}:5:12: plant.actuator: {}: cannot read: ",
            scene.display(),
            dir.join("gone.toml").display()
        )),
        "{e}"
    );
    assert_eq!(e.matches("No such file").count(), 1, "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn tf_loop_on_a_scene_of_several_actuators_measures_each_actuators_loop() {
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_pneuflex"))
            .args(args)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .unwrap()
    };
    let table = ok(run(&["tf", "--loop", "scenes/cross-slide.toml"]));
    assert!(table.contains("measured by injection"), "{table}");
    for actuator in ["press", "push"] {
        let line = table
            .lines()
            .find(|l| l.trim_start().starts_with(actuator))
            .unwrap_or_else(|| panic!("no line for {actuator}:\n{table}"));
        assert!(
            line.contains("crossover") && line.contains("gain margin"),
            "{line}"
        );
    }
    let json: serde_json::Value = serde_json::from_str(&ok(run(&[
        "tf",
        "--loop",
        "--json",
        "scenes/cross-slide.toml",
    ])))
    .unwrap();
    let loops = json.as_array().unwrap();
    assert_eq!(loops.len(), 2, "{json}");
    for l in loops {
        // A stable loop at its valve: |L| falls through 1 with a positive phase margin.
        assert!(l["crossover_hz"].as_f64().unwrap() > 0.1, "{l}");
        assert!(l["phase_margin_deg"].as_f64().unwrap() > 0.0, "{l}");
        assert!(l["bode"].as_array().unwrap().len() > 20, "{l}");
    }
    let e = err(run(&[
        "tf",
        "--loop",
        "scenes/cross-slide.toml",
        "--bode",
        "/tmp/never-written.png",
    ]));
    assert!(e.contains("--bode") && e.contains("--json"), "{e}");
}
