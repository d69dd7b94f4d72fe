//! A rig log on the board's clock (docs/identification.md, "Real-time logs"): `rig run` and `rig excite`
//! write, beside each row's sensors, the board time of the sample they came from (`board_t`) and the
//! board's echoes of the valve commands it applied, with the board time each took effect (`applied_t`,
//! `applied_u`; docs/protocol.md, 0x07). The host's own timing (late ticks, samples read twice, commands
//! sent in a burst) is then beside the point: the log is laid on the board's sample grid, each period's
//! command is the one the valve had, and a sample the host never read is a row that is not compared.
//!
//! Timing, as the emulated board runs it and the lockstep log assumes: the Sample stamped s_j holds the
//! state at the end of the sample period whose physics ran with the command in effect at s_j. So grid row
//! j's command, which the replay holds from row j to row j + 1, is the last echo at or before s_{j+1}.

use crate::IdentifyError;
use crate::log::Log;

/// A sample's board time may sit this far off the grid, in sample periods (the board counts whole µs).
const GRID_TOLERANCE: f64 = 0.1;

/// What the parser read of the board's columns, row by row.
#[derive(Clone, Debug, Default)]
pub struct BoardColumns {
    /// `board_t` of each data row (NaN where empty), aligned with the log's rows.
    pub sample_t: Vec<f64>,
    /// File line of each data row, for messages.
    pub lines: Vec<usize>,
    /// Every applied echo, (board time, duty), in the order written.
    pub applied: Vec<(f64, f64)>,
}

/// How a log was laid on the board's grid, for the report.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridSummary {
    /// The board's sample period, s.
    pub period_s: f64,
    /// Grid rows, and those with a sample the host read.
    pub rows: usize,
    /// Rows with a measurement.
    pub measured: usize,
    /// Applied echoes used.
    pub echoes: usize,
}

