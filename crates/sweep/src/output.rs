//! A sweep's files: `sweep.csv` (every point's keys and every metric per run), `sweep.json` (what was
//! swept), and for a grid of two keys a heatmap per run of one metric and of adaptive − impedance.

use std::path::{Path, PathBuf};

use crate::engine::{PointResult, Status, Sweep, SweepError};
use crate::key::Value;

/// A grid value as an axis label: four significant digits.
pub fn tick(v: &Value) -> String {
    match v {
        Value::Float(x) if x.is_finite() && *x != 0.0 => {
            let r: f64 = format!("{x:.3e}").parse().unwrap_or(*x);
            format!("{r}")
        }
        other => other.to_string(),
    }
}

/// What `sweep.json` records: enough to run the same sweep again.
#[derive(serde::Serialize)]
struct Record<'a> {
    tool: &'static str,
    version: &'static str,
    command: &'static str,
    scene: String,
    sets: &'a [String],
    seed: u64,
    points: usize,
    runs: Vec<&'a str>,
    metric_columns: Vec<String>,
    table: &'static str,
    heatmaps: Vec<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    heatmaps_skipped: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    partial: Option<String>,
}

/// The most cells a heatmap draws: beyond, a map is unreadable and its kept metrics would grow with the
/// sweep; sweep.csv has every point whatever the size.
pub const MAX_HEATMAP_CELLS: usize = 65_536;

/// Every figure's file name (relative) and its cells, for a two-key grid.
fn heatmap_cells(sweep: &Sweep, results: &[PointResult], metric: usize) -> Vec<Map> {
    let Some(grid) = &sweep.points.grid else {
        return Vec::new();
    };
    if grid.len() != 2 {
        return Vec::new();
    }
    let (nx, ny) = (grid[0].1.len(), grid[1].1.len());
    let name = sweep.columns[metric].name();
    // A settling time's map marks the cells where it is fragile (its window's settling_fragile column).
    let fragile_i = sweep.fragile_column(metric);
    let fragile = |p: &PointResult, run: usize| -> bool {
        fragile_i.is_some_and(|f| {
            p.runs
                .get(run)
                .is_some_and(|r| r.status == Status::Ok && r.metrics[f] == Some(1.0))
        })
    };
    let value = |p: &PointResult, run: usize| -> Option<f64> {
        let r = p.runs.get(run)?;
        // A run that never settled (a limit cycle, an end stop, lost contact) is drawn as not working
        // (grey, a circle) whatever the metric: its number would describe a run that does not work.
        match r.status {
            Status::Diverged | Status::Error => None,
            Status::NotSettled => Some(f64::INFINITY),
            Status::Ok => r.metrics[metric].or(Some(f64::NAN)),
        }
    };
    // Point index = x * ny + y (the first key varies slowest); cells row by row from the bottom.
    let cells = |f: &dyn Fn(&PointResult) -> Option<f64>| -> Vec<Option<f64>> {
        let mut c = vec![None; nx * ny];
        for p in results {
            let (x, y) = (p.index / ny, p.index % ny);
            c[y * nx + x] = f(p);
        }
        c
    };
    let marks = |f: &dyn Fn(&PointResult) -> bool| -> Vec<bool> {
        let mut m = vec![false; nx * ny];
        for p in results {
            let (x, y) = (p.index / ny, p.index % ny);
            m[y * nx + x] = f(p);
        }
        m
    };
    let mut out = Vec::new();
    for (k, run) in sweep.base_scene.runs.iter().enumerate() {
        out.push((
            format!("heatmap-{}-{name}.png", run.name),
            format!("{} ({}): {name}", run.name, run.controller.name()),
            cells(&|p| value(p, k)),
            marks(&|p| fragile(p, k)),
            false,
        ));
    }
    let find = |kind: &str| {
        sweep
            .base_scene
            .runs
            .iter()
            .position(|r| r.controller.name() == kind)
    };
    if let (Some(a), Some(i)) = (find("adaptive"), find("impedance")) {
        let (an, inn) = (
            &sweep.base_scene.runs[a].name,
            &sweep.base_scene.runs[i].name,
        );
        out.push((
            format!("heatmap-{an}-minus-{inn}-{name}.png"),
            format!("{an} − {inn}: {name} (< 0: {an} lower)"),
            cells(&|p| Some(value(p, a)? - value(p, i)?)),
            marks(&|p| fragile(p, a) || fragile(p, i)),
            true,
        ));
    }
    out
}

/// Writes the table, the record and (for a two-key grid) the heatmaps of each of `metrics` into `dir`;
/// returns the files written, relative to `dir`.
pub fn write(
    dir: &Path,
    sweep: &Sweep,
    results: &[PointResult],
    metrics: &[String],
) -> Result<Vec<PathBuf>, SweepError> {
    let io = |p: &Path, e: std::io::Error| {
        SweepError::Other(format!("{}: cannot write: {e}", p.display()))
    };
    let csv = dir.join("sweep.csv");
    std::fs::write(&csv, sweep.table(results)).map_err(|e| io(&csv, e))?;
    let mut files = vec![PathBuf::from("sweep.csv")];
    files.extend(write_figures(dir, sweep, results, metrics)?);
    Ok(files)
}

/// Whether the sweep draws heatmaps (a grid of exactly two swept keys, of at most [`MAX_HEATMAP_CELLS`]).
pub fn has_heatmaps(sweep: &Sweep) -> bool {
    sweep.points.grid.as_ref().is_some_and(|g| g.len() == 2) && sweep.len() <= MAX_HEATMAP_CELLS
}

