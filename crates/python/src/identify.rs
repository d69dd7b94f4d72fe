//! `pneuflex.identify(...)`: the fit of `pneuflex identify` (crates/identify) from Python. The native
//! function returns the report as JSON plus the held-out validation signals; the package's `identify`
//! (python/pneuflex/__init__.py) turns them into dicts and numpy arrays.

use std::path::PathBuf;

use pneuflex_identify::IdentifyError;
use pneuflex_identify::fit::FitOptions;
use pneuflex_identify::replay::ReplayOptions;
use pneuflex_identify::request::{Request, identify as fit_logs, write_outputs};
use pyo3::exceptions::{PyFileNotFoundError, PyOSError};
use pyo3::prelude::*;

use crate::errors::PneuflexError;

fn err(e: IdentifyError) -> PyErr {
    let m = e.to_string();
    match e {
        IdentifyError::Input(_) if m.contains("No such file") => PyFileNotFoundError::new_err(m),
        IdentifyError::Input(_) | IdentifyError::Output { .. } => PyOSError::new_err(m),
        _ => PneuflexError::new_err(m),
    }
}

/// Fits `free` keys of the actuator sheet to the logs; writes the outputs of the CLI into `out` when
/// given. Returns JSON: `{"report": <report.json>, "validation": [{"log", "t", "p_a", "p_b", "x",
/// "p_a_model", "p_b_model", "x_model"}]}` (held-out rows of each log; model values NaN where a segment's
/// settling was not compared). `log_format` names a format file for logs another tool wrote
/// (docs/identification.md, "Other people's logs").
#[pyfunction]
#[pyo3(signature = (logs, actuator, free, bounds=Vec::new(), validation=0.2, segment=0.1, settle=0.015, out=None, log_format=None, select=false))]
#[allow(clippy::too_many_arguments)]
pub fn identify_json(
    py: Python<'_>,
    logs: Vec<PathBuf>,
    actuator: PathBuf,
    free: Vec<String>,
    bounds: Vec<String>,
    validation: f64,
    segment: f64,
    settle: f64,
    out: Option<PathBuf>,
    log_format: Option<PathBuf>,
    select: bool,
) -> PyResult<String> {
    if !(segment.is_finite()
        && segment > 0.0
        && settle.is_finite()
        && (0.0..segment).contains(&settle))
    {
        return Err(PneuflexError::new_err(format!(
            "segment must be > 0 s and settle in [0, segment), got {segment}, {settle}"
        )));
    }
    let log_format = match &log_format {
        Some(f) => pneuflex_identify::log_format::LogFormat::load(f).map_err(err)?,
        None => Default::default(),
    };
    let req = Request {
        figure_format: pneuflex_plot::Format::Png,
        logs,
        actuator,
        free,
        bounds,
        limits: Default::default(),
        log_format,
        validation_fraction: validation,
        options: FitOptions {
            replay: ReplayOptions {
                segment_s: segment,
                settle_s: settle,
                ..ReplayOptions::default()
            },
            ..FitOptions::default()
        },
    };
    // `select`: each structure's sheets in a folder of this call's own, removed once the outputs are written.
    let work =
        std::env::temp_dir().join(format!("pneuflex-select-{}-{:p}", std::process::id(), &req));
    let fitted = py.detach(|| -> Result<_, IdentifyError> {
        let id = if select {
            pneuflex_identify::select::select(
                &req,
                &pneuflex_identify::select::STRUCTURES,
                &work,
                None,
                &|_| {},
            )?
        } else {
            fit_logs(&req)?
        };
        if let Some(dir) = &out {
            write_outputs(&id, &req, dir)?;
        }
        Ok(id)
    });
    if select {
        let _ = std::fs::remove_dir_all(&work);
    }
    let id = fitted.map_err(err)?;
    py.detach(|| -> Result<String, IdentifyError> {
        let mut val = Vec::new();
        for d in &id.data {
            let pred = d.replay(&id.model, &id.offsets, &id.options.replay, d.log.len());
            let (a, b) = match (d.validation.first(), d.validation.last()) {
                (Some(&a), Some(&b)) => (a, b + 1),
                _ => (0, 0),
            };
            let mut keep = vec![false; b - a];
            for &k in &d.validation {
                keep[k - a] = true;
            }
            let masked = |v: &[f64]| -> Vec<Option<f64>> {
                v[a..b]
                    .iter()
                    .zip(&keep)
                    .map(|(x, &k)| (k && x.is_finite()).then_some(*x))
                    .collect()
            };
            val.push(serde_json::json!({
                "log": d.log.path.display().to_string(),
                "t": &d.log.t[a..b],
                "p_a": &d.log.p_a[a..b],
                "p_b": &d.log.p_b[a..b],
                "x": &d.log.x[a..b],
                "p_a_model": masked(&pred.p_a),
                "p_b_model": masked(&pred.p_b),
                "x_model": masked(&pred.x),
            }));
        }
        Ok(serde_json::json!({"report": id.report, "validation": val}).to_string())
    })
    .map_err(err)
}
