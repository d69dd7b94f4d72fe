//! Bad inputs are refused with an error naming the file and the line, column or key.
mod common;

use std::path::{Path, PathBuf};

use pneuflex_identify::fit::FitOptions;
use pneuflex_identify::request::{Request, identify};

const HEADER: &str = "t,f_ref,f_e,x,x_r,p_a,p_b,u,wall_time,fault";

/// A well-formed log at rest: `rows` rows, 1 kHz.
fn rows(n: usize) -> Vec<String> {
    (0..n)
        .map(|k| format!("{},0,0,0.01,0.01,101325,101325,0,0,", k as f64 * 1e-3))
        .collect()
}

fn write(dir: &Path, name: &str, header: &str, rows: &[String]) -> PathBuf {
    let p = dir.join(name);
    let mut text = format!("# pneuflex 0.1.0, trace schema 1\n{header}\n");
    for r in rows {
        text += r;
        text.push('\n');
    }
    text += &format!("# end: complete, {} rows\n", rows.len());
    std::fs::write(&p, text).unwrap();
    p
}

fn request(log: PathBuf, free: &[&str], bounds: &[&str]) -> Request {
    Request {
        logs: vec![log],
        actuator: common::root().join("pneumatics/paper-actuator.toml"),
        free: free.iter().map(|s| s.to_string()).collect(),
        bounds: bounds.iter().map(|s| s.to_string()).collect(),
        limits: Default::default(),
        log_format: Default::default(),
        figure_format: Default::default(),
        validation_fraction: 0.2,
        options: FitOptions::default(),
    }
}

fn error(req: &Request) -> String {
    identify(req).expect_err("refused").to_string()
}

/// Fitting C from a log of `rows` under `header`, written in the scratch directory `name`: the log's path
/// and the error.
fn refused_log(name: &str, header: &str, rows: &[String]) -> (String, String) {
    let dir = common::scratch(name);
    let log = write(dir.path(), "trace.csv", header, rows);
    let e = error(&request(
        log.clone(),
        &["valve.sonic_conductance_m3_per_s_pa"],
        &[],
    ));
    (log.display().to_string(), e)
}

/// A well-formed log of 50 rows in the scratch directory `name` (alive as long as the guard).
fn log_at_rest(name: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = common::scratch(name);
    let log = write(dir.path(), "trace.csv", HEADER, &rows(50));
    (dir, log)
}

#[test]
fn missing_column_names_file_and_column() {
    let header = HEADER.replace("p_b,", "");
    let r: Vec<String> = rows(50)
        .iter()
        .map(|r| {
            let mut f: Vec<&str> = r.split(',').collect();
            f.remove(6);
            f.join(",")
        })
        .collect();
    let (log, e) = refused_log("bad-column", &header, &r);
    assert!(e.starts_with(&format!("{log}:2: column `p_b`")), "{e}");
    assert!(e.contains("missing column"), "{e}");
}

#[test]
fn nan_row_names_file_line_and_column() {
    let mut r = rows(50);
    r[20] = r[20].replace(",0.01,0.01,", ",NaN,0.01,");
    let (log, e) = refused_log("bad-nan", HEADER, &r);
    // Line 1 is the comment, 2 the header, row 20 is line 23.
    assert!(e.starts_with(&format!("{log}:23: column `x`")), "{e}");
    assert!(e.contains("NaN"), "{e}");
}

#[test]
fn time_going_backwards_names_file_line_and_t() {
    let mut r = rows(50);
    r[30] = r[30].replacen("0.03,", "0.01,", 1);
    let (log, e) = refused_log("bad-time", HEADER, &r);
    assert!(e.starts_with(&format!("{log}:33: column `t`")), "{e}");
    assert!(e.contains("time must increase"), "{e}");
}

#[test]
fn unknown_or_inapplicable_free_key_is_named() {
    let (_dir, log) = log_at_rest("bad-key");
    let e = error(&request(
        log.clone(),
        &["valve.sonic_conductance,mechanics.mass"],
        &[],
    ));
    assert!(
        e.starts_with("--free: valve.sonic_conductance: no such parameter"),
        "{e}"
    );
    // The shipped valve is on/off: a proportional valve's response time does not apply.
    let e = error(&request(log, &["valve.response_time_s"], &[]));
    assert!(e.starts_with("--free: valve.response_time_s:"), "{e}");
    assert!(e.contains("on/off"), "{e}");
}

#[test]
fn bounds_excluding_the_start_value_are_named() {
    let (_dir, log) = log_at_rest("bad-bounds");
    let free = ["mechanics.moving_mass_kg"];
    let e = error(&request(
        log.clone(),
        &free,
        &["mechanics.moving_mass_kg=[1,2]"],
    ));
    assert!(
        e.starts_with("--bounds: mechanics.moving_mass_kg: [1, 2] excludes the start value 0.6"),
        "{e}"
    );
    let e = error(&request(log.clone(), &free, &["mechanics.coulomb_n=[0,1]"]));
    assert!(e.contains("not a --free parameter"), "{e}");
    let e = error(&request(log, &free, &["mechanics.moving_mass_kg=[2,1]"]));
    assert!(e.contains("must be below"), "{e}");
}

#[test]
fn missing_log_names_the_file() {
    let e = error(&request(
        PathBuf::from("/nonexistent/trace.csv"),
        &["valve.sonic_conductance_m3_per_s_pa"],
        &[],
    ));
    assert!(e.contains("/nonexistent/trace.csv"), "{e}");
}
