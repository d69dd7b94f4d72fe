//! Issue 11, `pneuflex run` as a user meets it: outputs never destroy what pneuflex did not write, an
//! interrupt leaves the previous complete output untouched and a marked partial beside it, errors name the
//! file, the line and the key once.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

fn pneuflex() -> Command {
    Command::new(env!("CARGO_BIN_EXE_pneuflex"))
}

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// A fresh scratch directory, removed when the returned guard drops.
fn scratch(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix(&format!("pneuflex-cli-{name}-"))
        .tempdir()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A copy of the ideal-plant scene with another duration (metric windows dropped), in `dir`.
fn ideal_scene(dir: &Path, duration_s: f64) -> PathBuf {
    let text = std::fs::read_to_string(repo("scenes/paper-fig3-ideal.toml")).unwrap();
    let text = text.replacen(
        "duration_s = 10.0",
        &format!("duration_s = {duration_s:?}"),
        1,
    );
    let text = match text.find("[[metrics]]") {
        Some(i) => text[..i].to_string(),
        None => text,
    };
    let p = dir.join("scene.toml");
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn a_user_file_in_out_survives_and_the_run_fails_naming_it() {
    let d = scratch("userfile");
    let d = d.path().to_path_buf();
    let out = d.join("d");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "my notes").unwrap();
    let o = pneuflex()
        .args(["run", "-q", "--out"])
        .arg(&out)
        .arg(repo("scenes/paper-fig3-ideal.toml"))
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(stderr(&o).contains("notes.txt"), "{}", stderr(&o));
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "my notes"
    );
    // Nothing else left beside it.
    let names: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(names.len(), 1, "{names:?}");
}

#[test]
fn out_dot_is_refused_and_the_working_directory_is_untouched() {
    let d = scratch("dot");
    let d = d.path().to_path_buf();
    std::fs::write(d.join("keep.txt"), "x").unwrap();
    let o = pneuflex()
        .current_dir(&d)
        .args(["run", "-q", "--out", "."])
        .arg(repo("scenes/paper-fig3-ideal.toml"))
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(stderr(&o).contains("working directory"), "{}", stderr(&o));
    let names: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(names, vec![std::ffi::OsString::from("keep.txt")]);
}

#[test]
fn the_scene_folder_is_refused() {
    let d = scratch("scenefolder");
    let d = d.path().to_path_buf();
    let scene = ideal_scene(&d, 7.0);
    let o = pneuflex()
        .args(["run", "-q", "--out"])
        .arg(&d)
        .arg(&scene)
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(stderr(&o).contains("holds an input"), "{}", stderr(&o));
    assert!(scene.exists());
}

#[test]
fn an_output_is_replaced_and_carries_its_manifest_and_provenance() {
    let d = scratch("replace");
    let d = d.path().to_path_buf();
    let out = d.join("o");
    for _ in 0..2 {
        let o = pneuflex()
            .args(["run", "-q", "--out"])
            .arg(&out)
            .arg(repo("scenes/paper-fig3-ideal.toml"))
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join(".pneuflex-output.json")).unwrap())
            .unwrap();
    assert_eq!(m["tool"], "pneuflex");
    assert_eq!(m["complete"], true);
    let files: Vec<&str> = m["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap())
        .collect();
    assert!(
        files.contains(&"summary.json") && files.contains(&"impedance/trace.csv"),
        "{files:?}"
    );
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["version"], env!("CARGO_PKG_VERSION"));
    let scene_hash = &s["inputs"][0];
    assert_eq!(scene_hash["role"], "scene");
    let bytes = std::fs::read(repo("scenes/paper-fig3-ideal.toml")).unwrap();
    assert_eq!(scene_hash["bytes"], bytes.len() as u64);
    // Only pneuflex's output is left in the folder: no staging or old directories.
    let names: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(names, vec![std::ffi::OsString::from("o")]);
}

