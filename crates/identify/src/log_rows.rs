//! One log's rows as identification uses them: SI columns, and which rows hold a measurement.

use std::path::PathBuf;

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
    /// Whether each row holds a measurement: false for a sample period of the board's grid whose sample
    /// the host did not read (its sensors hold the last measured row's; crate::board_time), never compared.
    pub measured: Vec<bool>,
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
            measured: self.measured[a..b].to_vec(),
            note: self.note.clone(),
        }
    }
}
