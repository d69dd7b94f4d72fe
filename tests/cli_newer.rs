//! Issue 23: the newer commands (`sweep`, `tune`, `identify`, `perturb`, `rig excite`, `rig pil`, `tf --loop`)
//! as a user meets them, one test per class of the contract:
//! - a rig recording is never replaced or deleted by any command, and its manifest names its command;
//! - limits come before work, with the number and the flag that raises the limit;
//! - one key, one meaning (two spellings of a key are refused; integer keys searched as integers; a tuned
//!   scene only if it loads and is no worse than the start);
//! - every failure names its cause; a closed or full stdout is a clean exit;
//! - a signal stops the command at the next point or iteration with a marked partial beside the previous
//!   output (`rig pil`'s is in scripts/ci_firmware, where the firmware is built).
//!
//! Every command runs under a deadline: past it the test fails as a hang. No test measures time.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// A fresh scratch directory, removed when the returned guard drops.
fn scratch(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix(&format!("pneuflex-newer-{name}-"))
        .tempdir()
        .unwrap()
}

/// What a command did: its exit code and output; a panic or a hang fails the test here.
struct Ran {
    code: Option<i32>,
    stdout: String,
    stderr: String,
}

impl Ran {
    fn ok(&self) -> bool {
        self.code == Some(0)
    }
    /// Asserts a refusal whose message names every one of `words`.
    fn refused(&self, words: &[&str]) {
        assert!(
            !self.ok(),
            "accepted silently:\n{}\n{}",
            self.stdout,
            self.stderr
        );
        for w in words {
            assert!(
                self.stderr.contains(w),
                "the message does not name `{w}`:\n{}",
                self.stderr
            );
        }
    }
}

/// The deadline of one command: generous, for a loaded machine; a command past it hangs.
const DEADLINE: Duration = Duration::from_secs(240);

