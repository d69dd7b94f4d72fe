//! `pneuflex seal` and `pneuflex leak` on the shipped measurements, and `pneuflex tf` on a sheet with an
//! effect beyond the paper, as a user meets them: the built binary, its stdout, stderr and exit status.
//! (The figures themselves are asserted in crates/identify/tests/real_data.rs.)

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn pneuflex(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pneuflex"))
        .args(args)
        .current_dir(repo(""))
        .output()
        .unwrap()
}

fn ok(o: Output) -> String {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout).unwrap()
}

/// The seal's law, its RMS with and without the pressure term and its verdict; JSON with the same numbers.
#[test]
fn seal_prints_the_law_and_says_it_is_not_adequate() {
    let text = ok(pneuflex(&[
        "seal",
        "--data",
        "data/zillen-2021-printed-cylinder",
    ]));
    assert!(
        text.contains("| pressure term, an offset per test | 3.4397 | 0.7828 | 0.7520 | 1.3789 |"),
        "{text}"
    );
    assert!(text.contains("56.8 %"), "{text}");
    assert!(text.contains("adequate: false"), "{text}");
    let json = ok(pneuflex(&[
        "seal",
        "--data",
        "data/zillen-2021-printed-cylinder",
        "--json",
    ]));
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let k = v["pressure"]["coulomb_pressure_n_per_pa"].as_f64().unwrap();
    assert!((k - 7.82789e-6).abs() < 1e-10, "{k}");
    assert_eq!(v["adequacy"]["adequate"], false);
}

/// The leaks ranked tightest first, and which step is settled.
#[test]
fn leak_ranks_the_chambers() {
    let logs: Vec<String> = ["ultimaker_010", "aluminium", "prusa"]
        .iter()
        .map(|m| format!("data/zillen-2021-printed-cylinder/leakage/{m}.csv"))
        .collect();
    let mut args = vec!["leak"];
    for l in &logs {
        args.extend(["--log", l.as_str()]);
    }
    let text = ok(pneuflex(&args));
    assert!(
        text.contains("ranking, tightest to leakiest: aluminium < prusa < ultimaker_010"),
        "{text}"
    );
    assert!(
        text.contains("aluminium < prusa: C/V x 2.891, settled"),
        "{text}"
    );
    assert!(
        text.contains("prusa < ultimaker_010: C/V x 1.042, not settled"),
        "{text}"
    );
    args.push("--json");
    let v: serde_json::Value = serde_json::from_str(&ok(pneuflex(&args))).unwrap();
    let k = v["chambers"][0]["decay"]["rate_per_s"].as_f64().unwrap();
    assert!((k / 2.827805e-5 - 1.0).abs() < 1e-5, "{k}");
}

/// A missing folder or a malformed log ends the command with the file (and line) named.
#[test]
fn bad_bench_inputs_are_named() {
    let o = pneuflex(&["seal", "--data", "data/nope"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("data/nope"));
    let g = tempfile::tempdir().unwrap();
    let f = g.path().join("bad.csv");
    std::fs::write(&f, "0.000;3.8;7.6\r\n1.03.000;3.8;7.6\r\n").unwrap();
    let o = pneuflex(&["leak", "--log", f.to_str().unwrap()]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains(&format!("{}:2", f.display())) && e.contains("time_ms"),
        "{e}"
    );
}

/// `tf` linearises the paper's model and says which effects of a sheet it leaves out.
#[test]
fn tf_names_the_effects_it_does_not_linearise() {
    let g = tempfile::tempdir().unwrap();
    for e in std::fs::read_dir(repo("pneumatics")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "toml") {
            std::fs::copy(&p, g.path().join(p.file_name().unwrap())).unwrap();
        }
    }
    let cyl = g.path().join("smc-mqm16-cylinder.toml");
    let text = std::fs::read_to_string(&cyl).unwrap();
    std::fs::write(
        &cyl,
        format!("{text}\nwall_heat_transfer_w_per_m2_k = 50.0\n"),
    )
    .unwrap();
    let sheet = g.path().join("paper-actuator.toml");
    let out = ok(pneuflex(&["tf", sheet.to_str().unwrap()]));
    assert!(
        out.contains(
            "not linearised (the paper's model only): cylinder.wall_heat_transfer_w_per_m2_k"
        ),
        "{out}"
    );
    let shipped = ok(pneuflex(&["tf", "pneumatics/paper-actuator.toml"]));
    assert!(!shipped.contains("not linearised"));
}
