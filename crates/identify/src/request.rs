//! `pneuflex identify` as a library call: read and check the inputs, fit, report, write the outputs.

use std::path::{Path, PathBuf};
use std::time::Instant;

use pneuflex_files::output::{Manifest, Writer};
use pneuflex_files::{InputDigest, OutputDir};
use pneuflex_pneumatics::{ActuatorSheet, OneDofModel};

use crate::IdentifyError;
use crate::check::check;
use crate::fit::{FitOptions, Free, fit_stoppable};
use crate::log::LogLimits;
use crate::log_bag::read_any_log;
use crate::log_format::LogFormat;
use crate::params::{ALL, Key, Offsets};
use crate::replay::Prepared;
use crate::report::{LogEntry, Report, markdown, validation_figure, warnings};

/// What to identify from what.
#[derive(Clone, Debug)]
pub struct Request {
    /// The logs (rig traces).
    pub logs: Vec<PathBuf>,
    /// The actuator sheet to start from.
    pub actuator: PathBuf,
    /// Free keys, as given (`--free`, comma-separated entries allowed).
    pub free: Vec<String>,
    /// Bounds, as given: `KEY=[lo,hi]`.
    pub bounds: Vec<String>,
    /// Fraction of each log held out at its end for validation (0 = none).
    pub validation_fraction: f64,
    /// Fit settings.
    pub options: FitOptions,
    /// How long a log may be (rows, time span).
    pub limits: LogLimits,
    /// How the logs are written (pneuflex's trace.csv by default; `--log-format`).
    pub log_format: LogFormat,
    /// The validation figures' format (`--format`: PNG, SVG or PDF).
    pub figure_format: pneuflex_plot::Format,
}

/// The result of [`identify`].
#[derive(Clone, Debug)]
pub struct Identified {
    /// The sheet started from.
    pub sheet: ActuatorSheet,
    /// The free keys, in order.
    pub keys: Vec<Key>,
    /// The logs, prepared.
    pub data: Vec<Prepared>,
    /// The report.
    pub report: Report,
    /// The fitted model.
    pub model: OneDofModel,
    /// The fitted sensor offsets.
    pub offsets: Offsets,
    /// The fit settings used (the request's, with the sheet's stroke).
    pub options: FitOptions,
}

fn key_err(option: &'static str, key: &str, message: String) -> IdentifyError {
    IdentifyError::Key {
        option,
        key: key.to_string(),
        message,
    }
}

/// The free keys of `--free` entries (each may hold several, comma-separated).
pub fn parse_free(entries: &[String], model: &OneDofModel) -> Result<Vec<Key>, IdentifyError> {
    let mut keys = Vec::new();
    for name in entries.iter().flat_map(|e| e.split(',')).map(str::trim) {
        if name.is_empty() {
            continue;
        }
        let k = Key::parse(name).ok_or_else(|| {
            key_err(
                "--free",
                name,
                format!(
                    "no such parameter; the keys are {}",
                    ALL.iter().map(|k| k.name()).collect::<Vec<_>>().join(", ")
                ),
            )
        })?;
        k.applies(model).map_err(|m| key_err("--free", name, m))?;
        if keys.contains(&k) {
            return Err(key_err("--free", name, "given twice".into()));
        }
        keys.push(k);
    }
    if keys.is_empty() {
        return Err(key_err("--free", "", "no parameter to fit".into()));
    }
    Ok(keys)
}

/// The free parameters with their start values and bounds (defaults, or `--bounds KEY=[lo,hi]`).
pub fn parse_bounds(
    keys: &[Key],
    bounds: &[String],
    model: &OneDofModel,
) -> Result<Vec<Free>, IdentifyError> {
    let off = Offsets::default();
    let mut free: Vec<Free> = keys
        .iter()
        .map(|&k| {
            let start = k.get(model, &off);
            let (lo, hi) = k.default_bounds(start, model);
            Free {
                key: k,
                start,
                lo,
                hi,
            }
        })
        .collect();
    let mut bounded: Vec<Key> = Vec::new();
    for b in bounds {
        let (name, range) = b
            .split_once('=')
            .ok_or_else(|| key_err("--bounds", b, "expected KEY=[lo,hi]".into()))?;
        let k = Key::parse(name)
            .ok_or_else(|| key_err("--bounds", name, "no such parameter".into()))?;
        if bounded.contains(&k) {
            return Err(key_err(
                "--bounds",
                name,
                "given twice: one key, one box".into(),
            ));
        }
        bounded.push(k);
        let f = free
            .iter_mut()
            .find(|f| f.key == k)
            .ok_or_else(|| key_err("--bounds", name, "not a --free parameter".into()))?;
        let inner = range.trim().trim_start_matches('[').trim_end_matches(']');
        let nums: Vec<Result<f64, _>> = inner.split(',').map(|s| s.trim().parse::<f64>()).collect();
        let (lo, hi) = match nums.as_slice() {
            [Ok(lo), Ok(hi)] if lo.is_finite() && hi.is_finite() => (*lo, *hi),
            _ => {
                return Err(key_err(
                    "--bounds",
                    name,
                    format!("`{range}` is not [lo,hi] with two finite numbers"),
                ));
            }
        };
        if lo >= hi {
            return Err(key_err(
                "--bounds",
                name,
                format!("lower bound {lo} must be below the upper bound {hi}"),
            ));
        }
        if !(lo..=hi).contains(&f.start) {
            return Err(key_err(
                "--bounds",
                name,
                format!(
                    "[{lo}, {hi}] excludes the start value {} (from the sheet)",
                    f.start
                ),
            ));
        }
        f.lo = lo;
        f.hi = hi;
    }
    Ok(free)
}

