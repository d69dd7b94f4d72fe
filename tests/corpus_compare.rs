//! Hostile inputs to `pneuflex compare`, one test per class: each is refused with a non-zero exit, an error
//! naming the log (and its line and column, or the option), and no output folder left as if complete; a
//! recording that ended on a fault is compared up to the fault and says so. The recordings are made on the
//! rig file's emulator in lockstep (`rig run --lockstep-truth` with the shipped sheet), as a user makes one.

use std::path::Path;
use std::process::{Command, Output};

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn scene() -> String {
    repo().join("scenes/paper-fig3.toml").display().to_string()
}

fn pneuflex(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pneuflex"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("runs")
}

fn ok(o: &Output) -> String {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// `rig run` of paper-fig3's `run` for `duration` s on `rig` (default the shipped emulated rig), in
/// lockstep, into `cwd/out`.
fn record(cwd: &Path, rig: Option<&Path>, run: &str, duration: &str, out: &str) -> Output {
    let shipped = repo().join("rigs/emulated.toml");
    let rig = rig.unwrap_or(&shipped).display().to_string();
    let truth = repo().join("pneumatics/paper-actuator.toml");
    let truth = truth.display().to_string();
    let scene = scene();
    let args = [
        "rig",
        "run",
        "--rig",
        &rig,
        "--lockstep-truth",
        &truth,
        "--scene",
        &scene,
        "--run",
        run,
        "--duration",
        duration,
        "--out",
        out,
    ];
    pneuflex(&args, cwd)
}

/// `compare` of paper-fig3 (or `scene`) with `logs`, then `rest`.
fn compare_with(cwd: &Path, scene: &str, logs: &[&str], rest: &[&str]) -> Output {
    let mut args = vec!["compare", scene];
    for l in logs {
        args.extend(["--rig-log", l]);
    }
    args.extend(rest);
    pneuflex(&args, cwd)
}

/// Refused into `--out cmp`: non-zero exit, stderr holding every one of `says`, and neither `cmp` nor
/// a staging folder of it left.
fn refused(cwd: &Path, scene: &str, logs: &[&str], rest: &[&str], says: &[&str]) -> String {
    let mut all = vec!["--out", "cmp"];
    all.extend(rest);
    let o = compare_with(cwd, scene, logs, &all);
    let e = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!o.status.success(), "accepted {logs:?} {rest:?}: {e}");
    for s in says {
        assert!(e.contains(s), "{logs:?}: the error does not say `{s}`: {e}");
    }
    assert!(!cwd.join("cmp").exists(), "{logs:?}: an output was left");
    let staged = std::fs::read_dir(cwd)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(".cmp"))
        .collect::<Vec<_>>();
    assert!(staged.is_empty(), "{logs:?}: staging left: {staged:?}");
    e
}

/// A copy of recording `from` as `to` (its manifest with it), with `edit` applied to its trace's text.
fn edited(cwd: &Path, from: &str, to: &str, edit: impl Fn(&str) -> String) -> String {
    let (from, to_dir) = (cwd.join(from), cwd.join(to));
    std::fs::create_dir_all(&to_dir).unwrap();
    for e in std::fs::read_dir(&from).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, to_dir.join(p.file_name().unwrap())).unwrap();
    }
    let trace = to_dir.join("trace.csv");
    let text = std::fs::read_to_string(&trace).unwrap();
    std::fs::write(&trace, edit(&text)).unwrap();
    format!("{to}/trace.csv")
}

/// `text` with data row `row` (0 = the first after the header) passed through `f`; returns the text and
/// the row's line number.
fn with_row(text: &str, row: usize, f: impl Fn(&mut Vec<String>)) -> (String, usize) {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let header = lines.iter().position(|l| !l.starts_with('#')).unwrap();
    let at = header + 1 + row;
    let mut cells: Vec<String> = lines[at].split(',').map(str::to_string).collect();
    f(&mut cells);
    lines[at] = cells.join(",");
    (lines.join("\n") + "\n", at + 1)
}

