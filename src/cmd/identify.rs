//! `pneuflex identify` and `pneuflex perturb`: wiring only; the work is in `pneuflex-identify`.
//!
//! `identify` checks every option and stages its output directory before the fit (a refused `--out` costs
//! no fit). SIGINT, SIGTERM or SIGHUP stop the fit at its next evaluation: `DIR.partial` gets a report of
//! the values reached (not converged, no intervals, no fitted sheet), the previous output stays untouched,
//! and the exit code is 128 + the signal.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;

use anyhow::{Context, bail};
use pneuflex_files::OutputDir;
use pneuflex_files::output::{Manifest, Partial};
use pneuflex_identify::IdentifyError;
use pneuflex_identify::fit::FitOptions;
use pneuflex_identify::log::LogLimits;
use pneuflex_identify::replay::ReplayOptions;
use pneuflex_identify::request::{
    Identified, Request, identify_stoppable, stage_output, write_staged,
};
use pneuflex_identify::select::{STRUCTURES, select};

/// The options of `identify` beyond the logs and the sheet.
#[derive(Clone, Debug)]
pub struct IdentifyArgs {
    /// `--free`.
    pub free: Vec<String>,
    /// `--bounds`.
    pub bounds: Vec<String>,
    /// `--validation`: the held-out fraction.
    pub validation: f64,
    /// `--segment`, s.
    pub segment_s: f64,
    /// `--settle`, s.
    pub settle_s: f64,
    /// `--max-rows`, `--max-log-s`.
    pub limits: LogLimits,
    /// `--log-format`.
    pub log_format: Option<PathBuf>,
    /// `--channel`: one actuator of a recording of several.
    pub channel: Option<String>,
    /// `--format`: the validation figures'.
    pub figure_format: pneuflex_viz::Format,
    /// `--select`: fit every candidate structure and keep the best (`pneuflex_identify::select`).
    pub select: bool,
}

/// `pneuflex identify --log L... --actuator S --free K,... [--bounds K=[lo,hi]]... [--out DIR]` (default
/// `out/identify/<folder of the first log>[-<--channel>]`).
pub fn identify(
    logs: Vec<PathBuf>,
    actuator: &Path,
    out: Option<&Path>,
    a: IdentifyArgs,
) -> anyhow::Result<()> {
    let select_structures = a.select;
    let req = request_of(logs, actuator, a)?;
    let dest = match out {
        Some(d) => d.to_path_buf(),
        None => {
            let stem = req.logs[0]
                .parent()
                .and_then(|p| p.file_name())
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| "log".into());
            // Each actuator of one recording its own folder (`impedance-left`, `impedance-right`).
            let stem = match &req.log_format.channel {
                Some(name) => format!("{stem}-{name}"),
                None => stem,
            };
            Path::new("out").join("identify").join(stem)
        }
    };
    // The keys, the sheet and every log are read (and refused) first, then the output is staged, then the fit.
    let sheet = pneuflex_pneumatics::ActuatorSheet::load(&req.actuator)?;
    let keys = pneuflex_identify::request::parse_free(&req.free, &sheet.model())?;
    pneuflex_identify::request::parse_bounds(&keys, &req.bounds, &sheet.model())?;
    // A bag (`--mcap`) is a folder: crates/ros2 reads it.
    for l in req
        .logs
        .iter()
        .filter(|l| !pneuflex_identify::log_bag::is_bag(l))
    {
        pneuflex_files::input::check_regular(l, pneuflex_files::InputKind::Trace)?;
    }
    let stage = stage_output(&req, &dest)?;
    let stop = super::stop_flag()?;
    let fitted = if select_structures {
        // Each structure's sheet set in the output, beside the fit it led to.
        let work = stage.path().join("structures");
        let progress = |name: &str| eprintln!("fitting structure `{name}` ...");
        select(&req, &STRUCTURES, &work, Some(&stop), &progress)
    } else {
        identify_stoppable(&req, Some(&stop))
    };
    let id = match fitted {
        Ok(id) => id,
        Err(IdentifyError::Interrupted {
            signal,
            reached,
            pass,
        }) => return interrupted(stage, &req, &dest, signal, &reached, &pass),
        Err(e) => return Err(e.into()),
    };
    let sheet = write_staged(&id, &req, stage)?;
    if stop.load(Ordering::Relaxed) != 0 {
        // The signal came after the fit: the complete output is written; say so and end as interrupted.
        return Err(super::interrupted(
            stop.load(Ordering::Relaxed),
            format!(
                "came after the fit had finished; its output is complete in {}",
                dest.display()
            ),
        ));
    }
    print_result(&id, &sheet, &dest)
}

