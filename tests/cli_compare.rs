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

#[test]
fn the_true_sheet_closes_the_gap_the_shipped_one_leaves() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let keys = "valve.sonic_conductance_m3_per_s_pa,valve.critical_pressure_ratio,cylinder.dead_volume_a_m3,\
                cylinder.dead_volume_b_m3,mechanics.coulomb_n,mechanics.moving_mass_kg";
    let sheet = repo.join("pneumatics/paper-actuator.toml");
    ok(&pneuflex(
        &[
            "perturb",
            "--actuator",
            sheet.to_str().unwrap(),
            "--keys",
            keys,
            "--seed",
            "5",
            "--out",
            "truth",
        ],
        t,
    ));
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
    ok(&pneuflex(
        &[
            "compare",
            scene,
            "--rig-log",
            log,
            "--run",
            "impedance",
            "--out",
            "shipped",
        ],
        t,
    ));
    ok(&pneuflex(
        &[
            "compare",
            scene,
            "--rig-log",
            log,
            "--run",
            "impedance",
            "--actuator",
            truth.to_str().unwrap(),
            "--out",
            "true",
        ],
        t,
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
    let o = pneuflex(
        &[
            "compare",
            scene,
            "--rig-log",
            log,
            "--out",
            "rig/impedance/cmp",
        ],
        t,
    );
    assert!(!o.status.success());
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
    let o = pneuflex(&["compare", scene, "--rig-log", "bad.csv"], tmp.path());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("bad.csv: line 3: column `f_e`: `x` is not a number"),
        "{e}"
    );
    std::fs::write(
        tmp.path().join("coarse.csv"),
        "t,f_ref,f_e,x,x_r,p_a,p_b,u\n0,1,1,0,0,1e5,1e5,0\n0.01,1,1,0,0,1e5,1e5,0\n",
    )
    .unwrap();
    let o = pneuflex(&["compare", scene, "--rig-log", "coarse.csv"], tmp.path());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("a log of another scene?"),
        "{e}"
    );
    assert!(!tmp.path().join("out").exists(), "nothing written");
}
