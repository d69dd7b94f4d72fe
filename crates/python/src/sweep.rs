//! Sweeps and tuning from Python (`pneuflex.sweep`, `pneuflex.tune` in python/pneuflex/sweeps.py): the Rust
//! engine of `crates/sweep`, split so that an executor can run chunks of points (or candidates) elsewhere —
//! a Ray task calls `sweep_rows` / `tune_evaluate` on its share — and gather them into the same table (or
//! search) as the local thread pool.

use std::path::PathBuf;

use pneuflex_files::OutputDir;
use pneuflex_files::output::{Manifest, Writer};
use pneuflex_sweep::points::DEFAULT_MAX_POINTS;
use pneuflex_sweep::tune::{Evaluation, FreeArg, Term, TuneOptions, Tuner};
use pneuflex_sweep::{SetArg, Sweep, SweepError};
use pyo3::prelude::*;

use crate::errors;

fn err(e: SweepError) -> PyErr {
    match e {
        SweepError::Scene(s) => errors::scene(s),
        other => errors::other(other),
    }
}

fn sets(specs: &[String]) -> PyResult<Vec<SetArg>> {
    specs
        .iter()
        .map(|s| SetArg::parse(s).map_err(|e| err(e.into())))
        .collect()
}

/// Checks every point of a sweep (the scene's own validation, before anything runs) and returns
/// `(number of points, the table's header line)`.
#[pyfunction]
#[pyo3(signature = (scene_path, sets, samples=None, seed=0))]
pub fn sweep_plan(
    py: Python<'_>,
    scene_path: crate::shipped::ScenePath,
    sets: Vec<String>,
    samples: Option<usize>,
    seed: u64,
) -> PyResult<(usize, String)> {
    let s = self::sets(&sets)?;
    let sweep = py
        .detach(|| Sweep::new(&scene_path, &s, samples, seed, DEFAULT_MAX_POINTS))
        .map_err(err)?;
    Ok((sweep.len(), sweep.header()))
}

/// Runs the points `indices` of a sweep on `threads` threads (0: one per core) with the GIL released and
/// returns their table rows (sweep.csv's lines, in the order of `indices`).
#[pyfunction]
#[pyo3(signature = (scene_path, sets, indices, samples=None, seed=0, threads=0))]
pub fn sweep_rows(
    py: Python<'_>,
    scene_path: crate::shipped::ScenePath,
    sets: Vec<String>,
    indices: Vec<usize>,
    samples: Option<usize>,
    seed: u64,
    threads: usize,
) -> PyResult<String> {
    let s = self::sets(&sets)?;
    py.detach(|| -> Result<String, SweepError> {
        let sweep = Sweep::new_unchecked(&scene_path, &s, samples, seed, DEFAULT_MAX_POINTS)?;
        if let Some(i) = indices.iter().find(|&&i| i >= sweep.len()) {
            return Err(SweepError::Other(format!(
                "point {i}: the sweep has {} points",
                sweep.len()
            )));
        }
        let results = sweep.run(&indices, threads, None, &|| {})?;
        Ok(results.iter().map(|p| sweep.rows(p)).collect())
    })
    .map_err(err)
}

fn tuner(
    scene_path: &std::path::Path,
    free: &[String],
    over: &[String],
    run: Option<&str>,
    terms: &[String],
) -> Result<Tuner, SweepError> {
    let free = free
        .iter()
        .map(|s| FreeArg::parse(s))
        .collect::<Result<Vec<_>, _>>()?;
    let over = over
        .iter()
        .map(|s| SetArg::parse(s).map_err(SweepError::from))
        .collect::<Result<Vec<_>, _>>()?;
    let terms = terms
        .iter()
        .map(|s| Term::parse(s))
        .collect::<Result<Vec<_>, _>>()?;
    Tuner::new(scene_path, free, &over, run, terms, DEFAULT_MAX_POINTS)
}

