//! Sweeps of a scene with several actuators (the gripper): each point is the run of the scene edited by
//! hand, its columns name their actuator, sheet keys reach one actuator's sheet, and bad keys are the
//! scene's own errors.

use std::path::{Path, PathBuf};

use pneuflex_scene::AnyScene;
use pneuflex_scene::mechanism::{MechanismScene, run_all, summarise};
use pneuflex_sweep::points::DEFAULT_MAX_POINTS;
use pneuflex_sweep::{SetArg, Status, Sweep, SweepError};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

/// The gripper cut to its squeeze (2.5 s), in a folder of its own with the files it names, so that a sheet
/// can be given to one finger only. Returns the folder (kept alive) and the scene's path.
fn short_gripper(own_sheet_for_right: bool) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let urdf = repo("urdf/gripper.urdf").canonicalize().unwrap();
    let sheet = repo("pneumatics/gripper-finger.toml")
        .canonicalize()
        .unwrap();
    let mut text = std::fs::read_to_string(repo("scenes/gripper.toml"))
        .unwrap()
        .replace("duration_s = 8.0", "duration_s = 2.5")
        .replace("../urdf/gripper.urdf", urdf.to_str().unwrap())
        .replace("../pneumatics/gripper-finger.toml", sheet.to_str().unwrap());
    // The object stiffens at 2.2 s; one window, no claims.
    text = text.replace("t_s = 5.0", "t_s = 2.2");
    text.truncate(text.find("[[metrics]]").unwrap());
    text.push_str("[[metrics]]\nname = \"squeeze\"\nt0_s = 1.5\nt1_s = 2.5\n");
    if own_sheet_for_right {
        // The right finger's sheet is a copy beside the scene, with the components it names resolved.
        let sheet_text = std::fs::read_to_string(&sheet).unwrap();
        let sheet_dir = sheet.parent().unwrap();
        let mut copy = String::new();
        for line in sheet_text.lines() {
            match line.split_once("= \"") {
                Some((k, v)) if v.ends_with(".toml\"") => {
                    let rel = v.trim_end_matches('"');
                    let abs = sheet_dir.join(rel).canonicalize().unwrap();
                    copy.push_str(&format!("{k}= \"{}\"\n", abs.display()));
                }
                _ => {
                    copy.push_str(line);
                    copy.push('\n');
                }
            }
        }
        std::fs::write(dir.path().join("right-finger.toml"), copy).unwrap();
        let right = "joint = \"right_slide\"";
        let at = text.find(right).unwrap();
        let sheet_line = text[..at].rfind("sheet = ").unwrap();
        let end = sheet_line + text[sheet_line..].find('\n').unwrap();
        text.replace_range(sheet_line..end, "sheet = \"right-finger.toml\"");
    }
    let path = dir.path().join("gripper.toml");
    std::fs::write(&path, text).unwrap();
    (dir, path)
}

fn sweep(scene: &Path, args: &[&str]) -> Result<Sweep, SweepError> {
    let sets: Vec<SetArg> = args
        .iter()
        .map(|a| SetArg::parse(a).unwrap_or_else(|e| panic!("{e}")))
        .collect();
    Sweep::new(scene, &sets, None, 0, DEFAULT_MAX_POINTS)
}

/// `window.actuator.metric` of run `run` at every point.
fn column(s: &Sweep, run: &str, name: &str) -> Vec<f64> {
    let i = s.metric_index(name).unwrap();
    let idx: Vec<usize> = (0..s.len()).collect();
    s.run(&idx, 2, None, &|| {})
        .unwrap()
        .iter()
        .map(|p| {
            let r = p.runs.iter().find(|r| r.run == run).unwrap();
            assert_eq!(r.status, Status::Ok, "{}", r.reason);
            r.metrics[i].unwrap()
        })
        .collect()
}

#[test]
fn each_point_is_the_run_of_the_scene_edited_by_hand() {
    let (_dir, path) = short_gripper(false);
    let s = sweep(&path, &["contacts[left_pad].stiffness_n_per_m=1000,6000"]).unwrap();
    assert!(matches!(s.base_scene, AnyScene::Mechanism(_)));
    let names: Vec<String> = s.columns.iter().map(|c| c.name()).collect();
    for want in [
        "squeeze.left.rms_force_error_n",
        "squeeze.right.max_abs_force_error_n",
        "squeeze.right.mean_force_n",
        "squeeze.force_imbalance_n",
    ] {
        assert!(names.iter().any(|n| n == want), "{want} in {names:?}");
    }
    let swept = column(&s, "impedance", "squeeze.left.rms_force_error_n");
    let imbalance = column(&s, "impedance", "squeeze.force_imbalance_n");
    let text = std::fs::read_to_string(&path).unwrap();
    for (k, stiffness) in [1000.0, 6000.0].into_iter().enumerate() {
        // The left pad's stiffness written into a copy by hand (the first `stiffness_n_per_m = 2000.0`).
        let edited = text.replacen(
            "stiffness_n_per_m = 2000.0",
            &format!("stiffness_n_per_m = {stiffness:.1}"),
            1,
        );
        let scene = MechanismScene::from_toml_str(&edited, &path).unwrap();
        let runs = run_all(&scene, &mut |_| {}, None, &mut ()).unwrap();
        let summary = summarise(&scene, &runs);
        let w = &summary.runs[0].windows[0];
        assert_eq!(w.window, "squeeze");
        assert_eq!(w.actuators[0].0, "left");
        assert_eq!(swept[k], w.actuators[0].1.rms_force_error_n, "point {k}");
        assert_eq!(imbalance[k], w.force_imbalance_n, "point {k}");
    }
    // The key reached the plant: a sixfold stiffer pad changes the left finger's tracking.
    assert!(
        (swept[0] - swept[1]).abs() > 1e-3 * swept[0].abs().max(1e-3),
        "{swept:?}"
    );
}

