//! A run's time series, column by column, preallocated before the loop; and its CSV form.
//!
//! The columns are not typed out here: they are the loop's signals (`pneuflex_control::LOOP_SIGNALS`),
//! then the controller's and the plant's own, each declared once where it is produced.

use std::io::Write;

use pneuflex_control::Signal;
use pneuflex_control::signal::index;

/// A trace that cannot be built from the columns given.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TraceError {
    /// Columns of different lengths.
    #[error("column `{column}` has {rows} rows, `{first}` has {expected}")]
    Length {
        /// The column that differs.
        column: String,
        /// Its rows.
        rows: usize,
        /// The first column.
        first: String,
        /// Its rows.
        expected: usize,
    },
    /// The loop's columns are not first, in their order.
    #[error("column {index} must be `{expected}`")]
    Order {
        /// Position.
        index: usize,
        /// The loop signal expected there.
        expected: &'static str,
    },
}

/// One column of a trace: the declaration of its signal, owned (a trace read back or built from Python
/// has names that were not declared in Rust).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Column {
    /// Column name (CSV header, Python key, Rerun path leaf).
    pub name: String,
    /// SI unit.
    pub unit: String,
    /// Plot group (Rerun `signals/<group>/<name>`).
    pub group: String,
}

impl From<&Signal> for Column {
    fn from(s: &Signal) -> Self {
        Self {
            name: s.name.into(),
            unit: s.unit.into(),
            group: s.group.into(),
        }
    }
}

/// The recorded signals of one run, one entry per control tick (SI units, pressures absolute).
/// The first columns are always `LOOP_SIGNALS` (t, f_ref, f_e, x, x_r, p_a, p_b, u).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trace {
    columns: Vec<Column>,
    data: Vec<Vec<f64>>,
}

/// One tick as the loop records it: the trace's columns and this tick's values.
#[derive(Clone, Copy, Debug)]
pub struct Row<'a> {
    /// The columns (the same for every row of a run).
    pub columns: &'a [Column],
    /// This tick's values, one per column.
    pub values: &'a [f64],
}

impl Row<'_> {
    /// The value of the signal named `name`, if the run records it.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.columns
            .iter()
            .position(|c| c.name == name)
            .map(|i| self.values[i])
    }
    /// Time, s.
    pub fn t(&self) -> f64 {
        self.values[index::T]
    }
    /// Reference force, N.
    pub fn f_ref(&self) -> f64 {
        self.values[index::F_REF]
    }
    /// Contact force, N.
    pub fn f_e(&self) -> f64 {
        self.values[index::F_E]
    }
    /// Position, m.
    pub fn x(&self) -> f64 {
        self.values[index::X]
    }
    /// Reference position of the inner loop, m.
    pub fn x_r(&self) -> f64 {
        self.values[index::X_R]
    }
    /// Chamber A pressure, Pa (NaN without chambers).
    pub fn p_a(&self) -> f64 {
        self.values[index::P_A]
    }
    /// Chamber B pressure, Pa (NaN without chambers).
    pub fn p_b(&self) -> f64 {
        self.values[index::P_B]
    }
    /// Valve command.
    pub fn u(&self) -> f64 {
        self.values[index::U]
    }
}

impl Trace {
    /// The loop's columns followed by `extra` (the controller's and the plant's signals).
    pub fn loop_columns(extra: &[&[Signal]]) -> Vec<Column> {
        pneuflex_control::LOOP_SIGNALS
            .iter()
            .chain(extra.iter().flat_map(|s| s.iter()))
            .map(Column::from)
            .collect()
    }

    /// An empty trace with the given columns and room for `n` rows.
    pub fn with_capacity(n: usize, columns: Vec<Column>) -> Self {
        let data = columns.iter().map(|_| Vec::with_capacity(n)).collect();
        Self { columns, data }
    }

