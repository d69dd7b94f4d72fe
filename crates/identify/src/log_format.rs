//! How to read a log pneuflex did not write (`identify --log-format FILE`): the separator, the decimal and
//! thousands marks, the lines before the header, and for each signal identification needs the column that
//! holds it and its unit, so a LabVIEW or data-logger export is read as it is (docs/identification.md,
//! "Other people's logs").
//!
//! ```toml
//! separator = ";"            # ",", ";", "tab" or "whitespace"
//! decimal = ","              # "." or ","
//! thousands = "."            # absent: none
//! skip_lines = 3             # a preamble before the header
//! [columns]
//! t = { name = "Zeit", unit = "ms" }
//! u = { name = "Ventil", unit = "percent" }
//! x = { name = "Weg", unit = "mm" }
//! p_a = { name = "pA", unit = "bar", gauge = true }
//! p_b = { name = "pB", unit = "bar", gauge = true }
//! f_e = { name = "Kraft", unit = "N", scale = -1.0 }
//! ```

use std::collections::BTreeMap;
use std::path::Path;

use serde::Deserialize;

use crate::IdentifyError;

/// The columns identification reads, in this order.
pub const COLUMNS: [&str; 6] = ["t", "u", "x", "p_a", "p_b", "f_e"];

/// A log format file, as written.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
struct FormatFile {
    #[serde(default = "comma")]
    separator: String,
    #[serde(default = "dot")]
    decimal: String,
    #[serde(default)]
    thousands: Option<String>,
    #[serde(default)]
    skip_lines: usize,
    #[serde(default = "default_atmosphere")]
    atmosphere_pa: f64,
    columns: BTreeMap<String, ColumnFile>,
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
struct ColumnFile {
    name: String,
    unit: String,
    #[serde(default)]
    gauge: bool,
    #[serde(default = "one")]
    scale: f64,
}

fn comma() -> String {
    ",".into()
}
fn dot() -> String {
    ".".into()
}
fn one() -> f64 {
    1.0
}
fn default_atmosphere() -> f64 {
    pneuflex_pneumatics::P_ATM
}

/// How fields are separated on a row.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Separator {
    /// One character (`,`, `;`, tab).
    Char(char),
    /// Any run of spaces and tabs.
    Whitespace,
}

/// One signal's column: its header name, and the affine map to SI: `si = raw * factor + offset`.
#[derive(Clone, Debug, PartialEq)]
pub struct ColumnMap {
    /// The column's name in the header.
    pub name: String,
    /// Multiplies the number read (unit and `scale`).
    pub factor: f64,
    /// Added after (the atmosphere, for a gauge pressure), SI.
    pub offset: f64,
}

/// How to read a log: pneuflex's own trace.csv by default.
#[derive(Clone, Debug, PartialEq)]
pub struct LogFormat {
    /// Field separator.
    pub separator: Separator,
    /// The decimal mark.
    pub decimal: char,
    /// A thousands mark removed from numbers, if any.
    pub thousands: Option<char>,
    /// Lines before the header (not counting comment lines).
    pub skip_lines: usize,
    /// The columns of [`COLUMNS`], in that order.
    pub columns: [ColumnMap; COLUMNS.len()],
    /// Whether this is pneuflex's own trace (comment lines, the `fault` column and the end marker).
    pub own_trace: bool,
    /// Where `skip_lines` was given, `format.toml:LINE:COLUMN` (the format file alone when the key is
    /// absent), for the log's errors that it can cause; None for pneuflex's own trace.
    pub skip_lines_at: Option<String>,
    /// One actuator of pneuflex's recording of several (`identify --channel NAME`): the columns read are
    /// `t` and that actuator's `NAME.u`, `NAME.x`, `NAME.p_a`, `NAME.p_b`, `NAME.f_e` ([`LogFormat::channel`]).
    pub channel: Option<String>,
}

impl Default for LogFormat {
    fn default() -> Self {
        Self {
            separator: Separator::Char(','),
            decimal: '.',
            thousands: None,
            skip_lines: 0,
            columns: COLUMNS.map(|c| ColumnMap {
                name: c.to_string(),
                factor: 1.0,
                offset: 0.0,
            }),
            own_trace: true,
            skip_lines_at: None,
            channel: None,
        }
    }
}

