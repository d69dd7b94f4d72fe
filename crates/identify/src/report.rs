//! The identification report: warnings for what the data cannot identify, `report.json`, `report.md` and
//! the validation overlay `validation-<i>.png` (or .svg, .pdf).

use std::fmt::Write as _;
use std::path::Path;

use pneuflex_plot::overlay::{Panel, Series, write_overlay};

use crate::IdentifyError;
use crate::check::ModelCheck;
use crate::fit::FitResult;
use crate::params::Key;
use crate::replay::Prediction;

/// An interval wider than this (half-width relative to the value, ±10 %) counts as poorly identified.
pub const WIDE_INTERVAL: f64 = 0.1;
/// A correlation above this (absolute) counts as not separable.
pub const HIGH_CORRELATION: f64 = 0.95;

/// Warnings for parameters the data cannot identify, each naming the experiment that would.
pub fn warnings(fit: &FitResult, keys: &[Key]) -> Vec<String> {
    let mut w = Vec::new();
    for (e, k) in fit.estimates.iter().zip(keys) {
        if !e.std_error.is_finite() {
            w.push(format!(
                "{}: not identifiable from these logs (they carry no information on it: the fit did not \
                 move it and its interval is unbounded); identify it with {}",
                e.key,
                k.experiment()
            ));
        } else if e.rel_half_width > WIDE_INTERVAL {
            w.push(format!(
                "{}: poorly identified (95 % interval +-{:.0} % of the value); identify it with {}",
                e.key,
                100.0 * e.rel_half_width,
                k.experiment()
            ));
        }
        if e.at_bound {
            w.push(format!(
                "{}: fitted value {} is on a bound [{}, {}]: widen --bounds, or the model misses \
                 something the data show",
                e.key, e.value, e.bounds[0], e.bounds[1]
            ));
        }
    }
    for a in 0..keys.len() {
        for b in a + 1..keys.len() {
            let r = fit.correlation[a][b];
            if r.abs() > HIGH_CORRELATION {
                w.push(format!(
                    "{} and {} are correlated (r = {r:.3}): these logs determine a combination of the two, \
                     not each; add {} (for {}) or fix one of them",
                    keys[a].name(),
                    keys[b].name(),
                    keys[a].experiment(),
                    keys[a].name()
                ));
            }
        }
    }
    w
}

/// The whole report as JSON-serialisable data.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Report {
    /// The logs: path, SHA-256, rows used for fitting and validation, and notes.
    pub logs: Vec<LogEntry>,
    /// The actuator sheet started from.
    pub sheet: String,
    /// The fit.
    pub fit: FitResult,
    /// Whether the model explains the logs (residuals against the noise floor, whiteness, held-out rows)
    /// and the likely missing effect; when not, every estimate's `interval_valid` is false.
    pub model_check: ModelCheck,
    /// Validation pressure RMS as % of the supply pressure (p_a, p_b).
    pub validation_pressure_pct_supply: [f64; 2],
    /// Warnings.
    pub warnings: Vec<String>,
    /// Wall time of the fit, s (for information only).
    pub fit_seconds: f64,
    /// `identify --select`: every candidate structure's fit and the choice (absent without it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub structure_selection: Option<Selection>,
}

/// One log in the report.
#[derive(Clone, Debug, serde::Serialize)]
pub struct LogEntry {
    /// The path as given.
    pub path: String,
    /// SHA-256 of its bytes.
    pub sha256: String,
    /// Rows read.
    pub rows: usize,
    /// Rows compared in the fit.
    pub fit_rows: usize,
    /// Rows compared in the validation.
    pub validation_rows: usize,
    /// Why rows were dropped or the trace is suspicious.
    pub note: Option<String>,
}

fn g(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        format!("{v}")
    } else if v.abs() >= 1e4 || v.abs() < 1e-2 {
        format!("{v:.4e}")
    } else {
        format!("{v:.4}")
    }
}

/// `v` with `digits` decimals, or a dash when it is not a number.
fn fixed(v: f64, digits: usize) -> String {
    if v.is_finite() {
        format!("{v:.digits$}")
    } else {
        "–".to_string()
    }
}

