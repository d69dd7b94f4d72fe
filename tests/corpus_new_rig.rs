//! Hostile input to `pneuflex new rig` (issue 41): every option checked where the user typed it. Each class
//! of bad input is refused with a non-zero exit, a message naming the option as typed and a value that
//! would work, never a file inside the staging folder or a key of a derived sheet, and nothing written;
//! the user's own files are never touched.

use std::path::Path;
use std::process::{Command, Output};

fn pneuflex(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pneuflex"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("runs")
}

/// A rig that works, with `extra` added (a later option of the same name is not allowed by the CLI, so
/// the base leaves out what the cases give).
fn rig_args<'a>(extra: &[&'a str]) -> Vec<&'a str> {
    let mut a = vec!["new", "rig", "r"];
    for (k, v) in [("--bore", "25mm"), ("--stroke", "100mm")] {
        let given = extra.contains(&k) || (k == "--bore" && extra.contains(&"--iso-bore"));
        if !given {
            a.extend([k, v]);
        }
    }
    a.extend(extra.iter());
    a
}

/// `extra` on the working rig is refused with exit code `code`, stderr holding every one of `expect`, no
/// staging folder or derived sheet key named, nothing on stdout and nothing left in the folder.
fn refused_with(code: i32, extra: &[&str], expect: &[&str]) {
    let tmp = tempfile::tempdir().unwrap();
    let args = rig_args(extra);
    let out = pneuflex(&args, tmp.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(code), "{args:?}: {stderr}");
    for e in expect {
        assert!(stderr.contains(e), "{args:?}: `{e}` not in: {stderr}");
    }
    for never in [
        ".partial",
        "_m3",
        "bore_m",
        "pressure_abs_pa",
        "moving_mass_kg",
        "panicked",
    ] {
        assert!(
            !stderr.contains(never),
            "{args:?}: names `{never}`: {stderr}"
        );
    }
    if code == 1 {
        assert!(
            ["would work", "e.g.", "give "]
                .iter()
                .any(|w| stderr.contains(w)),
            "{args:?}: no value that would work: {stderr}"
        );
    }
    assert!(out.stdout.is_empty(), "{args:?}: printed {:?}", out.stdout);
    let left: Vec<_> = std::fs::read_dir(tmp.path()).unwrap().collect();
    assert!(left.is_empty(), "{args:?}: left {left:?}");
}

fn refused(extra: &[&str], expect: &[&str]) {
    refused_with(1, extra, expect);
}

#[test]
fn a_unit_missing_unknown_or_of_the_wrong_kind_is_named_with_the_option() {
    for (key, bare, wrong, kind) in [
        ("--bore", "25", "3bar", "pressure"),
        ("--rod", "10", "10N", "force"),
        ("--stroke", "100", "5kg", "mass"),
        ("--supply", "6", "6mm", "length"),
        ("--valve-flow", "300", "6bar", "pressure"),
        ("--pwm-frequency", "40", "5ms", "time"),
        ("--switching-delay", "5", "40Hz", "frequency"),
        ("--position-range", "125", "1bar", "pressure"),
        ("--pressure-range", "0.8", "1mm", "length"),
        ("--mass", "0.6", "3N", "force"),
        ("--incline", "30", "3mm", "length"),
        ("--friction", "3", "3kg", "mass"),
        ("--dead-volume", "3", "3mm", "length"),
        ("--tube-length", "0.5", "3cm3", "volume"),
        ("--force", "30", "30kg", "mass"),
    ] {
        refused(
            &[key, bare],
            &[&format!("{key} {bare}: give a unit"), "e.g."],
        );
        refused(
            &[key, wrong],
            &[
                &format!("{key} {wrong}:"),
                &format!("is a unit of {kind}"),
                &format!("e.g. {key} "),
            ],
        );
        let unknown = format!("{bare}furlong");
        refused(
            &[key, &unknown],
            &[&format!("{key} {unknown}: unknown unit `furlong`")],
        );
        refused(
            &[key, "fast"],
            &[&format!("{key} fast: not a number with a unit")],
        );
    }
    // A decimal comma is said to be one, not an unknown unit `,5mm`.
    refused(
        &["--bore", "2,5mm"],
        &["--bore 2,5mm: a decimal comma", "--bore 2.5mm"],
    );
    // The proportional valve's option, on the valve it applies to.
    refused(
        &["--valve", "proportional", "--response-time", "5"],
        &["--response-time 5: give a unit"],
    );
    refused(&["--valve-c", "5bar"], &["--valve-c 5bar", "m³/(s Pa)"]);
}

