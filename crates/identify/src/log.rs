//! Rig logs: `trace.csv` as `pneuflex rig run` and `rig excite` write it (docs/rig.md, "Trace"): comment
//! lines, a header naming the columns, one row per tick, the end marker. Identification needs `t`, `u`,
//! `x`, `p_a`, `p_b` and `f_e`; rows after the first fault are not used (the valve was then in its safe
//! state, not at `u`).

use std::path::{Path, PathBuf};

use crate::IdentifyError;

/// The columns identification reads, in this order.
pub const COLUMNS: [&str; 6] = ["t", "u", "x", "p_a", "p_b", "f_e"];

/// One log: the columns identification uses, SI units, pressures absolute.
#[derive(Clone, Debug, PartialEq)]
pub struct Log {
    /// The file.
    pub path: PathBuf,
    /// SHA-256 of the file's bytes.
    pub sha256: String,
    /// Time, s (strictly increasing).
    pub t: Vec<f64>,
    /// Valve command in [-1, 1], applied from this row to the next.
    pub u: Vec<f64>,
    /// Position, m.
    pub x: Vec<f64>,
    /// Chamber A pressure, Pa absolute.
    pub p_a: Vec<f64>,
    /// Chamber B pressure, Pa absolute.
    pub p_b: Vec<f64>,
    /// Contact force, N (the flange pushing is positive; f_ext on the flange = -f_e).
    pub f_e: Vec<f64>,
    /// Rows dropped at the end, and why (a fault, a cut trace), for the report.
    pub note: Option<String>,
}

impl Log {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.t.len()
    }
    /// Whether the log has no rows.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
    /// The median sample period, s.
    pub fn dt(&self) -> f64 {
        let mut d: Vec<f64> = self.t.windows(2).map(|w| w[1] - w[0]).collect();
        if d.is_empty() {
            return 0.0;
        }
        d.sort_by(f64::total_cmp);
        d[d.len() / 2]
    }
    /// The rows `[a, b)` as a log of their own (a held-out validation part).
    pub fn slice(&self, a: usize, b: usize) -> Log {
        Log {
            path: self.path.clone(),
            sha256: self.sha256.clone(),
            t: self.t[a..b].to_vec(),
            u: self.u[a..b].to_vec(),
            x: self.x[a..b].to_vec(),
            p_a: self.p_a[a..b].to_vec(),
            p_b: self.p_b[a..b].to_vec(),
            f_e: self.f_e[a..b].to_vec(),
            note: self.note.clone(),
        }
    }
}

/// How much of a log identification takes: its rows and its time span (the replay's cost grows with both),
/// refused beyond with the number and the option that raises the limit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogLimits {
    /// Largest number of data rows of one log (`--max-rows`).
    pub max_rows: usize,
    /// Longest time span of one log, s (`--max-log-s`).
    pub max_span_s: f64,
}

impl Default for LogLimits {
    fn default() -> Self {
        Self {
            max_rows: 2_000_000,
            max_span_s: 3600.0,
        }
    }
}

/// The most bytes a row of a trace takes, for the file-size limit that goes with `max_rows`: a rig trace's
/// row is ~120 bytes; this leaves room for long numbers.
const MAX_BYTES_PER_ROW: u64 = 512;

/// A gap in time that identification refuses: more than this many median sample periods (and more than
/// [`MIN_GAP_S`]): the replay would integrate the whole gap with the last command held.
pub const MAX_GAP_PERIODS: f64 = 50.0;
/// Gaps shorter than this are accepted whatever the sample period.
pub const MIN_GAP_S: f64 = 0.05;

/// Reads a trace file. Errors name the file and, where a row or column is to blame, the line and the column.
pub fn read_log(path: &Path) -> Result<Log, IdentifyError> {
    read_log_limited(path, &LogLimits::default())
}

/// [`read_log`] within `limits`: the file's size is checked against the rows limit before it is read.
pub fn read_log_limited(path: &Path, limits: &LogLimits) -> Result<Log, IdentifyError> {
    let size = pneuflex_files::input::check_regular(path, pneuflex_files::InputKind::Trace)
        .map_err(|e| IdentifyError::Input(e.to_string()))?;
    let max_bytes = (limits.max_rows as u64).saturating_mul(MAX_BYTES_PER_ROW) + 65_536;
    if size > max_bytes {
        return Err(IdentifyError::Log {
            file: path.to_path_buf(),
            line: None,
            column: None,
            message: format!(
                "{size} bytes: more than a log of {} rows takes ({max_bytes} bytes); cut the log, or raise \
                 --max-rows",
                limits.max_rows
            ),
        });
    }
    let text = pneuflex_files::read_text(path, pneuflex_files::InputKind::Trace)
        .map_err(|e| IdentifyError::Input(e.to_string()))?;
    let sha256 = pneuflex_files::sha256_hex(text.as_bytes());
    parse_log_limited(path, &text, sha256, limits)
}

/// Parses trace text (see [`read_log`]); `path` is used in messages.
pub fn parse_log(path: &Path, text: &str, sha256: String) -> Result<Log, IdentifyError> {
    parse_log_limited(path, text, sha256, &LogLimits::default())
}

