//! A rig log on the board's clock (docs/identification.md, "Real-time logs"). `rig run` and `rig excite`
//! write, beside the loop's columns, the board's own record: every sample the board sent, with its board
//! time (`board_t`, `board_x`, `board_f_e`, `board_p_a`, `board_p_b`), and every echo of a valve command it
//! applied, with the board time it took effect (`applied_t`, `applied_u`; docs/protocol.md, 0x07), one of
//! each a row in the order the board sent them. The host's own timing (late ticks, samples it read twice or
//! never, commands sent in a burst) is then beside the point: the log is the board's samples on its sample
//! grid, and each period's command is the one the valve had.
//!
//! Timing, as the emulated board runs it and the lockstep log assumes: the Sample stamped s_j holds the
//! state at the end of the sample period whose physics ran with the command in effect at s_j. So grid row
//! j's command, which the replay holds from row j to row j + 1, is the last echo at or before s_{j+1}.

use crate::IdentifyError;
use crate::log_rows::Log;

/// The sample periods identification replays, s: a median period outside is no rig's log (a time column in
/// the wrong unit, a corrupt clock; a 1 kHz log in ms read as s has 1 s); the replay would take a step per row
/// at that period, and a pneumatic actuator's dynamics (~10 ms) need more than 2 samples a second.
pub const PERIOD_RANGE_S: (f64, f64) = (1e-5, 0.5);

/// A sample's board time may sit this far off the grid, in sample periods (the board counts whole µs).
const GRID_TOLERANCE: f64 = 0.1;

/// One sample of the board's record: board time, position, contact force, chamber pressures (SI), and the
/// line it stands on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RecordedSample {
    /// Board time, s.
    pub t: f64,
    /// Position, m.
    pub x: f64,
    /// Contact force, N.
    pub f_e: f64,
    /// Chamber A pressure, Pa absolute.
    pub p_a: f64,
    /// Chamber B pressure, Pa absolute.
    pub p_b: f64,
    /// The file's line.
    pub line: usize,
}

/// The board's record as the parser read it.
#[derive(Clone, Debug, Default)]
pub struct BoardColumns {
    /// Every sample of the record, in the order written.
    pub samples: Vec<RecordedSample>,
    /// Every applied echo, (board time, duty), in the order written.
    pub applied: Vec<(f64, f64)>,
}

/// How a log was laid on the board's grid, for the report.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridSummary {
    /// The board's sample period, s.
    pub period_s: f64,
    /// Grid rows.
    pub rows: usize,
    /// Rows with a sample in the record.
    pub measured: usize,
    /// Applied echoes used.
    pub echoes: usize,
}

impl GridSummary {
    /// What the log's note says of it.
    pub fn note(&self) -> String {
        format!(
            "replayed on the board's clock: its record of {} sample periods ({} missing from it), the valve's \
             commands from {} applied echoes",
            self.rows,
            self.rows - self.measured,
            self.echoes
        )
    }
}

