//! A tune's files: the tuned scene (a copy with the new values and a comment saying how they were found),
//! `convergence.png`, `report.md` (the objective per environment before and after, every run's terms),
//! `history.csv` (every candidate) and `tune.json`.

use std::fmt::Write as _;
use std::path::Path;

use crate::engine::{SweepError, fmt_f64};
use crate::tune::{EnvEval, Evaluation, HistoryRow, TuneOptions, Tuner, round4};

/// What a tune found: before and after, in numbers.
#[derive(Clone, Debug, serde::Serialize)]
pub struct TuneSummary {
    /// The free keys.
    pub keys: Vec<String>,
    /// Their values in the scene as written (clamped into the box).
    pub before: Vec<f64>,
    /// Their tuned values (four significant digits, as written into the tuned scene).
    pub after: Vec<f64>,
    /// Worst-case objective before (∞ is written as null in JSON).
    pub j_before: f64,
    /// Worst-case objective after.
    pub j_after: f64,
    /// Candidates evaluated.
    pub evaluations: usize,
    /// CMA-ES generations.
    pub generations: usize,
    /// The tuned scene's file name; None when none was written (see `kept_start`).
    pub tuned_scene: Option<String>,
    /// Why no tuned scene was written and the start is kept: the search found nothing better, the best
    /// candidate's scene does not load, or the search was interrupted.
    pub kept_start: Option<String>,
    /// The signal that interrupted the search (a partial output), if one did.
    pub interrupted: Option<String>,
}

fn j_text(j: f64) -> String {
    if j.is_finite() {
        format!("{j:.4}")
    } else {
        "∞".into()
    }
}

fn v_text(v: Option<f64>) -> String {
    match v {
        Some(x) if x.is_finite() => format!("{x:.4}"),
        Some(_) => "∞".into(),
        None => "–".into(),
    }
}

/// The best evaluation of the search (lowest rank; the first such in history order).
pub fn best(history: &[HistoryRow]) -> Option<&Evaluation> {
    history
        .iter()
        .map(|h| &h.eval)
        .reduce(|a, b| if b.rank < a.rank { b } else { a })
}

/// Writes the outputs of a search into `dir`; `command` is the command line (for the comment). A tuned
/// scene is written only when the best candidate, as written (four significant digits), loads and is no
/// worse than the start; otherwise the report says why and the start is kept. `interrupted` (the signal's
/// name) marks a search stopped early: its history and report are written, no tuned scene.
pub fn write(
    dir: &Path,
    tuner: &Tuner,
    opts: &TuneOptions,
    history: &[HistoryRow],
    command: &str,
    interrupted: Option<&str>,
    figures: pneuflex_plot::Format,
) -> Result<TuneSummary, SweepError> {
    let io = |p: &Path, e: std::io::Error| {
        SweepError::Other(format!("{}: cannot write: {e}", p.display()))
    };
    let best = best(history);
    // The start as the file writes it (the search starts from it clamped into the box; a key the file
    // leaves to its default starts at the box's middle).
    let before: Vec<f64> = tuner
        .as_written
        .iter()
        .zip(&tuner.initial)
        .map(|(w, i)| w.unwrap_or(*i))
        .collect();
    let after: Vec<f64> = best.map_or(before.clone(), |b| b.x.iter().map(|v| round4(*v)).collect());
    let (all_before, all_after) = every_run_before_after(tuner, &after, interrupted);
    let (j_before, j_after) =
        worst_case_before_after(tuner, history, best, &all_before, &all_after, interrupted);
    let generations = history.last().map_or(0, |h| h.generation);
    let population = opts.population_for(tuner.free.len());
    let objective = objective_text(tuner);

    // The tuned scene.
    let stem = tuner
        .scene_path
        .file_stem()
        .map_or("scene".into(), |s| s.to_string_lossy().into_owned());
    let tuned_name = format!("{stem}-tuned.toml");
    let outcome = Outcome {
        command,
        objective: &objective,
        population,
        generations,
        before: &before,
        after: &after,
        j_before,
        j_after,
    };
    let comment = tuned_comment(tuner, opts, history.len(), &outcome);
    let text = tuner.tuned_text(&after, &comment, dir)?;
    let kept_start = why_start_kept(
        &text,
        &dir.join(&tuned_name),
        dir,
        history.len(),
        &outcome,
        interrupted,
    );
    if kept_start.is_none() {
        let tuned_path = dir.join(&tuned_name);
        std::fs::write(&tuned_path, text).map_err(|e| io(&tuned_path, e))?;
    }

    let (csv, candidates, best_line) = history_csv(tuner, history);
    let hist_path = dir.join("history.csv");
    std::fs::write(&hist_path, csv).map_err(|e| io(&hist_path, e))?;
    convergence_figure(dir, tuner, &candidates, &best_line, figures)?;

    // The report.
    let mut r = report_head(
        tuner,
        opts,
        history.len(),
        &outcome,
        interrupted,
        kept_start.as_deref(),
        &tuned_name,
    );
    if interrupted.is_none() {
        report_tables(&mut r, tuner, &all_before, &all_after);
    }
    let rep = dir.join("report.md");
    std::fs::write(&rep, r).map_err(|e| io(&rep, e))?;
    let tuned = kept_start.is_none().then_some(tuned_name);
    finish(
        dir,
        tuner,
        history,
        before,
        after,
        j_before,
        j_after,
        generations,
        tuned,
        kept_start,
        interrupted,
    )
}

