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
fn heatmap_cells(sweep: &Sweep, results: &[PointResult], metric: usize, ext: &str) -> Vec<Map> {
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
    // The cell says what sweep.csv says: the metric's value (an infinite settling time when its window did
    // not settle), no value for a run that diverged or failed; a run that did not settle in some window is
    // flagged, since its numbers describe a loop that does not work.
    let value = |p: &PointResult, run: usize| -> Option<f64> {
        let r = p.runs.get(run)?;
        match r.status {
            Status::Diverged | Status::Error => None,
            Status::NotSettled | Status::Ok => r.metrics[metric],
        }
    };
    let unsettled = |p: &PointResult, run: usize| -> bool {
        p.runs
            .get(run)
            .is_some_and(|r| r.status == Status::NotSettled)
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
    let scene = &sweep.base_scene.name();
    let what = with_unit(&name);
    for (k, run) in sweep.base_scene.runs().iter().enumerate() {
        out.push(Map {
            file: format!("heatmap-{}-{name}.{ext}", run.name),
            title: format!(
                "{scene}, run {} ({}): {what}",
                run.name,
                run.controller.name()
            ),
            cells: cells(&|p| value(p, k)),
            marked: marks(&|p| fragile(p, k)),
            flagged: marks(&|p| unsettled(p, k)),
            diverging: false,
        });
    }
    let find = |kind: &str| {
        sweep
            .base_scene
            .runs()
            .iter()
            .position(|r| r.controller.name() == kind)
    };
    if let (Some(a), Some(i)) = (find("adaptive"), find("impedance")) {
        let (an, inn) = (
            &sweep.base_scene.runs()[a].name,
            &sweep.base_scene.runs()[i].name,
        );
        out.push(Map {
            file: format!("heatmap-{an}-minus-{inn}-{name}.{ext}"),
            title: format!("{scene}, {an} − {inn}: {what} (< 0: {an} lower)"),
            cells: cells(&|p| Some(value(p, a)? - value(p, i)?)),
            marked: marks(&|p| fragile(p, a) || fragile(p, i)),
            flagged: marks(&|p| unsettled(p, a) || unsettled(p, i)),
            diverging: true,
        });
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
    format: pneuflex_plot::Format,
) -> Result<Vec<PathBuf>, SweepError> {
    let io = |p: &Path, e: std::io::Error| {
        SweepError::Other(format!("{}: cannot write: {e}", p.display()))
    };
    let csv = dir.join("sweep.csv");
    std::fs::write(&csv, sweep.table(results)).map_err(|e| io(&csv, e))?;
    let mut files = vec![PathBuf::from("sweep.csv")];
    files.extend(write_figures(dir, sweep, results, metrics, format)?);
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
    format: pneuflex_plot::Format,
) -> Result<Vec<PathBuf>, SweepError> {
    let mut files = Vec::new();
    let mut all_maps = Vec::new();
    for metric in metrics {
        let metric_i = sweep.metric_index(metric)?;
        if !has_heatmaps(sweep) {
            continue;
        }
        let maps = heatmap_cells(sweep, results, metric_i, format.ext());
        write_maps(dir, sweep, &maps, metric_i, &mut files)?;
        all_maps.extend(maps.into_iter().map(|m| m.file));
    }
    write_record(dir, sweep, all_maps, None)?;
    files.push(PathBuf::from("sweep.json"));
    Ok(files)
}

/// One heatmap to draw.
struct Map {
    /// File name, relative.
    file: String,
    title: String,
    cells: Vec<Option<f64>>,
    /// A fragile settling time.
    marked: Vec<bool>,
    /// A run that did not settle in some window (status not_settled).
    flagged: Vec<bool>,
    /// A difference: the scale centred on zero.
    diverging: bool,
}

/// Units by the suffix of a key's last part, longest first (the scene's and the sheets' naming convention).
const UNITS: [(&str, &str); 22] = [
    ("_m3_per_s_pa", "m³/(s·Pa)"),
    ("_ns_per_m", "N·s/m"),
    ("_n_s_per_m", "N·s/m"),
    ("_n_per_m", "N/m"),
    ("_m_per_n", "m/N"),
    ("_per_m_s", "1/(m·s)"),
    ("_s_per_m", "s/m"),
    ("_m_per_s2", "m/s²"),
    ("_m_per_s", "m/s"),
    ("_per_m", "1/m"),
    ("_m3", "m³"),
    ("_m2", "m²"),
    ("_kg", "kg"),
    ("_hz", "Hz"),
    ("_pct", "%"),
    ("_deg", "deg"),
    ("_pa", "Pa"),
    ("_k", "K"),
    ("_s", "s"),
    ("_n", "N"),
    ("_m", "m"),
    ("_rad", "rad"),
];

/// A key or metric as an axis label: the unit suffix of its last part dropped, underscores as spaces, and
/// the unit in brackets (`environment.stiffness_n_per_m` -> `environment.stiffness [N/m]`).
fn with_unit(key: &str) -> String {
    let (head, last) = key.rsplit_once('.').map_or(("", key), |(h, l)| (h, l));
    let (name, unit) = UNITS
        .iter()
        .find_map(|(suffix, unit)| last.strip_suffix(suffix).map(|n| (n, Some(*unit))))
        .filter(|(n, _)| !n.is_empty())
        .unwrap_or((last, None));
    // Words are spaced; a symbol with a subscript (b_d, k_e) keeps its underscore.
    let name = if name.split('_').all(|w| w.len() <= 2) {
        name.to_string()
    } else {
        name.replace('_', " ")
    };
    let text = if head.is_empty() {
        name
    } else {
        format!("{head}.{name}")
    };
    match unit {
        Some(u) => format!("{text} [{u}]"),
        None => text,
    }
}

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
        let (x_label, y_label) = (
            with_unit(&sweep.points.keys[grid[0].0].text),
            with_unit(&sweep.points.keys[grid[1].0].text),
        );
        let value_label = with_unit(&sweep.columns[metric_i].name());
        for m in maps {
            let path = dir.join(&m.file);
            pneuflex_plot::write_heatmap(
                &path,
                &pneuflex_plot::Heatmap {
                    title: &m.title,
                    x_label: &x_label,
                    x_ticks: &xt,
                    y_label: &y_label,
                    y_ticks: &yt,
                    cells: &m.cells,
                    marked: &m.marked,
                    mark_note: "* settling time hangs on the band (±5 % moves it > 10 %)",
                    flagged: &m.flagged,
                    flag_note: "†: the run did not settle in some window (sweep.csv: status not_settled)",
                    value_label: &value_label,
                    diverging: m.diverging,
                },
            )
            .map_err(|e| SweepError::Other(e.to_string()))?;
            files.push(PathBuf::from(&m.file));
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
            .runs()
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

#[cfg(test)]
mod tests {
    use super::with_unit;

    #[test]
    fn keys_become_labels_with_their_units() {
        for (key, label) in [
            (
                "environment.stiffness_n_per_m",
                "environment.stiffness [N/m]",
            ),
            (
                "runs[*].impedance.b_d_ns_per_m",
                "runs[*].impedance.b_d [N·s/m]",
            ),
            ("environment.x_e_m", "environment.x_e [m]"),
            (
                "runs[adaptive].inner.kp_per_m",
                "runs[adaptive].inner.kp [1/m]",
            ),
            ("runs[0].inner.ki_per_m_s", "runs[0].inner.ki [1/(m·s)]"),
            (
                "stiffness_change.settling_time_s",
                "stiffness_change.settling time [s]",
            ),
            ("sine.phase_lag_deg", "sine.phase lag [deg]"),
            (
                "stiffness_change.recovery_overshoot_pct",
                "stiffness_change.recovery overshoot [%]",
            ),
            (
                "plant.actuator:mechanics.moving_mass_kg",
                "plant.actuator:mechanics.moving mass [kg]",
            ),
            (
                "valve.sonic_conductance_m3_per_s_pa",
                "valve.sonic conductance [m³/(s·Pa)]",
            ),
            ("sine.amplitude_ratio", "sine.amplitude ratio"),
            ("plant.substeps", "plant.substeps"),
            // A name that is only a unit keeps its name.
            ("x.m", "x.m"),
        ] {
            assert_eq!(with_unit(key), label, "{key}");
        }
    }
}
