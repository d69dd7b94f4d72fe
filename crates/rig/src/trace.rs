//! The rig's `trace.csv`: the simulation's columns plus `wall_time` and `fault`, flushed every N rows and on
//! every fault and at exit, so that a crash or Ctrl-C loses at most the last buffer.

use std::io::{self, BufWriter, Write};

/// The header: the simulation's trace columns, then wall time (s since the Unix epoch) and the fault state.
pub const TRACE_HEADER: &str = "t,f_ref,f_e,x,x_r,p_a,p_b,u,g,p,d,wall_time,fault";

/// One row of the trace (SI units, pressures absolute).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TraceRow<'a> {
    /// Control time, s (tick × period).
    pub t: f64,
    /// Reference force, N.
    pub f_ref: f64,
    /// Measured contact force, N.
    pub f_e: f64,
    /// Flange position, m.
    pub x: f64,
    /// Reference position of the inner loop, m.
    pub x_r: f64,
    /// Chamber A pressure, Pa.
    pub p_a: f64,
    /// Chamber B pressure, Pa.
    pub p_b: f64,
    /// Valve command sent (0 in the safe state).
    pub u: f64,
    /// Adaptive g.
    pub g: f64,
    /// Adaptive p.
    pub p: f64,
    /// Adaptive d.
    pub d: f64,
    /// Wall-clock time, s since the Unix epoch.
    pub wall_time: f64,
    /// Empty when healthy, the fault kind while latched; the first faulty row also carries the message.
    pub fault: &'a str,
}

/// A buffered CSV trace writer.
pub struct TraceWriter<W: Write> {
    out: BufWriter<W>,
    flush_every: usize,
    since_flush: usize,
    rows: u64,
}

impl<W: Write> TraceWriter<W> {
    /// Writes the header and flushes it.
    pub fn new(inner: W, flush_every: usize) -> io::Result<Self> {
        let mut out = BufWriter::with_capacity(64 * 1024, inner);
        writeln!(out, "{TRACE_HEADER}")?;
        out.flush()?;
        Ok(Self {
            out,
            flush_every: flush_every.max(1),
            since_flush: 0,
            rows: 0,
        })
    }

    /// Appends a row; flushes every `flush_every` rows and on any row with a fault.
    pub fn row(&mut self, r: &TraceRow<'_>) -> io::Result<()> {
        write!(
            self.out,
            "{},{},{},{},{},{},{},{},{},{},{},{:.6},",
            r.t, r.f_ref, r.f_e, r.x, r.x_r, r.p_a, r.p_b, r.u, r.g, r.p, r.d, r.wall_time
        )?;
        // Keep the CSV one field per fault: no commas, quotes or newlines from messages.
        for ch in r.fault.chars() {
            let c = match ch {
                ',' => ';',
                '"' | '\n' | '\r' => ' ',
                c => c,
            };
            write!(self.out, "{c}")?;
        }
        writeln!(self.out)?;
        self.rows += 1;
        self.since_flush += 1;
        if self.since_flush >= self.flush_every || !r.fault.is_empty() {
            self.flush()?;
        }
        Ok(())
    }

    /// Pushes buffered rows to the file.
    pub fn flush(&mut self) -> io::Result<()> {
        self.since_flush = 0;
        self.out.flush()
    }

    /// Rows written so far.
    pub fn rows(&self) -> u64 {
        self.rows
    }
}

impl<W: Write> Drop for TraceWriter<W> {
    fn drop(&mut self) {
        let _ = self.out.flush();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::{Arc, Mutex};

    #[derive(Clone, Default)]
    struct Shared(Arc<Mutex<Vec<u8>>>);
    impl Write for Shared {
        fn write(&mut self, b: &[u8]) -> io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(b);
            Ok(b.len())
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn flushes_every_n_and_on_fault() {
        let sink = Shared::default();
        let mut w = TraceWriter::new(sink.clone(), 3).unwrap();
        let lines = || {
            String::from_utf8(sink.0.lock().unwrap().clone())
                .unwrap()
                .lines()
                .count()
        };
        assert_eq!(lines(), 1);
        for k in 0..2 {
            w.row(&TraceRow {
                t: k as f64,
                ..TraceRow::default()
            })
            .unwrap();
        }
        assert_eq!(lines(), 1, "still buffered");
        w.row(&TraceRow::default()).unwrap();
        assert_eq!(lines(), 4, "flushed after 3 rows");
        w.row(&TraceRow {
            fault: "limit: x = 1, too far",
            ..TraceRow::default()
        })
        .unwrap();
        let text = String::from_utf8(sink.0.lock().unwrap().clone()).unwrap();
        assert_eq!(text.lines().count(), 5, "a fault row is flushed at once");
        let last = text.lines().last().unwrap();
        assert_eq!(last.split(',').count(), TRACE_HEADER.split(',').count());
        assert!(last.ends_with("limit: x = 1; too far"));
    }
}