/// The objective as the tuned scene's comment and the report state it: the worst case over the
/// environments of the weighted terms of the tuned run.
fn objective_text(tuner: &Tuner) -> String {
    let run_name = &tuner.base_scene.runs()[tuner.run].name;
    let terms_text: Vec<String> = tuner
        .terms
        .iter()
        .map(|t| format!("{} × |{}|", t.weight, t.name()))
        .collect();
    format!(
        "J = max over the environments of J_e, J_e = {} of run `{run_name}`; J_e = ∞ when the run diverged or an event window did not settle",
        terms_text.join(" + ")
    )
}

/// Before and after as the files have them: every run, every environment (not re-run for an
/// interrupted search: the user asked it to stop).
fn every_run_before_after(
    tuner: &Tuner,
    after: &[f64],
    interrupted: Option<&str>,
) -> (Vec<Vec<EnvEval>>, Vec<Vec<EnvEval>>) {
    if interrupted.is_none() {
        (
            tuner.evaluate_all_runs(None),
            tuner.evaluate_all_runs(Some(after)),
        )
    } else {
        (Vec::new(), Vec::new())
    }
}

/// The tuned run's worst-case J over the environments, before and after; for an interrupted search, the
/// first candidate's and the best one's, as the search evaluated them.
fn worst_case_before_after(
    tuner: &Tuner,
    history: &[HistoryRow],
    best: Option<&Evaluation>,
    all_before: &[Vec<EnvEval>],
    all_after: &[Vec<EnvEval>],
    interrupted: Option<&str>,
) -> (f64, f64) {
    let worst = |all: &[Vec<EnvEval>]| {
        all.iter()
            .map(|e| e[tuner.run].j)
            .fold(f64::NEG_INFINITY, f64::max)
    };
    if interrupted.is_none() {
        (worst(all_before), worst(all_after))
    } else {
        let j0 = history.first().map_or(f64::INFINITY, |h| h.eval.j);
        (j0, best.map_or(f64::INFINITY, |b| b.j))
    }
}

/// convergence.png (or .svg, .pdf): each candidate's worst-case J and the best so far, by evaluation.
fn convergence_figure(
    dir: &Path,
    tuner: &Tuner,
    candidates: &[(f64, f64)],
    best_line: &[(f64, f64)],
    figures: pneuflex_plot::Format,
) -> Result<(), SweepError> {
    let run_name = &tuner.base_scene.runs()[tuner.run].name;
    let conv_name = format!("convergence.{}", figures.ext());
    let conv = dir.join(&conv_name);
    match pneuflex_plot::write_convergence(
        &conv,
        &format!(
            "tune {}: run `{run_name}`, worst case over the environments",
            tuner.base_scene.name()
        ),
        "J (worst case)",
        candidates,
        best_line,
    ) {
        Ok(()) => Ok(()),
        // Every candidate infinite: nothing to draw; the report says so.
        Err(pneuflex_plot::PlotError::Empty) => Ok(()),
        Err(e) => Err(SweepError::Other(e.to_string())),
    }
}