/// The board's record of `host`'s file as a log on the board's sample grid, with how it was laid, or `None`
/// when it holds no sample or no applied echo (a board that sends none: the host's rows are replayed as they
/// are). The log's note says so.
pub fn on_board_grid(
    host: &Log,
    board: &BoardColumns,
) -> Result<Option<(Log, GridSummary)>, IdentifyError> {
    let err = |line, column, message| log_error(host, line, column, message);
    let samples = &board.samples;
    if board.applied.is_empty() || samples.is_empty() {
        return Ok(None);
    }
    let (b0, period, index) = sample_grid(host, samples)?;
    let mut echoes = board.applied.clone();
    echoes.sort_by(|a, b| a.0.total_cmp(&b.0));
    let tol = 1e-3 * period;
    let grid_t = |j: usize| b0 + j as f64 * period;
    // The command in effect at board time s: the last echo at or before it.
    let in_effect = |s: f64| -> Option<f64> {
        let n = echoes.partition_point(|e| e.0 <= s + tol);
        n.checked_sub(1).map(|i| echoes[i].1)
    };
    // The first row is a sample whose next period already ran with an applied command.
    let Some(first) = (0..samples.len()).find(|&i| in_effect(grid_t(index[i] + 1)).is_some())
    else {
        return Err(err(
            None,
            "applied_t",
            "every applied echo comes after the last sample: nothing to replay".into(),
        ));
    };
    let j0 = index[first];
    // The echoes are written in the order applied, so the valve's command is known up to the last one
    // written and no further (the loop's last rows may not have had room for the last few): the grid ends
    // at the last sample at or before it.
    let known_until = echoes.last().map_or(f64::NEG_INFINITY, |e| e.0);
    let j1 = index
        .iter()
        .rev()
        .copied()
        .find(|&j| grid_t(j) <= known_until + tol)
        .unwrap_or(j0);
    if j1 < j0 + 10 {
        return Err(err(
            None,
            "board_t",
            "fewer than 10 sample periods after the first applied command".into(),
        ));
    }
    let n = j1 - j0 + 1;
    let mut grid = Log {
        path: host.path.clone(),
        sha256: host.sha256.clone(),
        t: Vec::with_capacity(n),
        u: Vec::with_capacity(n),
        x: Vec::with_capacity(n),
        p_a: Vec::with_capacity(n),
        p_b: Vec::with_capacity(n),
        f_e: Vec::with_capacity(n),
        measured: Vec::with_capacity(n),
        note: None,
    };
    // The run's clock starts with its first command (the emulated plant's does, and with it the valve's PWM
    // carrier): the Sample stamped s holds the state at the end of its period, at run time s + T - a_0.
    // In sample periods from b0 (a whole number on a board that applies commands at its ticks): row j's
    // run time is then (j + 1 - start) periods to the bit, as a lockstep log's k dt, so that the valve's
    // PWM edges fall on the replay's steps where they fall on the rig's (off by an ulp they cost the
    // replay extra integration segments: 1.5x the fit's time with stick-slip and wall heat).
    let start = {
        let k = (echoes[0].0 - b0) / period;
        if (k - k.round()).abs() < 1e-6 {
            k.round()
        } else {
            k
        }
    };
    let mut next = first;
    let mut held = &samples[first];
    for j in j0..=j1 {
        let measured = next < samples.len() && index[next] == j;
        if measured {
            held = &samples[next];
            next += 1;
        }
        grid.t.push((j as f64 + 1.0 - start) * period);
        // The last row's command is never used (it acts after the log ends).
        grid.u.push(in_effect(grid_t(j + 1)).unwrap_or(0.0));
        grid.x.push(held.x);
        grid.p_a.push(held.p_a);
        grid.p_b.push(held.p_b);
        grid.f_e.push(held.f_e);
        grid.measured.push(measured);
    }
    interpolate_unmeasured_force(&mut grid);
    let summary = GridSummary {
        period_s: period,
        rows: n,
        measured: grid.measured.iter().filter(|&&m| m).count(),
        echoes: echoes.len(),
    };
    grid.note = Some(match &host.note {
        Some(n) => format!("{}; {n}", summary.note()),
        None => summary.note(),
    });
    Ok(Some((grid, summary)))
}

/// The board's sample grid: its first sample's time, s, its period, s (a low percentile of the steps
/// between samples, robust to samples missing from the record, to the µs the board counts), and each
/// sample's index on it; refused when too few, not forward in time, or off the grid.
fn sample_grid(
    host: &Log,
    samples: &[RecordedSample],
) -> Result<(f64, f64, Vec<usize>), IdentifyError> {
    let err = |line, column, message| log_error(host, line, column, message);
    if samples.len() < 10 {
        return Err(err(
            None,
            "board_t",
            format!(
                "{} samples in the board's record: too few to replay",
                samples.len()
            ),
        ));
    }
    if let Some(w) = samples.windows(2).find(|w| w[1].t <= w[0].t) {
        return Err(err(
            Some(w[1].line),
            "board_t",
            format!(
                "{} s after {} s: the board's record must go forward in time",
                w[1].t, w[0].t
            ),
        ));
    }
    let b0 = samples[0].t;
    let mut steps: Vec<f64> = samples.windows(2).map(|w| w[1].t - w[0].t).collect();
    steps.sort_by(f64::total_cmp);
    // A low percentile of the steps: a step of two periods or more is a sample missing from the record.
    let period = (steps[steps.len() / 20] * 1e6).round() * 1e-6;
    // A period of 0 (steps below half a µs) would put every sample at one grid row.
    let (lo, hi) = PERIOD_RANGE_S;
    if !(lo..=hi).contains(&period) {
        return Err(err(
            Some(samples[1].line),
            "board_t",
            format!(
                "the board's sample period is {:e} s (to the µs it counts), outside [{lo:e}, {hi}] s: no \
                 board's clock",
                steps[steps.len() / 20]
            ),
        ));
    }
    // Each sample's place on the grid; off it by more than a tenth of a period is no board's clock.
    let mut index = Vec::with_capacity(samples.len());
    for s in samples {
        let j = ((s.t - b0) / period).round();
        if ((s.t - b0) - j * period).abs() > GRID_TOLERANCE * period {
            return Err(err(
                Some(s.line),
                "board_t",
                format!(
                    "{} s is not on the board's sample grid ({b0} s + multiples of its period {period} s): \
                     the board's clock must stamp one sample a period",
                    s.t
                ),
            ));
        }
        index.push(j as usize);
    }
    Ok((b0, period, index))
}

