//! A run's time series, column by column, preallocated before the loop; and its CSV form.
//!
//! The columns are not typed out here: they are the loop's signals (`pneuflex_control::LOOP_SIGNALS`),
//! then the controller's and the plant's own, each declared once where it is produced.

use std::io::Write;

use pneuflex_control::Signal;
use pneuflex_control::signal::index;

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
    pub fn from_columns(columns: Vec<(Column, Vec<f64>)>) -> Result<Self, String> {
        let n = columns.first().map_or(0, |c| c.1.len());
        if let Some((c, v)) = columns.iter().find(|(_, v)| v.len() != n) {
            return Err(format!(
                "column `{}` has {} rows, `{}` has {n}",
                c.name,
                v.len(),
                columns[0].0.name
            ));
        }
        for (i, s) in pneuflex_control::LOOP_SIGNALS.iter().enumerate() {
            if columns.get(i).map(|c| c.0.name.as_str()) != Some(s.name) {
                return Err(format!("column {i} must be `{}`", s.name));
            }
        }
        let (columns, data) = columns.into_iter().unzip();
        Ok(Self { columns, data })
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
    /// have) is an empty cell; numbers in the shortest form that reads back to the same f64.
    pub fn write_csv<W: Write>(&self, w: &mut W) -> std::io::Result<()> {
        let header: Vec<&str> = self.columns.iter().map(|c| c.name.as_str()).collect();
        writeln!(w, "{}", header.join(","))?;
        let mut line = String::with_capacity(16 * self.columns.len());
        for i in 0..self.len() {
            line.clear();
            for (j, c) in self.data.iter().enumerate() {
                if j > 0 {
                    line.push(',');
                }
                let v = c[i];
                if v.is_finite() {
                    use std::fmt::Write as _;
                    let _ = write!(line, "{v}");
                } else if v.is_infinite() {
                    line.push_str(if v > 0.0 { "inf" } else { "-inf" });
                }
            }
            writeln!(w, "{line}")?;
        }
        Ok(())
    }
}
