//! The tutorial is run, not written. `walk_the_tutorial` runs every ```sh block of docs/your-rig.md in order in
//! an empty folder and checks that each line of the ```text block after it is printed; `generated_next_commands_run`
//! runs every `pneuflex` command line that `new rig`'s README.md and rig.toml give. The doc's conventions (its
//! head says them): `pneuflex` is this build's binary; `NAME=value` lines set `$NAME`; a ```sh emulator block starts
//! its first command (a blocking `rig emulate`), puts the pseudo-terminal it prints in place of `/dev/pts/N` and
//! stops it with SIGINT (Ctrl-C) after the others; in a ```text line `…` skips text, a figure matches within 3 %
//! and one unit of its last digit, and runs of spaces count as one.

mod common;

use common::{Ran, finish, repo, run, spawn};
use std::collections::HashMap;
use std::io::BufRead;
use std::path::Path;
use std::process::Child;
use std::sync::mpsc;
use std::time::Duration;

/// A fenced block of the doc: its info string (`sh`, `sh emulator`, `text`), its lines and where it starts.
struct Block {
    info: String,
    lines: Vec<String>,
    line: usize,
}

fn blocks(doc: &str) -> Vec<Block> {
    let mut out = Vec::new();
    let mut open: Option<Block> = None;
    for (i, l) in doc.lines().enumerate() {
        if let Some(info) = l.strip_prefix("```") {
            match open.take() {
                Some(b) => out.push(b),
                None => {
                    open = Some(Block {
                        info: info.trim().to_string(),
                        lines: Vec::new(),
                        line: i + 1,
                    })
                }
            }
        } else if let Some(b) = open.as_mut() {
            b.lines.push(l.to_string());
        }
    }
    assert!(open.is_none(), "a ``` fence is not closed");
    out
}

/// The command lines of a shell block: continuations joined, comments dropped.
fn command_lines(lines: &[String]) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    for l in lines {
        let l = match l.find(" #") {
            Some(i) => &l[..i],
            None if l.trim_start().starts_with('#') => "",
            None => l,
        };
        let (body, more) = match l.trim_end().strip_suffix('\\') {
            Some(b) => (b, true),
            None => (l.trim_end(), false),
        };
        cur.push_str(body);
        cur.push(' ');
        if !more {
            if !cur.trim().is_empty() {
                out.push(cur.trim().to_string());
            }
            cur.clear();
        }
    }
    out
}

/// `pneuflex ARGS` as the binary's arguments, `$NAME` from `vars`. The doc's commands are plain words: a quote
/// or a shell operator would be run differently here than in a shell, so it fails the test.
fn args_of(line: &str, vars: &HashMap<String, String>, what: &str) -> Vec<String> {
    let mut line = line.to_string();
    for (k, v) in vars {
        line = line.replace(&format!("${k}"), v);
    }
    assert!(
        !line.contains(['$', '"', '\'', '|', '>', '<', ';', '&', '`']),
        "{what}: `{line}` needs a shell; the test runs plain words"
    );
    let words: Vec<String> = line.split_whitespace().map(String::from).collect();
    assert_eq!(
        words.first().map(String::as_str),
        Some("pneuflex"),
        "{what}: `{line}` is not a pneuflex command"
    );
    words[1..].to_vec()
}

/// A `NAME=value` line.
fn assignment(line: &str) -> Option<(String, String)> {
    let (k, v) = line.split_once('=')?;
    (!k.is_empty() && k.chars().all(|c| c.is_ascii_uppercase() || c == '_') && !v.contains(' '))
        .then(|| (k.to_string(), v.to_string()))
}

/// A piece of a `text` line: a character to match as is, or a figure to match within its tolerance.
#[derive(Debug)]
enum Piece {
    Char(char),
    Figure { value: f64, tolerance: f64 },
}