/// [`parse_log`] within `limits`; a gap in time of more than [`MAX_GAP_PERIODS`] sample periods is refused
/// with its line.
pub fn parse_log_limited(
    path: &Path,
    text: &str,
    sha256: String,
    limits: &LogLimits,
) -> Result<Log, IdentifyError> {
    let err = |line: Option<usize>, column: Option<&str>, message: String| IdentifyError::Log {
        file: path.to_path_buf(),
        line,
        column: column.map(str::to_string),
        message,
    };
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.starts_with('#'));
    let Some((header_no, header)) = lines.next() else {
        return Err(err(None, None, "no column header (an empty trace?)".into()));
    };
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let mut idx = [0usize; COLUMNS.len()];
    for (i, c) in COLUMNS.iter().enumerate() {
        idx[i] = names.iter().position(|n| n == c).ok_or_else(|| {
            err(
                Some(header_no + 1),
                Some(c),
                format!(
                    "missing column `{c}` (identification needs {}; the header has {})",
                    COLUMNS.join(", "),
                    names.join(", ")
                ),
            )
        })?;
    }
    let fault = names.iter().position(|n| *n == "fault");
    let mut log = Log {
        path: path.to_path_buf(),
        sha256,
        t: Vec::new(),
        u: Vec::new(),
        x: Vec::new(),
        p_a: Vec::new(),
        p_b: Vec::new(),
        f_e: Vec::new(),
        note: None,
    };
    for (no, line) in lines {
        let line_no = no + 1;
        if line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() != names.len() {
            return Err(err(
                Some(line_no),
                None,
                format!(
                    "{} fields where the header has {} columns",
                    fields.len(),
                    names.len()
                ),
            ));
        }
        if let Some(f) = fault
            && !fields[f].trim().is_empty()
        {
            log.note = Some(format!(
                "rows from line {line_no} on not used: fault `{}` (the valve was safe, not at u)",
                fields[f].trim()
            ));
            break;
        }
        let mut v = [0.0; COLUMNS.len()];
        for (i, c) in COLUMNS.iter().enumerate() {
            let s = fields[idx[i]].trim();
            let x: f64 = s
                .parse()
                .map_err(|_| err(Some(line_no), Some(c), format!("`{s}` is not a number")))?;
            if !x.is_finite() {
                return Err(err(
                    Some(line_no),
                    Some(c),
                    format!("{x}: every value must be finite (a NaN row?)"),
                ));
            }
            v[i] = x;
        }
        if let Some(&prev) = log.t.last()
            && v[0] <= prev
        {
            return Err(err(
                Some(line_no),
                Some("t"),
                format!("time must increase: {} after {prev}", v[0]),
            ));
        }
        if log.t.len() >= limits.max_rows {
            return Err(err(
                Some(line_no),
                None,
                format!(
                    "more than {} data rows; cut the log, or raise --max-rows",
                    limits.max_rows
                ),
            ));
        }
        if let (Some(&t0), Some(&prev)) = (log.t.first(), log.t.last())
            && v[0] - t0 > limits.max_span_s
        {
            // A jump out of an even log is named as a jump, not as the span it makes.
            let mean_dt = (prev - t0) / (log.t.len() - 1).max(1) as f64;
            let gap = v[0] - prev;
            if log.t.len() > 1 && gap > MAX_GAP_PERIODS * mean_dt && gap > MIN_GAP_S {
                return Err(err(
                    Some(line_no),
                    Some("t"),
                    format!(
                        "time jumps by {gap} s, from {prev} to {} s, where the mean sample period is {mean_dt} s: \
                         identification replays a log as one continuous recording; cut it at the gap and give \
                         each part as its own --log",
                        v[0]
                    ),
                ));
            }
            return Err(err(
                Some(line_no),
                Some("t"),
                format!(
                    "t = {} s: the log spans more than {} s from its first row (t = {t0} s); cut the log, or \
                     raise --max-log-s",
                    v[0], limits.max_span_s
                ),
            ));
        }
        log.t.push(v[0]);
        log.u.push(v[1]);
        log.x.push(v[2]);
        log.p_a.push(v[3]);
        log.p_b.push(v[4]);
        log.f_e.push(v[5]);
    }
    if log.t.len() < 10 {
        return Err(err(
            None,
            None,
            format!(
                "{} data rows; identification needs a log of many ticks",
                log.t.len()
            ),
        ));
    }
    // A gap: the replay would integrate across it with the last command held, at the log's step.
    let dt = log.dt();
    if let Some(k) = (1..log.t.len()).find(|&k| {
        let gap = log.t[k] - log.t[k - 1];
        gap > MAX_GAP_PERIODS * dt && gap > MIN_GAP_S
    }) {
        let line = data_line_number(text, k);
        return Err(err(
            line,
            Some("t"),
            format!(
                "time jumps by {} s, from {} to {} s, where the median sample period is {dt} s: identification \
                 replays a log as one continuous recording; cut it at the gap and give each part as its own --log",
                log.t[k] - log.t[k - 1],
                log.t[k - 1],
                log.t[k]
            ),
        ));
    }
    if log.note.is_none() && !text.lines().any(|l| l.starts_with("# end:")) {
        log.note = Some("no end marker: the trace was cut (its rows are used)".into());
    }
    Ok(log)
}

/// The 1-based line of the `k`-th data row (comments, the header and blank lines skipped).
fn data_line_number(text: &str, k: usize) -> Option<usize> {
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.starts_with('#'))
        .skip(1)
        .filter(|(_, l)| !l.trim().is_empty())
        .nth(k)
        .map(|(i, _)| i + 1)
}
