//! `pneuflex compare`: a recording made on the lockstep emulator hiding a truth (the shipped sheet with values
//! moved 20-40 %) is compared with the shipped sheet's simulation and with the truth's: every window's RMS
//! error difference shrinks with the true sheet; two recorded runs give the claims' verdicts on the rig from
//! the recordings' own metrics; bad logs are refused with their line (tests/corpus_compare.rs has the rest).

use std::path::Path;
use std::process::Command;

fn pneuflex(args: &[&str], cwd: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_pneuflex"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("runs")
}

fn ok(o: &std::process::Output) -> String {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// `compare` of `scene` with the rig's `logs` (each a `--rig-log`), then `rest` of the arguments.
fn compare(cwd: &Path, scene: &str, logs: &[&str], rest: &[&str]) -> std::process::Output {
    let mut args = vec!["compare", scene];
    for log in logs {
        args.extend(["--rig-log", log]);
    }
    args.extend(rest);
    pneuflex(&args, cwd)
}

/// The error of a run that must fail.
fn refused(o: &std::process::Output) -> String {
    let e = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!o.status.success(), "accepted: {e}");
    e
}

/// `perturb` of the shipped actuator sheet's `keys` (seed 5) into `dir/truth/`: the hidden truth.
fn perturb(dir: &Path, keys: &str) {
    let sheet = Path::new(env!("CARGO_MANIFEST_DIR")).join("pneumatics/paper-actuator.toml");
    let sheet = sheet.to_str().unwrap();
    let args = [
        "perturb",
        "--actuator",
        sheet,
        "--keys",
        keys,
        "--seed",
        "5",
        "--out",
        "truth",
    ];
    ok(&pneuflex(&args, dir));
}

/// `rig run --lockstep-truth TRUTH` of paper-fig3's `run` (seconds `duration`, the scene's when None) into
/// `dir/out`.
fn record(dir: &Path, truth: &str, run: &str, duration: Option<&str>, out: &str) {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let rig = repo.join("rigs/emulated.toml");
    let scene = repo.join("scenes/paper-fig3.toml");
    let (rig, scene) = (rig.to_str().unwrap(), scene.to_str().unwrap());
    let mut args = vec![
        "rig",
        "run",
        "--rig",
        rig,
        "--lockstep-truth",
        truth,
        "--scene",
        scene,
        "--run",
        run,
        "--out",
        out,
    ];
    if let Some(d) = duration {
        args.extend(["--duration", d]);
    }
    ok(&pneuflex(&args, dir));
}

#[test]
fn a_bad_log_is_refused_with_its_line() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let scene = repo.join("scenes/paper-fig3.toml");
    let scene = scene.to_str().unwrap();
    let sheet = repo.join("pneumatics/paper-actuator.toml");
    record(t, sheet.to_str().unwrap(), "impedance", Some("0.5"), "rec");
    // The recording copied with its manifest, one cell made a word (data starts on line 5).
    std::fs::create_dir(t.join("bad")).unwrap();
    for f in [".pneuflex-output.json", "summary.json", "trace.csv"] {
        std::fs::copy(t.join("rec").join(f), t.join("bad").join(f)).unwrap();
    }
    let text = std::fs::read_to_string(t.join("rec/trace.csv")).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let mut cells: Vec<&str> = lines[6].split(',').collect();
    cells[2] = "x";
    lines[6] = cells.join(",");
    std::fs::write(t.join("bad/trace.csv"), lines.join("\n") + "\n").unwrap();
    let e = refused(&compare(t, scene, &["bad/trace.csv"], &["--out", "x"]));
    assert!(
        e.contains("bad/trace.csv: line 7: column `f_e`: `x` is not a number"),
        "{e}"
    );
    // A CSV of the loop's columns alone is not a recording of the rig.
    std::fs::write(
        t.join("coarse.csv"),
        "t,f_ref,f_e,x,x_r,p_a,p_b,u\n0,1,1,0,0,1e5,1e5,0\n0.01,1,1,0,0,1e5,1e5,0\n",
    )
    .unwrap();
    let e = refused(&compare(t, scene, &["coarse.csv"], &["--out", "x"]));
    assert!(
        e.contains("coarse.csv: line 1: none of the rig's columns"),
        "{e}"
    );
    assert!(!t.join("x").exists(), "nothing written");
}