/// `host` (one row per host tick) laid on the board's sample grid, or `None` when the log carries no
/// applied echo (a board that does not send them: the host's rows are replayed as they are).
pub fn on_board_grid(
    host: &Log,
    board: &BoardColumns,
) -> Result<Option<(Log, GridSummary)>, IdentifyError> {
    let err = |line: Option<usize>, column: &str, message: String| IdentifyError::Log {
        file: host.path.clone(),
        line,
        column: Some(column.to_string()),
        message,
    };
    if board.applied.is_empty() {
        return Ok(None);
    }
    // The samples the host read: a row whose board time does not move on reused the last one.
    let mut samples: Vec<usize> = Vec::new();
    for (k, &b) in board.sample_t.iter().enumerate() {
        if b.is_finite() && samples.last().is_none_or(|&p| b > board.sample_t[p]) {
            samples.push(k);
        }
    }
    if samples.len() < 10 {
        return Err(err(
            None,
            "board_t",
            format!(
                "{} distinct board times: too few samples to replay",
                samples.len()
            ),
        ));
    }
    let b0 = board.sample_t[samples[0]];
    let mut steps: Vec<f64> = samples
        .windows(2)
        .map(|w| board.sample_t[w[1]] - board.sample_t[w[0]])
        .collect();
    steps.sort_by(f64::total_cmp);
    // The period is the step between consecutive samples: a low percentile of the steps, since a lost
    // sample makes a step of two periods or more (as many as a quarter of them on a loaded host).
    let period = steps[steps.len() / 20];
    // Each sample's place on the grid; off it by more than a tenth of a period is no board's clock.
    let mut index = Vec::with_capacity(samples.len());
    for &k in &samples {
        let b = board.sample_t[k];
        let j = ((b - b0) / period).round();
        if ((b - b0) - j * period).abs() > GRID_TOLERANCE * period {
            return Err(err(
                Some(board.lines[k]),
                "board_t",
                format!(
                    "{b} s is not on the board's sample grid ({b0} s + multiples of its period {period} s): \
                     the board's clock must stamp one sample a period"
                ),
            ));
        }
        index.push(j as usize);
    }
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
    // written and no further (the host's last rows may not have had room for the last few): the grid ends
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
        note: host.note.clone(),
    };
    let t0 = host.t[samples[first]];
    let mut next = first;
    let mut held = samples[first];
    for j in j0..=j1 {
        let measured = next < samples.len() && index[next] == j;
        if measured {
            held = samples[next];
            next += 1;
        }
        grid.t.push(t0 + (j - j0) as f64 * period);
        // The last row's command is never used (it acts after the log ends).
        grid.u.push(in_effect(grid_t(j + 1)).unwrap_or(0.0));
        grid.x.push(host.x[held]);
        grid.p_a.push(host.p_a[held]);
        grid.p_b.push(host.p_b[held]);
        grid.f_e.push(host.f_e[held]);
        grid.measured.push(measured);
    }
    // The contact force drives the replay (it is an input, not compared): across a sample the host did
    // not read it is the line between the samples either side, not the last one held.
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
    let summary = GridSummary {
        period_s: period,
        rows: n,
        measured: grid.measured.iter().filter(|&&m| m).count(),
        echoes: echoes.len(),
    };
    let lost = summary.rows - summary.measured;
    let said = format!(
        "replayed on the board's clock: {} of {} sample periods measured ({lost} samples the host did not \
         read), the valve's commands from {} applied echoes",
        summary.measured, summary.rows, summary.echoes
    );
    grid.note = Some(match grid.note {
        Some(n) => format!("{said}; {n}"),
        None => said,
    });
    Ok(Some((grid, summary)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log::parse_log;
    use std::path::Path;

    /// A rig trace (schema 2) of `n` host ticks at 1 ms: the host reads sample `sample(k)` at tick k
    /// (None: no new one) and writes echo `echo(k)` = (board time, duty) in row k.
    fn trace(
        n: usize,
        sample: impl Fn(usize) -> Option<usize>,
        echo: impl Fn(usize) -> Option<(f64, f64)>,
    ) -> String {
        let mut s = String::from(
            "# pneuflex 0.1.0, trace schema 2\nt,f_ref,f_e,x,x_r,p_a,p_b,u,board_t,applied_t,applied_u,wall_time,fault\n",
        );
        let mut last = None;
        for k in 0..n {
            last = sample(k).or(last);
            // Sample j reads x = j mm, p_a = 2e5 + j Pa, f_e = j N: which sample a row holds is plain.
            let (b, x, f) = match last {
                Some(j) => (
                    format!("{:.6}", 5.0 + j as f64 * 1e-3),
                    j as f64 * 1e-3,
                    j as f64,
                ),
                None => (String::new(), 0.0, 0.0),
            };
            let (at, au) = match echo(k) {
                Some((t, u)) => (format!("{t:.6}"), format!("{u}")),
                None => (String::new(), String::new()),
            };
            s += &format!(
                "{},0,{f},{x},0,{},{},0.9,{b},{at},{au},0,\n",
                k as f64 * 1e-3,
                2e5 + x * 1e3,
                2e5
            );
        }
        s + &format!("# end: complete, {n} rows\n")
    }

    fn read(text: &str) -> Result<Log, IdentifyError> {
        parse_log(Path::new("rt/trace.csv"), text, String::new())
    }

    #[test]
    fn a_log_is_laid_on_the_board_grid_with_the_commands_the_valve_had() {
        // Samples 0..60, every third not read by the host (it read the next one late instead); the
        // board applied duty j/100 at sample j's time for j = 2..60, echoed two rows late.
        let n = 62;
        let sample = |k: usize| (k < 60 && k % 3 != 1).then_some(k);
        let echo = |k: usize| {
            (4..62)
                .contains(&k)
                .then(|| ((5.0 + (k - 2) as f64 * 1e-3), (k - 2) as f64 / 100.0))
        };
        let log = read(&trace(n, sample, echo)).unwrap();
        // The first row is the first sample read whose next period ran with a command: sample 2's
        // command is the first, so sample 1 would do, but the host did not read it; row r holds sample
        // 2 + r.
        let j0 = (log.x[0] * 1e3).round() as usize;
        assert_eq!(j0, 2);
        for (r, &m) in log.measured.iter().enumerate() {
            let j = j0 + r;
            assert_eq!(m, j % 3 != 1, "row {r} (sample {j})");
            // Row j's command acts over the next period: the duty applied at sample j + 1's time (the last
            // row's acts after the log and is not used).
            assert!(
                r + 1 == log.len() || (log.u[r] - (j + 1) as f64 / 100.0).abs() < 1e-12,
                "row {r}: u {} for sample {j}",
                log.u[r]
            );
            if m {
                assert!((log.x[r] - j as f64 * 1e-3).abs() < 1e-12);
            } else {
                // A lost sample: its force the line between its neighbours (exact here), its sensors held.
                assert!(
                    (log.f_e[r] - j as f64).abs() < 1e-9,
                    "row {r}: f_e {}",
                    log.f_e[r]
                );
                assert!((log.x[r] - (j - 1) as f64 * 1e-3).abs() < 1e-12);
            }
            assert!((log.t[r] - log.t[0] - r as f64 * 1e-3).abs() < 1e-9);
        }
        assert!(log.measured.last() == Some(&true));
        assert!(
            log.note.as_deref().unwrap().contains("board's clock"),
            "{:?}",
            log.note
        );
    }

    #[test]
    fn a_replay_starts_and_compares_only_on_measured_rows() {
        use crate::replay::{Prepared, ReplayOptions};
        // 400 periods, one sample in three lost; segments of 10 rows, the held-out part from row 301.
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
            "the held-out part's nominal start is a lost sample"
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
        assert!(log.u.iter().all(|&u| u == 0.9), "the host's command column");
    }

    #[test]
    fn bad_board_cells_name_the_line_and_column() {
        let good = trace(30, Some, |k| Some((5.0 + k as f64 * 1e-3, 0.1)));
        // Line 3 is the first data row.
        let cases = [
            (",0.1,0,\n", ",1.5,0,\n", "applied_u", "duty in [-1, 1]"),
            (",0.1,0,\n", ",,0,\n", "applied_u", "needs its time"),
            (
                "5.000000,5.000000",
                "5.000000,x",
                "applied_t",
                "not a finite number",
            ),
            (
                "5.000000,5.000000",
                "NaN,5.000000",
                "board_t",
                "not a finite number",
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
        // A sample off the board's 1 ms grid.
        let bad = good.replacen("5.010000,5.010000", "5.010400,5.010000", 1);
        let e = read(&bad).expect_err("off the grid").to_string();
        assert!(
            e.starts_with("rt/trace.csv:13: column `board_t`")
                && e.contains("not on the board's sample grid"),
            "{e}"
        );
    }
}