/// The request the options describe, each option checked first.
fn request_of(logs: Vec<PathBuf>, actuator: &Path, a: IdentifyArgs) -> anyhow::Result<Request> {
    let (segment_s, settle_s) = (a.segment_s, a.settle_s);
    if !(segment_s.is_finite() && segment_s > 0.0) {
        bail!("--segment: must be > 0 s, got {segment_s}");
    }
    if !(settle_s.is_finite() && settle_s >= 0.0 && settle_s < segment_s) {
        bail!("--settle: must be in [0, --segment) s, got {settle_s}");
    }
    if !(a.validation.is_finite() && (0.0..0.9).contains(&a.validation)) {
        bail!(
            "--validation: the held-out fraction must be in [0, 0.9), got {}",
            a.validation
        );
    }
    // Memory: a row is ~60 bytes of columns, held a few times over by the fit's segments.
    const MAX_ROWS_CEILING: usize = 10_000_000;
    if !(10..=MAX_ROWS_CEILING).contains(&a.limits.max_rows) {
        bail!(
            "--max-rows: in 10 ..= {MAX_ROWS_CEILING}, got {}",
            a.limits.max_rows
        );
    }
    if !(a.limits.max_span_s.is_finite() && a.limits.max_span_s > 0.0) {
        bail!("--max-log-s: must be > 0 s, got {}", a.limits.max_span_s);
    }
    let log_format = match (&a.log_format, &a.channel) {
        (Some(_), Some(_)) => {
            bail!(
                "--channel reads pneuflex's own recording; with --log-format name the actuator's columns in the format file"
            )
        }
        (Some(f), None) => pneuflex_identify::log_format::LogFormat::load(f)?,
        (None, Some(name)) => pneuflex_identify::log_format::LogFormat::channel(name)?,
        (None, None) => Default::default(),
    };
    Ok(Request {
        logs,
        actuator: actuator.to_path_buf(),
        free: a.free,
        bounds: a.bounds,
        limits: a.limits,
        log_format,
        figure_format: a.figure_format,
        validation_fraction: a.validation,
        options: FitOptions {
            replay: ReplayOptions {
                segment_s,
                settle_s,
                ..ReplayOptions::default()
            },
            ..FitOptions::default()
        },
    })
}

