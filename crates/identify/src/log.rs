//! Rig logs: `trace.csv` as `pneuflex rig run` and `rig excite` write it (docs/rig.md, "Trace"): comment
//! lines, a header naming the columns, one row per tick, the end marker. Identification needs `t`, `u`,
//! `x`, `p_a`, `p_b` and `f_e`; rows after the first fault are not used (the valve was then in its safe
//! state, not at `u`).

use std::path::Path;

use crate::IdentifyError;
use crate::board_time::{BoardColumns, RecordedSample};
use crate::log_format::LogFormat;
use pneuflex_files::output::RIG_TRACE_COLUMNS;

/// The board's record in a rig trace (schema 2: a sample and an applied echo a row), which lays a log on the
/// board's clock (crate::board_time): the first nine of the rig's own columns but the wall time and fault.
const BOARD_COLUMNS: [&str; 7] = [
    RIG_TRACE_COLUMNS[0],
    RIG_TRACE_COLUMNS[1],
    RIG_TRACE_COLUMNS[2],
    RIG_TRACE_COLUMNS[3],
    RIG_TRACE_COLUMNS[4],
    RIG_TRACE_COLUMNS[5],
    RIG_TRACE_COLUMNS[6],
];

pub use crate::log_format::COLUMNS;

pub use crate::log_rows::Log;

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

pub use crate::board_time::PERIOD_RANGE_S;
/// A step in time shorter than this share of the median period is a clock that does not tick evenly (a
/// duplicated or corrupt time stamp), refused at its line.
pub const MIN_PERIOD_SHARE: f64 = 0.01;

/// The longest line a log may have, bytes: a rig trace's row is ~120 bytes; a longer line is not a row.
pub const MAX_LINE_BYTES: usize = 64 << 10;

/// Reads a trace file. Errors name the file and, where a row or column is to blame, the line and the column.
pub fn read_log(path: &Path) -> Result<Log, IdentifyError> {
    read_log_limited(path, &LogLimits::default())
}

/// [`read_log`] within `limits`: the file's size is checked against the rows limit before it is read, and
/// it is read line by line (memory holds the columns identification uses, never the text).
pub fn read_log_limited(path: &Path, limits: &LogLimits) -> Result<Log, IdentifyError> {
    read_log_formatted(path, limits, &LogFormat::default())
}

/// [`read_log_limited`] for a log in `format` (another tool's export: [`LogFormat`]); a text log (a bag is
/// read by [`crate::log_bag::read_any_log`]).
pub fn read_log_formatted(
    path: &Path,
    limits: &LogLimits,
    format: &LogFormat,
) -> Result<Log, IdentifyError> {
    use std::io::BufRead;
    let size = pneuflex_files::input::check_regular(path, pneuflex_files::InputKind::Trace)
        .map_err(|e| IdentifyError::Input(e.to_string()))?;
    let max_bytes = (limits.max_rows as u64).saturating_mul(MAX_BYTES_PER_ROW) + 65_536;
    let err = |line: Option<usize>, message: String| IdentifyError::Log {
        file: path.to_path_buf(),
        line,
        column: None,
        message,
    };
    if size > max_bytes {
        return Err(err(
            None,
            format!(
                "{size} bytes: more than a log of {} rows takes ({max_bytes} bytes); cut the log, or raise \
                 --max-rows",
                limits.max_rows
            ),
        ));
    }
    let file = std::fs::File::open(path)
        .map_err(|e| IdentifyError::Input(format!("{}: cannot read: {e}", path.display())))?;
    let mut reader = std::io::BufReader::new(file);
    let mut hasher = pneuflex_files::provenance::Sha256Hasher::new();
    let mut parser = LogParser::new(path, *limits, format);
    let mut buf = Vec::new();
    let mut line_no = 0;
    loop {
        buf.clear();
        line_no += 1;
        // At most MAX_LINE_BYTES + 1 bytes of one line: a file of one endless line is refused, not read.
        let n = std::io::Read::take(&mut reader, MAX_LINE_BYTES as u64 + 1)
            .read_until(b'\n', &mut buf)
            .map_err(|e| IdentifyError::Input(format!("{}: cannot read: {e}", path.display())))?;
        if n == 0 {
            break;
        }
        hasher.update(&buf);
        if n > MAX_LINE_BYTES && buf.last() != Some(&b'\n') {
            return Err(err(
                Some(line_no),
                format!("a line longer than {MAX_LINE_BYTES} bytes: not a row of a trace"),
            ));
        }
        let text = std::str::from_utf8(&buf).map_err(|e| {
            err(
                Some(line_no),
                format!("not UTF-8 text (byte {})", e.valid_up_to()),
            )
        })?;
        let line = text.trim_end_matches(['\n', '\r']);
        let line = if line_no == 1 {
            line.trim_start_matches('\u{feff}')
        } else {
            line
        };
        if !parser.line(line_no, line)? {
            break;
        }
    }
    parser.finish(hasher.finish())
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
    parse_log_formatted(path, text, sha256, limits, &LogFormat::default())
}