#[test]
fn a_sheet_key_reaches_its_actuator_only() {
    let (_dir, path) = short_gripper(true);
    // The right finger's seal friction, through its own sheet.
    let s = sweep(&path, &["actuators[right].sheet:mechanics.coulomb_n=0.3,3"]).unwrap();
    let left = column(&s, "impedance", "squeeze.left.rms_force_error_n");
    let right = column(&s, "impedance", "squeeze.right.rms_force_error_n");
    assert_ne!(
        right[0], right[1],
        "the right sheet's friction reached the plant"
    );
    // The fingers only meet through the object on its slide: the left one sees the right one's change
    // through it, but far less than the right one does.
    let (dl, dr) = ((left[0] - left[1]).abs(), (right[0] - right[1]).abs());
    assert!(dl < dr, "left moved {dl} N, right {dr} N");
}

fn err(scene: &Path, args: &[&str]) -> String {
    match sweep(scene, args) {
        Ok(_) => panic!("{args:?} must be refused"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn a_bad_key_is_the_scenes_own_error() {
    let gripper = repo("scenes/gripper.toml");
    let e = err(&gripper, &["actuators[middle].x_d_m=0.01"]);
    assert!(e.contains("gripper.toml"), "{e}");
    assert!(e.contains("no element named \"middle\""), "{e}");
    assert!(e.contains("[\"left\", \"right\"]"), "{e}");
    let e = err(&gripper, &["actuators[left].x_dd_m=0.01"]);
    assert!(e.contains("gripper.toml:"), "{e}");
    assert!(e.contains("unknown field `x_dd_m`"), "{e}");
    let e = err(&gripper, &["contacts[left_pad].stiffness_n_per_m=-5"]);
    assert!(e.contains("contacts[0].stiffness_n_per_m"), "{e}");
    let e = err(
        &gripper,
        &["actuators[left].sheet:mechanics.moving_mas_kg=0.2"],
    );
    assert!(
        e.contains("gripper-finger.toml") && e.contains("moving_mas_kg"),
        "{e}"
    );
    let e = SetArg::parse("contacts[left_pad].name:x=1")
        .unwrap_err()
        .to_string();
    assert!(e.contains("actuators[NAME].sheet:KEY"), "{e}");
}

#[test]
fn tune_on_a_mechanism_writes_a_scene_whose_run_scores_what_the_search_said() {
    use pneuflex_sweep::tune::{FreeArg, Term, TuneOptions, Tuner};
    let (dir, path) = short_gripper(false);
    let tuner = Tuner::new(
        &path,
        vec![FreeArg::parse("runs[impedance].impedance.b_d_ns_per_m=[150,600]").unwrap()],
        &[],
        Some("impedance"),
        vec![
            Term::parse("squeeze.left.rms_force_error_n=1").unwrap(),
            Term::parse("squeeze.force_imbalance_n=0.5").unwrap(),
        ],
        pneuflex_sweep::points::DEFAULT_MAX_POINTS,
    )
    .unwrap();
    let opts = TuneOptions {
        budget: 6,
        population: Some(3),
        seed: 1,
        threads: 2,
        ..TuneOptions::default()
    };
    let history = tuner.search(&opts, None, &|| {}).unwrap();
    let best = pneuflex_sweep::tune_output::best(&history).unwrap();
    assert!(best.j.is_finite(), "{:?}", best.envs);
    // The tuned scene, written and read back as a user would, scores J = rms + 0.5 imbalance.
    let text = tuner.tuned_text(&best.x, "test", dir.path()).unwrap();
    let tuned_path = dir.path().join("gripper-tuned.toml");
    std::fs::write(&tuned_path, &text).unwrap();
    let scene = MechanismScene::load(&tuned_path).unwrap();
    let runs = run_all(&scene, &mut |_| {}, None, &mut ()).unwrap();
    let summary = summarise(&scene, &runs);
    let w = &summary.runs[0].windows[0];
    let j = w.actuators[0].1.rms_force_error_n + 0.5 * w.force_imbalance_n;
    assert_eq!(j, best.j);
    // A term the scene does not have is refused, naming the columns it has.
    let e = Tuner::new(
        &path,
        vec![FreeArg::parse("runs[impedance].impedance.b_d_ns_per_m=[150,600]").unwrap()],
        &[],
        None,
        vec![Term::parse("squeeze.middle.rms_force_error_n=1").unwrap()],
        pneuflex_sweep::points::DEFAULT_MAX_POINTS,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("squeeze.left.rms_force_error_n"), "{e}");
}