/// The report as Markdown.
pub fn markdown(r: &Report) -> String {
    let mut s = String::new();
    let f = &r.fit;
    let _ = writeln!(s, "# Identification report\n");
    let mc = &r.model_check;
    if !mc.adequate {
        let _ = writeln!(
            s,
            "**The model does not explain these logs: the intervals below are not valid.** The residuals \
             are not the sensors' noise ({}). A rig richer than the model biases the estimates by an amount \
             the intervals do not include; a truth may lie outside them. Likely missing: {}. Add the effect \
             to the sheet and free its keys, then fit again.\n",
            mc.failed.join("; "),
            mc.likely_missing
                .iter()
                .map(|m| format!("**{}** ({}; `{}`)", m.effect, m.evidence, m.keys))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let _ = writeln!(s, "Sheet: `{}`\n", r.sheet);
    if let Some(sel) = &r.structure_selection {
        structure_table(&mut s, sel);
    }
    let _ = writeln!(
        s,
        "| log | sha256 | rows | fit rows | validation rows | note |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|");
    for l in &r.logs {
        let _ = writeln!(
            s,
            "| `{}` | `{}` | {} | {} | {} | {} |",
            l.path,
            l.sha256,
            l.rows,
            l.fit_rows,
            l.validation_rows,
            l.note.as_deref().unwrap_or("")
        );
    }
    let _ = writeln!(
        s,
        "\n## Estimates (95 % intervals: value +- (1.96 std error + replay bias bound), widened to hold the \
         truth under any effect the model lacks in the amounts the residuals allow{})\n",
        if mc.adequate {
            ""
        } else {
            "; NOT VALID: the model check failed, see the top"
        }
    );
    let _ = writeln!(
        s,
        "| key | start | fitted | 95 % interval | +- % | std error | replay bias | widened for | bounds |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|");
    for e in &f.estimates {
        let widened = e.widened.as_ref().map_or("–".to_string(), |w| {
            format!(
                "{} ({} to {} probes; before [{}, {}])",
                w.probe,
                fixed(w.amounts[0], 2),
                fixed(w.amounts[1], 2),
                g(w.noise_ci95[0]),
                g(w.noise_ci95[1])
            )
        });
        let _ = writeln!(
            s,
            "| `{}` | {} | {} | [{}, {}] | {:.2} | {} | {} | {} | [{}, {}] |",
            e.key,
            g(e.start),
            g(e.value),
            g(e.ci95[0]),
            g(e.ci95[1]),
            100.0 * e.rel_half_width,
            g(e.std_error),
            g(e.bias),
            widened,
            g(e.bounds[0]),
            g(e.bounds[1])
        );
    }
    correlation_section(&mut s, f);
    residual_section(&mut s, r);
    model_check_section(&mut s, mc);
    let _ = writeln!(s, "\n## Warnings\n");
    if r.warnings.is_empty() {
        let _ = writeln!(s, "None: every free parameter is identified by these logs.");
    }
    for w in &r.warnings {
        let _ = writeln!(s, "- {w}");
    }
    s
}

/// The estimates' correlation matrix.
fn correlation_section(s: &mut String, f: &FitResult) {
    let _ = writeln!(s, "\n## Correlation matrix\n");
    let _ = write!(s, "| |");
    for i in 0..f.estimates.len() {
        let _ = write!(s, " {} |", i + 1);
    }
    let _ = write!(s, "\n|---|");
    for _ in &f.estimates {
        let _ = write!(s, "---|");
    }
    let _ = writeln!(s);
    for (i, row) in f.correlation.iter().enumerate() {
        let _ = write!(s, "| {} `{}` |", i + 1, f.estimates[i].key);
        for v in row {
            let _ = write!(s, " {v:.3} |");
        }
        let _ = writeln!(s);
    }
}

/// The residual RMS per signal (start, fitted, held out) and the fit's figures.
fn residual_section(s: &mut String, r: &Report) {
    let f = &r.fit;
    let _ = writeln!(s, "\n## Residual RMS per signal\n");
    let _ = writeln!(s, "| | p_a [kPa] | p_b [kPa] | x [mm] |");
    let _ = writeln!(s, "|---|---|---|---|");
    let held_out = f.rms_validation.iter().all(|v| v.is_finite());
    for (name, v) in [
        ("start values, fit rows", f.rms_start),
        ("fitted, fit rows", f.rms_fit),
        ("fitted, held-out validation rows", f.rms_validation),
    ] {
        if !v.iter().all(|x| x.is_finite()) {
            let _ = writeln!(s, "| {name} | – | – | – |");
            continue;
        }
        let _ = writeln!(
            s,
            "| {name} | {:.3} | {:.3} | {:.4} |",
            v[0] * 1e-3,
            v[1] * 1e-3,
            v[2] * 1e3
        );
    }
    let validation = if held_out {
        format!(
            "Validation pressure RMS: {:.3} % (p_a), {:.3} % (p_b) of the supply pressure.",
            r.validation_pressure_pct_supply[0], r.validation_pressure_pct_supply[1],
        )
    } else {
        "No rows were held out for validation (--validation 0): the fit is judged on the rows it fitted only."
            .to_string()
    };
    let _ = writeln!(
        s,
        "\n{validation} {} rows fitted; weighted residual variance {:.3}; LM: {}; {} replays of the logs; fit \
         took {:.1} s.",
        f.rows,
        f.residual_variance,
        f.termination.join(", "),
        f.evaluations,
        r.fit_seconds
    );
}

/// The model check: each channel's floor, whiteness and held-out ratio, the limits and the signatures.
fn model_check_section(s: &mut String, mc: &ModelCheck) {
    let _ = writeln!(
        s,
        "\n## Model check: {}\n",
        if mc.adequate {
            "adequate (the residuals are the sensors' noise)"
        } else {
            "NOT adequate (intervals not valid)"
        }
    );
    let _ = writeln!(
        s,
        "| | floor | fit RMS / floor | mean abs autocorrelation, lags 1-{} | lags outside +-1.96/sqrt(N) | \
         Ljung-Box Q | held-out RMS / fit RMS |",
        crate::check::LAGS
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for c in &mc.channels {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} % | {} | {} |",
            c.signal,
            g(c.floor),
            fixed(c.floor_ratio, 2),
            fixed(c.mean_abs_autocorrelation, 3),
            fixed(100.0 * c.lags_outside_fraction, 0),
            fixed(c.ljung_box, 0),
            // No held-out rows (--validation 0): nothing to compare, not NaN.
            fixed(c.validation_ratio, 2)
        );
    }
    let _ = writeln!(
        s,
        "\nLimits: RMS / floor <= {}, mean |autocorrelation| <= {}, held-out / fit <= {}. Floor: the larger \
         of the readings' step / sqrt(12) and their scatter on still stretches ({} rows). A probe's amount \
         more than {} standard errors beyond the effect's absence names it. Signatures (|r|; amount the \
         residuals carry, in probes): {}.",
        mc.thresholds.max_floor_ratio,
        mc.thresholds.max_mean_abs_autocorrelation,
        mc.thresholds.max_validation_ratio,
        mc.channels.first().map_or(0, |c| c.still_rows),
        mc.thresholds.detect_z,
        mc.signatures
            .iter()
            .map(|g| {
                if g.modelled {
                    format!("{} ({}) modelled and fitted", g.effect, g.probe)
                } else {
                    format!(
                        "{} ({}) {:.2}; {} +- {}",
                        g.effect,
                        g.probe,
                        g.correlation,
                        fixed(g.amount, 3),
                        fixed(g.amount_se, 3)
                    )
                }
            })
            .collect::<Vec<_>>()
            .join(", ")
    );
}

/// The `--select` table: every candidate structure with its figures, the chosen one first in words.
fn structure_table(s: &mut String, sel: &Selection) {
    let _ = writeln!(
        s,
        "## Structure selection\n\nChosen: {}.\n\nCriterion: {}.\n",
        sel.verdict, sel.criterion
    );
    let _ = writeln!(
        s,
        "| structure | adds | free keys | BIC | fit (res/floor)^2 | held-out (res/floor)^2 | adequate | fit s |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|");
    for c in &sel.candidates {
        let mark = if c.structure == sel.chosen {
            " **(chosen)**"
        } else if c.screened {
            " (screened only)"
        } else if !c.significant {
            " (effect not significant)"
        } else {
            ""
        };
        match &c.skipped {
            Some(why) => {
                let _ = writeln!(
                    s,
                    "| `{}` | {} | {} | not fitted: {why} | | | | |",
                    c.structure,
                    c.adds,
                    c.keys.len()
                );
            }
            None => {
                let _ = writeln!(
                    s,
                    "| `{}`{mark} | {} | {} | {:.1} | {:.3} | {:.3} | {} | {:.1} |",
                    c.structure,
                    c.adds,
                    c.keys.len(),
                    c.bic,
                    c.fit_over_floor_sq,
                    c.validation_over_floor_sq,
                    c.adequate,
                    c.fit_seconds
                );
            }
        }
    }
    let _ = writeln!(s);
}

/// How much of the held-out part the validation figure shows, s (20 periods of the paper's 40 Hz PWM).
pub const VALIDATION_WINDOW_S: f64 = 0.5;

/// Draws the first [`VALIDATION_WINDOW_S`] of the held-out rows of one log: measured against simulated p_a,
/// p_b and x, each with its residual (measured - model) in a panel of its own.
pub fn validation_figure(
    path: &Path,
    log: &crate::log::Log,
    pred: &Prediction,
    rows: &[usize],
) -> Result<(), IdentifyError> {
    if rows.is_empty() {
        return Ok(());
    }
    // A readable window: the first VALIDATION_WINDOW_S of the held-out rows (a whole validation part of
    // seconds overlays dozens of PWM cycles into a band).
    let a = rows[0];
    let end_t = log.t[a] + VALIDATION_WINDOW_S;
    let b = rows
        .iter()
        .copied()
        .take_while(|&k| log.t[k] <= end_t)
        .last()
        .unwrap_or(a)
        + 1;
    let t = &log.t[a..b];
    let kpa = |v: &[f64]| v.iter().map(|p| p * 1e-3).collect::<Vec<f64>>();
    let mm = |v: &[f64]| v.iter().map(|p| p * 1e3).collect::<Vec<f64>>();
    // Rows inside a segment's settling time are not compared: drawn as gaps in the simulation.
    let mut keep = vec![false; b - a];
    for &k in rows.iter().filter(|&&k| k < b) {
        keep[k - a] = true;
    }
    let gap = |v: Vec<f64>| -> Vec<f64> {
        v.into_iter()
            .zip(&keep)
            .map(|(x, &k)| if k { x } else { f64::NAN })
            .collect()
    };
    let (ma, sa) = (kpa(&log.p_a[a..b]), gap(kpa(&pred.p_a[a..b])));
    let (mb, sb) = (kpa(&log.p_b[a..b]), gap(kpa(&pred.p_b[a..b])));
    let (mx, sx) = (mm(&log.x[a..b]), gap(mm(&pred.x[a..b])));
    // The residuals, measured - model, where compared.
    let res = |m: &[f64], s: &[f64]| -> Vec<f64> { m.iter().zip(s).map(|(m, s)| m - s).collect() };
    let (ra, rb, rx) = (res(&ma, &sa), res(&mb, &sb), res(&mx, &sx));
    fn panel<'a>(title: &str, unit: &str, t: &'a [f64], lines: &[(&str, &'a [f64])]) -> Panel<'a> {
        Panel {
            title: title.into(),
            y_desc: unit.into(),
            series: lines
                .iter()
                .map(|&(label, y)| Series {
                    label: label.into(),
                    t,
                    y,
                })
                .collect(),
            // A residual is read against zero.
            include_zero: title.contains("residual"),
        }
    }
    let name = log
        .path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let (m, f) = ("measured", "fitted model");
    write_overlay(
        path,
        &[
            panel(
                &format!(
                    "held-out validation of {name}, t = {:.2}-{:.2} s: chamber A pressure",
                    log.t[a],
                    log.t[b - 1]
                ),
                "p_a [kPa abs]",
                t,
                &[(m, &ma), (f, &sa)],
            ),
            panel(
                "chamber B pressure",
                "p_b [kPa abs]",
                t,
                &[(m, &mb), (f, &sb)],
            ),
            panel(
                "pressure residual, measured - model",
                "[kPa]",
                t,
                &[("p_a", &ra), ("p_b", &rb)],
            ),
            panel("position", "x [mm]", t, &[(m, &mx), (f, &sx)]),
            panel(
                "position residual, measured - model",
                "[mm]",
                t,
                &[("x", &rx)],
            ),
        ],
    )
    .map_err(|e| IdentifyError::Output {
        file: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// One structure's fit, as the report gives it.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Candidate {
    /// The structure's name.
    pub structure: &'static str,
    /// What it adds to the sheet, in words.
    pub adds: &'static str,
    /// Its free keys (the user's and the structure's).
    pub keys: Vec<String>,
    /// Why it was not fitted (the sheet has the effect already, or the valve has no spool to move), or
    /// why its fit failed; the figures below are then absent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub skipped: Option<String>,
    /// Bayesian information criterion on the fit rows: n ln(mean squared residual / floor^2) + k ln n, with
    /// n the rows times the three channels and k the free keys (lower is better; null when not fitted).
    pub bic: f64,
    /// Mean squared residual over the noise floor squared, on the fit rows.
    pub fit_over_floor_sq: f64,
    /// The same on the held-out rows.
    pub validation_over_floor_sq: f64,
    /// The model check's verdict on this structure's fit.
    pub adequate: bool,
    /// Whether the effect is there: one of its keys' 95 % interval excludes its absence (0 for a leak, wall
    /// heat, the seal term, spool travel); always for another friction law, which has no absent value. An
    /// effect whose size the logs cannot tell from none is not chosen, whatever its BIC.
    pub significant: bool,
    /// Whether only the screening fit was made (`identify --select`'s first stage: a short
    /// Levenberg-Marquardt from the sheet as given's fit, no intervals): the figures are the screen's, its
    /// BIC above the chosen structure's by more than the full fit could change it, and `adequate` and
    /// `significant` are not judged (false).
    pub screened: bool,
    /// The fit's wall time, s.
    pub fit_seconds: f64,
}

/// The report's `structure_selection`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Selection {
    /// How the choice is made.
    pub criterion: &'static str,
    /// Every structure, in the order the selection tried them.
    pub candidates: Vec<Candidate>,
    /// The chosen structure's name.
    pub chosen: &'static str,
    /// Why, in words (and whether it explains the logs).
    pub verdict: String,
}