fn finish(mut child: std::process::Child, what: &str) -> Ran {
    let start = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        if start.elapsed() > DEADLINE {
            let _ = child.kill();
            panic!("HANG: `{what}` still running after {DEADLINE:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let o: Output = child.wait_with_output().unwrap();
    let ran = Ran {
        code: o.status.code(),
        stdout: String::from_utf8_lossy(&o.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&o.stderr).into_owned(),
    };
    assert!(
        !ran.stderr.contains("panicked"),
        "PANIC in `{what}`:\n{}",
        ran.stderr
    );
    assert!(
        o.status.code().is_some(),
        "`{what}` died on a signal: {:?}\n{}",
        o.status,
        ran.stderr
    );
    ran
}

/// Runs `pneuflex ARGS` in `cwd` (the repository when None).
fn run_in(cwd: Option<&Path>, args: &[&str]) -> Ran {
    let child = cmd(cwd, args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    finish(child, &args.join(" "))
}

fn run(args: &[&str]) -> Ran {
    run_in(None, args)
}

fn cmd(cwd: Option<&Path>, args: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_pneuflex"));
    c.current_dir(cwd.map_or_else(|| repo(""), Path::to_path_buf))
        .args(args)
        .stdin(Stdio::null());
    c
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A hidden truth (perturb) and a 1.5 s recording of it (`rig excite` in lockstep) in `dir`.
fn recording(dir: &Path) -> (PathBuf, PathBuf) {
    recording_of(dir, 1.5)
}

/// [`recording`] of `duration_s` seconds.
fn recording_of(dir: &Path, duration_s: f64) -> (PathBuf, PathBuf) {
    let truth = dir.join("truth");
    let r = run(&[
        "perturb",
        "--actuator",
        "pneumatics/paper-actuator.toml",
        "--keys",
        "valve.sonic_conductance_m3_per_s_pa,mechanics.moving_mass_kg",
        "--seed",
        "5",
        "--out",
        s(&truth),
    ]);
    assert!(r.ok(), "{}", r.stderr);
    let rec = dir.join("rec");
    let r = run(&[
        "rig",
        "excite",
        "--lockstep-truth",
        s(&truth.join("paper-actuator.toml")),
        "--duration",
        &duration_s.to_string(),
        "--out",
        s(&rec),
    ]);
    assert!(r.ok(), "{}", r.stderr);
    (truth, rec)
}

/// Every file below `dir` with its bytes.
fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push((p.clone(), std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

/// A copy of the ideal-loop scene (paper-fig3-ideal: 10 s, a few milliseconds a run) in `dir`.
fn ideal_scene(dir: &Path) -> PathBuf {
    let p = dir.join("scene.toml");
    std::fs::copy(repo("scenes/paper-fig3-ideal.toml"), &p).unwrap();
    p
}

/// A 52-byte ELF header of the board's kind (32-bit little-endian ARM executable, hard-float ABI) and
/// nothing else: it passes the checks made before QEMU starts.
fn arm_elf_header(path: &Path) {
    let mut h = vec![0u8; 52];
    h[..4].copy_from_slice(b"\x7fELF");
    h[4] = 1; // 32-bit
    h[5] = 1; // little-endian
    h[6] = 1;
    h[16] = 2; // executable
    h[18] = 40; // ARM
    h[36..40].copy_from_slice(&0x0500_0400u32.to_le_bytes());
    std::fs::write(path, h).unwrap();
}

/// A stand-in for QEMU that records that it was started.
fn fake_qemu(dir: &Path) -> (PathBuf, PathBuf) {
    let marker = dir.join("qemu-was-started");
    let script = dir.join("qemu-system-arm");
    std::fs::write(
        &script,
        format!("#!/bin/sh\ntouch '{}'\nexit 1\n", marker.display()),
    )
    .unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    (script, marker)
}

#[test]
fn a_recording_survives_every_command_and_names_its_own() {
    let d = scratch("rec");
    let (truth, rec) = recording(d.path());
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(rec.join(".pneuflex-output.json")).unwrap())
            .unwrap();
    assert_eq!(m["command"], "rig excite");
    assert_eq!(m["recording"], true);
    let before = snapshot(&rec);
    let scene = ideal_scene(d.path());
    let (qemu, started) = fake_qemu(d.path());
    let elf = d.path().join("firmware.elf");
    arm_elf_header(&elf);
    let trace = rec.join("trace.csv");
    let attempts: Vec<Vec<String>> = vec![
        vec!["run", "-q", s(&scene), "--out", s(&rec)],
        vec![
            "sweep",
            "-q",
            s(&scene),
            "--set",
            "environment.stiffness_n_per_m=500,700",
            "--out",
            s(&rec),
        ],
        vec![
            "tune",
            "-q",
            s(&scene),
            "--free",
            "runs[adaptive].inner.kp_per_m=[100,300]",
            "--budget",
            "4",
            "--out",
            s(&rec),
        ],
        vec![
            "identify",
            "--log",
            s(&trace),
            "--actuator",
            "pneumatics/paper-actuator.toml",
            "--free",
            "mechanics.moving_mass_kg",
            "--out",
            s(&rec),
        ],
        vec![
            "rig",
            "excite",
            "--lockstep-truth",
            s(&truth.join("paper-actuator.toml")),
            "--duration",
            "1",
            "--out",
            s(&rec),
        ],
        vec![
            "rig",
            "pil",
            "--scene",
            s(&scene),
            "--firmware",
            s(&elf),
            "--out",
            s(&rec),
        ],
        vec![
            "perturb",
            "--actuator",
            "pneumatics/paper-actuator.toml",
            "--keys",
            "mechanics.moving_mass_kg",
            "--out",
            s(&rec),
        ],
        // Inside a recording: refused too.
        vec![
            "sweep",
            "-q",
            s(&scene),
            "--set",
            "environment.stiffness_n_per_m=500",
            "--out",
            s(&rec.join("sweep")),
        ],
    ]
    .into_iter()
    .map(|v| v.into_iter().map(String::from).collect())
    .collect();
    for a in &attempts {
        let args: Vec<&str> = a.iter().map(String::as_str).collect();
        let child = cmd(None, &args)
            .env("PNEUFLEX_QEMU", &qemu)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let r = finish(child, &a.join(" "));
        assert!(!r.ok(), "`{}` was accepted:\n{}", a.join(" "), r.stdout);
        assert!(
            r.stderr.contains(s(&rec)),
            "`{}`: the message does not name the recording:\n{}",
            a.join(" "),
            r.stderr
        );
        assert_eq!(
            snapshot(&rec),
            before,
            "`{}` changed the recording",
            a.join(" ")
        );
    }
    assert!(
        !started.exists(),
        "QEMU started although the output was refused"
    );
    // A manifest edited to claim a sweep wrote it: the trace's wall-clock column still marks a recording.
    let mpath = rec.join(".pneuflex-output.json");
    let text = std::fs::read_to_string(&mpath)
        .unwrap()
        .replace("\"rig excite\"", "\"sweep\"")
        .replace("\"recording\": true,", "");
    std::fs::write(&mpath, &text).unwrap();
    let r = run(&[
        "sweep",
        "-q",
        s(&scene),
        "--set",
        "environment.stiffness_n_per_m=500,700",
        "--out",
        s(&rec),
    ]);
    r.refused(&["rig recording", "wall_time"]);
    assert_eq!(
        std::fs::read(&trace).unwrap(),
        before.iter().find(|(p, _)| p == &trace).unwrap().1
    );

    // Without --out, a second recording goes beside the first.
    let cwd = d.path().join("cwd");
    std::fs::create_dir_all(&cwd).unwrap();
    let excite = |cwd: &Path| {
        run_in(
            Some(cwd),
            &[
                "rig",
                "excite",
                "--rig",
                s(&repo("rigs/emulated.toml")),
                "--lockstep-truth",
                s(&truth.join("paper-actuator.toml")),
                "--duration",
                "1",
            ],
        )
    };
    let first = excite(&cwd);
    assert!(first.ok(), "{}", first.stderr);
    let one = std::fs::read(cwd.join("out/rig/excite/steps/trace.csv")).unwrap();
    let second = excite(&cwd);
    assert!(second.ok(), "{}", second.stderr);
    assert!(cwd.join("out/rig/excite/steps-2/trace.csv").is_file());
    assert_eq!(
        std::fs::read(cwd.join("out/rig/excite/steps/trace.csv")).unwrap(),
        one
    );

    // A simulation output is replaced only by its own command.
    let out = d.path().join("swept");
    let sweep = |out: &Path| {
        run(&[
            "sweep",
            "-q",
            s(&scene),
            "--set",
            "environment.stiffness_n_per_m=500,700",
            "--out",
            s(out),
        ])
    };
    assert!(sweep(&out).ok());
    assert!(sweep(&out).ok(), "a sweep replaces its own output");
    let r = run(&[
        "tune",
        "-q",
        s(&scene),
        "--free",
        "runs[adaptive].inner.kp_per_m=[100,300]",
        "--budget",
        "4",
        "--out",
        s(&out),
    ]);
    r.refused(&["output of `pneuflex sweep`"]);
    assert!(out.join("sweep.csv").is_file());
}

#[test]
fn limits_are_refused_before_any_work_with_the_flag_that_raises_them() {
    let d = scratch("limits");
    let scene = ideal_scene(d.path());
    let out = d.path().join("o");
    let sweep = |extra: &[&str]| {
        let mut a = vec!["sweep", "-q", s(&scene), "--out", s(&out)];
        a.extend_from_slice(extra);
        run(&a)
    };
    let wide = "lin:100:1000:65536";
    // Four 65,536-value ranges: 2^64 points, more than any integer of the machine holds.
    sweep(&[
        "--set",
        &format!("environment.stiffness_n_per_m={wide}"),
        "--set",
        &format!("runs[0].inner.kp_per_m={wide}"),
        "--set",
        &format!("runs[1].inner.kp_per_m={wide}"),
        "--set",
        &format!("runs[0].inner.ki_per_m_s={wide}"),
    ])
    .refused(&["18446744073709551616 points", "--max-points"]);
    sweep(&[
        "--set",
        "environment.stiffness_n_per_m=rand:100:1000",
        "--samples",
        "1000000000",
    ])
    .refused(&["1000000000 points", "--max-points"]);
    // Raising the limit stops at its ceiling.
    sweep(&[
        "--set",
        &format!("environment.stiffness_n_per_m={wide}"),
        "--set",
        &format!("runs[0].inner.kp_per_m={wide}"),
        "--max-points",
        "100000000000",
    ])
    .refused(&["4294967296 points", "ceiling"]);
    // --traces: ~8 MB a point here; 2,000 points are far past 4 GiB.
    sweep(&[
        "--set",
        "environment.stiffness_n_per_m=lin:100:1000:2000",
        "--traces",
    ])
    .refused(&["--traces", "--max-output-mb"]);
    assert!(!out.exists(), "nothing was written");

    let tune = |extra: &[&str]| {
        let mut a = vec![
            "tune",
            "-q",
            s(&scene),
            "--free",
            "runs[adaptive].inner.kp_per_m=[100,300]",
            "--out",
            s(&out),
        ];
        a.extend_from_slice(extra);
        run(&a)
    };
    tune(&["--population", "1000000000"]).refused(&["--population", "--budget"]);
    tune(&["--budget", "0"]).refused(&["--budget 0", "one generation"]);
    tune(&["--budget", "3"]).refused(&["--budget 3", "one generation"]);
    tune(&[
        "--over",
        "environment.stiffness_n_per_m=lin:100:1000:100000",
    ])
    .refused(&["scene runs", "--max-runs"]);
    tune(&[
        "--over",
        &format!("environment.stiffness_n_per_m={wide}"),
        "--over",
        &format!("events[0].stiffness_n_per_m={wide}"),
    ])
    .refused(&["4294967296 points", "--max-runs"]);
    assert!(!out.exists(), "nothing was written");

    // identify: the rows and the time span of a log, and a log whose time jumps.
    let (_, rec) = recording(d.path());
    let log = rec.join("trace.csv");
    let identify = |log: &Path, extra: &[&str]| {
        let mut a = vec![
            "identify",
            "--log",
            s(log),
            "--actuator",
            "pneumatics/paper-actuator.toml",
            "--free",
            "mechanics.moving_mass_kg",
            "--out",
            s(&out),
        ];
        a.extend_from_slice(extra);
        run(&a)
    };
    identify(&log, &["--max-rows", "100"]).refused(&["100 rows", "--max-rows"]);
    identify(&log, &["--max-log-s", "1"]).refused(&["spans more than 1 s", "--max-log-s"]);
    let text = std::fs::read_to_string(&log).unwrap();
    let mut jumped = String::new();
    let mut data_rows = 0;
    let mut jump_line = 0;
    for (i, line) in text.lines().enumerate() {
        if line.starts_with('#') || line.starts_with("t,") {
            jumped.push_str(line);
        } else {
            data_rows += 1;
            let (t, rest) = line.split_once(',').unwrap();
            let mut t: f64 = t.parse().unwrap();
            if data_rows > 700 {
                t += 1e6;
                if jump_line == 0 {
                    jump_line = i + 1;
                }
            }
            jumped.push_str(&format!("{t},{rest}"));
        }
        jumped.push('\n');
    }
    let jlog = d.path().join("jump.csv");
    std::fs::write(&jlog, jumped).unwrap();
    identify(&jlog, &[]).refused(&[&format!("jump.csv:{jump_line}"), "time jumps by"]);
    assert!(!out.exists(), "nothing was written");
}

#[test]
fn one_key_has_one_meaning() {
    let d = scratch("keys");
    let scene = ideal_scene(d.path());
    let out = d.path().join("o");
    let r = run(&[
        "sweep",
        "-q",
        s(&scene),
        "--set",
        "runs[1].inner.kp_per_m=100,200",
        "--set",
        "runs[adaptive].inner.kp_per_m=300",
        "--out",
        s(&out),
    ]);
    r.refused(&["the same key", "runs[1].inner.kp_per_m", s(&scene)]);
    run(&[
        "sweep",
        "-q",
        s(&scene),
        "--set",
        "runs[*].inner.kp_per_m=100,200",
        "--set",
        "runs[impedance].inner.kp_per_m=300",
        "--out",
        s(&out),
    ])
    .refused(&["the same key", "runs[0].inner.kp_per_m"]);
    let tune = |extra: &[&str]| {
        let mut a = vec!["tune", "-q", s(&scene), "--out", s(&out)];
        a.extend_from_slice(extra);
        run(&a)
    };
    tune(&[
        "--free",
        "runs[adaptive].inner.kp_per_m=[100,300]",
        "--over",
        "runs[1].inner.kp_per_m=150,250",
    ])
    .refused(&["the same key", "--over"]);
    tune(&[
        "--free",
        "runs[adaptive].inner.kp_per_m=[100,300]",
        "--free",
        "runs[1].inner.kp_per_m=[100,300]",
    ])
    .refused(&["the same key", "--free"]);
    tune(&["--free", "runs[adaptive].inner.kp_per_m=[nan,300]"]).refused(&["finite"]);
    tune(&["--free", "runs[adaptive].inner.kp_per_m=[-100,300]"]).refused(&["kp_per_m"]);
    assert!(!out.exists());
    let truth = d.path().join("truth");
    run(&[
        "perturb",
        "--actuator",
        "pneumatics/paper-actuator.toml",
        "--keys",
        "mechanics.moving_mass_kg,valve.sonic_conductance_m3_per_s_pa,mechanics.moving_mass_kg",
        "--out",
        s(&truth),
    ])
    .refused(&["given twice", "mechanics.moving_mass_kg"]);
    assert!(!truth.exists());

    // An integer key is searched over integers and written as one: the tuned scene loads and runs.
    let tuned = d.path().join("tuned");
    let ideal = d.path().join("ideal");
    std::fs::create_dir_all(&ideal).unwrap();
    let mb_scene = mb_with_window(&ideal);
    let r = run(&[
        "tune",
        "-q",
        s(&mb_scene),
        "--free",
        "plant.chamber_substeps=[3,12]",
        "--term",
        "step.rms_force_error_n=1",
        "--budget",
        "4",
        "--out",
        s(&tuned),
    ]);
    assert!(r.ok(), "{}", r.stderr);
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tuned.join("tune.json")).unwrap()).unwrap();
    let after = summary["after"][0].as_f64().unwrap();
    assert_eq!(after.fract(), 0.0, "an integer key's value: {after}");
    if let Some(name) = summary["tuned_scene"].as_str() {
        let t = std::fs::read_to_string(tuned.join(name)).unwrap();
        assert!(
            t.contains(&format!("chamber_substeps = {}", after as i64)),
            "written as an integer"
        );
        let r = run(&[
            "run",
            "-q",
            s(&tuned.join(name)),
            "--out",
            s(&d.path().join("rerun")),
        ]);
        assert!(r.ok(), "the tuned scene loads and runs: {}", r.stderr);
    }
}

/// paper-fig3-multibody, 1.5 s with a step window (its paths made absolute), written into `dir`.
fn mb_with_window(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(repo("scenes/paper-fig3-multibody.toml"))
        .unwrap()
        .replace("duration_s = 10.0", "duration_s = 1.5")
        .replace("../urdf/", &format!("{}/", repo("urdf").display()))
        .replace(
            "../pneumatics/",
            &format!("{}/", repo("pneumatics").display()),
        );
    let mut text = match text.find("[[metrics]]") {
        Some(i) => text[..i].to_string(),
        None => text,
    };
    // The material swap at 6 s is after the end: gone.
    if let (Some(a), Some(b)) = (text.find("[[events]]"), text.find("[[runs]]")) {
        text.replace_range(a..b, "");
    }
    text.push_str("\n[[metrics]]\nname = \"step\"\nkind = \"step\"\nt0_s = 0.5\nt1_s = 1.5\n");
    let p = dir.join("mb.toml");
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn a_search_that_finds_nothing_better_keeps_the_start() {
    let d = scratch("worse");
    let scene = ideal_scene(d.path());
    let out = d.path().join("o");
    // b_d = 52.4 N s/m in the scene; a box of 1000-2000 N s/m holds only far slower, worse filters.
    let r = run(&[
        "tune",
        "-q",
        s(&scene),
        "--free",
        "runs[adaptive].impedance.b_d_ns_per_m=[1000,2000]",
        "--term",
        "step.rms_force_error_n=1",
        "--budget",
        "4",
        "--out",
        s(&out),
    ]);
    assert!(r.ok(), "{}", r.stderr);
    assert!(
        r.stderr.contains("nothing better than the start"),
        "{}",
        r.stderr
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("tune.json")).unwrap()).unwrap();
    assert!(summary["tuned_scene"].is_null(), "{summary}");
    assert_eq!(summary["before"][0], 52.4);
    assert!(summary["j_after"].as_f64().unwrap() > summary["j_before"].as_f64().unwrap());
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.contains("No tuned scene"), "{report}");
    assert!(!out.join("scene-tuned.toml").exists());
}

#[test]
fn every_failure_names_its_cause() {
    let d = scratch("causes");
    let scene = ideal_scene(d.path());
    let out = d.path().join("o");
    run(&[
        "tune",
        "-q",
        s(&scene),
        "--free",
        "runs[adaptive].inner.kp_per_m=[100,300]",
        "--sigma0",
        "nan",
        "--out",
        s(&out),
    ])
    .refused(&["--sigma0", "NaN"]);
    let r = run(&[
        "rig",
        "excite",
        "--lockstep-truth",
        "pneumatics/paper-actuator.toml",
        "--duration=-1",
        "--out",
        s(&out),
    ]);
    r.refused(&["--duration"]);
    assert!(!r.stderr.contains("--ramp"), "{}", r.stderr);
    // Scene-level errors of sweep and tune name the scene file (and the line of the table).
    run(&[
        "sweep",
        "-q",
        s(&scene),
        "--set",
        "runs[9].inner.kp_per_m=1",
        "--out",
        s(&out),
    ])
    .refused(&[&format!("{}:", s(&scene)), "runs[9]", "no [9]"]);
    run(&[
        "tune",
        "-q",
        s(&scene),
        "--free",
        "nosuch.key=[1,2]",
        "--out",
        s(&out),
    ])
    .refused(&[s(&scene), "nosuch"]);
    // A byte-order mark is not part of the first key's name.
    let bom = d.path().join("bom.toml");
    let text = std::fs::read_to_string(&scene).unwrap();
    std::fs::write(&bom, format!("\u{feff}bogus = 1\n{text}")).unwrap();
    let r = run(&[
        "sweep",
        "-q",
        s(&bom),
        "--set",
        "environment.stiffness_n_per_m=500",
        "--out",
        s(&out),
    ]);
    r.refused(&["bogus"]);
    assert!(!r.stderr.contains('\u{feff}'), "{}", r.stderr);
    // tf: an option of --loop without --loop is refused, not ignored.
    let png = d.path().join("b.png");
    run(&["tf", s(&scene), "--bode", s(&png)]).refused(&["--bode", "--loop"]);
    assert!(!png.exists());
    run(&["tf", "pneumatics/paper-actuator.toml", "--margin-db", "3"])
        .refused(&["--margin-db", "--loop"]);

    // rig pil: a file that is not the board's firmware is named before QEMU starts.
    let (qemu, started) = fake_qemu(d.path());
    let pil = |elf: &Path, qemu: &Path| {
        let child = cmd(
            None,
            &[
                "rig",
                "pil",
                "--scene",
                s(&scene),
                "--firmware",
                s(elf),
                "--out",
                s(&out),
            ],
        )
        .env("PNEUFLEX_QEMU", qemu)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
        finish(child, "rig pil")
    };
    let garbage = d.path().join("garbage.elf");
    std::fs::write(&garbage, b"this is not a firmware image, only some text\n").unwrap();
    pil(&garbage, &qemu).refused(&[s(&garbage), "not an ELF"]);
    // An ELF for this machine, not for the board: the pneuflex binary itself.
    let host_elf = Path::new(env!("CARGO_BIN_EXE_pneuflex"));
    pil(host_elf, &qemu).refused(&[s(host_elf), "not ARM"]);
    pil(d.path(), &qemu).refused(&[s(d.path()), "not a regular file"]);
    assert!(
        !started.exists(),
        "QEMU started on a file that is not firmware"
    );
    // A QEMU that cannot be run.
    let not_exec = d.path().join("qemu-not-exec");
    std::fs::write(&not_exec, "#!/bin/sh\n").unwrap();
    let elf = d.path().join("firmware.elf");
    arm_elf_header(&elf);
    pil(&elf, &not_exec).refused(&[s(&not_exec), "not executable"]);
    assert!(!out.exists());

    // identify: the output directory is checked before the fit, and a held-out fraction of 0 reads as
    // "none", not NaN.
    let (_, rec) = recording(d.path());
    let log = rec.join("trace.csv");
    // `identify` of the mass from the recording, with `more` arguments.
    let identify = |more: &[&str]| {
        let mut args = vec![
            "identify",
            "--log",
            s(&log),
            "--actuator",
            "pneumatics/paper-actuator.toml",
            "--free",
            "mechanics.moving_mass_kg",
        ];
        args.extend_from_slice(more);
        run(&args)
    };
    let r = identify(&["--out", s(&repo("pneumatics"))]);
    r.refused(&["pneumatics", "holds an input"]);
    assert!(
        !r.stdout.contains("fit took"),
        "the fit ran first: {}",
        r.stdout
    );
    // A log format file with a unit its signal does not take: refused with its line and key, nothing written.
    let format = d.path().join("logger.toml");
    std::fs::write(
        &format,
        "separator = \";\"\n[columns]\nt = { name = \"t\", unit = \"min\" }\n",
    )
    .unwrap();
    let fmt_out = d.path().join("fmt-out");
    let r = identify(&["--log-format", s(&format), "--out", s(&fmt_out)]);
    r.refused(&["logger.toml:3:", "columns.t.unit", "\"ms\""]);
    assert!(!fmt_out.exists(), "an output was left for a refused format");
    let fit = d.path().join("fit");
    let r = identify(&["--validation", "0", "--out", s(&fit)]);
    assert!(r.ok(), "{}", r.stderr);
    assert!(!r.stdout.contains("NaN"), "{}", r.stdout);
    let md = std::fs::read_to_string(fit.join("report.md")).unwrap();
    assert!(!md.contains("NaN"), "{md}");
    assert!(md.contains("No rows were held out"), "{md}");
}

#[cfg(unix)]
#[test]
fn a_full_or_closed_stdout_is_a_clean_exit() {
    let d = scratch("stdout");
    let scene = ideal_scene(d.path());
    let cases: Vec<Vec<String>> = vec![
        vec![
            "sweep".into(),
            s(&scene).into(),
            "--set".into(),
            "environment.stiffness_n_per_m=500,700".into(),
            "--out".into(),
            s(&d.path().join("sw")).into(),
        ],
        vec!["tf".into(), "pneumatics/paper-actuator.toml".into()],
        vec![
            "tf".into(),
            "scenes/paper-fig3.toml".into(),
            "--loop".into(),
        ],
        vec![
            "perturb".into(),
            "--actuator".into(),
            "pneumatics/paper-actuator.toml".into(),
            "--keys".into(),
            "mechanics.moving_mass_kg".into(),
            "--out".into(),
            s(&d.path().join("t")).into(),
        ],
    ];
    for (i, c) in cases.iter().enumerate() {
        let args: Vec<&str> = c.iter().map(String::as_str).collect();
        // /dev/full: every write fails with "No space left on device".
        if let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") {
            let child = cmd(None, &args)
                .stdout(full)
                .stderr(Stdio::piped())
                .spawn()
                .unwrap();
            let r = finish(child, &format!("{} > /dev/full", c.join(" ")));
            assert!(!r.ok(), "a failed write is not success: {}", c.join(" "));
            assert!(r.stderr.contains("stdout"), "{}", r.stderr);
        }
        // The perturb case wrote its directory before it printed: removed for the next try.
        let _ = std::fs::remove_dir_all(d.path().join("t"));
        // A reader that went away: a pipe whose read end is closed before the command writes.
        let mut child = cmd(None, &args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take());
        let r = finish(child, &format!("{} | (closed)", c.join(" ")));
        assert!(
            r.code == Some(141) || r.code == Some(0),
            "{}: exit {:?}: {}",
            c.join(" "),
            r.code,
            r.stderr
        );
        // The perturb case wrote its directory before it printed: remove it for the next try.
        let _ = std::fs::remove_dir_all(d.path().join("t"));
        let _ = i;
    }
}

/// Starts `pneuflex ARGS`, waits for its staging directory `.<dest>.partial-<pid>` (the work has begun),
/// sends `signal` after `after`, and returns what the command did.
#[cfg(unix)]
fn interrupt(args: &[&str], dest: &Path, signal: &str, after: Duration) -> Ran {
    let child = cmd(None, args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let staging = dest.parent().unwrap().join(format!(
        ".{}.partial-{}",
        dest.file_name().unwrap().to_string_lossy(),
        child.id()
    ));
    let start = Instant::now();
    while !staging.exists() {
        assert!(
            start.elapsed() < DEADLINE,
            "`{}` never started its output",
            args.join(" ")
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    std::thread::sleep(after);
    let pid = child.id().to_string();
    assert!(
        Command::new("kill")
            .args([&format!("-{signal}"), &pid])
            .status()
            .unwrap()
            .success()
    );
    let r = finish(child, &args.join(" "));
    assert!(!staging.exists(), "the staging directory is left behind");
    r
}

#[cfg(unix)]
#[test]
fn a_signal_leaves_the_previous_output_and_a_marked_partial() {
    let d = scratch("signal");
    let scene = ideal_scene(d.path());
    let manifest = |dir: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.join(".pneuflex-output.json")).unwrap())
            .unwrap()
    };

    // sweep: a small complete sweep, then a long one into the same directory, stopped by SIGTERM.
    let out = d.path().join("sw");
    let small = run(&[
        "sweep",
        "-q",
        s(&scene),
        "--set",
        "environment.stiffness_n_per_m=500,700",
        "--out",
        s(&out),
    ]);
    assert!(small.ok(), "{}", small.stderr);
    let before = snapshot(&out);
    let r = interrupt(
        &[
            "sweep",
            "-q",
            s(&scene),
            "--set",
            "environment.stiffness_n_per_m=lin:300:3000:4000",
            "--out",
            s(&out),
        ],
        &out,
        "TERM",
        Duration::from_millis(400),
    );
    assert_eq!(r.code, Some(128 + 15), "{}", r.stderr);
    assert!(
        r.stderr.contains("SIGTERM") && r.stderr.contains("of 4000 points"),
        "{}",
        r.stderr
    );
    assert_eq!(snapshot(&out), before, "the complete output changed");
    let partial = d.path().join("sw.partial");
    let m = manifest(&partial);
    assert_eq!(m["complete"], false);
    assert_eq!(m["partial"]["reason"], "SIGTERM");
    assert!(
        m["partial"]["done"]
            .as_str()
            .unwrap()
            .ends_with("of 4000 points")
    );
    let table = std::fs::read_to_string(partial.join("sweep.csv")).unwrap();
    assert!(table.lines().count() < 1 + 2 * 4000, "stopped early");
    let record = std::fs::read_to_string(partial.join("sweep.json")).unwrap();
    assert!(record.contains("interrupted"), "{record}");

    // tune: SIGINT during the search.
    let out = d.path().join("tu");
    let r = interrupt(
        &[
            "tune",
            "-q",
            s(&scene),
            "--free",
            "runs[adaptive].inner.kp_per_m=[100,300]",
            "--budget",
            "100000",
            "--out",
            s(&out),
        ],
        &out,
        "INT",
        Duration::from_millis(400),
    );
    assert_eq!(r.code, Some(128 + 2), "{}", r.stderr);
    assert!(!out.exists(), "no complete output appeared");
    let partial = d.path().join("tu.partial");
    assert_eq!(manifest(&partial)["partial"]["reason"], "SIGINT");
    let report = std::fs::read_to_string(partial.join("report.md")).unwrap();
    assert!(report.contains("Interrupted by SIGINT"), "{report}");
    assert!(partial.join("history.csv").is_file());
    assert!(!partial.join("scene-tuned.toml").exists());

    // identify: SIGHUP during the fit. A 6 s log: the fit of a 1.5 s one can end within the 300 ms a quiet
    // machine gives it (then the signal comes after the fit, and the output is complete).
    let (_, rec) = recording_of(d.path(), 6.0);
    let out = d.path().join("id");
    let r = interrupt(
        &[
            "identify",
            "--log",
            s(&rec.join("trace.csv")),
            "--actuator",
            "pneumatics/paper-actuator.toml",
            "--free",
            "valve.sonic_conductance_m3_per_s_pa,cylinder.dead_volume_a_m3,cylinder.dead_volume_b_m3,mechanics.moving_mass_kg",
            "--out",
            s(&out),
        ],
        &out,
        "HUP",
        Duration::from_millis(300),
    );
    assert_eq!(r.code, Some(128 + 1), "{}", r.stderr);
    let partial = d.path().join("id.partial");
    assert_eq!(manifest(&partial)["partial"]["reason"], "SIGHUP");
    let report = std::fs::read_to_string(partial.join("report.md")).unwrap();
    assert!(report.contains("INTERRUPTED by SIGHUP"), "{report}");
    assert!(
        !partial.join("paper-actuator.toml").exists(),
        "no fitted sheet"
    );
}

/// `--format pdf` on every command that draws (`run` is checked in cli_run.rs): sweep's heatmaps, tune's
/// convergence plot, identify's validation figure, compare's figures, `rig run`'s recording figures and
/// `tf --bode FILE.pdf` are PDFs, named with the extension; no PNG is left beside them.
#[test]
fn every_command_that_draws_writes_pdf() {
    let d = scratch("pdf");
    let dir = d.path();
    let scene = ideal_scene(dir);
    let (truth, rec) = recording(dir);
    let pdfs = |out: &Path| -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(out)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".pdf") || n.ends_with(".png"))
            .collect();
        names.sort();
        for n in &names {
            assert!(n.ends_with(".pdf"), "{}: {n} is not a PDF", out.display());
            let bytes = std::fs::read(out.join(n)).unwrap();
            assert!(bytes.starts_with(b"%PDF-"), "{}/{n}", out.display());
        }
        names
    };
    let out = dir.join("sweep");
    let r = run(&[
        "sweep",
        "-q",
        s(&scene),
        "--set",
        "environment.stiffness_n_per_m=500,700",
        "--set",
        "runs[*].impedance.b_d_ns_per_m=40,60",
        "--format",
        "pdf",
        "--out",
        s(&out),
    ]);
    assert!(r.ok(), "{}", r.stderr);
    assert!(!pdfs(&out).is_empty(), "sweep drew no heatmap");
    let out = dir.join("tune");
    let r = run(&[
        "tune",
        "-q",
        s(&scene),
        "--free",
        "runs[adaptive].inner.kp_per_m=[100,300]",
        "--budget",
        "4",
        "--format",
        "pdf",
        "--out",
        s(&out),
    ]);
    assert!(r.ok(), "{}", r.stderr);
    assert_eq!(pdfs(&out), ["convergence.pdf"]);
    let out = dir.join("identify");
    let r = run(&[
        "identify",
        "--log",
        s(&rec.join("trace.csv")),
        "--actuator",
        "pneumatics/paper-actuator.toml",
        "--free",
        "mechanics.moving_mass_kg",
        "--format",
        "pdf",
        "--out",
        s(&out),
    ]);
    assert!(r.ok(), "{}", r.stderr);
    assert_eq!(pdfs(&out), ["validation-1.pdf"]);
    let out = dir.join("rig-run");
    let r = run(&[
        "rig",
        "run",
        "--rig",
        "rigs/emulated.toml",
        "--lockstep-truth",
        s(&truth.join("paper-actuator.toml")),
        "--scene",
        "scenes/paper-fig3.toml",
        "--run",
        "impedance",
        "--duration",
        "1",
        "--format",
        "pdf",
        "--out",
        s(&out),
    ]);
    assert!(r.ok(), "{}", r.stderr);
    assert!(pdfs(&out).contains(&"force.pdf".to_string()));
    // compare takes a rig recording (a simulation's trace is refused): the one just made.
    let rig_log = out.join("trace.csv");
    let out = dir.join("compare");
    let r = run(&[
        "compare",
        "scenes/paper-fig3.toml",
        "--rig-log",
        s(&rig_log),
        "--format",
        "pdf",
        "--out",
        s(&out),
    ]);
    assert!(r.ok(), "{}", r.stderr);
    assert!(pdfs(&out).contains(&"force.pdf".to_string()));
    let bode = dir.join("loop.pdf");
    let r = run(&["tf", "--loop", "scenes/paper-fig3.toml", "--bode", s(&bode)]);
    assert!(r.ok(), "{}", r.stderr);
    assert!(std::fs::read(&bode).unwrap().starts_with(b"%PDF-"));
}

