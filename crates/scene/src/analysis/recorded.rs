//! A run recorded outside the simulation (on the rig, by `rig run`; a log given to `compare`) judged as the
//! scene's run: the same windows, metrics, Lyapunov check and warnings as a simulated run, from the same
//! code, so its `summary.json` and figures read as `run`'s do.

use super::adaptation::{lyapunov_summary, pinned_parameters};
use super::windows::compute_windows;
use crate::run::RunResult;
use crate::run::trace::Trace;
use crate::schema::{ControllerKind, Scene};
use serde::Serialize;

/// Run `index` of `scene` (a scene reduced by [`Scene::one_run`] or [`Scene::some_runs`] to the runs
/// recorded and the time they ran) as `trace` recorded it. `ended` is why the recording ended early (a rig fault): the run is then
/// treated as a diverged simulation is — its trace kept, no window metrics. `pwm_period_s` is the
/// valve's PWM period of the scene's plant (the event metrics average over it).
pub fn recorded_run(
    scene: &Scene,
    index: usize,
    name: &str,
    trace: Trace,
    ended: Option<String>,
    pwm_period_s: Option<f64>,
) -> RunResult {
    let run = &scene.runs[index];
    let windows = if ended.is_none() {
        compute_windows(scene, &trace, pwm_period_s)
    } else {
        Vec::new()
    };
    let warnings = pinned_parameters(run, &trace);
    RunResult {
        name: name.to_string(),
        controller: run.controller,
        windows,
        lyapunov: if run.controller == ControllerKind::Adaptive {
            lyapunov_summary(scene, run)
        } else {
            None
        },
        diverged: ended,
        interrupted: None,
        warnings,
        pwm_period_s,
        trace,
    }
}

/// What a rig recording's summary says of its two records (`summary.json` `rig`): which one its windows were
/// judged on, and the host's stalls. A rig trace holds the loop's columns (what the controller saw: the
/// newest sample at each tick, on the host's clock) and the board's own record (every sample it sent, on
/// its clock); a host descheduled for a few ms reads late and then in a burst, which the loop's columns show
/// as steps and repeats the plant never made. The plant's verdict (settled, oscillating) is the board's.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RigRecord {
    /// `board` (the board's samples on its sample grid) or `host` (the loop's columns).
    pub judged_on: &'static str,
    /// What the record held, or why the board's could not be used.
    pub note: String,
    /// The host loop's stalls (None: the trace has no `wall_time`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub host_stalls: Option<HostStalls>,
}

/// The host loop's stalls, from the ticks' start times (`wall_time`): the host's timing, not the plant's.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HostStalls {
    /// A stall is a tick starting more than this after the one before (1.5 periods: half a period late), s.
    pub threshold_s: f64,
    /// How many stalls.
    pub count: usize,
    /// Ticks that started more than half a period after their time on the loop's schedule (the stalled ones
    /// and those run back to back after them while the loop caught up).
    pub late_ticks: usize,
    /// The longest gap between two tick starts, s.
    pub longest_s: f64,
    /// The longest stalls, longest first (at most [`STALLS_LISTED`]).
    pub longest: Vec<Stall>,
}

/// One stall of the host loop.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Stall {
    /// The run time of the tick after the gap, s.
    pub at_s: f64,
    /// The gap between its start and the previous tick's, s.
    pub gap_s: f64,
}

/// How many stalls `summary.json` lists.
pub const STALLS_LISTED: usize = 10;

/// One sample of the board's record in a rig trace.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoardSample {
    /// The trace's line.
    pub line: usize,
    /// Board time, s.
    pub t: f64,
    /// Contact force, N (NaN when the cell is empty).
    pub f_e: f64,
}

/// The rig's own columns of a trace that [`Trace::from_csv`] leaves out.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RigColumns {
    /// The board's record (`board_t`, `board_f_e`), in the order written: rows with no sample are skipped.
    pub board: Vec<BoardSample>,
    /// Each tick's start, s since the Unix epoch (`wall_time`; None: no such column).
    pub wall_time: Option<Vec<f64>>,
}

