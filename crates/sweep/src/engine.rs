//! The sweep engine: every point's scene, checked before anything runs, then run on a rayon pool; one row
//! per point and run, in point order whatever the thread count.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

pub use pneuflex_scene::any_scene::{MetricColumn, metric_of, window_metrics};
use pneuflex_scene::{AnyScene, Limits, RunResult, SceneError, WindowKind};
use rayon::prelude::*;

use crate::key::{Base, KeyError, KeyPath, Value};
use crate::points::{Points, SetArg, SpecError};

/// Everything that stops a sweep before it runs.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    /// A `--set` that cannot be read.
    #[error(transparent)]
    Spec(#[from] SpecError),
    /// A key that cannot be written into the scene (no such table, run or element), or two spellings of
    /// one key: `file:line:col: key: message (option)`, the position that of the key's table where the
    /// file has it.
    #[error("{}{}: {error} ({option})", file.display(), at.map(|p| format!(":{p}")).unwrap_or_default())]
    Key {
        /// The scene file.
        file: PathBuf,
        /// Where the key (or the deepest part of it the file has) is written.
        at: Option<pneuflex_files::Position>,
        /// `--set`, `--free`, `--over`.
        option: &'static str,
        /// The key and what is wrong.
        error: KeyError,
    },
    /// The scene file itself (before any edit) is wrong or unreadable.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// A point's scene is rejected by the scene's own parser or validation.
    #[error("{error}\n  (sweep point {point})")]
    Point {
        /// Which point, with every key's value.
        point: String,
        /// The scene's error, located in the scene file.
        error: Box<SceneError>,
    },
    /// A point's actuator sheet is rejected by the sheet's own validation.
    #[error("{error}\n  (sweep point {point})")]
    Sheet {
        /// Which point.
        point: String,
        /// The sheet's error.
        error: Box<pneuflex_pneumatics::ComponentError>,
    },
    /// A signal stopped the work before it was done.
    #[error("interrupted by a signal")]
    Interrupted,
    /// Anything else (a thread pool that cannot start, a bad metric name, ...).
    #[error("{0}")]
    Other(String),
}

impl SweepError {
    /// A key error of `option`, located in the scene file `base` was read from.
    pub fn key(base: &Base, option: &'static str, error: KeyError) -> Self {
        let text = &base.scene.text;
        // The deepest prefix of the key the file writes (`runs[9].inner.kp_per_m` -> `runs`).
        let path = error.key.split(':').next().unwrap_or("").to_string();
        let mut at = None;
        let mut prefix = path.as_str();
        while !prefix.is_empty() {
            if let Some(p) = pneuflex_files::toml_key_position(text, prefix) {
                at = Some(p);
                break;
            }
            prefix = match prefix.rfind(['.', '[']) {
                Some(i) => &prefix[..i],
                None => "",
            };
        }
        SweepError::Key {
            file: base.scene.path.clone(),
            at,
            option,
            error,
        }
    }
}

/// How a run at a point ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// Simulated to the end; every event window settled.
    Ok,
    /// Simulated to the end; an event window did not settle.
    NotSettled,
    /// Stopped as diverged (its metrics are empty).
    Diverged,
    /// Could not be simulated (a plant that cannot be built at this point).
    Error,
}

impl Status {
    /// As written in the table.
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::NotSettled => "not_settled",
            Status::Diverged => "diverged",
            Status::Error => "error",
        }
    }
}

/// One run at one point: its status and its metrics in column order.
#[derive(Clone, Debug, PartialEq)]
pub struct RunRow {
    /// Run name.
    pub run: String,
    /// `impedance` or `adaptive`.
    pub controller: String,
    /// How it ended.
    pub status: Status,
    /// Why it diverged or did not settle (empty when ok).
    pub reason: String,
    /// Each metric column's value (None: not measured, or diverged).
    pub metrics: Vec<Option<f64>>,
}

/// Every run at one point.
#[derive(Clone, Debug, PartialEq)]
pub struct PointResult {
    /// The point's number.
    pub index: usize,
    /// One row per run, in the scene's order.
    pub runs: Vec<RunRow>,
}