#[test]
fn two_recorded_runs_give_the_claims_verdicts_on_the_rig_beside_the_simulation() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    // The "rig": the emulator hiding the shipped sheet with its Coulomb friction doubled (the sheets copied
    // beside it), both runs recorded.
    std::fs::create_dir(t.join("pneumatics")).unwrap();
    for e in std::fs::read_dir(repo.join("pneumatics")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "toml") {
            std::fs::copy(&p, t.join("pneumatics").join(p.file_name().unwrap())).unwrap();
        }
    }
    let sheet_path = t.join("pneumatics/paper-actuator.toml");
    let sheet = std::fs::read_to_string(&sheet_path).unwrap();
    assert!(
        sheet.contains("coulomb_n = 0.6 "),
        "the shipped sheet's Coulomb friction moved"
    );
    std::fs::write(
        &sheet_path,
        sheet.replace("coulomb_n = 0.6 ", "coulomb_n = 1.2 "),
    )
    .unwrap();
    record(
        t,
        "pneumatics/paper-actuator.toml",
        "impedance",
        None,
        "rec-impedance",
    );
    record(
        t,
        "pneumatics/paper-actuator.toml",
        "adaptive",
        None,
        "rec-adaptive",
    );
    let scene = repo.join("scenes/paper-fig3.toml");
    let scene = scene.to_str().unwrap();
    let imp = "rec-impedance/trace.csv";
    let ada = "rec-adaptive/trace.csv";
    ok(&compare(t, scene, &[imp, ada], &["--out", "cmp"]));
    let read = |p: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let c = read(&t.join("cmp/compare.json"));
    // The rig's verdicts are read on each recording's own metrics (the summary.json `rig run` wrote).
    let metric = |run: &str, window: &str, metric: &str| -> Option<f64> {
        let s = read(&t.join(format!("rec-{run}/summary.json")));
        let w = s["runs"][0]["windows"]
            .as_array()
            .unwrap()
            .iter()
            .find(|w| w["name"] == window)?
            .clone();
        w[metric].as_f64().or_else(|| w["event"][metric].as_f64())
    };
    let claims = c["claims"]["rig"].as_array().unwrap();
    assert!(!claims.is_empty(), "{c}");
    for a in claims {
        let (window, m) = (a["window"].as_str().unwrap(), a["metric"].as_str().unwrap());
        for (who, value) in [("better", "better_value"), ("than", "than_value")] {
            let own = metric(a[who].as_str().unwrap(), window, m).expect("the recording's metric");
            let x = a[value].as_f64().unwrap();
            assert!(
                (x - own).abs() <= 1e-9 * own.abs().max(1.0),
                "{}: {value} {x} vs the recording's {own}",
                a["statement"]
            );
        }
    }
    // The simulation side is the shipped scene's.
    assert_eq!(
        c["claims"]["simulation"].as_array().unwrap().len(),
        claims.len()
    );
    assert_eq!(c["runs"].as_array().unwrap().len(), 2);
    let md = std::fs::read_to_string(t.join("cmp/compare.md")).unwrap();
    assert!(
        md.contains("the claims, on the rig and in simulation"),
        "{md}"
    );
    for f in ["impedance/force.png", "adaptive/force.png"] {
        assert!(t.join("cmp").join(f).is_file(), "{f}");
    }
    // Each log's summary.json names its run; two of one run are refused.
    let twice = format!("impedance={ada}");
    let e = refused(&compare(t, scene, &[imp, &twice], &["--out", "x"]));
    assert!(e.contains("a recording of run `adaptive`"), "{e}");
    let e = refused(&compare(t, scene, &[imp, imp], &["--out", "x"]));
    assert!(e.contains("already given"), "{e}");
    assert!(!t.join("x").exists(), "nothing written");
}