/// The board's record and the ticks' start times of a rig trace (the text of `trace.csv`, rows as
/// [`Trace::from_csv`] reads them). Columns that are absent give an empty record / no wall time; a cell that
/// is not a number is an error naming the line and the column.
pub fn rig_columns(text: &str) -> Result<RigColumns, String> {
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim_start_matches('\u{feff}')))
        .filter(|(_, l)| !l.starts_with('#') && !l.trim().is_empty());
    let Some((_, header)) = lines.next() else {
        return Ok(RigColumns::default());
    };
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let at = |n: &str| names.iter().position(|c| *c == n);
    let (board_t, board_f_e, wall) = (at("board_t"), at("board_f_e"), at("wall_time"));
    let mut out = RigColumns {
        board: Vec::new(),
        wall_time: wall.map(|_| Vec::new()),
    };
    for (line, row) in lines {
        let cells: Vec<&str> = row.split(',').collect();
        let cell = |i: Option<usize>| -> Result<Option<f64>, String> {
            let Some(i) = i else { return Ok(None) };
            let c = cells.get(i).map_or("", |c| c.trim());
            if c.is_empty() {
                return Ok(None);
            }
            c.parse()
                .map(Some)
                .map_err(|_| format!("line {line}: column `{}`: `{c}` is not a number", names[i]))
        };
        if let Some(t) = cell(board_t)? {
            out.board.push(BoardSample {
                line,
                t,
                f_e: cell(board_f_e)?.unwrap_or(f64::NAN),
            });
        }
        if let Some(w) = out.wall_time.as_mut() {
            w.push(cell(wall)?.unwrap_or(f64::NAN));
        }
    }
    Ok(out)
}

/// The host loop's stalls from its ticks' run times `t` (k·dt) and start times `wall` (s, any origin), at
/// the control period `dt`. None when there is no tick or a start time is missing.
pub fn host_stalls(t: &[f64], wall: &[f64], dt: f64) -> Option<HostStalls> {
    let n = t.len().min(wall.len());
    if n == 0 || wall[..n].iter().any(|w| !w.is_finite()) {
        return None;
    }
    let threshold_s = 1.5 * dt;
    // The trace keeps start times to the µs: so are the gaps reported.
    let us = |s: f64| (s * 1e6).round() / 1e6;
    let mut stalls: Vec<Stall> = (1..n)
        .filter(|&k| wall[k] - wall[k - 1] > threshold_s)
        .map(|k| Stall {
            at_s: t[k],
            gap_s: us(wall[k] - wall[k - 1]),
        })
        .collect();
    let late_ticks = (0..n)
        .filter(|&k| (wall[k] - wall[0]) - (t[k] - t[0]) > 0.5 * dt)
        .count();
    let count = stalls.len();
    stalls.sort_by(|a, b| b.gap_s.total_cmp(&a.gap_s).then(a.at_s.total_cmp(&b.at_s)));
    stalls.truncate(STALLS_LISTED);
    Some(HostStalls {
        threshold_s,
        count,
        late_ticks,
        longest_s: stalls.first().map_or(0.0, |s| s.gap_s),
        longest: stalls,
    })
}

/// A sample this far off the board's grid, in periods, is not on it (the board counts whole µs).
const GRID_TOLERANCE: f64 = 0.1;