/// The number starting at `i` of `c`, with its last digit's unit: `-1.5e-8`, `38`, `0.001`.
fn number_at(c: &[char], i: usize) -> Option<(f64, f64, usize)> {
    let mut j = i;
    if c.get(j) == Some(&'-') && (i == 0 || !c[i - 1].is_alphanumeric()) {
        j += 1;
    }
    let digits = |j: &mut usize| {
        let s = *j;
        while c.get(*j).is_some_and(|d| d.is_ascii_digit()) {
            *j += 1;
        }
        *j - s
    };
    if digits(&mut j) == 0 {
        return None;
    }
    let mut decimals = 0;
    if c.get(j) == Some(&'.') && c.get(j + 1).is_some_and(|d| d.is_ascii_digit()) {
        j += 1;
        decimals = digits(&mut j);
    }
    let mut exponent = 0;
    if c.get(j) == Some(&'e') {
        let mut k = j + 1;
        if matches!(c.get(k), Some('-' | '+')) {
            k += 1;
        }
        if c.get(k).is_some_and(|d| d.is_ascii_digit()) {
            let start = j + 1;
            j = k;
            digits(&mut j);
            exponent = c[start..j].iter().collect::<String>().parse().unwrap();
        }
    }
    let text: String = c[i..j].iter().collect();
    let unit = 10f64.powi(exponent - decimals as i32);
    Some((text.parse().ok()?, unit, j))
}

fn pieces(segment: &str) -> Vec<Piece> {
    let c: Vec<char> = segment.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < c.len() {
        let at_boundary = i == 0 || !(c[i - 1].is_ascii_digit() || c[i - 1] == '.');
        match number_at(&c, i).filter(|_| at_boundary) {
            Some((value, unit, j)) => {
                out.push(Piece::Figure {
                    value,
                    tolerance: 0.03 * value.abs() + unit,
                });
                i = j;
            }
            None => {
                out.push(Piece::Char(c[i]));
                i += 1;
            }
        }
    }
    out
}

/// Where `p` ends when it matches `c` from `i`.
fn match_at(p: &[Piece], c: &[char], mut i: usize) -> Option<usize> {
    for piece in p {
        match piece {
            Piece::Char(ch) => {
                if c.get(i) != Some(ch) {
                    return None;
                }
                i += 1;
            }
            Piece::Figure { value, tolerance } => {
                let (v, _, j) = number_at(c, i)?;
                if (v - value).abs() > *tolerance {
                    return None;
                }
                i = j;
            }
        }
    }
    Some(i)
}

fn collapse(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Whether the doc's `expected` line (with `…` and figures) is one of `printed`'s lines.
fn printed_line(expected: &str, printed: &str) -> bool {
    let segments: Vec<Vec<Piece>> = collapse(expected)
        .split('…')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(pieces)
        .collect();
    printed.lines().any(|l| {
        let c: Vec<char> = collapse(l).chars().collect();
        (0..=c.len()).any(|start| {
            let mut from = Some(start);
            for (n, seg) in segments.iter().enumerate() {
                from = from.and_then(|f| {
                    if n == 0 {
                        match_at(seg, &c, f)
                    } else {
                        (f..=c.len()).find_map(|k| match_at(seg, &c, k))
                    }
                });
            }
            from.is_some()
        })
    })
}

/// A blocking `rig emulate` started in `cwd`, with the pseudo-terminal it serves; its later output is gathered
/// on a thread.
struct Emulator {
    /// None once stopped.
    child: Option<Child>,
    pts: String,
    /// What it printed up to its terminal.
    head: String,
    lines: mpsc::Receiver<String>,
}

fn start_emulator(args: &[String], cwd: &Path, what: &str) -> Emulator {
    let a: Vec<&str> = args.iter().map(String::as_str).collect();
    let mut child = spawn(&a, cwd);
    let out = child.stdout.take().unwrap();
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for l in std::io::BufReader::new(out).lines().map_while(Result::ok) {
            if tx.send(l).is_err() {
                break;
            }
        }
    });
    let mut seen = String::new();
    // Generous: the emulator prints its terminal before simulating anything.
    while let Ok(l) = rx.recv_timeout(Duration::from_secs(120)) {
        seen.push_str(&l);
        seen.push('\n');
        if let Some(i) = l.find("/dev/pts/") {
            let pts: String = l[i..]
                .chars()
                .take_while(|c| !c.is_whitespace() && *c != ')')
                .collect();
            return Emulator {
                child: Some(child),
                pts,
                head: seen,
                lines: rx,
            };
        }
    }
    let _ = child.kill();
    let ran = finish(child, what);
    panic!("{what}: printed no pseudo-terminal:\n{seen}{}", ran.stderr);
}