/// Why a two-key grid gets no heatmap, if it gets none.
fn heatmaps_skipped(sweep: &Sweep) -> Option<String> {
    (sweep.points.grid.as_ref().is_some_and(|g| g.len() == 2) && !has_heatmaps(sweep)).then(|| {
        format!(
            "{} cells are more than a heatmap draws ({MAX_HEATMAP_CELLS}); every point is in sweep.csv",
            sweep.len()
        )
    })
}

/// sweep.csv written as the points come: the header at creation, then each chunk's rows.
pub struct TableWriter {
    path: PathBuf,
    file: std::io::BufWriter<std::fs::File>,
}

impl TableWriter {
    /// Creates `dir/sweep.csv` with the header.
    pub fn create(dir: &Path, sweep: &Sweep) -> Result<Self, SweepError> {
        use std::io::Write as _;
        let path = dir.join("sweep.csv");
        let io =
            |e: std::io::Error| SweepError::Other(format!("{}: cannot write: {e}", path.display()));
        let mut file = std::io::BufWriter::new(std::fs::File::create(&path).map_err(io)?);
        file.write_all(sweep.header().as_bytes()).map_err(io)?;
        Ok(Self { path, file })
    }

    /// Appends the rows of `results`.
    pub fn write(&mut self, sweep: &Sweep, results: &[PointResult]) -> Result<(), SweepError> {
        use std::io::Write as _;
        for p in results {
            self.file.write_all(sweep.rows(p).as_bytes()).map_err(|e| {
                SweepError::Other(format!("{}: cannot write: {e}", self.path.display()))
            })?;
        }
        Ok(())
    }

    /// Flushes the file.
    pub fn finish(mut self) -> Result<(), SweepError> {
        use std::io::Write as _;
        self.file
            .flush()
            .map_err(|e| SweepError::Other(format!("{}: cannot write: {e}", self.path.display())))
    }
}

/// The heatmaps of each of `metrics` (for a two-key grid) and sweep.json, from the points' results (all
/// of them, or their [`PointResult::slim`] copies); returns the files written.
pub fn write_figures(
    dir: &Path,
    sweep: &Sweep,
    results: &[PointResult],
    metrics: &[String],
) -> Result<Vec<PathBuf>, SweepError> {
    let mut files = Vec::new();
    let mut all_maps = Vec::new();
    for metric in metrics {
        let metric_i = sweep.metric_index(metric)?;
        if !has_heatmaps(sweep) {
            continue;
        }
        let maps = heatmap_cells(sweep, results, metric_i);
        write_maps(dir, sweep, &maps, metric_i, &mut files)?;
        all_maps.extend(maps.into_iter().map(|m| m.0));
    }
    write_record(dir, sweep, all_maps, None)?;
    files.push(PathBuf::from("sweep.json"));
    Ok(files)
}

/// File name, title, cells, marked cells (a fragile settling time), diverging scale.
type Map = (String, String, Vec<Option<f64>>, Vec<bool>, bool);

fn write_maps(
    dir: &Path,
    sweep: &Sweep,
    maps: &[Map],
    metric_i: usize,
    files: &mut Vec<PathBuf>,
) -> Result<(), SweepError> {
    if let Some(grid) = sweep.points.grid.as_ref().filter(|g| g.len() == 2) {
        let xt: Vec<String> = grid[0].1.values().iter().map(tick).collect();
        let yt: Vec<String> = grid[1].1.values().iter().map(tick).collect();
        for (file, title, cells, marked, diverging) in maps {
            let path = dir.join(file);
            pneuflex_plot::write_heatmap(
                &path,
                &pneuflex_plot::Heatmap {
                    title,
                    x_label: &sweep.points.keys[grid[0].0].text,
                    x_ticks: &xt,
                    y_label: &sweep.points.keys[grid[1].0].text,
                    y_ticks: &yt,
                    cells,
                    marked,
                    mark_note: "* settling time hangs on the band (±5 % moves it > 10 %)",
                    value_label: &sweep.columns[metric_i].name(),
                    diverging: *diverging,
                },
            )
            .map_err(|e| SweepError::Other(e.to_string()))?;
            files.push(PathBuf::from(file));
        }
    }
    Ok(())
}

/// Writes sweep.json: what was swept, the heatmaps drawn, and for an interrupted sweep (`partial`: the
/// points done) that its table is partial.
pub fn write_record(
    dir: &Path,
    sweep: &Sweep,
    heatmaps: Vec<String>,
    partial: Option<usize>,
) -> Result<(), SweepError> {
    let io = |p: &Path, e: std::io::Error| {
        SweepError::Other(format!("{}: cannot write: {e}", p.display()))
    };
    let record = Record {
        tool: "pneuflex",
        version: env!("CARGO_PKG_VERSION"),
        command: "sweep",
        scene: sweep.scene_path.display().to_string(),
        sets: &sweep.specs,
        seed: sweep.seed,
        points: sweep.len(),
        runs: sweep
            .base_scene
            .runs
            .iter()
            .map(|r| r.name.as_str())
            .collect(),
        metric_columns: sweep.columns.iter().map(|c| c.name()).collect(),
        table: "sweep.csv: one row per point and run; status ok | not_settled | diverged | error \
                (a diverged run's metrics are empty; a settling time that never came is inf)",
        heatmaps,
        heatmaps_skipped: heatmaps_skipped(sweep),
        partial: partial.map(|d| {
            format!(
                "interrupted: sweep.csv has the {d} of {} points done (in point order per chunk)",
                sweep.len()
            )
        }),
    };
    let json = dir.join("sweep.json");
    let text =
        serde_json::to_string_pretty(&record).map_err(|e| SweepError::Other(e.to_string()))?;
    std::fs::write(&json, text + "\n").map_err(|e| io(&json, e))?;
    Ok(())
}