/// `host` (the loop's columns, one row a tick at `dt`) with its contact force replaced by the board's record
/// laid on the board's sample grid: row j holds the board's j-th sample period from the record's first
/// (the sample the loop read first, at tick 0), with its reference the loop's at tick j. A sample period
/// missing from the record is the line between its neighbours; the grid ends at the record's last sample
/// or the loop's last tick. Returns the trace and what it holds, or why the record cannot be used (none in
/// the trace, a clock that goes back, a sample period other than the loop's, a sample off the grid).
pub fn on_board_grid(
    host: &Trace,
    board: &[BoardSample],
    dt: f64,
) -> Result<(Trace, String), String> {
    if board.len() < 2 || host.is_empty() {
        return Err("the trace holds no board record (`board_t`, `board_f_e`)".into());
    }
    if let Some(s) = board.iter().find(|s| !s.t.is_finite()) {
        return Err(format!("line {}: `board_t` is {}", s.line, s.t));
    }
    if let Some(w) = board.windows(2).find(|w| w[1].t <= w[0].t) {
        return Err(format!(
            "line {}: `board_t` {} does not follow {} (line {}): the board's clock went back",
            w[1].line, w[1].t, w[0].t, w[0].line
        ));
    }
    let mut steps: Vec<f64> = board.windows(2).map(|w| w[1].t - w[0].t).collect();
    steps.sort_by(f64::total_cmp);
    let period = steps[steps.len() / 2];
    if (period - dt).abs() > 0.01 * dt {
        // The board counts whole µs.
        let period = (period * 1e6).round() / 1e6;
        return Err(format!(
            "the board samples every {period} s and the loop runs every {dt} s: its record is not on the \
             loop's grid"
        ));
    }
    let n_host = host.len();
    let mut f_e: Vec<Option<f64>> = Vec::new();
    let mut past_the_loop = 0;
    for s in board {
        let j = (s.t - board[0].t) / dt;
        if (j - j.round()).abs() > GRID_TOLERANCE {
            return Err(format!(
                "line {}: `board_t` {} is {:.2} periods off the board's {dt} s grid",
                s.line,
                s.t,
                (j - j.round()).abs()
            ));
        }
        let j = j.round() as usize;
        if j >= n_host {
            past_the_loop += 1;
            continue;
        }
        if f_e.len() <= j {
            f_e.resize(j + 1, None);
        }
        if f_e[j].is_some() {
            return Err(format!(
                "line {}: `board_t` {} is the board's sample period {j} again",
                s.line, s.t
            ));
        }
        f_e[j] = Some(s.f_e).filter(|v| v.is_finite());
    }
    // The loop's rows are its ticks, k·dt from the first: row j's reference is the one at grid row j.
    let t = host.t();
    if let Some(k) =
        (0..f_e.len()).find(|&k| ((t[k] - t[0]) - k as f64 * dt).abs() > GRID_TOLERANCE * dt)
    {
        return Err(format!(
            "the loop's row {k} is at t = {} s, not on its {dt} s ticks",
            t[k]
        ));
    }
    let rows = f_e.len();
    let missing = f_e.iter().filter(|v| v.is_none()).count();
    let known: Vec<(usize, f64)> = f_e
        .iter()
        .enumerate()
        .filter_map(|(j, v)| v.map(|v| (j, v)))
        .collect();
    if known.len() < 2 {
        return Err("the board's record holds fewer than two readings of the contact force".into());
    }
    // A sample period missing from the record: the line between the samples either side.
    let mut next = 0;
    let grid: Vec<f64> = (0..rows)
        .map(|j| {
            while next + 1 < known.len() && known[next + 1].0 <= j {
                next += 1;
            }
            let (j0, v0) = known[next];
            match known.get(next + 1) {
                Some(&(j1, v1)) if j > j0 => v0 + (v1 - v0) * (j - j0) as f64 / (j1 - j0) as f64,
                _ => v0,
            }
        })
        .collect();
    let mut columns = host.clone().into_columns();
    for (_, data) in &mut columns {
        data.truncate(rows);
    }
    columns[pneuflex_control::signal::index::F_E].1 = grid;
    let trace = Trace::from_columns(columns).map_err(|e| e.to_string())?;
    let mut note = format!(
        "the board's record: {rows} sample periods of {dt} s on its own clock ({missing} missing from it"
    );
    if missing > 0 {
        note += ", their contact force the line between the samples either side";
    }
    note += ")";
    if rows < n_host {
        note += &format!(
            "; the loop's last {} ticks are past its last sample written",
            n_host - rows
        );
    }
    if past_the_loop > 0 {
        note += &format!("; {past_the_loop} samples past the loop's last tick left out");
    }
    Ok((trace, note))
}