#[test]
fn nan_infinity_and_overflow_are_not_numbers_for_any_option() {
    for key in [
        "--bore",
        "--stroke",
        "--supply",
        "--mass",
        "--friction",
        "--force",
    ] {
        for v in ["NaNmm", "infmm", "1e999mm"] {
            // Whatever the unit, a number that is not finite is refused before the unit matters.
            let unit_fixed = match key {
                "--supply" => v.replace("mm", "bar"),
                "--mass" => v.replace("mm", "kg"),
                "--friction" | "--force" => v.replace("mm", "N"),
                _ => v.to_string(),
            };
            let out_of_numbers = [key, unit_fixed.as_str()];
            refused(&out_of_numbers, &[&format!("{key} {unit_fixed}: not a")]);
        }
    }
    for (key, v) in [
        ("--valve-kv", "nan"),
        ("--valve-kv", "inf"),
        ("--valve-cv", "NaN"),
        ("--valve-b", "inf"),
        ("--valve-c", "nan"),
        ("--iso-bore", "nan"),
    ] {
        refused(&[key, v], &[key, "not a finite number", "e.g."]);
    }
}

#[test]
fn zero_and_negative_values_are_refused_with_a_value_that_works() {
    for (key, zero, negative) in [
        ("--bore", "0mm", "-25mm"),
        ("--rod", "0mm", "-10mm"),
        ("--stroke", "0mm", "-100mm"),
        ("--supply", "0bar", "-6bar"),
        ("--valve-flow", "0l/min", "-300l/min"),
        ("--valve-c", "0", "-5e-9"),
        ("--valve-kv", "0", "-1"),
        ("--valve-cv", "0", "-1"),
        ("--valve-b", "0", "-0.3"),
        ("--pwm-frequency", "0Hz", "-40Hz"),
        ("--switching-delay", "0ms", "-5ms"),
        ("--position-range", "0mm", "-125mm"),
        ("--pressure-range", "0MPa", "-0.8MPa"),
        ("--mass", "0kg", "-0.6kg"),
        ("--dead-volume", "0cm3", "-3cm3"),
        ("--force", "0N", "-30N"),
        ("--iso-bore", "0", "-32"),
    ] {
        for v in [zero, negative] {
            refused(&[key, v], &[&format!("{key} {v}")]);
        }
    }
    refused(
        &["--friction", "-3N"],
        &["--friction -3N", "--friction 0N would work"],
    );
    refused(
        &["--tube-length", "-0.5m"],
        &["--tube-length -0.5m", "--tube-length 0m would work"],
    );
}

