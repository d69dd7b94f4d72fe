//! A run's time series, column by column, preallocated before the loop; and its CSV form.

use std::io::Write;

/// The recorded signals of one run, one entry per control tick (SI units, pressures absolute).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trace {
    /// Time, s.
    pub t: Vec<f64>,
    /// Reference force f_r, N.
    pub f_ref: Vec<f64>,
    /// Contact force f_e, N.
    pub f_e: Vec<f64>,
    /// Flange position x, m.
    pub x: Vec<f64>,
    /// Reference position handed to the inner loop x_r, m.
    pub x_r: Vec<f64>,
    /// Chamber A pressure, Pa absolute (NaN for plants without chambers).
    pub p_a: Vec<f64>,
    /// Chamber B pressure, Pa absolute (NaN for plants without chambers).
    pub p_b: Vec<f64>,
    /// Valve command, in [-1, 1].
    pub u: Vec<f64>,
    /// Adaptive auxiliary term g (adaptive runs only, else empty).
    pub g: Vec<f64>,
    /// Adaptive proportional factor p (adaptive runs only, else empty).
    pub p: Vec<f64>,
    /// Adaptive differential factor d (adaptive runs only, else empty).
    pub d: Vec<f64>,
}

/// One row of a trace.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Row {
    /// Time, s.
    pub t: f64,
    /// Reference force, N.
    pub f_ref: f64,
    /// Contact force, N.
    pub f_e: f64,
    /// Position, m.
    pub x: f64,
    /// Reference position, m.
    pub x_r: f64,
    /// Chamber A pressure, Pa.
    pub p_a: f64,
    /// Chamber B pressure, Pa.
    pub p_b: f64,
    /// Valve command.
    pub u: f64,
    /// Adaptive g.
    pub g: f64,
    /// Adaptive p.
    pub p: f64,
    /// Adaptive d.
    pub d: f64,
}

impl Trace {
    /// An empty trace with room for `n` rows; `adaptive` also reserves the g, p, d columns.
    pub fn with_capacity(n: usize, adaptive: bool) -> Self {
        let c = || Vec::with_capacity(n);
        let a = || {
            if adaptive {
                Vec::with_capacity(n)
            } else {
                Vec::new()
            }
        };
        Self {
            t: c(),
            f_ref: c(),
            f_e: c(),
            x: c(),
            x_r: c(),
            p_a: c(),
            p_b: c(),
            u: c(),
            g: a(),
            p: a(),
            d: a(),
        }
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether the trace has no rows.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Appends a row (no allocation while within the reserved capacity).
    pub fn push(&mut self, r: &Row, adaptive: bool) {
        self.t.push(r.t);
        self.f_ref.push(r.f_ref);
        self.f_e.push(r.f_e);
        self.x.push(r.x);
        self.x_r.push(r.x_r);
        self.p_a.push(r.p_a);
        self.p_b.push(r.p_b);
        self.u.push(r.u);
        if adaptive {
            self.g.push(r.g);
            self.p.push(r.p);
            self.d.push(r.d);
        }
    }

    /// Writes the trace as CSV with a header row; NaN (a signal the plant does not have) is an empty cell.
    pub fn write_csv<W: Write>(&self, w: &mut W, adaptive: bool) -> std::io::Result<()> {
        let mut cols: Vec<(&str, &[f64])> = vec![
            ("t", &self.t),
            ("f_ref", &self.f_ref),
            ("f_e", &self.f_e),
            ("x", &self.x),
            ("x_r", &self.x_r),
            ("p_a", &self.p_a),
            ("p_b", &self.p_b),
            ("u", &self.u),
        ];
        if adaptive {
            cols.extend([("g", &self.g[..]), ("p", &self.p[..]), ("d", &self.d[..])]);
        }
        let header: Vec<&str> = cols.iter().map(|c| c.0).collect();
        writeln!(w, "{}", header.join(","))?;
        let mut line = String::with_capacity(16 * cols.len());
        for i in 0..self.len() {
            line.clear();
            for (j, (_, c)) in cols.iter().enumerate() {
                if j > 0 {
                    line.push(',');
                }
                let v = c[i];
                if v.is_finite() {
                    // Shortest representation that reads back to the same f64.
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