    /// A trace from whole columns (all of the same length; the loop's columns first).
    pub fn from_columns(columns: Vec<(Column, Vec<f64>)>) -> Result<Self, TraceError> {
        let n = columns.first().map_or(0, |c| c.1.len());
        if let Some((c, v)) = columns.iter().find(|(_, v)| v.len() != n) {
            return Err(TraceError::Length {
                column: c.name.clone(),
                rows: v.len(),
                first: columns[0].0.name.clone(),
                expected: n,
            });
        }
        for (i, s) in pneuflex_control::LOOP_SIGNALS.iter().enumerate() {
            if columns.get(i).map(|c| c.0.name.as_str()) != Some(s.name) {
                return Err(TraceError::Order {
                    index: i,
                    expected: s.name,
                });
            }
        }
        let (columns, data) = columns.into_iter().unzip();
        Ok(Self { columns, data })
    }

    /// A trace from `trace.csv` text as `run` and `rig run` write it: `#` comment lines, a header, one row per
    /// tick, an empty cell NaN. Columns in `skip` (a rig's `wall_time`, `fault`) are left out. Errors name
    /// the line and the column.
    pub fn from_csv(text: &str, skip: &[&str]) -> Result<Self, String> {
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim_start_matches('\u{feff}')))
            .filter(|(_, l)| !l.starts_with('#') && !l.trim().is_empty());
        let (_, header) = lines.next().ok_or("no header row")?;
        let names: Vec<&str> = header.split(',').map(str::trim).collect();
        let keep: Vec<bool> = names.iter().map(|n| !skip.contains(n)).collect();
        let known = |n: &str| {
            pneuflex_control::LOOP_SIGNALS
                .iter()
                .find(|s| s.name == n)
                .map(Column::from)
                .unwrap_or(Column {
                    name: n.into(),
                    unit: String::new(),
                    group: "other".into(),
                })
        };
        let mut cols: Vec<(Column, Vec<f64>)> = names
            .iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(n, _)| (known(n), Vec::new()))
            .collect();
        for (line, row) in lines {
            let cells: Vec<&str> = row.split(',').collect();
            if cells.len() != names.len() {
                return Err(format!(
                    "line {line}: {} cells, the header has {}",
                    cells.len(),
                    names.len()
                ));
            }
            let mut j = 0;
            for ((cell, name), k) in cells.iter().zip(&names).zip(&keep) {
                if !k {
                    continue;
                }
                let c = cell.trim();
                let v = if c.is_empty() {
                    f64::NAN
                } else {
                    c.parse().map_err(|_| {
                        format!("line {line}: column `{name}`: `{c}` is not a number")
                    })?
                };
                cols[j].1.push(v);
                j += 1;
            }
        }
        Self::from_columns(cols).map_err(|e| e.to_string())
    }

    /// The columns with their data, in order.
    pub fn into_columns(self) -> Vec<(Column, Vec<f64>)> {
        self.columns.into_iter().zip(self.data).collect()
    }

    /// The columns, in order.
    pub fn columns(&self) -> &[Column] {
        &self.columns
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.data.first().map_or(0, Vec::len)
    }

    /// Whether the trace has no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Appends a row, one value per column (no allocation while within the reserved capacity).
    pub fn push(&mut self, row: &[f64]) {
        debug_assert_eq!(row.len(), self.data.len());
        for (col, &v) in self.data.iter_mut().zip(row) {
            col.push(v);
        }
    }

    /// The column named `name`, if recorded.
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        self.columns
            .iter()
            .position(|c| c.name == name)
            .map(|i| &self.data[i][..])
    }

    /// Whether the column named `name` is recorded.
    pub fn has(&self, name: &str) -> bool {
        self.columns.iter().any(|c| c.name == name)
    }

    /// Time, s.
    pub fn t(&self) -> &[f64] {
        &self.data[index::T]
    }
    /// Reference force f_r, N.
    pub fn f_ref(&self) -> &[f64] {
        &self.data[index::F_REF]
    }
    /// Contact force f_e, N.
    pub fn f_e(&self) -> &[f64] {
        &self.data[index::F_E]
    }
    /// Flange position x, m.
    pub fn x(&self) -> &[f64] {
        &self.data[index::X]
    }
    /// Reference position of the inner loop x_r, m.
    pub fn x_r(&self) -> &[f64] {
        &self.data[index::X_R]
    }
    /// Chamber A pressure, Pa absolute (NaN for plants without chambers).
    pub fn p_a(&self) -> &[f64] {
        &self.data[index::P_A]
    }
    /// Chamber B pressure, Pa absolute (NaN for plants without chambers).
    pub fn p_b(&self) -> &[f64] {
        &self.data[index::P_B]
    }
    /// Valve command, in [-1, 1].
    pub fn u(&self) -> &[f64] {
        &self.data[index::U]
    }

    /// Writes the trace as CSV with a header row of the column names; NaN (a signal the plant does not
    /// have) is an empty cell; numbers in the shortest form that reads back to the same f64, written as
    /// Rust's `{}` writes them (never an exponent). Rows are formatted into a buffer and written in blocks
    /// of about 64 KiB, so `w` need not be buffered.
    pub fn write_csv<W: Write>(&self, w: &mut W) -> std::io::Result<()> {
        const BLOCK: usize = 1 << 16;
        let mut buf: Vec<u8> = Vec::with_capacity(BLOCK + 64 * self.columns.len());
        for (j, c) in self.columns.iter().enumerate() {
            if j > 0 {
                buf.push(b',');
            }
            buf.extend_from_slice(c.name.as_bytes());
        }
        buf.push(b'\n');
        let mut digits = zmij::Buffer::new();
        for i in 0..self.len() {
            for (j, c) in self.data.iter().enumerate() {
                if j > 0 {
                    buf.push(b',');
                }
                let v = c[i];
                if v.is_finite() {
                    push_f64(&mut buf, &mut digits, v);
                } else if v.is_infinite() {
                    buf.extend_from_slice(if v > 0.0 { b"inf" } else { b"-inf" });
                }
            }
            buf.push(b'\n');
            if buf.len() >= BLOCK {
                w.write_all(&buf)?;
                buf.clear();
            }
        }
        w.write_all(&buf)
    }
}

