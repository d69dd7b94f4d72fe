//! Writing a scene's outputs: `<dir>/<run>/trace.csv` and `<dir>/summary.json`, into a staging directory
//! (`pneuflex_files::OutputDir`) that is renamed into place only when complete. summary.json carries the
//! tool version, its schema version and the SHA-256 of every input file.

use std::fs;
use std::io::Write;
use std::path::Path;

use pneuflex_files::InputDigest;

use serde::Serialize;

use crate::error::SceneError;
use crate::run::result::{LyapunovSummary, RunResult, WindowMetrics};
use crate::schema::Scene;

fn werr(path: &Path) -> impl FnOnce(std::io::Error) -> SceneError + '_ {
    move |os_error| SceneError::Write {
        path: path.to_path_buf(),
        os_error,
    }
}

/// Layout version of summary.json (2: provenance and partial outputs; 3: event metrics against the run's
/// periodic steady state, claims).
pub const SUMMARY_SCHEMA_VERSION: u32 = 3;

/// The content of summary.json.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// Always `pneuflex`.
    pub tool: &'static str,
    /// The pneuflex version that wrote it.
    pub version: &'static str,
    /// Layout version of this file.
    pub schema_version: u32,
    /// Scene format version of the input.
    pub scene_schema_version: u32,
    /// Every input file, by content hash.
    pub inputs: Vec<InputDigest>,
    /// Whether every run was simulated to its end (false for an interrupted command).
    pub complete: bool,
    /// Why the output is incomplete.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub interrupted: Option<String>,
    /// Scene name.
    pub scene: String,
    /// Scene file.
    pub source: String,
    /// Simulated time, s.
    pub duration_s: f64,
    /// Control period, s.
    pub dt_s: f64,
    /// Plant kind.
    pub plant: String,
    /// One entry per run.
    pub runs: Vec<RunSummary>,
    /// The scene's claims, each with the two values and whether it holds.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub claims: Vec<crate::analysis::claims::ClaimResult>,
    /// A rig recording's records: which one the windows were judged on, and the host loop's stalls.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rig: Option<crate::analysis::recorded::RigRecord>,
}

/// One run in summary.json.
#[derive(Clone, Debug, Serialize)]
pub struct RunSummary {
    /// Run name.
    pub name: String,
    /// `impedance` or `adaptive`.
    pub controller: String,
    /// Whether the run was stopped as diverged.
    pub diverged: bool,
    /// Why (diverged runs only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// Why the run was cut short (interrupted runs only): the signal and the time reached.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub interrupted: Option<String>,
    /// Simulated time of the last recorded tick, s.
    pub time_reached_s: f64,
    /// Relative path of the trace file.
    pub trace: String,
    /// Metrics per window (empty for a diverged run).
    pub windows: Vec<WindowMetrics>,
    /// Lyapunov check (adaptive runs).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lyapunov: Option<LyapunovSummary>,
    /// Warnings about the run's results.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// Name of a run's trace file: `trace.csv`, `trace.diverged.csv` for a diverged run, or
/// `trace.interrupted.csv` for a run cut short by a signal.
pub fn trace_file_name(r: &RunResult) -> &'static str {
    if r.diverged.is_some() {
        "trace.diverged.csv"
    } else if r.interrupted.is_some() {
        "trace.interrupted.csv"
    } else {
        "trace.csv"
    }
}

