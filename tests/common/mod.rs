//! What the CLI's hostile-input tests share: the `pneuflex` binary run under a deadline (past it, a hang),
//! its pipes drained on threads, and what a refusal must show. Each `tests/corpus_*.rs` takes it with
//! `mod common;` and uses what it needs (hence `dead_code` allowed here).
#![allow(dead_code)]

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The repository: its scenes, sheets, URDFs and data.
pub fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// A path as an argument.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// What a command did; a panic or a hang fails the test where it ran.
pub struct Ran {
    /// Exit code (None: killed by a signal).
    pub code: Option<i32>,
    /// Standard output.
    pub stdout: String,
    /// Standard error.
    pub stderr: String,
}

impl Ran {
    /// A refusal: a non-zero exit, nothing on stdout as if done, a message naming every one of `words`.
    pub fn refused(&self, words: &[&str]) {
        assert!(
            self.code.is_some_and(|c| c != 0),
            "accepted ({:?}):\n{}\n{}",
            self.code,
            self.stdout,
            self.stderr
        );
        assert!(
            self.stdout.trim().is_empty(),
            "a refusal printed a result:\n{}",
            self.stdout
        );
        for w in words {
            assert!(
                self.stderr.contains(w),
                "the message does not name `{w}`:\n{}",
                self.stderr
            );
        }
    }

    /// Exit 0.
    pub fn accepted(&self) {
        assert_eq!(self.code, Some(0), "{}", self.stderr);
    }
}

/// A command past this is a hang (generous, for a loaded machine).
pub const DEADLINE: Duration = Duration::from_secs(300);

/// `pneuflex ARGS` started in `cwd`, no standard input, its output piped.
pub fn spawn(args: &[&str], cwd: &Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_pneuflex"))
        .args(args)
        .current_dir(cwd)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("runs")
}

/// Waits for `child` (named `what` in a failure) within [`DEADLINE`], its pipes drained on threads so that a
/// large output cannot block it.
pub fn finish(mut child: Child, what: &str) -> Ran {
    let mut out = child.stdout.take().unwrap();
    let mut err = child.stderr.take().unwrap();
    let o = std::thread::spawn(move || {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut out, &mut s).unwrap();
        s
    });
    let e = std::thread::spawn(move || {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut err, &mut s).unwrap();
        s
    });
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > DEADLINE {
            let _ = child.kill();
            panic!("HANG: `{what}` still running after {DEADLINE:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let ran = Ran {
        code: status.code(),
        stdout: o.join().unwrap(),
        stderr: e.join().unwrap(),
    };
    assert!(
        !ran.stderr.contains("panicked"),
        "PANIC in `{what}`:\n{}",
        ran.stderr
    );
    ran
}

/// `pneuflex ARGS` in `cwd`, to its end.
pub fn run(args: &[&str], cwd: &Path) -> Ran {
    finish(spawn(args, cwd), &format!("pneuflex {}", args.join(" ")))
}

/// `pneuflex ARGS` in the repository, waited for (the tests of commands that end by themselves).
pub fn pneuflex(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_pneuflex"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("runs")
}

/// What a command printed, stdout then stderr.
pub fn text(o: &std::process::Output) -> String {
    format!(
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// A trace file as its header and its rows of numbers.
pub fn read_trace(p: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let t = std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    let mut lines = t.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    (header, rows)
}

/// The index of column `name` in a trace's header.
pub fn col(h: &[String], name: &str) -> usize {
    h.iter()
        .position(|c| c == name)
        .unwrap_or_else(|| panic!("no column {name} in {h:?}"))
}