#[test]
fn out_of_range_values_name_the_option_typed_and_a_value_that_works() {
    // The issue's cases first: each once refused naming a sheet in a staging folder and a derived key.
    for (args, expect) in [
        (vec!["--bore", "10m"], "--bore 10m: 10000 mm is over 320mm"),
        (vec!["--bore", "1e300mm"], "--bore 1e300mm:"),
        (
            vec!["--supply", "1000bar"],
            "--supply 1000bar: 1000 bar is over 16bar",
        ),
        (vec!["--mass", "1e6kg"], "--mass 1e6kg:"),
        (vec!["--bore", "1mm"], "--bore 1mm: 1 mm is under 8mm"),
        (vec!["--stroke", "100m"], "--stroke 100m:"),
        (vec!["--stroke", "1mm"], "--stroke 1mm:"),
        (vec!["--supply", "0.1bar"], "--supply 0.1bar:"),
        (vec!["--supply", "100MPa"], "--supply 100MPa:"),
        (vec!["--valve-flow", "1e9l/min"], "--valve-flow 1e9l/min:"),
        (vec!["--valve-flow", "0.01l/min"], "--valve-flow 0.01l/min:"),
        (vec!["--valve-c", "1"], "--valve-c 1:"),
        (
            vec!["--valve-c", "500dm3/(s*bar)"],
            "--valve-c 500dm3/(s*bar):",
        ),
        (vec!["--valve-kv", "1e6"], "--valve-kv 1e6:"),
        (vec!["--valve-cv", "1e-9"], "--valve-cv 1e-9:"),
        (vec!["--valve-b", "0.99"], "--valve-b 0.99:"),
        (vec!["--pwm-frequency", "100kHz"], "--pwm-frequency 100kHz:"),
        (vec!["--pwm-frequency", "1Hz"], "--pwm-frequency 1Hz:"),
        (vec!["--switching-delay", "10s"], "--switching-delay 10s:"),
        (vec!["--switching-delay", "1us"], "--switching-delay 1us:"),
        (vec!["--dead-volume", "1m3"], "--dead-volume 1m3:"),
        (vec!["--tube-length", "1000m"], "--tube-length 1000m:"),
        (vec!["--incline", "720deg"], "--incline 720deg:"),
        (vec!["--force", "1000kN"], "--force 1000kN:"),
        (
            vec!["--pressure-range", "100MPa"],
            "--pressure-range 100MPa:",
        ),
        (vec!["--position-range", "100m"], "--position-range 100m:"),
        (vec!["--iso-bore", "1000"], "--iso-bore 1000:"),
        (
            vec!["--iso-bore", "30"],
            "--iso-bore 30: not a bore of ISO 6432 or ISO 15552",
        ),
        (
            vec!["--valve", "proportional", "--response-time", "1s"],
            "--response-time 1s:",
        ),
        (
            vec!["--valve", "proportional", "--response-time", "1us"],
            "--response-time 1us:",
        ),
    ] {
        let would_work = if args.contains(&"--iso-bore") && args.contains(&"30") {
            "give --bore"
        } else {
            "would work"
        };
        refused(&args, &[expect, would_work]);
    }
}

#[test]
fn an_option_that_does_not_apply_is_refused_not_dropped() {
    for (args, expect) in [
        (
            vec!["--valve", "proportional", "--pwm-frequency", "40Hz"],
            vec!["--pwm-frequency: does not apply", "--valve pwm"],
        ),
        (
            vec!["--valve", "proportional", "--switching-delay", "5ms"],
            vec!["--switching-delay: does not apply", "--valve pwm"],
        ),
        // No --valve: the assumed on/off valve has no spool.
        (
            vec!["--response-time", "5ms"],
            vec![
                "--response-time: does not apply",
                "assumed without --valve",
                "--valve proportional",
            ],
        ),
        (
            vec!["--valve", "pwm", "--response-time", "5ms"],
            vec!["--response-time: does not apply", "the valve given is pwm"],
        ),
        (
            vec!["--dead-volume", "3cm3", "--tube-length", "0.5m"],
            vec!["--tube-length: does not apply", "--dead-volume"],
        ),
        (
            vec!["--iso-bore", "32", "--bore", "32mm"],
            vec!["--iso-bore", "not both"],
        ),
    ] {
        refused(&args, &expect);
    }
    // Two flow ratings of one valve, or an option twice: the CLI's usage error (exit 2) names them.
    refused_with(
        2,
        &["--valve-flow", "300l/min", "--valve-kv", "1"],
        &["--valve-flow", "--valve-kv"],
    );
    refused_with(2, &["--supply", "6bar", "--supply", "5bar"], &["--supply"]);
    refused_with(
        2,
        &["--valve", "servo"],
        &["--valve", "pwm", "proportional"],
    );
}