/// The report's head: the command, the objective, the search, each free key before and after, the worst
/// case, and whether a tuned scene was written (`kept_start`: why not).
fn report_head(
    tuner: &Tuner,
    opts: &TuneOptions,
    candidates: usize,
    o: &Outcome,
    interrupted: Option<&str>,
    kept_start: Option<&str>,
    tuned_name: &str,
) -> String {
    let run_name = &tuner.base_scene.runs()[tuner.run].name;
    let mut r = String::new();
    let _ = writeln!(r, "# pneuflex tune: {}\n", tuner.base_scene.name());
    if let Some(sig) = interrupted {
        let _ = writeln!(
            r,
            "**Interrupted by {sig}: a partial search of {} candidate(s), not the result of the budget asked \
             for. No tuned scene is written.**\n",
            candidates
        );
    }
    let _ = writeln!(r, "Command: `{}`\n", o.command);
    let _ = writeln!(r, "Objective: {}.\n", o.objective);
    let _ = writeln!(
        r,
        "Search: CMA-ES (cmaes crate), seed {}, population {}, budget {}, {} candidates in {} generations, each over {} environment(s).\n",
        opts.seed,
        o.population,
        opts.budget,
        candidates,
        o.generations,
        tuner.envs.len()
    );
    let _ = writeln!(r, "| key | box | before | after |\n|---|---|---|---|");
    for (f, (b, a)) in tuner.free.iter().zip(o.before.iter().zip(o.after)) {
        let _ = writeln!(
            r,
            "| `{}` | {}[{}, {}] | {b} | {a} |",
            f.key.text,
            if f.log { "log" } else { "" },
            f.lo,
            f.hi
        );
    }
    let _ = writeln!(
        r,
        "\nWorst-case J of `{run_name}`: **{} → {}**{}.\n",
        j_text(o.j_before),
        j_text(o.j_after),
        if interrupted.is_some() {
            " (the first candidate's and the best one's, as the search evaluated them)"
        } else {
            ""
        }
    );
    match kept_start {
        Some(why) => {
            let _ = writeln!(r, "**No tuned scene: {why}.**\n");
        }
        None => {
            let _ = writeln!(r, "Tuned scene: `{tuned_name}`.\n");
        }
    }
    r
}

/// What the search did, as the tuned scene's comment and the report state it.
struct Outcome<'a> {
    command: &'a str,
    objective: &'a str,
    population: usize,
    generations: usize,
    /// The free keys' values before (as the file writes them) and after (the best candidate, as written).
    before: &'a [f64],
    after: &'a [f64],
    /// The worst-case objective before and after.
    j_before: f64,
    j_after: f64,
}

/// The tuned scene's head comment: the command, the search, the objective, each free key's change.
fn tuned_comment(tuner: &Tuner, opts: &TuneOptions, candidates: usize, o: &Outcome) -> String {
    let Outcome {
        command,
        objective,
        population,
        generations,
        before,
        after,
        j_before,
        j_after,
    } = *o;
    let mut comment = String::new();
    let _ = writeln!(comment, "Tuned by `{command}`:");
    let _ = writeln!(
        comment,
        "CMA-ES (cmaes crate), seed {}, population {population}, {} candidates in {generations} generations.",
        opts.seed, candidates
    );
    let _ = writeln!(comment, "Objective: {objective}.");
    if !tuner.envs.keys.is_empty() {
        let _ = writeln!(comment, "Environments: {}.", tuner.over_specs.join(", "));
    }
    for (f, (b, a)) in tuner.free.iter().zip(before.iter().zip(after)) {
        let _ = writeln!(
            comment,
            "{} in {}[{}, {}]: {} -> {}",
            f.key.text,
            if f.log { "log" } else { "" },
            f.lo,
            f.hi,
            b,
            a
        );
    }
    let _ = writeln!(
        comment,
        "Worst-case J: {} -> {} (report.md beside this file: per environment, every run).",
        j_text(j_before),
        j_text(j_after)
    );
    comment
}

/// Why the start is kept instead of a tuned scene (None: the tuned scene is written): an interrupted
/// search, a best candidate whose scene `text` (to be written at `tuned_path`) does not load, or one no
/// better than the start.
fn why_start_kept(
    text: &str,
    tuned_path: &Path,
    dir: &Path,
    candidates: usize,
    o: &Outcome,
    interrupted: Option<&str>,
) -> Option<String> {
    let (j_before, j_after) = (o.j_before, o.j_after);
    if let Some(sig) = interrupted {
        Some(format!(
            "the search was interrupted by {sig} after {} candidate(s): no tuned scene",
            candidates
        ))
    } else if let Err(e) =
        pneuflex_scene::AnyScene::from_toml_str(text, tuned_path, dir).and_then(|s| {
            // Loading the sheet (and the URDF) is part of loading: a plant that cannot be built does not load.
            s.check_builds()
        })
    {
        Some(format!(
            "the best candidate's scene does not load ({e}); the start is kept"
        ))
    } else if !matches!(
        j_after.partial_cmp(&j_before),
        Some(std::cmp::Ordering::Less | std::cmp::Ordering::Equal)
    ) || (!j_after.is_finite() && !j_before.is_finite())
    {
        Some(format!(
            "the search found nothing better than the start (worst-case J {} before, {} for the best \
             candidate as written); the start is kept",
            j_text(j_before),
            j_text(j_after)
        ))
    } else {
        None
    }
}

