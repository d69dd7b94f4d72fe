//! `pneuflex identify --channel NAME` on a recording of several actuators (issue 43 item 6): the gripper run
//! on an emulated board of two channels in lockstep, each finger's plant with its own hidden truth (two
//! perturbed sheets, different seeds), then each finger's sheet fitted from its own columns of the one
//! recording, with its own measured contact force and motion as the replay's inputs.
//!
//! The quick form here (CI): 3 s of the scene's first run (impedance: the approach, contact and the 10 N
//! squeeze). The full form, the whole 8 s of each run, is in docs/identification.md "Several actuators".

mod common;

use common::{pneuflex, text};
use std::path::Path;
use std::process::Command;

const SHEET: &str = "pneumatics/gripper-finger.toml";
const KEYS: [&str; 2] = ["valve.sonic_conductance_m3_per_s_pa", "mechanics.coulomb_n"];

fn json(p: &Path) -> serde_json::Value {
    let t = std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    serde_json::from_str(&t).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// `perturb`'s hidden truth of the finger's sheet with `seed`: (folder's sheet, truth per key of [`KEYS`]).
fn truth(dir: &Path, seed: u64) -> (String, [f64; 2]) {
    let out = dir.join(format!("truth{seed}"));
    let seed = seed.to_string();
    let o = pneuflex(&[
        "perturb",
        "--actuator",
        SHEET,
        "--keys",
        &KEYS.join(","),
        "--seed",
        &seed,
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let t = json(&out.join("truth.json"));
    let value = |key: &str| {
        t.as_array()
            .unwrap()
            .iter()
            .find(|e| e["key"] == key)
            .and_then(|e| e["truth"].as_f64())
            .unwrap_or_else(|| panic!("no truth of {key} in {t}"))
    };
    (
        out.join("gripper-finger.toml").display().to_string(),
        KEYS.map(value),
    )
}

/// Per key of [`KEYS`]: (estimate, 95 % interval, whether the interval is valid) from `identify`'s report.
fn estimates(report: &Path) -> Vec<(f64, [f64; 2], bool)> {
    let r = json(report);
    KEYS.iter()
        .map(|k| {
            let e = r["fit"]["estimates"]
                .as_array()
                .unwrap()
                .iter()
                .find(|e| e["key"] == *k)
                .unwrap_or_else(|| panic!("no estimate of {k} in {}", report.display()));
            let ci = e["ci95"].as_array().unwrap();
            (
                e["value"].as_f64().unwrap(),
                [ci[0].as_f64().unwrap(), ci[1].as_f64().unwrap()],
                e["interval_valid"].as_bool().unwrap(),
            )
        })
        .collect()
}

/// The text of the first `<tag .../>` after `<link name="LINK">` (or `<joint name="...">`) in the URDF.
fn urdf_attr(urdf: &str, element: &str, tag: &str, attr: &str) -> f64 {
    let start = urdf
        .find(element)
        .unwrap_or_else(|| panic!("no {element} in urdf/gripper.urdf"));
    let rest = &urdf[start..];
    let at = rest.find(&format!("<{tag} ")).unwrap() + tag.len() + 2;
    let rest = &rest[at..];
    let v = rest.find(&format!("{attr}=\"")).unwrap() + attr.len() + 2;
    let rest = &rest[v..];
    rest[..rest.find('"').unwrap()].parse().unwrap()
}

/// The replay is the 1-DOF model of one finger: its mechanics must be the finger's in the mechanism, the
/// sheet's moving mass the URDF's finger link, its viscous friction the slide joint's damping (the sheet
/// says a mechanism does not use them; identification does).
#[test]
fn the_finger_sheets_mechanics_are_the_urdfs_finger() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let urdf = std::fs::read_to_string(root.join("urdf/gripper.urdf")).unwrap();
    let sheet = std::fs::read_to_string(root.join(SHEET)).unwrap();
    // `key = value  # comment` in the sheet's [mechanics] table.
    let mechanics = |key: &str| -> f64 {
        let table = &sheet[sheet.find("[mechanics]").unwrap()..];
        let line = table
            .lines()
            .find(|l| l.split('=').next().is_some_and(|k| k.trim() == key))
            .unwrap_or_else(|| panic!("{SHEET}: no mechanics.{key}"));
        let value = line.split('=').nth(1).unwrap().split('#').next().unwrap();
        value.trim().parse().unwrap()
    };
    for side in ["left", "right"] {
        let link = format!("<link name=\"finger_{side}\">");
        let joint = format!("<joint name=\"{side}_slide\"");
        assert_eq!(
            mechanics("moving_mass_kg"),
            urdf_attr(&urdf, &link, "mass", "value"),
            "{SHEET} mechanics.moving_mass_kg against finger_{side}'s mass"
        );
        assert_eq!(
            mechanics("viscous_n_s_per_m"),
            urdf_attr(&urdf, &joint, "dynamics", "damping"),
            "{SHEET} mechanics.viscous_n_s_per_m against {side}_slide's damping"
        );
    }
}

#[test]
fn identify_fits_each_finger_of_a_gripper_recording_to_its_own_hidden_truth() {
    let dir = tempfile::tempdir().unwrap();
    let (left_sheet, left_truth) = truth(dir.path(), 1);
    let (right_sheet, right_truth) = truth(dir.path(), 2);
    // The two truths differ in both keys (else "in the direction of their truths" is no check).
    for i in 0..2 {
        assert!(
            (left_truth[i] - right_truth[i]).abs() > 0.1 * left_truth[i],
            "{}: the truths {} and {} are too close to tell apart",
            KEYS[i],
            left_truth[i],
            right_truth[i]
        );
    }
    let rec = dir.path().join("rec");
    let o = pneuflex(&[
        "rig",
        "run",
        "--rig",
        "rigs/gripper.toml",
        "--scene",
        "scenes/gripper.toml",
        "--lockstep-truth",
        SHEET,
        "--truth",
        &format!("left={left_sheet}"),
        "--truth",
        &format!("right={right_sheet}"),
        "--duration",
        "3",
        "--out",
        rec.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let trace = rec.join("impedance").join("trace.csv");
    let trace = trace.to_str().unwrap();
    let identify = |extra: &[&str], out: &Path| {
        let mut args = vec![
            "identify",
            "--log",
            trace,
            "--actuator",
            SHEET,
            "--free",
            "valve.sonic_conductance_m3_per_s_pa,mechanics.coulomb_n",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        pneuflex(&args)
    };

    // Without --channel: refused at the header, naming the actuators and the option.
    let o = identify(&[], &dir.path().join("none"));
    assert!(!o.status.success());
    let e = text(&o);
    assert!(
        e.contains("trace.csv:1:")
            && e.contains("several actuators (left, right)")
            && e.contains("--channel"),
        "{e}"
    );
    // An actuator the recording does not have: refused with the ones it has.
    let o = identify(&["--channel", "middle"], &dir.path().join("middle"));
    assert!(!o.status.success());
    let e = text(&o);
    assert!(
        e.contains("trace.csv:1:")
            && e.contains("no actuator `middle`")
            && e.contains("left, right"),
        "{e}"
    );

    let mut fitted = Vec::new();
    println!(
        "{:<6} {:<36} {:>12} {:>12} {:>28}",
        "finger", "key", "truth", "estimate", "95 % interval"
    );
    for (finger, truth) in [("left", left_truth), ("right", right_truth)] {
        // Without --out, from the temporary folder: each finger's output in its own default folder
        // (out/identify/<the log's folder>-<finger>), so that the second does not replace the first.
        let sheet = Path::new(env!("CARGO_MANIFEST_DIR")).join(SHEET);
        let o = Command::new(env!("CARGO_BIN_EXE_pneuflex"))
            .args([
                "identify",
                "--log",
                trace,
                "--channel",
                finger,
                "--actuator",
            ])
            .arg(&sheet)
            .args(["--free", &KEYS.join(",")])
            .current_dir(dir.path())
            .output()
            .expect("runs");
        assert!(o.status.success(), "{}", text(&o));
        let out = dir
            .path()
            .join("out/identify")
            .join(format!("impedance-{finger}"));
        let report = json(&out.join("report.json"));
        assert_eq!(
            report["model_check"]["adequate"], true,
            "{finger}: model check: {}",
            report["model_check"]
        );
        let note = report["logs"][0]["note"].as_str().unwrap_or_default();
        assert!(note.contains(&format!("actuator `{finger}`")), "{note}");
        let est = estimates(&out.join("report.json"));
        for (i, (value, ci, valid)) in est.iter().enumerate() {
            println!(
                "{finger:<6} {:<36} {:>12.4e} {:>12.4e}   [{:.4e}, {:.4e}]",
                KEYS[i], truth[i], value, ci[0], ci[1]
            );
            assert!(valid, "{finger} {}: interval not valid", KEYS[i]);
            assert!(
                ci[0] <= truth[i] && truth[i] <= ci[1],
                "{finger} {}: truth {} outside the 95 % interval [{}, {}] (estimate {value})",
                KEYS[i],
                truth[i],
                ci[0],
                ci[1]
            );
        }
        fitted.push(est.iter().map(|e| e.0).collect::<Vec<f64>>());
    }
    for finger in ["left", "right"] {
        let out = dir.path().join(format!("out/identify/impedance-{finger}"));
        assert!(out.join("report.json").is_file(), "{}", out.display());
    }
    // Each finger fitted to its own truth: the estimates differ in the direction the truths do.
    for i in 0..2 {
        assert_eq!(
            (fitted[1][i] - fitted[0][i]).signum(),
            (right_truth[i] - left_truth[i]).signum(),
            "{}: estimates left {} right {}, truths left {} right {}",
            KEYS[i],
            fitted[0][i],
            fitted[1][i],
            left_truth[i],
            right_truth[i]
        );
    }
}