#[test]
fn values_that_contradict_the_rest_of_the_rig_name_the_option_to_change() {
    for (args, expect) in [
        (vec!["--rod", "25mm"], vec!["--rod 25mm", "--rod 10mm"]),
        (vec!["--rod", "1mm"], vec!["--rod 1mm", "would work"]),
        (
            vec!["--bore", "320mm", "--stroke", "10mm"],
            vec!["--stroke 10mm", "would work", "--stroke 80mm"],
        ),
        (
            vec!["--bore", "8mm", "--stroke", "1m"],
            vec!["--stroke 1000mm", "--stroke 200mm"],
        ),
        (
            vec!["--mass", "0.01kg"],
            vec!["--mass", "less than the steel rod", "e.g. --mass"],
        ),
        (
            vec!["--mass", "30kg"],
            vec!["--mass", "air springs", "(--mass 21kg)"],
        ),
        (
            vec!["--friction", "100N"],
            vec!["--friction", "force range", "would work (--friction"],
        ),
        (
            vec!["--force", "0.5N"],
            vec!["--force", "under 1 %", "would work (--force"],
        ),
        (
            vec!["--force", "200N"],
            vec!["--force", "over half", "would work"],
        ),
        (
            vec!["--dead-volume", "0.01cm3"],
            vec!["--dead-volume", "end cap", "e.g. --dead-volume"],
        ),
        (
            vec!["--position-range", "75mm"],
            vec![
                "--position-range",
                "shorter than the 100.0 mm stroke",
                "--position-range 125mm",
            ],
        ),
        (
            vec!["--position-range", "5m"],
            vec!["--position-range", "ten times", "--position-range 125mm"],
        ),
        (
            vec!["--pressure-range", "0.4MPa"],
            vec!["--pressure-range", "--pressure-range 0.8MPa"],
        ),
        (
            vec!["--pressure-range", "7MPa"],
            vec!["--pressure-range", "ten times", "--pressure-range 0.8MPa"],
        ),
        (
            vec![
                "--valve-flow",
                "5l/min",
                "--bore",
                "63mm",
                "--stroke",
                "200mm",
            ],
            vec!["--valve-flow", "too slow", "would work (--valve-flow"],
        ),
        // The rating the user gave is the one named, not a derived one.
        (
            vec!["--valve-kv", "0.005", "--bore", "63mm", "--stroke", "200mm"],
            vec!["--valve-kv", "too slow"],
        ),
        (
            vec!["--switching-delay", "20ms"],
            vec!["--pwm-frequency", "would work (--pwm-frequency 12Hz)"],
        ),
        // No carrier within --pwm-frequency's range is slow enough: the valve is named, not a carrier
        // the range refuses.
        (
            vec!["--switching-delay", "50ms"],
            vec!["--switching-delay", "would work (--switching-delay 6.2ms)"],
        ),
        // A valve far too small for a large cylinder: the suggestion is a valve there is.
        (
            vec![
                "--bore",
                "320mm",
                "--stroke",
                "2m",
                "--valve-flow",
                "100l/min",
            ],
            vec!["--valve-flow", "too slow", "(--valve-flow 20000l/min)"],
        ),
        (
            vec![
                "--mass",
                "20kg",
                "--incline",
                "60deg",
                "--bore",
                "16mm",
                "--stroke",
                "50mm",
            ],
            vec!["--mass"],
        ),
        // A valve far larger than its chamber: minutes of simulation, refused with a flow that works.
        (
            vec![
                "--bore",
                "8mm",
                "--stroke",
                "10mm",
                "--valve-flow",
                "20000l/min",
                "--dead-volume",
                "0.03cm3",
            ],
            vec![
                "--valve-flow",
                "far larger than the chamber",
                "would work (--valve-flow",
            ],
        ),
    ] {
        refused(&args, &expect);
    }
}

#[test]
fn rig_names_that_are_no_folder_name_are_refused() {
    let long = "a".repeat(65);
    for name in ["..", ".hidden", "-rig", "../escape", "my rig", "", &long] {
        refused(&["--name", name], &["--name", "e.g. --name my-rig"]);
    }
}