/// Reads the inputs, fits, and builds the report (nothing is written).
pub fn identify(req: &Request) -> Result<Identified, IdentifyError> {
    identify_stoppable(req, None)
}

/// [`identify`] that a signal can stop: `stop` holds the signal's number once one came, and the fit then
/// returns [`IdentifyError::Interrupted`] with the values reached.
pub fn identify_stoppable(
    req: &Request,
    stop: Option<&std::sync::atomic::AtomicUsize>,
) -> Result<Identified, IdentifyError> {
    let sheet = ActuatorSheet::load(&req.actuator)?;
    let base = sheet.model();
    let keys = parse_free(&req.free, &base)?;
    let free = parse_bounds(&keys, &req.bounds, &base)?;
    if !(0.0..0.9).contains(&req.validation_fraction) {
        return Err(IdentifyError::Fit(format!(
            "--validation: the held-out fraction must be in [0, 0.9), got {}",
            req.validation_fraction
        )));
    }
    if req.logs.is_empty() {
        return Err(IdentifyError::Fit("no --log given".into()));
    }
    // The same log twice would count its rows twice and narrow every interval for nothing.
    for (i, p) in req.logs.iter().enumerate() {
        let c = std::fs::canonicalize(p).unwrap_or_else(|_| p.clone());
        if let Some(q) = req.logs[..i]
            .iter()
            .find(|q| std::fs::canonicalize(q).unwrap_or_else(|_| (*q).clone()) == c)
        {
            return Err(IdentifyError::Fit(format!(
                "--log {}: the same file as --log {}: give each log once",
                p.display(),
                q.display()
            )));
        }
    }
    let mut options = req.options;
    options.replay.stroke_m = Some(base.actuator.cylinder.stroke_m);
    let mut data = Vec::new();
    for p in &req.logs {
        let log = read_any_log(p, &req.limits, &req.log_format)?;
        let n = log.len();
        let span = log.t[n - 1] - log.t[0];
        if options.replay.segment_s > span {
            return Err(IdentifyError::Fit(format!(
                "--segment {} s: longer than the log {} ({span} s)",
                options.replay.segment_s,
                p.display()
            )));
        }
        // A segment of a few samples restarts the replay so often that nothing is left to compare.
        let dt = log.dt();
        if options.replay.segment_s < 5.0 * dt {
            return Err(IdentifyError::Fit(format!(
                "--segment {} s: shorter than 5 sample periods of {} (its period is {dt} s)",
                options.replay.segment_s,
                p.display()
            )));
        }
        let fit_end = ((1.0 - req.validation_fraction) * (n - 1) as f64).round() as usize;
        data.push(Prepared::new(log, &options.replay, fit_end));
    }
    let t0 = Instant::now();
    let mut result = fit_stoppable(&base, &free, &data, &options, stop)?;
    let fit_seconds = t0.elapsed().as_secs_f64();
    let mut model = base;
    let mut offsets = Offsets::default();
    for (k, e) in keys.iter().zip(&result.estimates) {
        k.set(&mut model, &mut offsets, e.value);
    }
    // Widened to hold the truth under any probed effect the model lacks in the amounts the residuals allow
    // (check::widen); marked not valid when the model check fails.
    let fitted: Vec<(Key, f64)> = free.iter().map(|f| (f.key, f.start)).collect();
    let model_check = check(&model, &offsets, &fitted, &data, &options.replay);
    crate::check::widen(&mut result.estimates, &model_check);
    for e in &mut result.estimates {
        e.interval_valid = model_check.adequate;
    }
    let supply = base.actuator.supply.supply_pressure_pa;
    let warnings = warnings(&result, &keys);
    let report = Report {
        logs: data
            .iter()
            .map(|d| LogEntry {
                path: d.log.path.display().to_string(),
                sha256: d.log.sha256.clone(),
                rows: d.log.len(),
                fit_rows: d.compared.len(),
                validation_rows: d.validation.len(),
                note: d.log.note.clone(),
            })
            .collect(),
        sheet: req.actuator.display().to_string(),
        validation_pressure_pct_supply: [
            100.0 * result.rms_validation[0] / supply,
            100.0 * result.rms_validation[1] / supply,
        ],
        fit: result,
        model_check,
        warnings,
        fit_seconds,
        structure_selection: None,
    };
    Ok(Identified {
        sheet,
        keys,
        data,
        report,
        model,
        offsets,
        options,
    })
}