#[test]
fn a_simulation_trace_is_refused_as_one() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    ok(&pneuflex(&["run", &scene(), "--quiet", "--out", "sim"], t));
    refused(
        t,
        &scene(),
        &["sim/impedance/trace.csv"],
        &[],
        &[
            "sim/impedance/trace.csv",
            "a simulation's trace",
            "`pneuflex run`",
        ],
    );
    // Copied out of its folder: known by its columns (no rig columns).
    std::fs::copy(t.join("sim/impedance/trace.csv"), t.join("loose.csv")).unwrap();
    refused(
        t,
        &scene(),
        &["loose.csv"],
        &[],
        &["loose.csv", "line 1", "a simulation's trace"],
    );
}

#[test]
fn an_excitation_log_is_refused_as_one() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let rig = repo().join("rigs/emulated.toml").display().to_string();
    let truth = repo().join("pneumatics/paper-actuator.toml");
    let truth = truth.display().to_string();
    ok(&pneuflex(
        &[
            "rig",
            "excite",
            "--rig",
            &rig,
            "--lockstep-truth",
            &truth,
            "--duration",
            "0.5",
            "--out",
            "exc",
        ],
        t,
    ));
    refused(
        t,
        &scene(),
        &["exc/trace.csv"],
        &[],
        &[
            "exc/trace.csv",
            "an excitation log",
            "`pneuflex rig excite`",
        ],
    );
    // Without its manifest: a rig trace that names no scene.
    std::fs::copy(t.join("exc/trace.csv"), t.join("loose.csv")).unwrap();
    refused(
        t,
        &scene(),
        &["loose.csv"],
        &[],
        &["loose.csv", "names no scene", "rig excite"],
    );
}

#[test]
fn a_recording_of_another_scene_or_of_a_changed_scene_is_refused_naming_the_scene() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    ok(&record(t, None, "impedance", "1", "rec"));
    // The scene edited since the recording (same name; its sheets by absolute path, one line added).
    let text = std::fs::read_to_string(scene()).unwrap();
    let changed = format!(
        "{}\n# edited after the recording\n",
        text.replace("\"../", &format!("\"{}/", repo().display()))
    );
    std::fs::write(t.join("paper-fig3.toml"), changed).unwrap();
    refused(
        t,
        "paper-fig3.toml",
        &["rec/trace.csv"],
        &[],
        &[
            "rec/trace.csv",
            "the scene changed since the recording",
            "paper-fig3.toml",
        ],
    );
    // Another scene of the same tick: named from the recording's summary.json.
    let other = repo().join("scenes/paper-fig3-ideal.toml");
    let other = other.display().to_string();
    refused(
        t,
        &other,
        &["rec/trace.csv"],
        &[],
        &["rec/trace.csv", "a recording of scene `paper-fig3`"],
    );
    // The trace alone: its own `# input scene` line still names the scene it ran.
    std::fs::copy(t.join("rec/trace.csv"), t.join("loose.csv")).unwrap();
    refused(
        t,
        "paper-fig3.toml",
        &["loose.csv"],
        &[],
        &[
            "loose.csv",
            "another scene, or this one changed",
            "paper-fig3.toml",
        ],
    );
}

#[test]
fn a_recording_of_another_run_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    ok(&record(t, None, "impedance", "1", "rec"));
    refused(
        t,
        &scene(),
        &["rec/trace.csv"],
        &["--run", "adaptive"],
        &[
            "rec/trace.csv",
            "a recording of run `impedance`",
            "not of run `adaptive`",
        ],
    );
    refused(
        t,
        &scene(),
        &["adaptive=rec/trace.csv"],
        &[],
        &["a recording of run `impedance`"],
    );
    // Without its summary.json: the adaptive controller's columns are not in it.
    std::fs::copy(t.join("rec/trace.csv"), t.join("loose.csv")).unwrap();
    refused(
        t,
        &scene(),
        &["loose.csv"],
        &["--run", "adaptive"],
        &[
            "loose.csv",
            "line 4",
            "the controller's columns",
            "run `adaptive`",
        ],
    );
    // A run the scene does not have, by --run or by RUN=.
    refused(
        t,
        &scene(),
        &["rec/trace.csv"],
        &["--run", "adaptve"],
        &[
            "--run adaptve",
            "not a run of scene `paper-fig3`",
            "`adaptive`",
        ],
    );
    refused(
        t,
        &scene(),
        &["adaptve=rec/trace.csv"],
        &[],
        &["adaptve=rec/trace.csv", "`adaptve` is not a run"],
    );
    // --run and RUN= naming two runs.
    refused(
        t,
        &scene(),
        &["impedance=rec/trace.csv"],
        &["--run", "adaptive"],
        &["--run adaptive", "two different runs"],
    );
}