/// The SI factor of `unit` for signal `column`, or the units it accepts.
fn unit_factor(column: &str, unit: &str) -> Result<f64, &'static str> {
    let known: (&[(&str, f64)], &'static str) = match column {
        "t" => (
            &[("s", 1.0), ("ms", 1e-3), ("us", 1e-6)],
            "\"s\", \"ms\", \"us\"",
        ),
        "u" => (
            &[("1", 1.0), ("percent", 0.01)],
            "\"1\" (the command in [-1, 1]), \"percent\" ([-100, 100])",
        ),
        "x" => (
            &[("m", 1.0), ("mm", 1e-3), ("um", 1e-6)],
            "\"m\", \"mm\", \"um\"",
        ),
        "p_a" | "p_b" => (
            &[
                ("Pa", 1.0),
                ("kPa", 1e3),
                ("MPa", 1e6),
                ("bar", 1e5),
                ("mbar", 1e2),
                ("psi", 6_894.757_293_168),
            ],
            "\"Pa\", \"kPa\", \"MPa\", \"bar\", \"mbar\", \"psi\"",
        ),
        _ => (&[("N", 1.0), ("kN", 1e3)], "\"N\", \"kN\""),
    };
    known
        .0
        .iter()
        .find(|(u, _)| *u == unit)
        .map(|(_, f)| *f)
        .ok_or(known.1)
}

/// One character of a mark key, or why not.
fn mark(value: &str, names: &[(&str, char)]) -> Option<char> {
    names.iter().find(|(n, _)| *n == value).map(|(_, c)| *c)
}

impl LogFormat {
    /// Reads a format file; errors name the file, the line and the key.
    pub fn load(path: &Path) -> Result<LogFormat, IdentifyError> {
        let text = pneuflex_files::read_text(path, pneuflex_files::InputKind::Sheet)
            .map_err(|e| IdentifyError::Input(e.to_string()))?;
        LogFormat::parse(path, &text)
    }

    /// Parses format text; `path` names it in errors.
    pub fn parse(path: &Path, text: &str) -> Result<LogFormat, IdentifyError> {
        let at = |key: &str, message: String| {
            let pos = pneuflex_files::toml_key_position(text, key)
                .map(|p| format!(":{p}"))
                .unwrap_or_default();
            IdentifyError::Input(format!("{}{pos}: {key}: {message}", path.display()))
        };
        let f: FormatFile = toml::from_str(text).map_err(|e| {
            let pos = e
                .span()
                .map(|s| format!(":{}", pneuflex_files::line_col(text, s.start)))
                .unwrap_or_default();
            // The key whose value is wrong, from the text before the value (`skip_lines = -1`).
            let key = e
                .span()
                .and_then(|s| text.get(..s.start))
                .and_then(|before| before.rsplit('\n').next())
                .and_then(|line| line.rsplit_once('='))
                .map(|(k, _)| k.rsplit([',', '{']).next().unwrap_or(k).trim())
                .filter(|k| !k.is_empty() && k.chars().all(|c| c.is_alphanumeric() || c == '_'))
                .map(|k| format!(" {k}:"))
                .unwrap_or_default();
            IdentifyError::Input(format!(
                "{}{pos}:{key} {}",
                path.display(),
                e.message().trim()
            ))
        })?;
        let separator = match f.separator.as_str() {
            "whitespace" => Separator::Whitespace,
            s => Separator::Char(
                mark(s, &[(",", ','), (";", ';'), ("tab", '\t'), ("|", '|')]).ok_or_else(|| {
                    at(
                        "separator",
                        format!("{s:?}: expected \",\", \";\", \"tab\", \"|\" or \"whitespace\""),
                    )
                })?,
            ),
        };
        let decimal = mark(&f.decimal, &[(".", '.'), (",", ',')]).ok_or_else(|| {
            at(
                "decimal",
                format!("{:?}: expected \".\" or \",\"", f.decimal),
            )
        })?;
        let thousands = match &f.thousands {
            None => None,
            Some(t) => Some(
                mark(
                    t,
                    &[(".", '.'), (",", ','), ("'", '\''), (" ", ' '), ("_", '_')],
                )
                .ok_or_else(|| {
                    at(
                        "thousands",
                        format!("{t:?}: expected \".\", \",\", \"'\", \" \" or \"_\""),
                    )
                })?,
            ),
        };
        if separator == Separator::Char(decimal) {
            return Err(at(
                "decimal",
                format!("{decimal:?} is also the separator: a row could not be split"),
            ));
        }
        if thousands == Some(decimal) {
            return Err(at(
                "thousands",
                format!("{decimal:?} is also the decimal mark"),
            ));
        }
        if let Some(t) = thousands
            && (separator == Separator::Char(t) || (separator == Separator::Whitespace && t == ' '))
        {
            return Err(at(
                "thousands",
                format!("{t:?} is also the separator: a row could not be split"),
            ));
        }
        if !(f.atmosphere_pa.is_finite() && f.atmosphere_pa > 0.0) {
            return Err(at(
                "atmosphere_pa",
                format!("must be > 0 Pa, got {}", f.atmosphere_pa),
            ));
        }
        if let Some(k) = f.columns.keys().find(|k| !COLUMNS.contains(&k.as_str())) {
            return Err(at(
                &format!("columns.{k}"),
                format!(
                    "not a signal identification reads: expected {}",
                    COLUMNS.join(", ")
                ),
            ));
        }
        let mut columns = LogFormat::default().columns;
        for (i, c) in COLUMNS.iter().enumerate() {
            let Some(spec) = f.columns.get(*c) else {
                return Err(at(
                    "columns",
                    format!(
                        "missing `{c}`: identification needs a column for each of {}",
                        COLUMNS.join(", ")
                    ),
                ));
            };
            let key = |k: &str| format!("columns.{c}.{k}");
            let unit = unit_factor(c, &spec.unit)
                .map_err(|known| at(&key("unit"), format!("{:?}: expected {known}", spec.unit)))?;
            if !(spec.scale.is_finite() && spec.scale != 0.0) {
                return Err(at(
                    &key("scale"),
                    format!("must be finite and not 0, got {}", spec.scale),
                ));
            }
            let pressure = c.starts_with("p_");
            if spec.gauge && !pressure {
                return Err(at(
                    &key("gauge"),
                    "only a pressure is gauge or absolute".into(),
                ));
            }
            if spec.name.trim().is_empty() {
                return Err(at(
                    &key("name"),
                    "the column's name in the header is empty".into(),
                ));
            }
            if let Some(j) = (0..i).find(|&j| columns[j].name == spec.name) {
                return Err(at(
                    &key("name"),
                    format!("{:?} is also the column of `{}`", spec.name, COLUMNS[j]),
                ));
            }
            columns[i] = ColumnMap {
                name: spec.name.clone(),
                factor: unit * spec.scale,
                offset: if spec.gauge { f.atmosphere_pa } else { 0.0 },
            };
        }
        let skip_lines_at = pneuflex_files::toml_key_position(text, "skip_lines").map_or_else(
            || path.display().to_string(),
            |p| format!("{}:{p}", path.display()),
        );
        Ok(LogFormat {
            separator,
            decimal,
            thousands,
            skip_lines: f.skip_lines,
            columns,
            own_trace: false,
            skip_lines_at: Some(skip_lines_at),
            channel: None,
        })
    }