/// An error in `host`'s log at `line` (if known) in `column`.
fn log_error(host: &Log, line: Option<usize>, column: &str, message: String) -> IdentifyError {
    IdentifyError::Log {
        file: host.path.clone(),
        line,
        column: Some(column.to_string()),
        message,
    }
}

/// A sample missing from the record (it overflowed, or the board skipped one) is not compared; the
/// contact force, an input of the replay, is the line between the samples either side across it.
pub(crate) fn interpolate_unmeasured_force(grid: &mut Log) {
    let n = grid.measured.len();
    let mut k = 0;
    while k < n {
        if grid.measured[k] {
            k += 1;
            continue;
        }
        let a = k - 1; // row 0 is measured
        let b = (k..n).find(|&i| grid.measured[i]).unwrap_or(n - 1);
        for i in k..b {
            let w = (i - a) as f64 / (b - a) as f64;
            grid.f_e[i] = grid.f_e[a] + w * (grid.f_e[b] - grid.f_e[a]);
        }
        k = b + 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log::parse_log;
    use std::path::Path;

    /// A rig trace (schema 2) of `n` host ticks at 1 ms, whose row k records sample `sample(k)` of the board
    /// (sample j at board time 5 s + j ms reads x = j mm, f_e = j N, p_a = 2e5 + j Pa) and echo `echo(k)` =
    /// (board time, duty). The loop's own columns hold a constant the grid must not use.
    fn trace(
        n: usize,
        sample: impl Fn(usize) -> Option<usize>,
        echo: impl Fn(usize) -> Option<(f64, f64)>,
    ) -> String {
        let mut s = String::from(
            "# pneuflex 0.1.0, trace schema 2\nt,f_ref,f_e,x,x_r,p_a,p_b,u,board_t,board_x,board_f_e,board_p_a,\
             board_p_b,applied_t,applied_u,wall_time,fault\n",
        );
        for k in 0..n {
            let board = match sample(k) {
                Some(j) => format!(
                    "{:.6},{},{},{},2e5",
                    5.0 + j as f64 * 1e-3,
                    j as f64 * 1e-3,
                    j as f64,
                    2e5 + j as f64
                ),
                None => ",,,,".into(),
            };
            let applied = match echo(k) {
                Some((t, u)) => format!("{t:.6},{u}"),
                None => ",".into(),
            };
            s += &format!(
                "{},0,7,0.01,0,3e5,3e5,0.9,{board},{applied},0,\n",
                k as f64 * 1e-3
            );
        }
        s + &format!("# end: complete, {n} rows\n")
    }

    fn read(text: &str) -> Result<Log, IdentifyError> {
        parse_log(Path::new("rt/trace.csv"), text, String::new())
    }

    #[test]
    fn a_log_is_the_boards_record_on_its_grid_with_the_commands_the_valve_had() {
        // The board's samples 0..60, recorded three rows late (the loop's FIFO), sample 30 missing from
        // the record; the board applied duty j/100 at sample j's time for j = 2..60, echoed two rows late.
        let n = 64;
        let sample = |k: usize| (3..63).contains(&k).then(|| k - 3).filter(|&j| j != 30);
        let echo = |k: usize| {
            (4..62)
                .contains(&k)
                .then(|| (5.0 + (k - 2) as f64 * 1e-3, (k - 2) as f64 / 100.0))
        };
        let log = read(&trace(n, sample, echo)).unwrap();
        // The first row is the first sample whose next period had a command: sample 1 (sample 2's period
        // ran with the first echo); row r holds sample 1 + r, up to sample 59.
        let j0 = (log.x[0] * 1e3).round() as usize;
        assert_eq!((j0, log.len()), (1, 59));
        for r in 0..log.len() {
            let j = j0 + r;
            assert_eq!(log.measured[r], j != 30, "row {r} (sample {j})");
            // Row j's command acts over the next period: the duty applied at sample j + 1's time (the last
            // row's acts after the log and is not used).
            assert!(
                r + 1 == log.len() || (log.u[r] - (j + 1) as f64 / 100.0).abs() < 1e-12,
                "row {r}: u {} for sample {j}",
                log.u[r]
            );
            // The board's readings, not the loop's columns; across the missing sample the force is the
            // line between its neighbours (exact here) and the rest held.
            assert!(
                (log.f_e[r] - j as f64).abs() < 1e-9,
                "row {r}: f_e {}",
                log.f_e[r]
            );
            let shown = if j == 30 { 29 } else { j };
            assert!((log.x[r] - shown as f64 * 1e-3).abs() < 1e-12);
            assert!((log.p_a[r] - 2e5 - shown as f64).abs() < 1e-9);
            // Run time: sample j ends its period at j + 1 ms past the first command (sample 2's time).
            assert!(
                (log.t[r] - (j as f64 + 1.0 - 2.0) * 1e-3).abs() < 1e-9,
                "row {r}: t {}",
                log.t[r]
            );
        }
        assert!(
            log.note.as_deref().unwrap().contains("board's clock"),
            "{:?}",
            log.note
        );
    }

    #[test]
    fn a_replay_starts_and_compares_only_on_measured_rows() {
        use crate::replay::{Prepared, ReplayOptions};
        // 400 periods, one sample in three missing from the record; segments of 10 rows, the held-out
        // part from row 301.
        let log = read(&trace(
            402,
            |k| (k < 400 && k % 3 != 1).then_some(k),
            |k| (k >= 1).then_some((5.0 + k as f64 * 1e-3, 0.2)),
        ))
        .unwrap();
        let o = ReplayOptions {
            segment_s: 0.01,
            settle_s: 0.002,
            ..ReplayOptions::default()
        };
        let p = Prepared::new(log.clone(), &o, 301);
        assert!(
            !log.measured[301],
            "the held-out part's nominal start is a missing sample"
        );
        assert!(
            log.measured[p.fit_end],
            "it starts from a measurement: row {}",
            p.fit_end
        );
        for &(s, _) in &p.segments {
            assert!(log.measured[s], "segment starting at row {s}");
        }
        assert!(!p.compared.is_empty() && !p.validation.is_empty());
        assert!(
            p.compared
                .iter()
                .chain(&p.validation)
                .all(|&k| log.measured[k])
        );
    }

    #[test]
    fn the_grid_ends_where_the_echoes_end() {
        // Echoes only up to sample 40's time: what the valve did after it is not known.
        let log = read(&trace(60, Some, |k| {
            (1..=40)
                .contains(&k)
                .then_some((5.0 + k as f64 * 1e-3, 0.5))
        }))
        .unwrap();
        let last = (log.x[log.len() - 1] * 1e3).round() as usize;
        assert_eq!(
            last, 40,
            "the last row is the last sample at or before the last echo"
        );
    }

    #[test]
    fn without_echoes_the_host_rows_are_replayed_as_they_are() {
        let log = read(&trace(30, Some, |_| None)).unwrap();
        assert_eq!(log.len(), 30);
        assert!(log.measured.iter().all(|&m| m));
        assert!(log.u.iter().all(|&u| u == 0.9), "the loop's command column");
        assert!(
            log.x.iter().all(|&x| x == 0.01),
            "the loop's position column"
        );
    }

    #[test]
    fn bad_board_cells_name_the_line_and_column() {
        let good = trace(30, Some, |k| Some((5.0 + k as f64 * 1e-3, 0.1)));
        // Line 3 is the first data row: `...,0.9,5.000000,0,0,200000,2e5,5.000000,0.1,0,`.
        let cases = [
            (",0.1,0,\n", ",1.5,0,\n", "applied_u", "duty in [-1, 1]"),
            (",0.1,0,\n", ",,0,\n", "applied_u", "needs its time"),
            (
                "2e5,5.000000,",
                "2e5,x,",
                "applied_t",
                "not a finite number",
            ),
            (
                "0.9,5.000000,",
                "0.9,NaN,",
                "board_t",
                "not a finite number",
            ),
            (
                "0.9,5.000000,0,0,",
                "0.9,5.000000,,0,",
                "board_x",
                "recorded whole",
            ),
            (
                "0.9,5.000000,0,0,200000,",
                "0.9,5.000000,0,0,-5,",
                "board_p_a",
                "Pa absolute",
            ),
        ];
        for (from, to, column, what) in cases {
            let bad = good.replacen(from, to, 1);
            assert_ne!(bad, good, "{from} -> {to}");
            let e = read(&bad).expect_err(to).to_string();
            assert!(e.starts_with("rt/trace.csv:3: column `"), "{e}");
            assert!(
                e.contains(&format!("`{column}`")) && e.contains(what),
                "{e}"
            );
        }
        // A sample off the board's 1 ms grid, and one back in time.
        let bad = good.replacen("0.9,5.010000,", "0.9,5.010400,", 1);
        let e = read(&bad).expect_err("off the grid").to_string();
        assert!(
            e.starts_with("rt/trace.csv:13: column `board_t`")
                && e.contains("not on the board's sample grid"),
            "{e}"
        );
        let bad = good.replacen("0.9,5.010000,", "0.9,5.008000,", 1);
        let e = read(&bad).expect_err("back in time").to_string();
        assert!(
            e.starts_with("rt/trace.csv:13: column `board_t`") && e.contains("go forward in time"),
            "{e}"
        );
    }
}