#[test]
fn a_nan_an_infinity_or_an_empty_cell_is_refused_with_its_line_and_column() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    ok(&record(t, None, "impedance", "1", "rec"));
    for (i, (column, value)) in [(2, "NaN"), (3, "inf"), (7, "")].into_iter().enumerate() {
        let line = std::cell::Cell::new(0);
        let log = edited(t, "rec", &format!("bad{i}"), |text| {
            let (text, at) = with_row(text, 500, |c| c[column] = value.to_string());
            line.set(at);
            text
        });
        let name = ["f_e", "x", "u"][i];
        refused(
            t,
            &scene(),
            &[&log],
            &[],
            &[
                &log,
                &format!("line {}: column `{name}`", line.get()),
                "not a measurement",
            ],
        );
    }
    // A cell that is no number at all.
    let log = edited(t, "rec", "word", |text| {
        with_row(text, 3, |c| c[2] = "x".into()).0
    });
    refused(
        t,
        &scene(),
        &[&log],
        &[],
        &[&log, "line 8: column `f_e`: `x` is not a number"],
    );
}

/// An edit of one row's cells.
type RowEdit = dyn Fn(&mut Vec<String>);

#[test]
fn time_going_backwards_standing_still_jumping_or_not_starting_at_zero_is_refused_with_its_line() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    ok(&record(t, None, "impedance", "1", "rec"));
    let cases: [(&str, &RowEdit, usize, &str); 4] = [
        (
            "back",
            &|c| c[0] = "0.05".into(),
            100,
            "does not come after",
        ),
        (
            "still",
            &|c| c[0] = "0.099".into(),
            100,
            "does not come after",
        ),
        ("jump", &|c| c[0] = "0.2".into(), 100, "t jumps from"),
        ("late", &|c| c[0] = "5".into(), 0, "starts at t = 5 s"),
    ];
    for (name, f, row, says) in cases {
        let line = std::cell::Cell::new(0);
        let log = edited(t, "rec", name, |text| {
            let (text, at) = with_row(text, row, f);
            line.set(at);
            text
        });
        refused(
            t,
            &scene(),
            &[&log],
            &[],
            &[&log, &format!("line {}", line.get()), says],
        );
    }
}

#[test]
fn a_recording_that_ended_on_a_fault_is_compared_up_to_the_fault_and_says_so() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    // The shipped rig file with the supply lost at 1 s, its sheets by absolute path.
    let text = std::fs::read_to_string(repo().join("rigs/emulated.toml")).unwrap();
    let pneumatics = repo().join("pneumatics").display().to_string();
    let text = text
        .replace("\"../pneumatics", &format!("\"{pneumatics}"))
        .replace(
            "faults = []",
            "faults = [{ kind = \"supply_loss\", at_s = 1.0 }]",
        );
    assert!(
        text.contains("supply_loss"),
        "the rig file's faults line moved"
    );
    std::fs::write(t.join("faulty.toml"), text).unwrap();
    let o = record(t, Some(&t.join("faulty.toml")), "impedance", "2", "rec");
    assert!(!o.status.success(), "the rig run ended on its fault");
    let trace = std::fs::read_to_string(t.join("rec/trace.csv")).unwrap();
    let (header, rows) = {
        let mut data = trace.lines().filter(|l| !l.starts_with('#'));
        let header = data.next().unwrap().to_string();
        (header, data.collect::<Vec<_>>())
    };
    let fault = header.split(',').position(|c| c == "fault").unwrap();
    let first = rows
        .iter()
        .position(|r| !r.split(',').nth(fault).unwrap().is_empty())
        .expect("a faulty row");
    let o = compare_with(t, &scene(), &["rec/trace.csv"], &["--out", "done"]);
    let out = ok(&o);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("rec/trace.csv") && e.contains("ended on a fault") && e.contains("supply"),
        "{e}"
    );
    let c: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(t.join("done/compare.json")).unwrap())
            .unwrap();
    assert_eq!(c["samples"].as_u64().unwrap() as usize, first, "{c}");
    assert!(
        c["rig_fault"]
            .as_str()
            .unwrap()
            .contains("ended on a fault")
    );
    assert!(c["f_e_rms_difference_n"].as_f64().unwrap().is_finite());
    let md = std::fs::read_to_string(t.join("done/compare.md")).unwrap();
    assert!(md.contains("ended early") && md.contains("supply"), "{md}");
    assert!(out.contains("ended early"), "{out}");
    // Stopped by a signal (`rig run` commits it as `<out>.partial`): the same, said as such.
    let text = std::fs::read_to_string(t.join("rec/trace.csv")).unwrap();
    std::fs::create_dir(t.join("rec.partial")).unwrap();
    for f in [".pneuflex-output.json", "summary.json"] {
        std::fs::copy(t.join("rec").join(f), t.join("rec.partial").join(f)).unwrap();
    }
    let (text, line) = with_row(&text, 400, |c| c[fault] = "interrupted: SIGINT".into());
    std::fs::write(t.join("rec.partial/trace.csv"), text).unwrap();
    let o = compare_with(t, &scene(), &["rec.partial/trace.csv"], &["--out", "done"]);
    ok(&o);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains(&format!(
            "was stopped by a signal at t = 0.4 s (line {line}"
        )),
        "{e}"
    );
    // A fault in the second row leaves nothing to compare.
    let log = edited(t, "rec", "at-once", |text| {
        let (text, _) = with_row(text, 1, |c| c[fault] = "limit: made up".into());
        text
    });
    refused(
        t,
        &scene(),
        &[&log],
        &[],
        &[&log, "ended on a fault", "fewer than two rows"],
    );
}