/// A test that fails between starting and stopping an emulator leaves none running.
impl Drop for Emulator {
    fn drop(&mut self) {
        if let Some(c) = self.child.as_mut() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Stops the emulator as Ctrl-C does; its whole output.
fn stop_emulator(mut e: Emulator, what: &str) -> String {
    let mut child = e.child.take().unwrap();
    let status = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill runs");
    if !status.success() {
        let _ = child.kill();
        panic!("{what}: kill -INT failed");
    }
    let mut err = child.stderr.take().unwrap();
    let err = std::thread::spawn(move || {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut err, &mut s).unwrap();
        s
    });
    let start = std::time::Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > common::DEADLINE {
            let _ = child.kill();
            panic!("HANG: {what} still running after Ctrl-C");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let err = err.join().unwrap();
    assert!(!err.contains("panicked"), "PANIC in {what}:\n{err}");
    assert_eq!(status.code(), Some(0), "{what} after Ctrl-C: {err}");
    // The reading thread ends at the pipe's end, after the child.
    let mut out = std::mem::take(&mut e.head);
    for l in e.lines.iter() {
        out.push_str(&l);
        out.push('\n');
    }
    out + &err
}

fn output(ran: &Ran) -> String {
    format!("{}\n{}", ran.stdout, ran.stderr)
}

#[test]
fn walk_the_tutorial() {
    let doc_path = repo().join("docs/your-rig.md");
    let doc = std::fs::read_to_string(&doc_path).unwrap();
    let blocks = blocks(&doc);
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let mut vars = HashMap::new();
    let mut walked = 0;
    for (n, b) in blocks.iter().enumerate() {
        let emulator = match b.info.as_str() {
            "sh" => false,
            "sh emulator" => true,
            _ => continue,
        };
        let mut printed = String::new();
        let mut emu: Option<(Emulator, String)> = None;
        for line in command_lines(&b.lines) {
            let what = format!("docs/your-rig.md:{}: `{line}`", b.line);
            if let Some((k, v)) = assignment(&line) {
                vars.insert(k, v);
                continue;
            }
            let mut args = args_of(&line, &vars, &what);
            if emulator && emu.is_none() {
                let e = start_emulator(&args, dir, &what);
                emu = Some((e, what));
                continue;
            }
            if let Some((e, _)) = &emu {
                for a in &mut args {
                    *a = a.replace("/dev/pts/N", &e.pts);
                }
            }
            let a: Vec<&str> = args.iter().map(String::as_str).collect();
            let ran = run(&a, dir);
            // Over a pseudo-terminal the run is real time: on a loaded machine the watchdog may end it on a
            // fault (the doc says so), the one failure taken here; it must still have connected (its excerpt).
            let faulted = emu.is_some() && ran.stderr.contains("run ended on a fault");
            assert!(
                ran.code == Some(0) || (faulted && ran.code == Some(1)),
                "{what} failed:\n{}",
                output(&ran)
            );
            printed.push_str(&output(&ran));
            walked += 1;
        }
        let pts = emu.as_ref().map(|(e, _)| e.pts.clone());
        if let Some((e, what)) = emu {
            printed.push_str(&stop_emulator(e, &what));
            walked += 1;
        }
        // What the doc says the block prints.
        if let Some(t) = blocks.get(n + 1).filter(|t| t.info == "text") {
            for l in t.lines.iter().filter(|l| !l.trim().is_empty()) {
                let l = match &pts {
                    Some(p) => l.replace("/dev/pts/N", p),
                    None => l.clone(),
                };
                assert!(
                    printed_line(&l, &printed),
                    "docs/your-rig.md:{}: the doc says the commands print\n  {l}\nthey printed:\n{printed}",
                    t.line
                );
            }
        }
    }
    assert!(
        walked >= 15,
        "only {walked} commands found in the doc's ```sh blocks"
    );

    // Section 4's claim: every hidden truth lies inside its fitted 95 % interval.
    let read = |p: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.join(p)).unwrap()).unwrap()
    };
    let truth = read("out/my-truth/truth.json");
    let report = read("out/my-fit/report.json");
    let estimates = report["fit"]["estimates"].as_array().unwrap();
    for t in truth.as_array().unwrap() {
        let key = t["key"].as_str().unwrap();
        let e = estimates
            .iter()
            .find(|e| e["key"] == key)
            .unwrap_or_else(|| panic!("{key} not fitted"));
        let (lo, hi) = (
            e["ci95"][0].as_f64().unwrap(),
            e["ci95"][1].as_f64().unwrap(),
        );
        let v = t["truth"].as_f64().unwrap();
        assert!(
            lo <= v && v <= hi,
            "{key}: truth {v} outside the fitted interval [{lo}, {hi}]"
        );
    }
}