/// [`parse_log_limited`] for a log in `format`.
pub fn parse_log_formatted(
    path: &Path,
    text: &str,
    sha256: String,
    limits: &LogLimits,
    format: &LogFormat,
) -> Result<Log, IdentifyError> {
    let mut parser = LogParser::new(path, *limits, format);
    for (i, line) in text.lines().enumerate() {
        if !parser.line(i + 1, line)? {
            break;
        }
    }
    parser.finish(sha256)
}

/// The range a reading of a pneumatic actuator can take, per column, far wider than any rig's (a value
/// beyond is a corrupt row, and would only make the replay blow up later without a line to blame).
fn plausible(column: &str) -> Option<(f64, f64, &'static str)> {
    match column {
        "u" => Some((-1.5, 1.5, "(the valve command)")),
        "x" => Some((-10.0, 10.0, "m")),
        "p_a" | "p_b" => Some((0.0, 1e8, "Pa absolute")),
        "f_e" => Some((-1e6, 1e6, "N")),
        _ => None,
    }
}

/// A column header as a message shows it: its first names, each cut short (a garbage header stays short).
fn header_text(names: &[String]) -> String {
    let shown: Vec<String> = names
        .iter()
        .take(16)
        .map(|n| {
            if n.chars().count() > 40 {
                format!("{}…", n.chars().take(40).collect::<String>())
            } else {
                n.clone()
            }
        })
        .collect();
    let more = names.len().saturating_sub(16);
    if more > 0 {
        format!("{} and {more} more", shown.join(", "))
    } else {
        shown.join(", ")
    }
}

/// The actuators of a recording of several, in the header's order: each NAME with all of `NAME.u`,
/// `NAME.x`, `NAME.p_a`, `NAME.p_b` and `NAME.f_e` among `names`.
fn actuators_in(names: &[String]) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for n in names {
        if let Some(a) = n.strip_suffix(".u")
            && !out.iter().any(|o| o == a)
            && COLUMNS[2..]
                .iter()
                .all(|c| names.iter().any(|m| *m == format!("{a}.{c}")))
        {
            out.push(a.to_string());
        }
    }
    out
}

/// A log read line by line: the header, then the rows, checked as they come.
struct LogParser<'a> {
    path: &'a Path,
    limits: LogLimits,
    format: &'a LogFormat,
    /// Lines of the preamble still to skip.
    preamble: usize,
    /// The header's column names, once read.
    names: Option<Vec<String>>,
    idx: [usize; COLUMNS.len()],
    fault: Option<usize>,
    /// Line number of each row (for the gap check's message).
    row_lines: Vec<usize>,
    end_marker: bool,
    log: Log,
    /// pneuflex's rig trace with the board's record: the indices of [`BOARD_COLUMNS`] and what they held.
    board: Option<([usize; 7], BoardColumns)>,
    /// Lines read (for the message when `skip_lines` skips them all).
    lines: usize,
    /// One actuator of a recording of several ([`LogFormat::channel`]): the `board_t` column's index, if
    /// the recording has one.
    board_t: Option<usize>,
    /// The previous row's `board_t`.
    prev_board_t: Option<f64>,
}