#[test]
fn rows_removed_added_or_cut_are_refused_or_said() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    ok(&record(t, None, "impedance", "1", "rec"));
    // Rows taken out of the end: the end marker's count says so.
    let log = edited(t, "rec", "fewer", |text| {
        let lines: Vec<&str> = text.lines().collect();
        let n = lines.len();
        let mut kept: Vec<&str> = lines[..n - 11].to_vec();
        kept.push(lines[n - 1]);
        kept.join("\n") + "\n"
    });
    refused(
        t,
        &scene(),
        &[&log],
        &[],
        &[&log, "the end marker counts 1000 rows, the file has 990"],
    );
    // Two recordings joined one after the other.
    let log = edited(t, "rec", "joined", |text| format!("{text}{text}"));
    refused(
        t,
        &scene(),
        &[&log],
        &[],
        &[&log, "more after the end marker"],
    );
    // Cut (a crash): compared, with a warning on stderr and in the report.
    let log = edited(t, "rec", "cut", |text| {
        let lines: Vec<&str> = text.lines().collect();
        lines[..lines.len() - 300].join("\n") + "\n"
    });
    let o = compare_with(t, &scene(), &[&log], &["--out", "done"]);
    ok(&o);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains(&log) && e.contains("no end marker"), "{e}");
    let c: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(t.join("done/compare.json")).unwrap())
            .unwrap();
    assert!(
        c["rig_notes"][0]
            .as_str()
            .unwrap()
            .contains("no end marker"),
        "{c}"
    );
    // A file put into a recording's folder by hand is not the recording.
    std::fs::copy(t.join("rec/trace.csv"), t.join("rec/mine.csv")).unwrap();
    refused(
        t,
        &scene(),
        &["rec/mine.csv"],
        &[],
        &["rec/mine.csv", "not a file of the recording"],
    );
}

