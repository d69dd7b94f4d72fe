//! Writing a scene's outputs: `<dir>/<run>/trace.csv` and `<dir>/summary.json`, staged in a temporary
//! sibling directory and renamed into place only when complete.

use std::fs;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::error::SceneError;
use crate::runner::{LyapunovSummary, RunResult, WindowMetrics};
use crate::schema::Scene;

/// A directory being filled; it appears under its final name only on [`Staging::commit`].
/// Dropped without commit, it is removed.
#[derive(Debug)]
pub struct Staging {
    tmp: PathBuf,
    dest: PathBuf,
    committed: bool,
}

fn werr(path: &Path) -> impl FnOnce(std::io::Error) -> SceneError + '_ {
    move |source| SceneError::Write {
        path: path.to_path_buf(),
        source,
    }
}

impl Staging {
    /// Creates `<parent>/.<name>.partial-<pid>` for an eventual `dest`.
    pub fn new(dest: &Path) -> Result<Self, SceneError> {
        let parent = match dest.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        fs::create_dir_all(&parent).map_err(werr(&parent))?;
        let name = dest
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "out".into());
        let tmp = parent.join(format!(".{name}.partial-{}", std::process::id()));
        if tmp.exists() {
            fs::remove_dir_all(&tmp).map_err(werr(&tmp))?;
        }
        fs::create_dir_all(&tmp).map_err(werr(&tmp))?;
        Ok(Self {
            tmp,
            dest: dest.to_path_buf(),
            committed: false,
        })
    }

    /// The directory to write into until commit.
    pub fn path(&self) -> &Path {
        &self.tmp
    }

    /// Replaces `dest` by the staged directory.
    pub fn commit(mut self) -> Result<PathBuf, SceneError> {
        if self.dest.exists() {
            fs::remove_dir_all(&self.dest).map_err(werr(&self.dest))?;
        }
        fs::rename(&self.tmp, &self.dest).map_err(werr(&self.dest))?;
        self.committed = true;
        Ok(self.dest.clone())
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        if !self.committed {
            let _ = fs::remove_dir_all(&self.tmp);
        }
    }
}

/// The content of summary.json.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
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
    /// Relative path of the trace file.
    pub trace: String,
    /// Metrics per window (empty for a diverged run).
    pub windows: Vec<WindowMetrics>,
    /// Lyapunov check (adaptive runs).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lyapunov: Option<LyapunovSummary>,
}

/// Name of a run's trace file: `trace.csv`, or `trace.diverged.csv` for a diverged run.
pub fn trace_file_name(r: &RunResult) -> &'static str {
    if r.diverged.is_some() {
        "trace.diverged.csv"
    } else {
        "trace.csv"
    }
}

/// The summary of a scene's results.
pub fn summary(scene: &Scene, results: &[RunResult]) -> Summary {
    Summary {
        scene: scene.name.clone(),
        source: scene.source.display().to_string(),
        duration_s: scene.duration_s,
        dt_s: scene.dt_s,
        plant: match scene.plant {
            crate::schema::PlantSpec::Ideal { .. } => "ideal".into(),
            crate::schema::PlantSpec::Pneumatic { .. } => "pneumatic".into(),
            crate::schema::PlantSpec::Multibody(_) => "multibody".into(),
        },
        runs: results
            .iter()
            .map(|r| RunSummary {
                name: r.name.clone(),
                controller: r.controller.name().into(),
                diverged: r.diverged.is_some(),
                reason: r.diverged.clone(),
                trace: format!("{}/{}", r.name, trace_file_name(r)),
                windows: r.windows.clone(),
                lyapunov: r.lyapunov,
            })
            .collect(),
    }
}

/// Writes every run's trace and summary.json into `dir` (normally a [`Staging::path`]).
/// A diverged run's partial trace goes to `trace.diverged.csv`, never to `trace.csv`.
pub fn write_results(dir: &Path, scene: &Scene, results: &[RunResult]) -> Result<(), SceneError> {
    for r in results {
        let run_dir = dir.join(&r.name);
        fs::create_dir_all(&run_dir).map_err(werr(&run_dir))?;
        let path = run_dir.join(trace_file_name(r));
        let f = fs::File::create(&path).map_err(werr(&path))?;
        let mut w = BufWriter::new(f);
        r.trace
            .write_csv(&mut w, r.is_adaptive())
            .map_err(werr(&path))?;
        w.flush().map_err(werr(&path))?;
    }
    let path = dir.join("summary.json");
    let text =
        serde_json::to_string_pretty(&summary(scene, results)).map_err(|e| SceneError::Write {
            path: path.clone(),
            source: std::io::Error::other(e),
        })?;
    fs::write(&path, text + "\n").map_err(werr(&path))?;
    Ok(())
}