/// Appends a finite `v` exactly as `format!("{v}")` writes it: the shortest digits that read back to the
/// same f64, in positional notation with no exponent, no trailing `.0` on integers, `-0` for negative zero.
///
/// zmij (like ryu before it, at about half ryu's time per value) finds the same shortest digits as the
/// standard library and, of those, the closest to `v`; a value exactly halfway between two may be
/// rounded differently (ryu takes the even one, the standard library rounds up: 0.5 + 2⁻¹⁷ =
/// 0.50000762939453125, ryu `…312`, `{}` `…313`). A tie needs the exact decimal expansion of `v` to have at
/// most 18 significant digits; such values (few significant bits: 0.5, 2.75, and integers from 2⁵³ up)
/// are written by the standard library, everything else by zmij, its text rewritten positionally.
pub fn push_f64(out: &mut Vec<u8>, digits: &mut zmij::Buffer, v: f64) {
    if may_tie(v) {
        use std::io::Write as _;
        let _ = write!(out, "{v}");
        return;
    }
    let s = digits.format_finite(v).as_bytes();
    if !s.contains(&b'e') {
        // Positional already: as Display, except that an integer may end in `.0`.
        out.extend_from_slice(s.strip_suffix(b".0").unwrap_or(s));
        return;
    }
    let (neg, s) = match s.split_first() {
        Some((b'-', rest)) => (true, rest),
        _ => (false, s),
    };
    // An exponent form (`de-7`, `d.ddde20`, `1e-07`, `1e+20`): the digits and the decimal exponent.
    let (mant, exp) = match s.iter().position(|&b| b == b'e') {
        Some(e) => (&s[..e], parse_exp(&s[e + 1..])),
        None => (s, 0),
    };
    let (int, frac) = match mant.iter().position(|&b| b == b'.') {
        Some(d) => (&mant[..d], &mant[d + 1..]),
        None => (mant, &[][..]),
    };
    if neg {
        out.push(b'-');
    }
    // The significant digits and where the decimal point falls among them.
    let mut digits = [0u8; 40];
    let mut n = 0;
    for &b in int.iter().chain(frac) {
        digits[n] = b;
        n += 1;
    }
    let mut point = int.len() as i32 + exp;
    let lead = digits[..n].iter().take_while(|&&b| b == b'0').count();
    let trail = digits[lead..n]
        .iter()
        .rev()
        .take_while(|&&b| b == b'0')
        .count();
    let sig = &digits[lead..n - trail];
    point -= lead as i32;
    if sig.is_empty() {
        out.push(b'0');
    } else if point <= 0 {
        out.extend_from_slice(b"0.");
        out.extend(std::iter::repeat_n(b'0', (-point) as usize));
        out.extend_from_slice(sig);
    } else if point as usize >= sig.len() {
        out.extend_from_slice(sig);
        out.extend(std::iter::repeat_n(b'0', point as usize - sig.len()));
    } else {
        let (a, b) = sig.split_at(point as usize);
        out.extend_from_slice(a);
        out.push(b'.');
        out.extend_from_slice(b);
    }
}

