//! `pneuflex identify` and `pneuflex perturb`: wiring only; the work is in `pneuflex-identify`.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use pneuflex_identify::fit::FitOptions;
use pneuflex_identify::params::Key;
use pneuflex_identify::replay::ReplayOptions;
use pneuflex_identify::request::{Request, identify as fit_logs, write_outputs};

/// `pneuflex identify --log L... --actuator S --free K,... [--bounds K=[lo,hi]]... [--out DIR]`.
#[allow(clippy::too_many_arguments)]
pub fn identify(
    logs: Vec<PathBuf>,
    actuator: &Path,
    free: Vec<String>,
    bounds: Vec<String>,
    out: Option<&Path>,
    validation: f64,
    segment_s: f64,
    settle_s: f64,
) -> anyhow::Result<()> {
    if !(segment_s.is_finite() && segment_s > 0.0) {
        bail!("--segment: must be > 0 s, got {segment_s}");
    }
    if !(settle_s.is_finite() && settle_s >= 0.0 && settle_s < segment_s) {
        bail!("--settle: must be in [0, --segment) s, got {settle_s}");
    }
    let req = Request {
        logs,
        actuator: actuator.to_path_buf(),
        free,
        bounds,
        validation_fraction: validation,
        options: FitOptions {
            replay: ReplayOptions {
                segment_s,
                settle_s,
                ..ReplayOptions::default()
            },
            ..FitOptions::default()
        },
    };
    let id = fit_logs(&req)?;
    let dest = match out {
        Some(d) => d.to_path_buf(),
        None => {
            let stem = req.logs[0]
                .parent()
                .and_then(|p| p.file_name())
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| "log".into());
            Path::new("out").join("identify").join(stem)
        }
    };
    let sheet = write_outputs(&id, &req, &dest)?;
    let f = &id.report.fit;
    println!(
        "{:<40} {:>14} {:>14} {:>32}",
        "key", "start", "fitted", "95 % interval"
    );
    for e in &f.estimates {
        println!(
            "{:<40} {:>14.6e} {:>14.6e}   [{:.6e}, {:.6e}]",
            e.key, e.start, e.value, e.ci95[0], e.ci95[1]
        );
    }
    println!(
        "residual RMS (fit): p_a {:.0} Pa, p_b {:.0} Pa, x {:.3} mm; held-out validation: p_a {:.0} Pa, p_b {:.0} Pa ({:.2} / {:.2} % of supply), x {:.3} mm",
        f.rms_fit[0],
        f.rms_fit[1],
        f.rms_fit[2] * 1e3,
        f.rms_validation[0],
        f.rms_validation[1],
        id.report.validation_pressure_pct_supply[0],
        id.report.validation_pressure_pct_supply[1],
        f.rms_validation[2] * 1e3
    );
    for w in &id.report.warnings {
        eprintln!("warning: {w}");
    }
    println!(
        "fit took {:.1} s; fitted sheet: {}",
        id.report.fit_seconds,
        sheet.display()
    );
    println!("report: {}", dest.join("report.md").display());
    Ok(())
}

/// `pneuflex perturb --actuator S --keys K,... --seed N --out DIR`: a hidden truth for tests, written with
/// `truth.json` (shipped and perturbed value per key).
pub fn perturb(actuator: &Path, keys: &[String], seed: u64, out: &Path) -> anyhow::Result<()> {
    let mut ks = Vec::new();
    for k in keys.iter().flat_map(|k| k.split(',')).map(str::trim) {
        if k.is_empty() {
            continue;
        }
        ks.push(Key::parse(k).with_context(|| format!("--keys: {k}: no such parameter"))?);
    }
    if ks.is_empty() {
        bail!("--keys: no parameter to perturb");
    }
    if out.exists() {
        bail!(
            "{}: exists; perturb writes a new directory and replaces nothing",
            out.display()
        );
    }
    let (sheet, changes) = pneuflex_identify::perturb::perturb(actuator, &ks, seed, out)?;
    let table: Vec<serde_json::Value> = changes
        .iter()
        .map(|c| serde_json::json!({"key": c.key.name(), "shipped": c.shipped, "truth": c.truth}))
        .collect();
    let json = out.join("truth.json");
    std::fs::write(&json, serde_json::to_string_pretty(&table)?)
        .with_context(|| format!("{}: cannot write", json.display()))?;
    println!(
        "hidden truth: {} (values in {})",
        sheet.display(),
        json.display()
    );
    Ok(())
}