/// One candidate of a tune, evaluated here: its text form (`Evaluation::encode`), for a remote executor.
#[pyfunction]
#[pyo3(signature = (scene_path, free, over, x, run=None, terms=Vec::new()))]
pub fn tune_evaluate(
    py: Python<'_>,
    scene_path: crate::shipped::ScenePath,
    free: Vec<String>,
    over: Vec<String>,
    x: Vec<f64>,
    run: Option<String>,
    terms: Vec<String>,
) -> PyResult<String> {
    py.detach(|| -> Result<String, SweepError> {
        let t = tuner(&scene_path, &free, &over, run.as_deref(), &terms)?;
        if x.len() != t.free.len() {
            return Err(SweepError::Other(format!(
                "{} values for {} free keys",
                x.len(),
                t.free.len()
            )));
        }
        Ok(t.evaluate(&x).encode())
    })
    .map_err(err)
}

/// Runs a tune and writes its outputs into `out` (the tuned scene, report.md, convergence.png,
/// history.csv, tune.json, and the manifest), staged and committed as `pneuflex tune --out` does: an `out`
/// that holds files pneuflex did not write is refused before the search. `evaluate`, when given, is called with each candidate's values and returns
/// `tune_evaluate`'s text (a remote executor); otherwise the candidates run on the Rust pool. Returns
/// tune.json's content as a JSON string.
#[pyfunction]
#[pyo3(signature = (scene_path, free, over, out, run=None, terms=Vec::new(), budget=200, seed=0, population=None, sigma0=0.3, threads=0, evaluate=None, command=None))]
#[allow(clippy::too_many_arguments)]
pub fn tune_run(
    py: Python<'_>,
    scene_path: crate::shipped::ScenePath,
    free: Vec<String>,
    over: Vec<String>,
    out: PathBuf,
    run: Option<String>,
    terms: Vec<String>,
    budget: usize,
    seed: u64,
    population: Option<usize>,
    sigma0: f64,
    threads: usize,
    evaluate: Option<Py<PyAny>>,
    command: Option<String>,
) -> PyResult<String> {
    let t = py
        .detach(|| tuner(&scene_path, &free, &over, run.as_deref(), &terms))
        .map_err(err)?;
    // Staged as `pneuflex tune --out` stages, before the search: a folder pneuflex did not write (or one
    // holding an input) is refused, not written into; the files appear there only when complete.
    let inputs = t.base_scene.input_files(&scene_path);
    let protect: Vec<&std::path::Path> = inputs.iter().map(PathBuf::as_path).collect();
    let stage =
        OutputDir::create(&out, &protect, Writer::simulation("tune")).map_err(errors::other)?;
    let opts = TuneOptions {
        budget,
        seed,
        population,
        sigma0,
        threads,
        max_runs: DEFAULT_MAX_POINTS,
    };
    let failed = std::sync::Mutex::new(None::<String>);
    let history = py
        .detach(|| match &evaluate {
            None => t.search(&opts, None, &|| {}),
            Some(f) => t.search_with(&opts, None, &|| {}, &|x: &[f64]| {
                let text = Python::attach(|py| -> PyResult<String> {
                    f.call1(py, (x.to_vec(),))?.extract::<String>(py)
                });
                match text.map(|s| Evaluation::decode(&s)) {
                    Ok(Some(ev)) => ev,
                    other => {
                        let why = match other {
                            Err(e) => e.to_string(),
                            _ => "the executor's answer is not an evaluation".into(),
                        };
                        failed
                            .lock()
                            .unwrap_or_else(|e| e.into_inner())
                            .get_or_insert(why);
                        Evaluation {
                            x: x.to_vec(),
                            j: f64::INFINITY,
                            rank: 1e15,
                            envs: Vec::new(),
                        }
                    }
                }
            }),
        })
        .map_err(err)?;
    if let Some(why) = failed.into_inner().unwrap_or_else(|e| e.into_inner()) {
        return Err(errors::other(format!(
            "a candidate's evaluation failed: {why}"
        )));
    }
    let command = command.unwrap_or_else(|| format!("pneuflex.tune({})", scene_path.display()));
    let summary = py
        .detach(|| {
            pneuflex_sweep::tune_output::write(
                stage.path(),
                &t,
                &opts,
                &history,
                &command,
                None,
                pneuflex_plot::Format::Png,
            )
        })
        .map_err(err)?;
    let manifest = Manifest::new(
        "tune",
        env!("CARGO_PKG_VERSION"),
        t.base_scene.input_digests(),
    );
    stage.commit(manifest).map_err(errors::other)?;
    serde_json::to_string(&summary).map_err(errors::other)
}