    /// Actuator `name`'s columns of pneuflex's recording of several actuators (`rig run` or `run` of a scene
    /// with `[[actuators]]`: `t`, then `NAME.f_ref, NAME.f_e, NAME.x, ...` per actuator): the time column
    /// shared, each signal from `NAME.<signal>`. Errors when `name` could not be a column's prefix.
    pub fn channel(name: &str) -> Result<LogFormat, IdentifyError> {
        if name.is_empty() || name.contains([',', '.', '"']) || name.trim() != name {
            return Err(IdentifyError::Input(format!(
                "--channel {name:?}: an actuator's name as the recording's columns carry it (`left` for \
                 `left.u`, ...): not empty, no `,`, `.` or quote, no surrounding space"
            )));
        }
        let mut f = LogFormat::default();
        for (m, c) in f.columns.iter_mut().zip(COLUMNS).skip(1) {
            m.name = format!("{name}.{c}");
        }
        f.channel = Some(name.to_string());
        Ok(f)
    }

    /// The fields of a row (or of the header).
    pub fn split<'a>(&self, line: &'a str) -> Vec<&'a str> {
        match self.separator {
            Separator::Char(c) => line.split(c).collect(),
            Separator::Whitespace => line.split_whitespace().collect(),
        }
    }

    /// The number in a field, in the file's marks (None: not a number).
    pub fn number(&self, field: &str) -> Option<f64> {
        let s = field.trim();
        if self.decimal == '.' && self.thousands.is_none() {
            return s.parse().ok();
        }
        let mut out = String::with_capacity(s.len());
        for ch in s.chars() {
            if Some(ch) == self.thousands {
                continue;
            }
            out.push(if ch == self.decimal { '.' } else { ch });
        }
        out.parse().ok()
    }
}