/// The output directory of `identify`, staged beside `out` before the fit (a refused `--out` costs no fit):
/// never the folder of a log or of the sheet, never a recording, never inside another output.
pub fn stage_output(req: &Request, out: &Path) -> Result<OutputDir, IdentifyError> {
    let mut protect: Vec<&Path> = req.logs.iter().map(PathBuf::as_path).collect();
    protect.push(&req.actuator);
    Ok(OutputDir::create(
        out,
        &protect,
        Writer::simulation("identify"),
    )?)
}

/// Writes the fitted sheet set, `report.json`, `report.md` and `validation-<i>.png` (or .svg, .pdf) into `out` (staged
/// beside it and renamed into place: `pneuflex_files::OutputDir`). Returns the fitted actuator sheet.
pub fn write_outputs(id: &Identified, req: &Request, out: &Path) -> Result<PathBuf, IdentifyError> {
    let stage = stage_output(req, out)?;
    write_staged(id, req, stage)
}

/// [`write_outputs`] into a directory staged by [`stage_output`].
pub fn write_staged(
    id: &Identified,
    req: &Request,
    stage: OutputDir,
) -> Result<PathBuf, IdentifyError> {
    let dir = stage.path().to_path_buf();
    let f = &id.report.fit;
    let mut header = String::from("Fitted by `pneuflex identify` from the logs:\n");
    for l in &id.report.logs {
        header += &format!("  {} sha256 {}\n", l.path, l.sha256);
    }
    header += &format!(
        "started from {}; free: {}\n",
        req.actuator.display(),
        id.keys
            .iter()
            .map(|k| k.name())
            .collect::<Vec<_>>()
            .join(", ")
    );
    let validation = if f.rms_validation.iter().all(|v| v.is_finite()) {
        format!(
            "held-out validation p_a {:.0} Pa, p_b {:.0} Pa, x {:.3} mm",
            f.rms_validation[0],
            f.rms_validation[1],
            f.rms_validation[2] * 1e3
        )
    } else {
        "no rows held out for validation".to_string()
    };
    header += &format!(
        "fit quality: residual RMS p_a {:.0} Pa, p_b {:.0} Pa, x {:.3} mm on {} rows; {validation} (report.md)\n",
        f.rms_fit[0],
        f.rms_fit[1],
        f.rms_fit[2] * 1e3,
        f.rows,
    );
    for e in &f.estimates {
        header += &format!(
            "  {} = {:e}, 95 % interval [{:e}, {:e}]\n",
            e.key, e.value, e.ci95[0], e.ci95[1]
        );
    }
    if !id.report.model_check.adequate {
        header += &format!(
            "MODEL NOT ADEQUATE: {}; the intervals above are not valid (report.md)\n",
            id.report.model_check.summary()
        );
    }
    if !id.report.warnings.is_empty() {
        header += &format!("{} warning(s): see report.md\n", id.report.warnings.len());
    }
    let values: Vec<(Key, f64)> = id
        .keys
        .iter()
        .zip(&f.estimates)
        .map(|(k, e)| (*k, e.value))
        .collect();
    let sheet = crate::sheet::write_sheets(&id.sheet, &values, &dir, &header)?;
    let werr = |file: PathBuf, e: String| IdentifyError::Output { file, message: e };
    let json = serde_json::to_string_pretty(&id.report)
        .map_err(|e| werr(dir.join("report.json"), e.to_string()))?;
    std::fs::write(dir.join("report.json"), json)
        .map_err(|e| werr(dir.join("report.json"), e.to_string()))?;
    std::fs::write(dir.join("report.md"), markdown(&id.report))
        .map_err(|e| werr(dir.join("report.md"), e.to_string()))?;
    for (i, d) in id.data.iter().enumerate() {
        if d.validation.is_empty() {
            continue;
        }
        let pred = d.replay(&id.model, &id.offsets, &id.options.replay, d.log.len());
        validation_figure(
            &dir.join(format!("validation-{}.{}", i + 1, req.figure_format.ext())),
            &d.log,
            &pred,
            &d.validation,
        )?;
    }
    let mut inputs = Vec::new();
    for p in &req.logs {
        // A bag's files (its MCAP files; the log's sha256 is theirs).
        let files = match crate::log_bag::is_bag(p) {
            true => pneuflex_ros2::bag::bag_files(p).map_err(|e| werr(p.clone(), e.to_string()))?,
            false => vec![p.clone()],
        };
        for f in &files {
            inputs
                .push(InputDigest::of_file(f, "log").map_err(|e| werr(f.clone(), e.to_string()))?);
        }
    }
    inputs.push(
        InputDigest::of_file(&req.actuator, "actuator")
            .map_err(|e| werr(req.actuator.clone(), e.to_string()))?,
    );
    let manifest = Manifest::new("identify", env!("CARGO_PKG_VERSION"), inputs);
    let dest = stage.commit(manifest)?;
    Ok(dest.join(sheet.file_name().unwrap_or_default()))
}