/// The `pneuflex` command lines of a generated file: those of its ```sh blocks and those in backticks.
fn generated_commands(text: &str) -> (Vec<String>, Vec<String>) {
    let mut block = Vec::new();
    let mut in_sh = false;
    let mut spans = Vec::new();
    let mut sh_lines = Vec::new();
    for l in text.lines() {
        if let Some(info) = l.strip_prefix("```") {
            if in_sh {
                block.extend(command_lines(&sh_lines));
                sh_lines.clear();
            }
            in_sh = !in_sh && info.trim() == "sh";
            continue;
        }
        if in_sh {
            sh_lines.push(l.to_string());
            continue;
        }
        for (i, span) in l.split('`').enumerate() {
            if i % 2 == 1 && span.starts_with("pneuflex ") {
                spans.push(span.to_string());
            }
        }
    }
    (block, spans)
}

#[test]
fn generated_next_commands_run() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    run(
        &[
            "new",
            "rig",
            "my-rig",
            "--bore",
            "25mm",
            "--stroke",
            "100mm",
            "--valve",
            "proportional",
        ],
        dir,
    )
    .accepted();
    let rig_dir = dir.join("my-rig");
    let readme = std::fs::read_to_string(rig_dir.join("README.md")).unwrap();
    let rig_file = std::fs::read_to_string(rig_dir.join("rig.toml")).unwrap();
    let (next, readme_spans) = generated_commands(&readme);
    let (rig_block, rig_spans) = generated_commands(&rig_file);
    assert!(rig_block.is_empty());
    assert!(next.len() >= 4, "README.md's next commands: {next:?}");
    assert!(rig_spans.len() >= 2, "rig.toml's commands: {rig_spans:?}");
    assert!(
        !readme_spans.is_empty(),
        "README.md names its `new rig` command"
    );
    let none = HashMap::new();
    // README.md's commands run from the folder `new rig` ran in, rig.toml's from its own folder (as each says);
    // the next commands and the rig file's must work, the rest (the `new rig` that wrote the folder, which now
    // exists) must at least be taken by the parser.
    let all = next
        .iter()
        .map(|c| (c, dir, true, "README.md"))
        .chain(readme_spans.iter().map(|c| (c, dir, false, "README.md")))
        .chain(
            rig_spans
                .iter()
                .map(|c| (c, rig_dir.as_path(), true, "rig.toml")),
        );
    for (line, cwd, must_work, file) in all {
        let what = format!("{file}: `{line}`");
        let args = args_of(line, &none, &what);
        if args.starts_with(&["rig".into(), "emulate".into()]) {
            let e = start_emulator(&args, cwd, &what);
            stop_emulator(e, &what);
            continue;
        }
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let ran = finish(spawn(&a, cwd), &what);
        assert!(
            ran.code != Some(2) && !ran.stderr.contains("Usage:"),
            "{what}: refused by the parser:\n{}",
            ran.stderr
        );
        if must_work {
            assert_eq!(ran.code, Some(0), "{what} failed:\n{}", output(&ran));
        }
    }
}

#[test]
fn the_matcher_refuses_what_was_not_printed() {
    let printed =
        "adaptive      step   2.8108 N  steady-state error 0.058 N\nmodel check: adequate (white)";
    assert!(printed_line(
        "adaptive step 2.8108 N steady-state error 0.058 N",
        printed
    ));
    assert!(printed_line("adaptive step 2.82 N …error 0.058", printed));
    assert!(printed_line("model check: adequate…", printed));
    // A figure off by more than its tolerance, a word changed, a verdict flipped.
    assert!(!printed_line("adaptive step 3.1 N", printed));
    assert!(!printed_line("impedance step 2.8108 N", printed));
    assert!(!printed_line("model check: not adequate", printed));
    assert!(printed_line("C 1.505418e-8", "C 1.505e-8 m"));
    assert!(!printed_line("C 1.505418e-8", "C 1.605e-8 m"));
}