#[test]
fn what_is_not_a_trace_file_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    ok(&record(t, None, "impedance", "1", "rec"));
    refused(
        t,
        &scene(),
        &["rec"],
        &[],
        &["--rig-log rec: is a directory", "rec/trace.csv"],
    );
    refused(
        t,
        &scene(),
        &["nothing.csv"],
        &[],
        &["nothing.csv: no such file"],
    );
    refused(
        t,
        &scene(),
        &["/dev/zero"],
        &[],
        &["/dev/zero", "not a regular file"],
    );
    refused(t, &scene(), &[""], &[], &["--rig-log", "empty path"]);
    std::fs::write(t.join("empty.csv"), "").unwrap();
    refused(
        t,
        &scene(),
        &["empty.csv"],
        &[],
        &["empty.csv", "no header row"],
    );
    std::fs::write(
        t.join("binary.csv"),
        [0x89, b'P', b'N', b'G', 0xff, 0xfe, 0],
    )
    .unwrap();
    refused(
        t,
        &scene(),
        &["binary.csv"],
        &[],
        &["binary.csv", "not a text file"],
    );
    // Another file of the recording, or a scene given as the log.
    refused(
        t,
        &scene(),
        &["rec/summary.json"],
        &[],
        &["rec/summary.json", "line 1", "is not a trace's header"],
    );
    let scene_path = scene();
    refused(
        t,
        &scene(),
        &[&scene_path],
        &[],
        &[&scene_path, "is not a trace's header"],
    );
    // A recording still being made: its staging folder.
    let log = edited(t, "rec", ".rec2.partial-4194399", |text| {
        text.lines().take(200).collect::<Vec<_>>().join("\n") + "\n"
    });
    refused(t, &scene(), &[&log], &[], &[&log, "still being made"]);
    // The rig trace of schema 1 (no board columns).
    let log = edited(t, "rec", "schema1", |text| {
        text.lines()
            .map(|l| {
                if l.starts_with('#') {
                    return l.to_string();
                }
                let cells: Vec<&str> = l.split(',').collect();
                let n = cells.len();
                // Keep the loop's 8 columns, drop the board's 7, keep wall_time and fault.
                let mut kept = cells[..8].to_vec();
                kept.extend(&cells[n - 2..]);
                kept.join(",")
            })
            .collect::<Vec<_>>()
            .join("\n")
            + "\n"
    });
    refused(
        t,
        &scene(),
        &[&log],
        &[],
        &[&log, "line 4", "the board's columns board_t"],
    );
}

#[test]
fn one_log_and_two_logs_write_beside_each_other_by_default() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    ok(&record(t, None, "impedance", "1", "imp"));
    ok(&record(t, None, "adaptive", "1", "ada"));
    let one = || ok(&compare_with(t, &scene(), &["imp/trace.csv"], &[]));
    let two = || {
        ok(&compare_with(
            t,
            &scene(),
            &["imp/trace.csv", "ada/trace.csv"],
            &[],
        ))
    };
    // Each order, each again: the documented sequence never refuses its own outputs.
    one();
    two();
    one();
    two();
    let base = t.join("out/compare/paper-fig3");
    assert!(base.join("impedance/compare.json").is_file());
    assert!(base.join("impedance+adaptive/compare.json").is_file());
    assert!(base.join("impedance+adaptive/adaptive/force.png").is_file());
}

#[test]
fn an_older_recording_without_the_scene_hash_is_compared_with_a_warning_and_its_reference_checked()
{
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    ok(&record(t, None, "impedance", "1", "rec"));
    // As an older `rig run` left it: no scene among the manifest's inputs, no `# input scene` line.
    let older = |dir: &str, edit: &dyn Fn(&str) -> String| -> String {
        let log = edited(t, "rec", dir, |text| {
            let kept: Vec<&str> = text
                .lines()
                .filter(|l| !l.starts_with("# input scene "))
                .collect();
            edit(&(kept.join("\n") + "\n"))
        });
        let manifest = t.join(dir).join(".pneuflex-output.json");
        let mut m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&manifest).unwrap()).unwrap();
        m["inputs"]
            .as_array_mut()
            .unwrap()
            .retain(|i| i["role"] != "scene");
        std::fs::write(&manifest, m.to_string()).unwrap();
        log
    };
    let log = older("old", &|text| text.to_string());
    let o = compare_with(t, &scene(), &[&log], &["--out", "done"]);
    ok(&o);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("warning") && e.contains(&log) && e.contains("an older recording"),
        "{e}"
    );
    let c: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(t.join("done/compare.json")).unwrap())
            .unwrap();
    assert!(
        c["rig_notes"][0]
            .as_str()
            .unwrap()
            .contains("an older recording"),
        "{c}"
    );
    // Its reference is still the scene's, tick by tick: one f_ref moved is another scene's.
    let line = std::cell::Cell::new(0);
    let log = older("old-ref", &|text| {
        let (text, at) = with_row(text, 700, |c| c[1] = "12.5".into());
        line.set(at);
        text
    });
    refused(
        t,
        &scene(),
        &[&log],
        &[],
        &[
            &log,
            &format!("line {}: f_ref = 12.5 N", line.get()),
            "the reference of scene `paper-fig3`",
        ],
    );
}