/// The input files of a scene: the scene, and the actuator sheet with its components and the URDF
/// where the plant names them. Files that cannot be read are left out (the plant would have failed).
pub fn scene_inputs(scene: &Scene) -> Vec<InputDigest> {
    let mut out = Vec::new();
    let mut add = |p: &Path, role: &str| {
        if let Ok(d) = InputDigest::of_file(p, role) {
            out.push(d);
        }
    };
    add(&scene.source, "scene");
    let (actuator, urdf) = (
        scene.actuator_sheet_path(),
        scene
            .input_files()
            .into_iter()
            .find(|(role, _)| *role == "urdf")
            .map(|(_, p)| p),
    );
    if let Some(a) = actuator {
        add(&a, "actuator");
        // The component sheets the actuator sheet names in [components].
        let components = pneuflex_files::read_text(&a, pneuflex_files::InputKind::Sheet)
            .ok()
            .and_then(|t| t.parse::<toml::Table>().ok())
            .and_then(|t| t.get("components").and_then(|c| c.as_table()).cloned());
        let dir = a.parent().map(Path::to_path_buf).unwrap_or_default();
        for (role, v) in components.iter().flatten() {
            if let Some(rel) = v.as_str() {
                add(&dir.join(rel), role);
            }
        }
    }
    if let Some(u) = urdf {
        add(&u, "urdf");
    }
    out
}

/// The summary of a scene's results. Runs the command did not reach (after an interrupt) are absent.
pub fn summary(scene: &Scene, results: &[RunResult]) -> Summary {
    let interrupted = results.iter().find_map(|r| r.interrupted.clone());
    Summary {
        tool: "pneuflex",
        version: env!("CARGO_PKG_VERSION"),
        schema_version: SUMMARY_SCHEMA_VERSION,
        scene_schema_version: scene
            .schema_version
            .unwrap_or(crate::schema::SCENE_SCHEMA_VERSION),
        inputs: scene_inputs(scene),
        complete: interrupted.is_none() && results.len() == scene.runs.len(),
        interrupted,
        scene: scene.name.clone(),
        source: scene.source.display().to_string(),
        duration_s: scene.duration_s,
        dt_s: scene.dt_s,
        plant: scene.plant.kind().into(),
        runs: results
            .iter()
            .map(|r| RunSummary {
                name: r.name.clone(),
                controller: r.controller.name().into(),
                diverged: r.diverged.is_some(),
                reason: r.diverged.clone(),
                interrupted: r.interrupted.clone(),
                time_reached_s: r.trace.t().last().copied().unwrap_or(0.0),
                trace: format!("{}/{}", r.name, trace_file_name(r)),
                windows: r.windows.clone(),
                lyapunov: r.lyapunov,
                warnings: r.warnings.clone(),
            })
            .collect(),
        claims: crate::analysis::claims::check_all(scene, results),
        rig: None,
    }
}

/// Writes every run's trace and summary.json into `dir` (normally a [`Staging::path`]).
/// A diverged run's partial trace goes to `trace.diverged.csv`, never to `trace.csv`.
/// The traces are written in parallel (one file per run); the first error in run order is returned.
pub fn write_results(dir: &Path, scene: &Scene, results: &[RunResult]) -> Result<(), SceneError> {
    use rayon::prelude::*;
    let written: Vec<Result<(), SceneError>> =
        results.par_iter().map(|r| write_trace(dir, r)).collect();
    written.into_iter().collect::<Result<(), _>>()?;
    write_summary(dir, scene, results)
}

/// Writes summary.json into `dir`: the scene's results as [`summary`] gives them.
pub fn write_summary(dir: &Path, scene: &Scene, results: &[RunResult]) -> Result<(), SceneError> {
    let path = dir.join("summary.json");
    let text =
        serde_json::to_string_pretty(&summary(scene, results)).map_err(|e| SceneError::Write {
            path: path.clone(),
            os_error: std::io::Error::other(e),
        })?;
    fs::write(&path, text + "\n").map_err(werr(&path))?;
    Ok(())
}

/// Writes `<dir>/<run>/<trace file>` (`trace.csv`, or `trace.diverged.csv` / `trace.interrupted.csv` for a
/// run that did not end normally).
pub fn write_trace(dir: &Path, r: &RunResult) -> Result<(), SceneError> {
    let run_dir = dir.join(&r.name);
    fs::create_dir_all(&run_dir).map_err(werr(&run_dir))?;
    let path = run_dir.join(trace_file_name(r));
    let mut f = fs::File::create(&path).map_err(werr(&path))?;
    // write_csv buffers by itself, in blocks.
    r.trace.write_csv(&mut f).map_err(werr(&path))?;
    f.flush().map_err(werr(&path))
}