/// Whether the exact decimal expansion of `v` (finite) may be short enough (≤ 18 significant digits) for
/// `v` to lie halfway between two shortest candidates: conservative, it never misses one.
fn may_tie(v: f64) -> bool {
    let bits = v.to_bits();
    let (exp, frac) = ((bits >> 52) & 0x7ff, bits & ((1 << 52) - 1));
    let (m, e) = if exp == 0 {
        (frac, -1074)
    } else {
        (frac | (1 << 52), exp as i32 - 1075)
    };
    if m == 0 {
        return false; // ±0: no choice of digits
    }
    // v = m'·2^e' with m' odd, of b bits.
    let tz = m.trailing_zeros();
    let (m, e) = (m >> tz, e + tz as i32);
    let b = 64 - m.leading_zeros() as i32;
    if e >= 0 {
        // An integer: below 2⁵³ its rounding interval holds no other candidate of as few digits.
        return e + b > 53;
    }
    // The expansion ends at 10^e (m'·5^-e is odd) and starts at 10^d, d ≥ floor((e + b − 1)·log10 2):
    // it has d − e + 1 significant digits. (x·78913) >> 18 is floor(x·log10 2) for |x| ≤ 1650.
    let d_min = ((e + b - 1) * 78913) >> 18;
    d_min - e < 18
}

fn parse_exp(s: &[u8]) -> i32 {
    let (neg, digits) = match s.split_first() {
        Some((b'-', rest)) => (true, rest),
        Some((b'+', rest)) => (false, rest),
        _ => (false, s),
    };
    let e = digits
        .iter()
        .fold(0i32, |a, &d| a * 10 + i32::from(d - b'0'));
    if neg { -e } else { e }
}

#[cfg(test)]
mod tests {
    use super::push_f64;

    fn both(v: f64) {
        let mut out = Vec::new();
        push_f64(&mut out, &mut zmij::Buffer::new(), v);
        assert_eq!(std::str::from_utf8(&out).unwrap(), format!("{v}"), "{v:e}");
    }

    #[test]
    fn formats_as_display() {
        for v in [
            0.0,
            -0.0,
            1.0,
            -1.0,
            10.0,
            100.0,
            0.1,
            0.001,
            1e-7,
            -1.5e-7,
            1e15,
            1e16,
            1.5e16,
            1e21,
            123456789.125,
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            f64::MIN,
            f64::EPSILON,
            101325.0,
            0.5,
            2.5e-5,
        ] {
            both(v);
        }
        // Random bit patterns (every magnitude) and random values of a trace's magnitudes.
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        for _ in 0..300_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let v = f64::from_bits(x);
            if v.is_finite() {
                both(v);
            }
            both((x >> 11) as f64 / (1u64 << 53) as f64 * 2e6 - 1e6);
            both((x >> 11) as f64 / (1u64 << 53) as f64 * 1e-3);
            // Few significant bits (the values that can lie halfway between two candidates).
            let k = (x >> 58) as i32 - 20;
            both(((x >> 40) | 1) as f64 * 2f64.powi(-(k + 24)));
            both(((x >> 30) | 1) as f64 * 2f64.powi(-(k + 34)));
            both(((x >> 50) | 1) as f64 * 2f64.powi(-(k + 14)));
        }
        both(0.5 + 2f64.powi(-17));
        both(1.658_206_780_088_562_3e15);
    }
}