impl<'a> LogParser<'a> {
    fn new(path: &'a Path, limits: LogLimits, format: &'a LogFormat) -> Self {
        Self {
            path,
            limits,
            format,
            preamble: format.skip_lines,
            names: None,
            idx: [0; COLUMNS.len()],
            fault: None,
            row_lines: Vec::new(),
            end_marker: false,
            log: Log {
                path: path.to_path_buf(),
                sha256: String::new(),
                t: Vec::new(),
                u: Vec::new(),
                x: Vec::new(),
                p_a: Vec::new(),
                p_b: Vec::new(),
                f_e: Vec::new(),
                measured: Vec::new(),
                note: None,
            },
            board: None,
            lines: 0,
            board_t: None,
            prev_board_t: None,
        }
    }

    fn err(&self, line: Option<usize>, column: Option<&str>, message: String) -> IdentifyError {
        IdentifyError::Log {
            file: self.path.to_path_buf(),
            line,
            column: column.map(str::to_string),
            message,
        }
    }

    /// Takes one line; false once the rest of the log is not used (after a fault row).
    fn line(&mut self, line_no: usize, line: &str) -> Result<bool, IdentifyError> {
        self.lines = line_no;
        if line.starts_with('#') {
            self.end_marker |= line.starts_with("# end:");
            return Ok(true);
        }
        if self.preamble > 0 {
            self.preamble -= 1;
            return Ok(true);
        }
        let Some(names) = &self.names else {
            self.header(line_no, line)?;
            return Ok(true);
        };
        if line.trim().is_empty() {
            return Ok(true);
        }
        let fields = self.format.split(line);
        if fields.len() != names.len() {
            return Err(self.err(
                Some(line_no),
                None,
                format!(
                    "{} fields where the header has {} columns",
                    fields.len(),
                    names.len()
                ),
            ));
        }
        if let Some(f) = self.fault
            && !fields[f].trim().is_empty()
        {
            self.log.note = Some(format!(
                "rows from line {line_no} on not used: fault `{}` (the valve was safe, not at u)",
                fields[f].trim().chars().take(80).collect::<String>()
            ));
            return Ok(false);
        }
        let mut v = [0.0; COLUMNS.len()];
        for (i, c) in COLUMNS.iter().enumerate() {
            let s = fields[self.idx[i]].trim();
            let map = &self.format.columns[i];
            let x = self.format.number(s).ok_or_else(|| {
                self.err(
                    Some(line_no),
                    Some(c),
                    format!(
                        "`{}` is not a number",
                        s.chars().take(40).collect::<String>()
                    ),
                )
            })?;
            // To SI, absolute (the format's unit, scale and gauge offset; 1 and 0 for pneuflex's trace).
            let x = x * map.factor + map.offset;
            if !x.is_finite() {
                return Err(self.err(
                    Some(line_no),
                    Some(c),
                    format!("{x}: every value must be finite (a NaN row?)"),
                ));
            }
            if let Some((lo, hi, what)) = plausible(c)
                && !(lo..=hi).contains(&x)
            {
                return Err(self.err(
                    Some(line_no),
                    Some(c),
                    format!("{x}: outside [{lo:e}, {hi:e}] {what}: not a reading of a pneumatic cylinder"),
                ));
            }
            v[i] = x;
        }
        self.row(line_no, v)?;
        if let Some(i) = self.board_t {
            self.board_time(line_no, fields[i])?;
        }
        if let Some((idx, _)) = &self.board {
            let [t, x, f_e, p_a, p_b, at, au] = self.board_cells(line_no, &fields, *idx)?;
            if let Some((_, cols)) = &mut self.board {
                if t.is_finite() {
                    cols.samples.push(RecordedSample {
                        t,
                        x,
                        f_e,
                        p_a,
                        p_b,
                        line: line_no,
                    });
                }
                if at.is_finite() {
                    cols.applied.push((at, au));
                }
            }
        }
        Ok(true)
    }