/// Prints the structure selection (with `--select`), the fitted values with their intervals, the
/// residuals, the model check and where the outputs are.
fn print_result(id: &Identified, sheet: &Path, dest: &Path) -> anyhow::Result<()> {
    if let Some(sel) = &id.report.structure_selection {
        outln!("structure selection ({}):", sel.criterion);
        for c in &sel.candidates {
            match &c.skipped {
                Some(why) => outln!("  {:<16} not fitted: {why}", c.structure),
                None => outln!(
                    "  {:<16} BIC {:>12.1}  fit {:>8.3}  held-out {:>8.3}  adequate {}{}{}",
                    c.structure,
                    c.bic,
                    c.fit_over_floor_sq,
                    c.validation_over_floor_sq,
                    c.adequate,
                    if c.screened {
                        "  (screened only)"
                    } else if c.significant {
                        ""
                    } else {
                        "  (effect not significant)"
                    },
                    if c.structure == sel.chosen {
                        "  <- chosen"
                    } else {
                        ""
                    }
                ),
            }
        }
        outln!("chosen: {}", sel.verdict);
    }
    let f = &id.report.fit;
    outln!(
        "{:<40} {:>14} {:>14} {:>32}",
        "key",
        "start",
        "fitted",
        "95 % interval"
    );
    for e in &f.estimates {
        outln!(
            "{:<40} {:>14.6e} {:>14.6e}   [{:.6e}, {:.6e}]{}",
            e.key,
            e.start,
            e.value,
            e.ci95[0],
            e.ci95[1],
            if e.interval_valid {
                ""
            } else {
                " (not valid: model not adequate)"
            }
        );
    }
    let validation = if id.data.iter().all(|d| d.validation.is_empty()) {
        "no held-out validation (--validation 0)".to_string()
    } else {
        format!(
            "held-out validation: p_a {:.0} Pa, p_b {:.0} Pa ({:.2} / {:.2} % of supply), x {:.3} mm",
            f.rms_validation[0],
            f.rms_validation[1],
            id.report.validation_pressure_pct_supply[0],
            id.report.validation_pressure_pct_supply[1],
            f.rms_validation[2] * 1e3
        )
    };
    outln!(
        "residual RMS (fit): p_a {:.0} Pa, p_b {:.0} Pa, x {:.3} mm; {validation}",
        f.rms_fit[0],
        f.rms_fit[1],
        f.rms_fit[2] * 1e3,
    );
    for w in &id.report.warnings {
        errln!("warning: {w}");
    }
    let mc = &id.report.model_check;
    if mc.adequate {
        outln!(
            "model check: adequate (residuals at the sensors' noise, white, held-out as good as fitted)"
        );
    } else {
        errln!("warning: model check: {}", mc.summary());
    }
    outln!(
        "fit took {:.1} s; fitted sheet: {}",
        id.report.fit_seconds,
        sheet.display()
    );
    outln!("report: {}", dest.join("report.md").display());
    Ok(())
}

/// Commits an interrupted fit as `<dest>.partial`: a report of the values reached, no fitted sheet.
fn interrupted(
    stage: OutputDir,
    req: &Request,
    dest: &Path,
    signal: usize,
    reached: &[(String, f64)],
    pass: &str,
) -> anyhow::Result<()> {
    let reason = pneuflex_scene::signal_name(signal);
    let mut md = format!(
        "# pneuflex identify: INTERRUPTED by {reason}\n\nThe fit was stopped during {pass}, before it \
         converged: the values below are where it was, with no intervals, and no fitted sheet was written. \
         Run the command again to finish it.\n\n| key | value reached |\n|---|---|\n"
    );
    for (k, v) in reached {
        let _ = writeln!(md, "| `{k}` | {v:e} |");
    }
    let _ = writeln!(md, "\nLogs:");
    for l in &req.logs {
        let _ = writeln!(md, "- {}", l.display());
    }
    std::fs::write(stage.path().join("report.md"), md).context("writing report.md")?;
    let json = serde_json::json!({
        "complete": false,
        "interrupted": reason,
        "pass": pass,
        "reached": reached.iter().map(|(k, v)| serde_json::json!({"key": k, "value": v})).collect::<Vec<_>>(),
    });
    std::fs::write(
        stage.path().join("report.json"),
        serde_json::to_string_pretty(&json)? + "\n",
    )
    .context("writing report.json")?;
    let to = stage.commit_partial(
        Manifest::new("identify", env!("CARGO_PKG_VERSION"), Vec::new()),
        Partial {
            reason,
            time_reached_s: 0.0,
            done: Some(format!("stopped during {pass}")),
        },
    )?;
    Err(super::interrupted(
        signal,
        format!(
            "the fit was stopped during {pass}; the values reached are in {} (not converged, no fitted \
             sheet); {} is untouched",
            to.join("report.md").display(),
            dest.display()
        ),
    ))
}
