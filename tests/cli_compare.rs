//! `pneuflex compare`: a log made by a hidden truth (the shipped sheet with six values moved 20-40 %) is
//! compared with the shipped sheet's simulation and with the truth's: every metric difference and the trace
//! difference shrink to nothing with the true sheet; bad logs are refused with their line.

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

#[test]
fn the_true_sheet_closes_the_gap_the_shipped_one_leaves() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let keys = "valve.sonic_conductance_m3_per_s_pa,valve.critical_pressure_ratio,cylinder.dead_volume_a_m3,\
                cylinder.dead_volume_b_m3,mechanics.coulomb_n,mechanics.moving_mass_kg";
    perturb(t, keys);
    let truth = t.join("truth/paper-actuator.toml");
    // The "rig": the scene run on the truth.
    let scene = repo.join("scenes/paper-fig3.toml");
    let text = std::fs::read_to_string(&scene).unwrap().replace(
        "actuator = \"../pneumatics/paper-actuator.toml\"",
        &format!("actuator = {:?}", truth.to_str().unwrap()),
    );
    std::fs::write(t.join("truth-scene.toml"), text).unwrap();
    ok(&pneuflex(
        &["run", "truth-scene.toml", "--quiet", "--out", "rig"],
        t,
    ));
    let log = t.join("rig/impedance/trace.csv");
    let scene = scene.to_str().unwrap();
    let log = log.to_str().unwrap();
    ok(&compare(
        t,
        scene,
        &[log],
        &["--run", "impedance", "--out", "shipped"],
    ));
    let truth = truth.to_str().unwrap();
    ok(&compare(
        t,
        scene,
        &[log],
        &["--run", "impedance", "--actuator", truth, "--out", "true"],
    ));
    let read = |d: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(t.join(d).join("compare.json")).unwrap())
            .unwrap()
    };
    let (shipped, truth) = (read("shipped"), read("true"));
    let f = |v: &serde_json::Value| v["f_e_rms_difference_n"].as_f64().unwrap();
    assert!(
        f(&shipped) > 0.1,
        "the shipped sheet differs from the truth: {}",
        f(&shipped)
    );
    assert!(
        f(&truth) < 1e-9,
        "the true sheet reproduces the log: {}",
        f(&truth)
    );
    let diffs = |v: &serde_json::Value| -> Vec<f64> {
        v["metrics"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|m| m["difference"].as_f64())
            .map(f64::abs)
            .collect()
    };
    assert!(diffs(&shipped).iter().sum::<f64>() > 0.1);
    assert!(
        diffs(&truth).iter().all(|d| *d < 1e-9),
        "{:?}",
        diffs(&truth)
    );
    for d in ["shipped", "true"] {
        for f in ["compare.md", "force.png", "position.png"] {
            assert!(t.join(d).join(f).is_file(), "{d}/{f}");
        }
    }
    // The log is an input: compare never writes inside the rig's directory.
    refused(&compare(t, scene, &[log], &["--out", "rig/impedance/cmp"]));
}

#[test]
fn a_bad_log_is_refused_with_its_line() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let tmp = tempfile::tempdir().unwrap();
    let scene = repo.join("scenes/paper-fig3.toml");
    let scene = scene.to_str().unwrap();
    std::fs::write(
        tmp.path().join("bad.csv"),
        "t,f_ref,f_e,x,x_r,p_a,p_b,u\n0,1,1,0,0,1e5,1e5,0\n0.001,1,x,0,0,1e5,1e5,0\n",
    )
    .unwrap();
    let e = refused(&compare(tmp.path(), scene, &["bad.csv"], &[]));
    assert!(
        e.contains("bad.csv: line 3: column `f_e`: `x` is not a number"),
        "{e}"
    );
    std::fs::write(
        tmp.path().join("coarse.csv"),
        "t,f_ref,f_e,x,x_r,p_a,p_b,u\n0,1,1,0,0,1e5,1e5,0\n0.01,1,1,0,0,1e5,1e5,0\n",
    )
    .unwrap();
    let e = refused(&compare(tmp.path(), scene, &["coarse.csv"], &[]));
    assert!(e.contains("a log of another scene?"), "{e}");
    assert!(!tmp.path().join("out").exists(), "nothing written");
}

#[test]
fn two_recorded_runs_give_the_claims_verdicts_on_the_rig_beside_the_simulation() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    // The "rig": paper-fig3 run with the Coulomb friction doubled, both runs (the sheets copied beside it).
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
    std::fs::create_dir(t.join("scenes")).unwrap();
    let scene = repo.join("scenes/paper-fig3.toml");
    std::fs::copy(&scene, t.join("scenes/rig-scene.toml")).unwrap();
    ok(&pneuflex(
        &["run", "scenes/rig-scene.toml", "--quiet", "--out", "rig"],
        t,
    ));
    let scene = scene.to_str().unwrap();
    let imp = format!("impedance={}", t.join("rig/impedance/trace.csv").display());
    let ada = format!("adaptive={}", t.join("rig/adaptive/trace.csv").display());
    ok(&compare(t, scene, &[&imp, &ada], &["--out", "cmp"]));
    let read = |p: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let c = read(&t.join("cmp/compare.json"));
    let rig_summary = read(&t.join("rig/summary.json"));
    // The rig's verdicts are the rig scene's own claims (its summary.json), value for value.
    let claims = c["claims"]["rig"].as_array().unwrap();
    let own = rig_summary["claims"].as_array().unwrap();
    assert_eq!(claims.len(), own.len());
    for (a, b) in claims.iter().zip(own) {
        assert_eq!(a["statement"], b["statement"]);
        assert_eq!(a["holds"], b["holds"], "{}", a["statement"]);
        for k in ["better_value", "than_value"] {
            let (x, y) = (a[k].as_f64().unwrap(), b[k].as_f64().unwrap());
            assert!(
                (x - y).abs() <= 1e-9 * x.abs().max(1.0),
                "{}: {k} {x} vs {y}",
                a["statement"]
            );
        }
    }
    // The simulation side is the shipped scene's.
    assert_eq!(
        c["claims"]["simulation"].as_array().unwrap().len(),
        own.len()
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
    // Two logs must say which run each recorded, and two of one run are refused.
    let bare = t.join("rig/impedance/trace.csv");
    let bare = bare.to_str().unwrap();
    let e = refused(&compare(t, scene, &[bare, &ada], &["--out", "x"]));
    assert!(e.contains("give RUN="), "{e}");
    let twice = format!("adaptive={bare}");
    let e = refused(&compare(t, scene, &[&ada, &twice], &["--out", "x"]));
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
    let fe = |c: &serde_json::Value| c["f_e_rms_difference_n"].as_f64().unwrap();
    assert!(
        fe(&truth) < fe(&shipped),
        "{} vs {}",
        fe(&truth),
        fe(&shipped)
    );
}