/// history.csv's text, with each candidate's J and the best J so far, by evaluation (for the convergence
/// figure).
#[allow(clippy::type_complexity)]
fn history_csv(
    tuner: &Tuner,
    history: &[HistoryRow],
) -> (String, Vec<(f64, f64)>, Vec<(f64, f64)>) {
    let mut csv = String::from("evaluation,generation");
    for f in &tuner.free {
        csv.push(',');
        csv.push_str(&f.key.text.replace(',', ";"));
    }
    csv.push_str(",j,rank");
    for e in 0..tuner.envs.len() {
        let _ = write!(csv, ",j_env{e}");
    }
    csv.push('\n');
    let mut best_so_far = f64::INFINITY;
    let mut candidates = Vec::new();
    let mut best_line = Vec::new();
    for (i, h) in history.iter().enumerate() {
        let _ = write!(csv, "{},{}", i + 1, h.generation);
        for v in &h.eval.x {
            let _ = write!(csv, ",{}", fmt_f64(*v));
        }
        let _ = write!(csv, ",{},{}", fmt_f64(h.eval.j), fmt_f64(h.eval.rank));
        for e in &h.eval.envs {
            let _ = write!(csv, ",{}", fmt_f64(e.j));
        }
        csv.push('\n');
        candidates.push(((i + 1) as f64, h.eval.j));
        best_so_far = best_so_far.min(h.eval.j);
        best_line.push(((i + 1) as f64, best_so_far));
    }
    (csv, candidates, best_line)
}

/// The report's tables: the tuned run's J_e per environment, and every run's terms, before → after.
fn report_tables(
    r: &mut String,
    tuner: &Tuner,
    all_before: &[Vec<EnvEval>],
    all_after: &[Vec<EnvEval>],
) {
    let run_name = &tuner.base_scene.runs()[tuner.run].name;
    let _ = writeln!(r, "## J_e of `{run_name}` per environment\n");
    let _ = writeln!(
        r,
        "| environment | J_e before | J_e after | after: status |\n|---|---|---|---|"
    );
    for e in 0..tuner.envs.len() {
        let _ = writeln!(
            r,
            "| {} | {} | {} | {} |",
            tuner.describe_env(e),
            j_text(all_before[e][tuner.run].j),
            j_text(all_after[e][tuner.run].j),
            all_after[e][tuner.run].status
        );
    }
    let _ = writeln!(r, "\n## Every run's terms, before → after\n");
    let mut head = String::from("| environment | run | J_e |");
    let mut rule = String::from("|---|---|---|");
    for t in &tuner.terms {
        let _ = write!(head, " {} |", t.name());
        rule.push_str("---|");
    }
    let _ = writeln!(r, "{head}\n{rule}");
    for e in 0..tuner.envs.len() {
        for (k, run) in tuner.base_scene.runs().iter().enumerate() {
            let (b, a) = (&all_before[e][k], &all_after[e][k]);
            let mut line = format!(
                "| {} | {} | {} → {} |",
                tuner.describe_env(e),
                run.name,
                j_text(b.j),
                j_text(a.j)
            );
            for (tb, ta) in b.terms.iter().zip(&a.terms) {
                let _ = write!(line, " {} → {} |", v_text(*tb), v_text(*ta));
            }
            let _ = writeln!(r, "{line}");
        }
    }
    let _ = writeln!(
        r,
        "\nThe free keys apply to the scene as the tuned file has them; runs whose keys are not free keep their values (their change, if any, comes from shared keys)."
    );
}

/// Writes tune.json and returns the summary.
#[allow(clippy::too_many_arguments)]
fn finish(
    dir: &Path,
    tuner: &Tuner,
    history: &[HistoryRow],
    before: Vec<f64>,
    after: Vec<f64>,
    j_before: f64,
    j_after: f64,
    generations: usize,
    tuned_scene: Option<String>,
    kept_start: Option<String>,
    interrupted: Option<&str>,
) -> Result<TuneSummary, SweepError> {
    let io = |p: &Path, e: std::io::Error| {
        SweepError::Other(format!("{}: cannot write: {e}", p.display()))
    };
    let summary = TuneSummary {
        keys: tuner.free.iter().map(|f| f.key.text.clone()).collect(),
        before,
        after,
        j_before,
        j_after,
        evaluations: history.len(),
        generations,
        tuned_scene,
        kept_start,
        interrupted: interrupted.map(str::to_string),
    };
    let json = dir.join("tune.json");
    let text =
        serde_json::to_string_pretty(&summary).map_err(|e| SweepError::Other(e.to_string()))?;
    std::fs::write(&json, text + "\n").map_err(|e| io(&json, e))?;
    Ok(summary)
}