#[cfg(unix)]
#[test]
fn sigterm_leaves_the_complete_output_untouched_and_a_marked_partial_beside_it() {
    let d = scratch("sigterm");
    let d = d.path().to_path_buf();
    let out = d.join("o");
    let short = ideal_scene(&d.join("short").tap_mkdir(), 7.0);
    let o = pneuflex()
        .args(["run", "-q", "--out"])
        .arg(&out)
        .arg(&short)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let before = std::fs::read(out.join("summary.json")).unwrap();
    // Long enough that no machine finishes it before the signal arrives (2 runs of 2e6 ticks).
    let long = ideal_scene(&d.join("long").tap_mkdir(), 2000.0);
    let child = pneuflex()
        .args(["run", "-q", "--out"])
        .arg(&out)
        .arg(&long)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The staging directory appears before the simulation starts.
    let staging = d.join(format!(".o.partial-{}", child.id()));
    for _ in 0..6000 {
        if staging.exists() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    assert!(staging.exists(), "the run never started");
    std::thread::sleep(std::time::Duration::from_millis(50));
    let pid = child.id().to_string();
    assert!(
        Command::new("kill")
            .args(["-TERM", &pid])
            .status()
            .unwrap()
            .success()
    );
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(128 + 15), "{}", stderr(&o));
    assert!(stderr(&o).contains("SIGTERM"), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(out.join("summary.json")).unwrap(),
        before,
        "the complete output changed"
    );
    let partial = d.join("o.partial");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(partial.join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(s["complete"], false);
    assert!(
        s["interrupted"]
            .as_str()
            .unwrap()
            .starts_with("SIGTERM at t = "),
        "{s}"
    );
    let m: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(partial.join(".pneuflex-output.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(m["complete"], false);
    assert_eq!(m["partial"]["reason"], "SIGTERM");
    let trace = std::fs::read_to_string(partial.join("impedance/trace.interrupted.csv")).unwrap();
    assert!(trace.lines().count() > 2);
    assert!(!staging.exists());
}

#[test]
fn a_missing_file_is_reported_once() {
    let o = pneuflex()
        .args(["run", "no/such/scene.toml"])
        .output()
        .unwrap();
    assert!(!o.status.success());
    let e = stderr(&o);
    assert_eq!(e.matches("No such file or directory").count(), 1, "{e}");
    assert!(e.contains("no/such/scene.toml"), "{e}");
}

#[test]
fn a_warning_names_the_file_line_and_key_before_the_run() {
    let d = scratch("warn");
    let d = d.path().to_path_buf();
    let text = std::fs::read_to_string(repo("scenes/paper-fig3.toml")).unwrap();
    let text = text.replacen("stiffness_n_per_m = 700.0", "stiffness_n_per_m = 1e12", 1);
    let text = text.replacen(
        "actuator = \"../pneumatics/",
        &format!("actuator = \"{}/", repo("pneumatics").display()),
        1,
    );
    let scene = d.join("stiff.toml");
    std::fs::write(&scene, text).unwrap();
    let o = pneuflex()
        .args(["run", "-q", "--out"])
        .arg(d.join("o"))
        .arg(&scene)
        .output()
        .unwrap();
    let e = stderr(&o);
    assert!(
        e.contains("warning: ")
            && e.contains("stiff.toml:")
            && e.contains("environment.stiffness_n_per_m"),
        "{e}"
    );
    assert!(!o.status.success(), "a diverged run exits non-zero: {e}");
    assert!(e.contains("diverged"), "{e}");
}

trait TapMkdir {
    fn tap_mkdir(self) -> Self;
}

impl TapMkdir for PathBuf {
    fn tap_mkdir(self) -> Self {
        std::fs::create_dir_all(&self).unwrap();
        self
    }
}

/// `run --format svg|pdf`: the figures as SVG or PDF (for a paper), listed in the output manifest, with the
/// scene's description under each title; an unknown format is refused before anything is written.
#[test]
fn the_figures_can_be_written_as_svg_or_pdf() {
    let d = scratch("svg");
    let scene = repo("scenes/paper-fig3-ideal.toml");
    let description = pneuflex_scene::Scene::load(&scene).unwrap().description;
    assert!(!description.is_empty());
    for ext in ["svg", "pdf"] {
        let out = d.path().join(ext);
        let o = pneuflex()
            .args(["run", "-q", "--format", ext, "--out"])
            .arg(&out)
            .arg(&scene)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
        let mut figures: Vec<String> = std::fs::read_dir(&out)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| [".svg", ".png", ".pdf"].iter().any(|x| n.ends_with(x)))
            .collect();
        figures.sort();
        let want: Vec<String> = ["event-0", "force", "position"]
            .iter()
            .map(|f| format!("{f}.{ext}"))
            .collect();
        assert_eq!(figures, want);
        for f in &figures {
            let bytes = std::fs::read(out.join(f)).unwrap();
            let magic: &[u8] = if ext == "svg" { b"<svg" } else { b"%PDF-" };
            assert!(bytes.starts_with(magic), "{f}");
            if ext == "svg" {
                // The title names the scene; the line under it is the scene's description.
                let text = String::from_utf8(bytes).unwrap();
                let escaped = description
                    .replace('&', "&amp;")
                    .replace('>', "&gt;")
                    .replace('<', "&lt;");
                assert!(text.contains(&escaped), "{f} lacks the description");
            }
        }
        let manifest = std::fs::read_to_string(out.join(".pneuflex-output.json")).unwrap();
        assert!(manifest.contains(&format!("force.{ext}")), "{manifest}");
    }
    let bad = d.path().join("eps");
    let o = pneuflex()
        .args(["run", "-q", "--format", "eps", "--out"])
        .arg(&bad)
        .arg(&scene)
        .output()
        .unwrap();
    assert!(!o.status.success() && stderr(&o).contains("possible values: png, svg, pdf"));
    assert!(!bad.exists());
}
