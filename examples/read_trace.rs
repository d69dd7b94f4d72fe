//! Reading a trace and computing a metric: run scenes/paper-fig3.toml, write trace.csv and summary.json as
//! `pneuflex run` does, then read them back like any other program would, by column name.
//!
//! `cargo run --example read_trace [-- OUT_DIR]`: with OUT_DIR (e.g. out/paper-fig3 after
//! `pneuflex run scenes/paper-fig3.toml`) it reads that output instead of running the scene.
//!
//! It recomputes the RMS force error of every metric window from trace.csv (it must match summary.json)
//! and adds a metric summary.json does not have: the mean valve effort |u|.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use pneuflex::scene::{Scene, run_scene, write_results};

/// A file's text; the error names the file.
fn read(path: &Path) -> Result<String, String> {
    std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))
}

/// A trace.csv by column: header name → values (an empty cell, a signal the plant lacks, is NaN).
fn read_csv(path: &Path) -> Result<HashMap<String, Vec<f64>>, Box<dyn std::error::Error>> {
    let text = read(path)?;
    let mut lines = text.lines();
    let names: Vec<&str> = lines.next().ok_or("empty trace")?.split(',').collect();
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); names.len()];
    for line in lines {
        for (col, cell) in cols.iter_mut().zip(line.split(',')) {
            col.push(if cell.is_empty() {
                f64::NAN
            } else {
                cell.parse()?
            });
        }
    }
    Ok(names.into_iter().map(String::from).zip(cols).collect())
}

/// RMS of f_ref - f_e over the samples in [t0, t1), and t1 itself when the window ends with the run:
/// the definition of `rms_force_error_n` in summary.json.
fn rms_force_error(tr: &HashMap<String, Vec<f64>>, t0: f64, t1: f64, end_s: f64) -> f64 {
    let eps = 1e-9 * (t1 - t0);
    let inside = |t: f64| {
        (t >= t0 - eps && t < t1 - eps) || ((t - t1).abs() <= eps && (t1 - end_s).abs() <= eps)
    };
    let (t, f_ref, f_e) = (&tr["t"], &tr["f_ref"], &tr["f_e"]);
    let (sum, n) = (0..t.len())
        .filter(|&i| inside(t[i]))
        .fold((0.0, 0), |(s, n), i| {
            (s + (f_ref[i] - f_e[i]).powi(2), n + 1)
        });
    (sum / n as f64).sqrt()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = match std::env::args().nth(1) {
        Some(d) => PathBuf::from(d),
        None => {
            // Run the scene and write its outputs into a scratch directory.
            let scene = Scene::load(Path::new(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/scenes/paper-fig3.toml"
            )))?;
            let runs = run_scene(&scene, &mut |_| {})?;
            let dir =
                std::env::temp_dir().join(format!("pneuflex-read-trace-{}", std::process::id()));
            write_results(&dir, &scene, &runs)?;
            dir
        }
    };

    // summary.json names each run's trace file and holds the metrics the CLI computed.
    let summary: serde_json::Value = serde_json::from_str(&read(&dir.join("summary.json"))?)?;
    let end_s = summary["duration_s"]
        .as_f64()
        .ok_or("summary.json: no duration_s")?;
    println!(
        "{}: {}",
        summary["scene"].as_str().unwrap_or("?"),
        dir.display()
    );
    for run in summary["runs"].as_array().ok_or("summary.json: no runs")? {
        let file = dir.join(
            run["trace"]
                .as_str()
                .ok_or("summary.json: run without trace")?,
        );
        let tr = read_csv(&file)?;
        let u = &tr["u"];
        let effort = u.iter().map(|u| u.abs()).sum::<f64>() / u.len() as f64;
        println!(
            "{} ({} rows, columns {}): mean valve effort |u| = {effort:.3}",
            run["name"].as_str().unwrap_or("?"),
            tr["t"].len(),
            tr.len()
        );
        for w in run["windows"].as_array().into_iter().flatten() {
            let (t0, t1) = (
                w["t0_s"].as_f64().unwrap_or(0.0),
                w["t1_s"].as_f64().unwrap_or(0.0),
            );
            let mine = rms_force_error(&tr, t0, t1, end_s);
            let theirs = w["rms_force_error_n"].as_f64().unwrap_or(f64::NAN);
            println!(
                "  {:<17} RMS force error: trace.csv {mine:.6} N, summary.json {theirs:.6} N, diff {:.0e}",
                w["name"].as_str().unwrap_or("?"),
                mine - theirs
            );
            // The CSV holds shortest round-trip decimals (the exact f64 values): equal up to
            // rounding in the sum.
            assert!(
                (mine - theirs).abs() <= 1e-9 * theirs.abs().max(1.0),
                "{mine} vs {theirs}"
            );
        }
    }
    if std::env::args().nth(1).is_none() {
        std::fs::remove_dir_all(&dir)?;
    }
    Ok(())
}