#[test]
fn the_output_folder_and_everything_of_the_users_are_left_alone() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let run = |dir: &str| {
        pneuflex(
            &["new", "rig", dir, "--bore", "25mm", "--stroke", "100mm"],
            t,
        )
    };
    // A folder holding the user's files.
    std::fs::create_dir(t.join("mine")).unwrap();
    std::fs::write(t.join("mine/notes.txt"), "my notes").unwrap();
    // A file, and a link to nowhere.
    std::fs::write(t.join("afile"), "data").unwrap();
    std::os::unix::fs::symlink(t.join("nowhere"), t.join("link")).unwrap();
    for dir in ["mine", "mine/", "afile", "link", ".", ".."] {
        let out = run(dir);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{dir}: {stderr}");
        assert!(
            stderr.contains("exists") && stderr.contains("replaces nothing"),
            "{dir}: {stderr}"
        );
    }
    // A folder under a file cannot be made: the file is named.
    let out = run("afile/rig");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("afile"), "{stderr}");
    assert!(!stderr.contains(".partial"), "{stderr}");
    assert_eq!(
        std::fs::read_to_string(t.join("mine/notes.txt")).unwrap(),
        "my notes"
    );
    assert_eq!(std::fs::read_to_string(t.join("afile")).unwrap(), "data");
    assert_eq!(std::fs::read_dir(t.join("mine")).unwrap().count(), 1);
    // A failure after the folders above DIR were made takes them away again (they were the tool's).
    let out = pneuflex(
        &[
            "new",
            "rig",
            "deep/er/rig",
            "--bore",
            "8mm",
            "--stroke",
            "10mm",
            "--valve-flow",
            "20000l/min",
            "--dead-volume",
            "0.03cm3",
        ],
        t,
    );
    assert_eq!(out.status.code(), Some(1));
    let mut left: Vec<String> = std::fs::read_dir(t)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["afile", "link", "mine"], "only the user's files");
    // A rig made beside them leaves no staging folder and touches nothing else.
    let out = run("r/");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut left: Vec<String> = std::fs::read_dir(t)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["afile", "link", "mine", "r"]);
}

#[test]
fn edge_values_inside_the_ranges_still_make_a_rig_that_loads() {
    let tmp = tempfile::tempdir().unwrap();
    for (dir, extra) in [
        // The smallest ISO 6432 size, at its shortest stroke.
        ("small", vec!["--bore", "8mm", "--stroke", "10mm"]),
        // No Coulomb friction at all: once written with kp = 5.5e-10 /m (a describing-function search at
        // its floor taken for an onset).
        (
            "ideal",
            vec![
                "--bore",
                "25mm",
                "--stroke",
                "100mm",
                "--friction",
                "0N",
                "--valve-flow",
                "300l/min",
            ],
        ),
        // A directory whose name is no rig name: the rig is named from its sizes.
        (
            "my rig",
            vec!["--bore", "25mm", "--stroke", "100mm", "--supply", "16bar"],
        ),
    ] {
        let mut a = vec!["new", "rig", dir];
        a.extend(extra.iter());
        let out = pneuflex(&a, tmp.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{a:?}: {stderr}");
        let scene = std::fs::read_to_string(tmp.path().join(dir).join("scene.toml")).unwrap();
        // A position loop worth the name: a full-stroke error opens the valve at least 10 %.
        let kp: f64 = scene
            .split("kp_per_m = ")
            .nth(1)
            .and_then(|t| t.split([',', ' ']).next())
            .and_then(|t| t.parse().ok())
            .unwrap_or_else(|| panic!("{dir}: no kp in {scene}"));
        assert!(kp > 1.0, "{dir}: kp = {kp} /m");
    }
    let scene = std::fs::read_to_string(tmp.path().join("my rig/scene.toml")).unwrap();
    assert!(scene.contains("name = \"rig-25x100-pwm\""), "{scene}");
}

#[test]
fn an_interrupt_during_the_gains_search_leaves_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    // A valve this large on an 8 mm bore takes 55 RK4 steps a tick: seconds of search, time to interrupt.
    let mut child = Command::new(env!("CARGO_BIN_EXE_pneuflex"))
        .args([
            "new",
            "rig",
            "a/b/r",
            "--bore",
            "8mm",
            "--stroke",
            "10mm",
            "--valve-flow",
            "20000l/min",
        ])
        .current_dir(tmp.path())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("runs");
    // Wait for the staging folder: the search has begun.
    let staged = || {
        std::fs::read_dir(tmp.path().join("a/b"))
            .map(|d| d.count() > 0)
            .unwrap_or(false)
    };
    while !staged() {
        assert!(
            child.try_wait().unwrap().is_none(),
            "ended before it staged anything"
        );
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{stderr}");
    assert!(
        stderr.contains("SIGINT") && stderr.contains("a/b/r: nothing written"),
        "{stderr}"
    );
    let left: Vec<_> = std::fs::read_dir(tmp.path()).unwrap().collect();
    assert!(left.is_empty(), "left {left:?}");
}