/// `identify --select`: every structure is fitted (or skipped with a reason), report.json's
/// `structure_selection` chooses the lowest BIC among those whose effect is significant and whose held-out
/// figure is within 1.05 of the sheet's own (recomputed here from the report's numbers), each structure's
/// sheet set is in `structures/`, and the command prints the table. On this truth of the sheet's own model
/// (1.5 s) the seal term has the lowest BIC with an interval that includes 0: the sheet as given is kept.
#[test]
fn identify_select_reports_every_structure_and_chooses_by_its_rule() {
    let d = scratch("select");
    let dir = d.path();
    let (_truth, rec) = recording(dir);
    let out = dir.join("fit");
    let r = run(&[
        "identify",
        "--log",
        s(&rec.join("trace.csv")),
        "--actuator",
        "pneumatics/paper-actuator.toml",
        "--free",
        "valve.sonic_conductance_m3_per_s_pa,mechanics.moving_mass_kg",
        "--select",
        "--out",
        s(&out),
    ]);
    assert!(r.ok(), "{}", r.stderr);
    assert!(
        r.stdout.contains("structure selection") && r.stdout.contains("<- chosen"),
        "{}",
        r.stdout
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let sel = &report["structure_selection"];
    let cands = sel["candidates"].as_array().unwrap();
    assert_eq!(cands.len(), 8);
    let base =
        cands.iter().find(|c| c["structure"] == "as_given").unwrap()["validation_over_floor_sq"]
            .as_f64()
            .unwrap();
    let eligible = cands.iter().filter(|c| {
        c["skipped"].is_null()
            && c["significant"] == true
            && c["validation_over_floor_sq"].as_f64().unwrap() <= 1.05 * base
    });
    let best = eligible
        .min_by(|a, b| {
            a["bic"]
                .as_f64()
                .unwrap()
                .total_cmp(&b["bic"].as_f64().unwrap())
        })
        .unwrap();
    assert_eq!(sel["chosen"], best["structure"], "{sel}");
    assert_eq!(sel["chosen"], "as_given", "{sel}");
    for c in cands {
        let name = c["structure"].as_str().unwrap();
        if name != "as_given" && c["skipped"].is_null() {
            assert!(
                out.join("structures")
                    .join(name)
                    .join("paper-actuator.toml")
                    .is_file(),
                "{name}"
            );
        }
    }
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("## Structure selection"), "{md}");
}