impl PointResult {
    /// The same point keeping only the metric columns `keep` (the others None) and no reasons: what a
    /// heatmap needs, small.
    pub fn slim(&self, keep: &[usize]) -> PointResult {
        PointResult {
            index: self.index,
            runs: self
                .runs
                .iter()
                .map(|r| RunRow {
                    run: r.run.clone(),
                    controller: r.controller.clone(),
                    status: r.status,
                    reason: String::new(),
                    metrics: (0..r.metrics.len())
                        .map(|i| {
                            if keep.contains(&i) {
                                r.metrics[i]
                            } else {
                                None
                            }
                        })
                        .collect(),
                })
                .collect(),
        }
    }
}

/// How [`Sweep::new_checked`] reports while it checks every point: a stop flag (a signal's number; the check
/// ends early with [`SweepError::Interrupted`]) and a tick after every point checked (a progress bar).
pub struct Checking<'a> {
    pub stop: Option<&'a AtomicUsize>,
    pub tick: &'a (dyn Fn() + Sync),
}

/// A sweep: the scene, its points, and the metric columns of its table.
#[derive(Debug)]
pub struct Sweep {
    /// The scene file.
    pub scene_path: PathBuf,
    /// The scene as the file has it (validated), of either kind.
    pub base_scene: AnyScene,
    /// The points.
    pub points: Points,
    /// The metric columns (from the scene's windows).
    pub columns: Vec<MetricColumn>,
    /// The `--set` specs as written (`KEY=SPEC`), for the record.
    pub specs: Vec<String>,
    /// Seed of the sampled keys.
    pub seed: u64,
    /// What one run of a point may cost (`--max-steps`, `--max-trace-mb`); a point beyond is refused.
    pub limits: Limits,
    base: Base,
}