    /// A row's board record ([`BOARD_COLUMNS`], NaN where empty): finite numbers, a sample whole and within
    /// the readings' plausible ranges, an echo whole with its duty in [-1, 1].
    fn board_cells(
        &self,
        line_no: usize,
        fields: &[&str],
        idx: [usize; 7],
    ) -> Result<[f64; 7], IdentifyError> {
        let mut read = [f64::NAN; 7];
        for (r, (&i, c)) in read.iter_mut().zip(idx.iter().zip(BOARD_COLUMNS)) {
            let cell = fields[i].trim();
            if cell.is_empty() {
                continue;
            }
            let v = cell
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| {
                    self.err(
                        Some(line_no),
                        Some(c),
                        format!(
                            "`{}` is not a finite number (an empty cell is none)",
                            cell.chars().take(40).collect::<String>()
                        ),
                    )
                })?;
            // The readings' ranges are the loop's columns' (board_x is an x).
            if let Some((lo, hi, what)) = c.strip_prefix("board_").and_then(plausible)
                && !(lo..=hi).contains(&v)
            {
                return Err(self.err(
                    Some(line_no),
                    Some(c),
                    format!("{v}: outside [{lo:e}, {hi:e}] {what}: not a reading of a pneumatic cylinder"),
                ));
            }
            *r = v;
        }
        let whole =
            |cells: &[f64]| cells.iter().all(|v| v.is_finite()) || cells.iter().all(|v| v.is_nan());
        if !whole(&read[..5]) {
            let c = (0..5).find(|&i| read[i].is_nan()).unwrap_or(0);
            return Err(self.err(
                Some(line_no),
                Some(BOARD_COLUMNS[c]),
                "empty where the rest of the board's sample is given: a sample is recorded whole"
                    .into(),
            ));
        }
        let [t, u] = [read[5], read[6]];
        if !whole(&read[5..]) || (u.is_finite() && !(-1.0..=1.0).contains(&u)) {
            return Err(self.err(
                Some(line_no),
                Some("applied_u"),
                format!("an applied echo needs its time and a duty in [-1, 1] (applied_t {t}, applied_u {u})"),
            ));
        }
        Ok(read)
    }

    /// One actuator of a recording of several: the row's `board_t`, the board's time of the samples the
    /// host's tick used. The same time as the previous row's is a tick that read no new sample (it held the
    /// last one): the row is not compared, and its contact force is the line between its neighbours'.
    fn board_time(&mut self, line_no: usize, cell: &str) -> Result<(), IdentifyError> {
        let cell = cell.trim();
        let b = cell
            .parse::<f64>()
            .ok()
            .filter(|b| b.is_finite())
            .ok_or_else(|| {
                self.err(
                    Some(line_no),
                    Some("board_t"),
                    format!(
                        "`{}` is not a finite number (the board's time of the tick's samples)",
                        cell.chars().take(40).collect::<String>()
                    ),
                )
            })?;
        if let Some(prev) = self.prev_board_t {
            if b < prev {
                return Err(self.err(
                    Some(line_no),
                    Some("board_t"),
                    format!("{b} s after {prev} s: the board's time must not go back"),
                ));
            }
            if b == prev
                && let Some(m) = self.log.measured.last_mut()
            {
                *m = false;
            }
        }
        self.prev_board_t = Some(b);
        Ok(())
    }

    fn header(&mut self, line_no: usize, line: &str) -> Result<(), IdentifyError> {
        let names: Vec<String> = self
            .format
            .split(line)
            .iter()
            .map(|n| n.trim().trim_matches('"').to_string())
            .collect();
        // A recording of several actuators (`t`, then `NAME.u`, ... per actuator): one actuator at a time.
        if self.format.own_trace {
            let actuators = actuators_in(&names);
            let list = actuators.join(", ");
            match &self.format.channel {
                None if !names.iter().any(|n| n == "u") && !actuators.is_empty() => {
                    return Err(self.err(
                        Some(line_no),
                        None,
                        format!(
                            "a recording of several actuators ({list}): identification fits one actuator's \
                             sheet at a time; choose it with --channel NAME (docs/identification.md, \
                             \"Several actuators\")"
                        ),
                    ));
                }
                Some(name) if !actuators.contains(name) => {
                    return Err(self.err(
                        Some(line_no),
                        None,
                        if actuators.is_empty() {
                            format!(
                                "--channel {name}: the log has no actuator's columns `NAME.u, NAME.x, NAME.p_a, \
                                 NAME.p_b, NAME.f_e` (the header has {}); a trace of one actuator is read \
                                 without --channel",
                                header_text(&names)
                            )
                        } else {
                            format!(
                                "--channel {name}: no actuator `{name}` in this recording; it has {list}"
                            )
                        },
                    ));
                }
                Some(_) => self.board_t = names.iter().position(|n| n == "board_t"),
                None => {}
            }
        }
        for (i, c) in COLUMNS.iter().enumerate() {
            let name = &self.format.columns[i].name;
            let found: Vec<usize> = (0..names.len()).filter(|&k| names[k] == *name).collect();
            match found.as_slice() {
                [k] => self.idx[i] = *k,
                [] if self.format.own_trace => {
                    return Err(self.err(
                        Some(line_no),
                        Some(c),
                        format!(
                            "missing column `{c}` (identification needs {}; the header has {})",
                            COLUMNS.join(", "),
                            header_text(&names)
                        ),
                    ));
                }
                [] => {
                    return Err(self.err(
                        Some(line_no),
                        Some(c),
                        format!(
                            "no column named `{name}` (the log format's columns.{c}.name; the header has {}): \
                             check the name, the separator and skip_lines",
                            header_text(&names)
                        ),
                    ));
                }
                [a, b, ..] => {
                    return Err(self.err(
                        Some(line_no),
                        Some(c),
                        format!(
                            "the header names `{name}` twice (columns {} and {}): which one is the signal?",
                            a + 1,
                            b + 1
                        ),
                    ));
                }
            }
        }
        // pneuflex's rig trace since schema 2: the board's clock and applied-command echoes.
        if self.format.own_trace && self.format.channel.is_none() {
            let at = |c: &str| names.iter().position(|n| n == c);
            if let [
                Some(a),
                Some(b),
                Some(c),
                Some(d),
                Some(e),
                Some(f),
                Some(g),
            ] = BOARD_COLUMNS.map(at)
            {
                self.board = Some(([a, b, c, d, e, f, g], BoardColumns::default()));
            }
        }
        // Only pneuflex's trace has a fault column (another tool's export is used as it is).
        self.fault = if self.format.own_trace {
            names.iter().position(|n| n == "fault")
        } else {
            None
        };
        self.names = Some(names);
        Ok(())
    }

    fn row(&mut self, line_no: usize, v: [f64; COLUMNS.len()]) -> Result<(), IdentifyError> {
        let log = &self.log;
        if let Some(&prev) = log.t.last()
            && v[0] <= prev
        {
            return Err(self.err(
                Some(line_no),
                Some("t"),
                format!("time must increase: {} after {prev}", v[0]),
            ));
        }
        if log.t.len() >= self.limits.max_rows {
            return Err(self.err(
                Some(line_no),
                None,
                format!(
                    "more than {} data rows; cut the log, or raise --max-rows",
                    self.limits.max_rows
                ),
            ));
        }
        if let (Some(&t0), Some(&prev)) = (log.t.first(), log.t.last())
            && v[0] - t0 > self.limits.max_span_s
        {
            // A jump out of an even log is named as a jump, not as the span it makes.
            let mean_dt = (prev - t0) / (log.t.len() - 1).max(1) as f64;
            let gap = v[0] - prev;
            if log.t.len() > 1 && gap > MAX_GAP_PERIODS * mean_dt && gap > MIN_GAP_S {
                return Err(self.err(
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
            return Err(self.err(
                Some(line_no),
                Some("t"),
                format!(
                    "t = {} s: the log spans more than {} s from its first row (t = {t0} s); cut the log, or \
                     raise --max-log-s",
                    v[0], self.limits.max_span_s
                ),
            ));
        }
        let log = &mut self.log;
        log.t.push(v[0]);
        log.u.push(v[1]);
        log.x.push(v[2]);
        log.p_a.push(v[3]);
        log.p_b.push(v[4]);
        log.f_e.push(v[5]);
        log.measured.push(true);
        self.row_lines.push(line_no);
        Ok(())
    }

    fn finish(mut self, sha256: String) -> Result<Log, IdentifyError> {
        if self.names.is_none() {
            if self.format.skip_lines > 0 && self.preamble < self.format.skip_lines {
                let at = self
                    .format
                    .skip_lines_at
                    .as_deref()
                    .unwrap_or("--log-format");
                return Err(self.err(
                    None,
                    None,
                    format!(
                        "no column header: the log has {} line(s), and --log-format's skip_lines = {} ({at}) skips past its end; count the preamble's lines before the header again",
                        self.lines, self.format.skip_lines
                    ),
                ));
            }
            return Err(self.err(None, None, "no column header (an empty trace?)".into()));
        }
        if self.log.t.len() < 10 {
            return Err(self.err(
                None,
                None,
                format!(
                    "{} data rows; identification needs a log of many ticks{}",
                    self.log.t.len(),
                    match &self.format.skip_lines_at {
                        Some(at) if self.format.skip_lines > 0 => format!(
                            " (after --log-format's skip_lines = {} ({at}) and the header)",
                            self.format.skip_lines
                        ),
                        _ => String::new(),
                    }
                ),
            ));
        }
        // A gap: the replay would integrate across it with the last command held, at the log's step.
        let dt = self.log.dt();
        let t = &self.log.t;
        let (lo, hi) = PERIOD_RANGE_S;
        if !(lo..=hi).contains(&dt) {
            return Err(self.err(
                Some(self.row_lines[1]),
                Some("t"),
                format!(
                    "the median sample period is {dt:.3e} s, outside [{lo:e}, {hi}] s: no rig samples at that rate; \
                     check the time column's unit (seconds in a trace; a log format's columns.t.unit)"
                ),
            ));
        }
        if let Some(k) = (1..t.len()).find(|&k| t[k] - t[k - 1] < MIN_PERIOD_SHARE * dt) {
            return Err(self.err(
                Some(self.row_lines[k]),
                Some("t"),
                format!(
                    "a step of {:.3e} s, from {} to {} s, where the median sample period is {dt:.3e} s: the clock \
                     does not tick evenly (a repeated or corrupt time stamp)",
                    t[k] - t[k - 1],
                    t[k - 1],
                    t[k]
                ),
            ));
        }
        if let Some(k) = (1..t.len()).find(|&k| {
            let gap = t[k] - t[k - 1];
            gap > MAX_GAP_PERIODS * dt && gap > MIN_GAP_S
        }) {
            return Err(self.err(
                Some(self.row_lines[k]),
                Some("t"),
                format!(
                    "time jumps by {} s, from {} to {} s, where the median sample period is {dt} s: identification \
                     replays a log as one continuous recording; cut it at the gap and give each part as its own --log",
                    t[k] - t[k - 1],
                    t[k - 1],
                    t[k]
                ),
            ));
        }
        if let Some(name) = &self.format.channel {
            // A scene's recording has no end marker, and no record of the board's samples and applied
            // commands: its rows are the host's ticks (docs/identification.md, "Several actuators").
            let held = self.log.measured.iter().filter(|&&m| !m).count();
            self.log.note = Some(format!(
                "actuator `{name}` of a recording of several actuators: the host's rows replayed as they are \
                 (the recording has no board record of samples and applied commands){}",
                if self.board_t.is_none() {
                    String::new()
                } else {
                    format!(
                        "; {held} row(s) whose tick read no new sample (board_t repeated) not compared"
                    )
                }
            ));
            if held > 0 {
                crate::board_time::interpolate_unmeasured_force(&mut self.log);
            }
        } else if self.log.note.is_none() && !self.end_marker && self.format.own_trace {
            self.log.note = Some("no end marker: the trace was cut (its rows are used)".into());
        }
        self.log.sha256 = sha256;
        if let Some((_, cols)) = &self.board
            && let Some((grid, _)) = crate::board_time::on_board_grid(&self.log, cols)?
        {
            return Ok(grid);
        }
        Ok(self.log)
    }
}