#[test]
fn on_the_lockstep_emulator_the_true_sheet_explains_the_rig_better_than_the_shipped_one() {
    // `rig run --lockstep-truth`: the emulated rig (ADC quantisation, noise, the emulator's own start and
    // stiffness change) hides a perturbed sheet; compare with the shipped sheet, then with the hidden one.
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    perturb(
        t,
        "valve.sonic_conductance_m3_per_s_pa,mechanics.coulomb_n,mechanics.moving_mass_kg",
    );
    let rig = repo.join("rigs/emulated.toml");
    let scene = repo.join("scenes/paper-fig3.toml");
    let (rig, scene) = (rig.to_str().unwrap(), scene.to_str().unwrap());
    let run = |out: &str| {
        ok(&pneuflex(
            &[
                "rig",
                "run",
                "--rig",
                rig,
                "--lockstep-truth",
                "truth/paper-actuator.toml",
                "--scene",
                scene,
                "--run",
                "impedance",
                "--out",
                out,
            ],
            t,
        ))
    };
    run("rec");
    // Lockstep: the same recording again, value for value (all but the host's wall clock).
    run("rec-again");
    let values = |d: &str| -> Vec<String> {
        let text = std::fs::read_to_string(t.join(d).join("trace.csv")).unwrap();
        let rows: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
        let wall = rows[0]
            .split(',')
            .position(|c| c == "wall_time")
            .expect("a wall_time column");
        rows.iter()
            .map(|r| {
                let mut cells: Vec<&str> = r.split(',').collect();
                cells.remove(wall);
                cells.join(",")
            })
            .collect()
    };
    let (first, again) = (values("rec"), values("rec-again"));
    assert!(
        first.len() > 10_000 && first == again,
        "the lockstep recording is not reproducible"
    );
    // rig run --scene judged the recording: every window of the scene, the stiffness change's included.
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(t.join("rec/summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["runs"][0]["windows"].as_array().unwrap().len(), 4);
    for (out, extra) in [
        ("shipped", None),
        ("true", Some("truth/paper-actuator.toml")),
    ] {
        let mut rest = vec!["--out", out];
        if let Some(a) = extra {
            rest.extend(["--actuator", a]);
        }
        ok(&compare(t, scene, &["rec/trace.csv"], &rest));
    }
    let read = |d: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(t.join(d).join("compare.json")).unwrap())
            .unwrap()
    };
    let (shipped, truth) = (read("shipped"), read("true"));
    assert_eq!(truth["run"], "impedance");
    let rms = |c: &serde_json::Value| -> Vec<f64> {
        c["metrics"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|m| m["metric"] == "rms_force_error_n")
            .map(|m| m["difference"].as_f64().unwrap().abs())
            .collect()
    };
    let (a, b) = (rms(&shipped), rms(&truth));
    assert_eq!(a.len(), 4);
    for (s, tr) in a.iter().zip(&b) {
        assert!(
            *tr < 0.2 * s,
            "each window's RMS error difference shrinks: {a:?} -> {b:?}"
        );
    }
    for d in ["shipped", "true"] {
        for f in ["compare.md", "force.png", "position.png"] {
            assert!(t.join(d).join(f).is_file(), "{d}/{f}");
        }
    }
    // The log is an input: compare never writes inside the recording.
    refused(&compare(
        t,
        scene,
        &["rec/trace.csv"],
        &["--out", "rec/cmp"],
    ));
    assert!(!t.join("rec/cmp").exists());
    let fe = |c: &serde_json::Value| c["f_e_rms_difference_n"].as_f64().unwrap();
    assert!(
        fe(&truth) < fe(&shipped),
        "{} vs {}",
        fe(&truth),
        fe(&shipped)
    );
}