fn quote(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// A number as the table writes it: the shortest text that reads back as the same f64 (`inf`, `NaN`).
pub fn fmt_f64(x: f64) -> String {
    format!("{x}")
}

impl Sweep {
    /// Reads the scene, expands the points and checks every point's scene (and sheet) before anything
    /// runs: the first bad point's error is returned, located in the file, with the point.
    /// At most `max_points` points (refused beyond, before anything is allocated: `--max-points`).
    pub fn new(
        scene_path: &Path,
        sets: &[SetArg],
        samples: Option<usize>,
        seed: u64,
        max_points: u64,
    ) -> Result<Sweep, SweepError> {
        Self::new_checked(
            scene_path,
            sets,
            samples,
            seed,
            max_points,
            Limits::default(),
            Checking {
                stop: None,
                tick: &|| {},
            },
        )
    }

    /// [`Sweep::new`] with a stop flag and a progress tick ([`Checking`]).
    pub fn new_checked(
        scene_path: &Path,
        sets: &[SetArg],
        samples: Option<usize>,
        seed: u64,
        max_points: u64,
        limits: Limits,
        checking: Checking<'_>,
    ) -> Result<Sweep, SweepError> {
        let Checking { stop, tick } = checking;
        let mut sweep = Self::new_unchecked(scene_path, sets, samples, seed, max_points)?;
        sweep.limits = limits;
        // Structural key errors are the same at every point: the first point says them once.
        sweep.scene_at(0)?;
        tick();
        let stopped = || stop.is_some_and(|s| s.load(Ordering::Relaxed) != 0);
        let first_bad = (1..sweep.len())
            .into_par_iter()
            .map(|i| {
                if stopped() {
                    return Some(SweepError::Interrupted);
                }
                let e = sweep.scene_at(i).err();
                tick();
                e
            })
            .find_first(Option::is_some)
            .flatten();
        if let Some(e) = first_bad {
            return Err(e);
        }
        Ok(sweep)
    }

    /// [`Sweep::new`] without checking every point (a worker that runs a chunk of a sweep its caller has
    /// checked: each point's scene is still built, and refused, by [`Sweep::run_point`]).
    pub fn new_unchecked(
        scene_path: &Path,
        sets: &[SetArg],
        samples: Option<usize>,
        seed: u64,
        max_points: u64,
    ) -> Result<Sweep, SweepError> {
        let base_scene = AnyScene::load(scene_path)?;
        let base = Base::load(scene_path).map_err(|e| SweepError::Other(e.to_string()))?;
        let keys: Vec<(&str, &KeyPath)> = sets.iter().map(|s| ("--set", &s.key)).collect();
        base.check_distinct(&keys)
            .map_err(|e| SweepError::key(&base, "--set", e))?;
        let points = crate::points::points(sets, samples, seed, max_points, "--max-points")?;
        let columns = base_scene.metric_columns();
        let sweep = Sweep {
            scene_path: scene_path.to_path_buf(),
            base_scene,
            points,
            columns,
            specs: sets
                .iter()
                .map(|s| format!("{}={}", s.key.text, s.spec_text))
                .collect(),
            seed,
            limits: Limits::default(),
            base,
        };
        Ok(sweep)
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether the sweep has no points (never, once built).
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The bytes `--traces` would write: every run's trace at every point (its rows times its columns at
    /// about 14 bytes a value) and a summary, from the scene's duration and step.
    pub fn traces_bytes(&self) -> u64 {
        let s = &self.base_scene;
        let rows = (s.duration_s() / s.dt_s()).ceil().max(1.0) + 1.0;
        // Per actuator the loop's 8 signals, a controller's 3 and the plant's few.
        let actuators = match s {
            AnyScene::One(_) => 1.0,
            AnyScene::Mechanism(m) => m.actuators.len() as f64,
        };
        let columns = 14.0 * actuators;
        let per_point = s.runs().len() as f64 * rows * columns * 14.0 + 16_384.0;
        (per_point * self.len() as f64).min(u64::MAX as f64) as u64
    }

    /// `#i of n: key = value, ...`.
    pub fn describe(&self, i: usize) -> String {
        let kv: Vec<String> = self
            .points
            .keys
            .iter()
            .zip(&self.points.row(i))
            .map(|(k, v)| format!("{} = {v}", k.text))
            .collect();
        format!("#{i} of {}: {}", self.len(), kv.join(", "))
    }

    /// The scene of point `i`, parsed and validated by the scene's own code, with the sheet's edited
    /// files as its overlay (and the sheet loaded once, to check it).
    pub fn scene_at(&self, i: usize) -> Result<AnyScene, SweepError> {
        let row = self.points.row(i);
        let edits: Vec<(&crate::key::KeyPath, &Value)> =
            self.points.keys.iter().zip(&row).collect();
        let edited = self
            .base
            .edit(&edits)
            .map_err(|e| SweepError::key(&self.base, "--set", e))?;
        let located = |e: SceneError| -> SweepError {
            // Positions of the file as the user wrote it (an added key moves later lines of the copy).
            let e = match e {
                SceneError::Invalid {
                    file, key, message, ..
                } => SceneError::Invalid {
                    at: pneuflex_files::toml_key_position(&self.base.scene.text, &key),
                    file,
                    key,
                    message,
                },
                SceneError::Parse {
                    file,
                    key,
                    message,
                    at,
                } if !key.is_empty() => SceneError::Parse {
                    at: pneuflex_files::toml_key_position(&self.base.scene.text, &key).or(at),
                    file,
                    key,
                    message,
                },
                other => other,
            };
            SweepError::Point {
                point: self.describe(i),
                error: Box::new(e),
            }
        };
        let mut scene =
            AnyScene::from_toml_str(&edited.scene_text, &self.scene_path, &self.base.base_dir)
                .map_err(located)?;
        // Errors and summaries point at the file as written.
        scene.set_text(self.base.scene.text.clone());
        if !edited.overlay.is_empty() {
            with_overlay(&mut scene, edited.overlay, &self.describe(i)).map_err(|e| match e {
                SweepError::Scene(e) => located(e),
                other => other,
            })?;
        }
        scene.check_budget(&self.limits).map_err(located)?;
        Ok(scene)
    }

    /// Runs point `i` (every run of its scene, one after another on this thread); `traces` writes its
    /// traces and summary.json into `traces/point-<i>/`.
    pub fn run_point(&self, i: usize, traces: Option<&Path>) -> PointResult {
        let fail = |why: String| PointResult {
            index: i,
            runs: self
                .base_scene
                .runs()
                .iter()
                .map(|r| RunRow {
                    run: r.name.clone(),
                    controller: r.controller.name().into(),
                    status: Status::Error,
                    reason: why.clone(),
                    metrics: vec![None; self.columns.len()],
                })
                .collect(),
        };
        let scene = match self.scene_at(i) {
            Ok(s) => s,
            Err(e) => return fail(e.to_string()),
        };
        let results = match scene.run(&mut |_| {}) {
            Ok(r) => r,
            Err(e) => return fail(e.to_string()),
        };
        if let Some(dir) = traces {
            let d = dir.join(format!("point-{i:0w$}", w = digits(self.len())));
            if let Err(e) = std::fs::create_dir_all(&d)
                .map_err(|e| e.to_string())
                .and_then(|()| scene.write_results(&d, &results).map_err(|e| e.to_string()))
            {
                return fail(format!("writing traces: {e}"));
            }
        }
        PointResult {
            index: i,
            runs: results.iter().map(|r| self.row_of(&scene, r)).collect(),
        }
    }

    /// The table row of one run's result of the point's `scene` (status, reason, every metric column).
    pub fn row_of(&self, scene: &AnyScene, r: &RunResult) -> RunRow {
        let unsettled = scene.unsettled(r);
        let (status, reason) = match (&r.diverged, unsettled.is_empty()) {
            (Some(why), _) => (Status::Diverged, why.clone()),
            (None, false) => (Status::NotSettled, unsettled.join("; ")),
            (None, true) => (Status::Ok, String::new()),
        };
        let metrics = scene.values(r, &self.columns);
        RunRow {
            run: r.name.clone(),
            controller: r.controller.name().into(),
            status,
            reason,
            metrics,
        }
    }

    /// Runs the points `indices` on a pool of `threads` threads (0: one per core); `tick` is called after
    /// each point. The results are in the order of `indices`.
    pub fn run(
        &self,
        indices: &[usize],
        threads: usize,
        traces: Option<&Path>,
        tick: &(dyn Fn() + Sync),
    ) -> Result<Vec<PointResult>, SweepError> {
        let pool = thread_pool(threads)?;
        Ok(pool.install(|| {
            indices
                .par_iter()
                .map(|&i| {
                    let r = self.run_point(i, traces);
                    tick();
                    r
                })
                .collect()
        }))
    }

    /// [`Sweep::run`] in chunks of consecutive points: `on_chunk` gets each chunk's results in point order
    /// as soon as the chunk is done, and nothing else is kept, so memory does not grow with the number of
    /// points (the CLI streams the rows to sweep.csv this way).
    ///
    /// `stop` (a signal's number, 0 while none came) is checked before each point: once set, no point
    /// starts, the points done are handed on, and the sweep returns [`SweepError::Interrupted`].
    pub fn run_chunked(
        &self,
        indices: &[usize],
        threads: usize,
        traces: Option<&Path>,
        stop: Option<&AtomicUsize>,
        tick: &(dyn Fn() + Sync),
        on_chunk: &mut dyn FnMut(&[PointResult]) -> Result<(), SweepError>,
    ) -> Result<(), SweepError> {
        let pool = thread_pool(threads)?;
        let stopped = || stop.is_some_and(|s| s.load(Ordering::Relaxed) != 0);
        // Big enough to keep every thread busy (the chunk's slowest point idles the others at its end).
        let chunk = (64 * pool.current_num_threads()).max(64);
        for part in indices.chunks(chunk) {
            let results: Vec<Option<PointResult>> = pool.install(|| {
                part.par_iter()
                    .map(|&i| {
                        if stopped() {
                            return None;
                        }
                        let r = self.run_point(i, traces);
                        tick();
                        Some(r)
                    })
                    .collect()
            });
            let done: Vec<PointResult> = results.into_iter().flatten().collect();
            on_chunk(&done)?;
            if stopped() {
                return Err(SweepError::Interrupted);
            }
        }
        Ok(())
    }

    /// The table's header line (with its newline).
    pub fn header(&self) -> String {
        let mut cols: Vec<String> = vec!["point".into()];
        cols.extend(self.points.keys.iter().map(|k| quote(&k.text)));
        cols.extend(["run", "controller", "status", "reason"].map(String::from));
        cols.extend(self.columns.iter().map(|c| quote(&c.name())));
        cols.join(",") + "\n"
    }

    /// The table's lines of one point (one per run).
    pub fn rows(&self, p: &PointResult) -> String {
        let mut s = String::new();
        let keys: Vec<String> = self
            .points
            .row(p.index)
            .iter()
            .map(|v| quote(&v.to_string()))
            .collect();
        for r in &p.runs {
            let _ = write!(
                s,
                "{},{},{},{},{},{}",
                p.index,
                keys.join(","),
                quote(&r.run),
                r.controller,
                r.status.as_str(),
                quote(&r.reason)
            );
            for m in &r.metrics {
                s.push(',');
                if let Some(x) = m {
                    s.push_str(&fmt_f64(*x));
                }
            }
            s.push('\n');
        }
        s
    }

    /// The whole table (header and every point's rows).
    pub fn table(&self, results: &[PointResult]) -> String {
        let mut s = self.header();
        for p in results {
            s.push_str(&self.rows(p));
        }
        s
    }

    /// The index of a metric column by its `window.metric` name; the error lists them.
    pub fn metric_index(&self, name: &str) -> Result<usize, SweepError> {
        self.columns
            .iter()
            .position(|c| c.name() == name)
            .ok_or_else(|| {
                let known: Vec<String> = self.columns.iter().map(MetricColumn::name).collect();
                SweepError::Other(format!(
                    "--metric {name}: no such metric column; the scene's are {}",
                    known.join(", ")
                ))
            })
    }

    /// For a settling-time column, its window's `settling_fragile` column (what a heatmap of it marks).
    pub fn fragile_column(&self, metric: usize) -> Option<usize> {
        let c = self.columns.get(metric)?;
        if c.metric != "settling_time_s" {
            return None;
        }
        self.columns
            .iter()
            .position(|f| f.window == c.window && f.metric == "settling_fragile")
    }

    /// The default heatmap metric: the first sine window's RMS error, else the first column.
    pub fn default_metric(&self) -> Option<String> {
        let sine = self.base_scene.one().and_then(|s| {
            s.metrics
                .iter()
                .find(|w| w.kind == WindowKind::Sine)
                .map(|w| format!("{}.rms_force_error_n", w.name))
        });
        sine.or_else(|| self.columns.first().map(MetricColumn::name))
    }
}

/// Gives a point's scene the edited copies of its sheets (`overlay`) and reads them once to check them; `point`
/// describes the point in errors.
pub(crate) fn with_overlay(
    scene: &mut AnyScene,
    overlay: pneuflex_pneumatics::FileOverlay,
    point: &str,
) -> Result<(), SweepError> {
    match scene {
        AnyScene::One(scene) => {
            scene.overlay = overlay;
            let Some(sheet) = scene.actuator_sheet_path() else {
                return Err(SweepError::Other(format!(
                    "sweep point {point}: the plant of this scene has no actuator sheet"
                )));
            };
            scene.load_sheet(&sheet).map_err(|e| SweepError::Sheet {
                point: point.to_string(),
                error: Box::new(e),
            })?;
            Ok(())
        }
        // Each actuator's sheet is read through the overlay when the mechanism is built.
        AnyScene::Mechanism(m) => {
            m.overlay = overlay;
            m.check_sheets().map_err(|e| SweepError::Point {
                point: point.to_string(),
                error: Box::new(e),
            })
        }
    }
}

/// The most worker threads a sweep or a tune starts (`--threads`): past a few per core they only cost memory.
pub const MAX_THREADS: usize = 1024;

/// A pool of `threads` workers (0: one per core), refused past [`MAX_THREADS`].
pub fn thread_pool(threads: usize) -> Result<rayon::ThreadPool, SweepError> {
    if threads > MAX_THREADS {
        return Err(SweepError::Other(format!(
            "--threads {threads}: at most {MAX_THREADS} (0: one per core)"
        )));
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| SweepError::Other(format!("cannot start the thread pool: {e}")))
}

fn digits(n: usize) -> usize {
    n.saturating_sub(1).max(1).to_string().len()
}
