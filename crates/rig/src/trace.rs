//! The rig's `trace.csv`: provenance comment lines, the simulation's columns plus the board's clock and
//! applied-command echo, `wall_time` and `fault` ([`pneuflex_files::output::RIG_TRACE_COLUMNS`]), then an
//! end marker. Rows are formatted into a reusable buffer and written whole, flushed every N rows, on
//! every fault and at exit; a failed write is cut back to the last complete row. Format: docs/rig.md "Trace".

use std::fs::File;
use std::io::{self, Seek, SeekFrom, Write};

use pneuflex_control::Signal;
use pneuflex_files::InputDigest;
use pneuflex_files::output::RIG_TRACE_COLUMNS;

use crate::rig::{Applied, BoardSample};

/// The column header: the loop's signals (`pneuflex_control::LOOP_SIGNALS`), the controller's own signals
/// as it declares them, then the rig's own columns ([`RIG_TRACE_COLUMNS`]: board time, the applied-command
/// echo, wall time in s since the Unix epoch, the fault).
pub fn header_for(own: &[Signal]) -> String {
    let names: Vec<&str> = pneuflex_control::LOOP_SIGNALS
        .iter()
        .chain(own)
        .map(|s| s.name)
        .chain(RIG_TRACE_COLUMNS)
        .collect();
    names.join(",")
}
/// Layout version of the trace (comment lines, columns, end marker). 2: the board's columns.
pub const TRACE_SCHEMA: u32 = 2;
/// Start of the last line of a trace that was closed properly: `# end: <reason>, <n> rows`.
pub const END_MARKER: &str = "# end: ";

/// One row of the trace (SI units, pressures absolute).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TraceRow<'a> {
    /// The loop's signals then the controller's, in the order of the header ([`header_for`]); the valve
    /// command is the one sent (0 in the safe state).
    pub values: &'a [f64],
    /// The oldest sample the board sent not written yet (one a row: the board sends one a period, so the
    /// record keeps up even when the loop, late, read only the newest), or none.
    pub sampled: Option<BoardSample>,
    /// The oldest applied-command echo not written yet (one a row: the host sends one command a tick), or
    /// none.
    pub applied: Option<Applied>,
    /// Wall-clock time, s since the Unix epoch.
    pub wall_time: f64,
    /// Empty when healthy, the fault kind while latched; the first faulty row also carries the message.
    pub fault: &'a str,
}

/// Where a trace goes: bytes that can be made durable, and cut back after a failed write.
pub trait TraceSink: Write {
    /// Makes what was written durable (fsync for a file).
    fn sync(&mut self) -> io::Result<()> {
        Ok(())
    }
    /// Cuts the sink back to its first `len` bytes; an error if it cannot.
    fn truncate_to(&mut self, _len: u64) -> io::Result<()> {
        Err(io::Error::new(
            io::ErrorKind::Unsupported,
            "this sink cannot be truncated",
        ))
    }
}

impl TraceSink for File {
    fn sync(&mut self) -> io::Result<()> {
        self.sync_data()
    }
    fn truncate_to(&mut self, len: u64) -> io::Result<()> {
        self.set_len(len)?;
        self.seek(SeekFrom::Start(len)).map(|_| ())
    }
}

impl TraceSink for Vec<u8> {
    fn truncate_to(&mut self, len: u64) -> io::Result<()> {
        self.truncate(len as usize);
        Ok(())
    }
}

impl TraceSink for io::Sink {}

impl<T: TraceSink + ?Sized> TraceSink for &mut T {
    fn sync(&mut self) -> io::Result<()> {
        (**self).sync()
    }
    fn truncate_to(&mut self, len: u64) -> io::Result<()> {
        (**self).truncate_to(len)
    }
}

/// A buffered CSV trace writer that never leaves a half line behind.
pub struct TraceWriter<W: TraceSink> {
    out: W,
    name: String,
    buf: Vec<u8>,
    flush_every: usize,
    since_flush: usize,
    rows: u64,
    /// Bytes and rows known to be in `out` (complete lines only).
    committed_bytes: u64,
    committed_rows: u64,
    broken: bool,
    /// Values per row, once the column header is written.
    columns: Option<usize>,
}

/// Replaces what would break one-line comment fields.
fn one_line(s: &str) -> String {
    s.chars()
        .map(|c| if c.is_control() { '?' } else { c })
        .collect()
}

impl<W: TraceSink> TraceWriter<W> {
    /// Writes the version line (no input files listed) and flushes it.
    pub fn new(inner: W, flush_every: usize) -> io::Result<Self> {
        Self::create(inner, flush_every, "trace.csv", &[])
    }

    /// Writes the provenance lines (`# pneuflex <version>, trace schema N`, one `# input <role> <path>
    /// sha256 <hex>` per input) and flushes them; the column header follows with [`TraceWriter::columns`].
    /// `name` (the file's path) is named in every error.
    pub fn create(
        inner: W,
        flush_every: usize,
        name: &str,
        inputs: &[InputDigest],
    ) -> io::Result<Self> {
        let mut w = Self {
            out: inner,
            name: name.to_string(),
            buf: Vec::with_capacity(64 * 1024),
            flush_every: flush_every.max(1),
            since_flush: 0,
            rows: 0,
            committed_bytes: 0,
            committed_rows: 0,
            broken: false,
            columns: None,
        };
        let mut head = format!(
            "# pneuflex {}, trace schema {TRACE_SCHEMA}\n",
            env!("CARGO_PKG_VERSION")
        );
        for i in inputs {
            head += &format!(
                "# input {} {} sha256 {}\n",
                one_line(&i.role),
                one_line(&i.path),
                i.sha256
            );
        }
        w.buf.extend_from_slice(head.as_bytes());
        w.flush()?;
        Ok(w)
    }

    /// Writes the column header for a controller with signals `own` ([`header_for`]); once, before rows.
    pub fn columns(&mut self, own: &[Signal]) -> io::Result<()> {
        if self.columns.is_some() {
            return Err(io::Error::other(format!(
                "{}: the column header is already written",
                self.name
            )));
        }
        self.columns = Some(pneuflex_control::LOOP_SIGNALS.len() + own.len());
        let line = header_for(own) + "\n";
        self.buf.extend_from_slice(line.as_bytes());
        self.flush()
    }

    /// Appends a row; flushes every `flush_every` rows and on any row with a fault.
    pub fn row(&mut self, r: &TraceRow<'_>) -> io::Result<()> {
        if self.broken {
            return Err(self.broken_error());
        }
        if self.columns != Some(r.values.len()) {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "{}: a row of {} values where the header has {:?}",
                    self.name,
                    r.values.len(),
                    self.columns
                ),
            ));
        }
        let start = self.buf.len();
        for v in r.values {
            let _ = write!(self.buf, "{v},");
        }
        // The board's clock to the µs it counts; an empty cell where there is nothing to say.
        match r.sampled.and_then(|b| b.si.map(|v| (b.board_time_s, v))) {
            Some((t, v)) => {
                let _ = write!(self.buf, "{t:.6},{},{},{},{}", v.x, v.f_e, v.p_a, v.p_b);
            }
            None => self.buf.extend_from_slice(b",,,,"),
        }
        match r.applied {
            Some(a) => {
                let _ = write!(self.buf, ",{:.6},{},", a.board_time_s, a.u);
            }
            None => self.buf.extend_from_slice(b",,,"),
        }
        let _ = write!(self.buf, "{:.6},", r.wall_time);
        // Keep the CSV one field per fault: no commas, quotes or newlines from messages.
        for ch in r.fault.chars() {
            let c = match ch {
                ',' => ';',
                '"' | '\n' | '\r' => ' ',
                c => c,
            };
            let mut tmp = [0u8; 4];
            self.buf
                .extend_from_slice(c.encode_utf8(&mut tmp).as_bytes());
        }
        self.buf.push(b'\n');
        debug_assert!(self.buf.len() > start);
        self.rows += 1;
        self.since_flush += 1;
        if self.since_flush >= self.flush_every || !r.fault.is_empty() {
            self.flush()?;
        }
        Ok(())
    }

    fn broken_error(&self) -> io::Error {
        io::Error::other(format!(
            "{}: the trace could not be written earlier; it ends at its last complete row ({} rows)",
            self.name, self.committed_rows
        ))
    }

    /// Pushes buffered rows to the sink with one `write_all`. On failure the sink is cut back to its last
    /// complete row (if it can be) and the error names the file.
    pub fn flush(&mut self) -> io::Result<()> {
        if self.broken {
            return Err(self.broken_error());
        }
        self.since_flush = 0;
        if self.buf.is_empty() {
            return Ok(());
        }
        let res = self
            .out
            .write_all(&self.buf)
            .and_then(|()| self.out.flush());
        match res {
            Ok(()) => {
                self.committed_bytes += self.buf.len() as u64;
                self.committed_rows = self.rows;
                self.buf.clear();
                Ok(())
            }
            Err(e) => {
                self.broken = true;
                self.buf.clear();
                let cut = match self.out.truncate_to(self.committed_bytes) {
                    Ok(()) => format!(
                        "it was cut back to its last complete row ({} rows)",
                        self.committed_rows
                    ),
                    Err(t) => format!(
                        "it could not be cut back to its last complete row ({} rows, {} bytes): {t}",
                        self.committed_rows, self.committed_bytes
                    ),
                };
                Err(io::Error::new(
                    e.kind(),
                    format!("{}: cannot write the trace: {e}; {cut}", self.name),
                ))
            }
        }
    }

    /// Flushes, then makes the trace durable (fsync for a file).
    pub fn sync(&mut self) -> io::Result<()> {
        self.flush()?;
        self.out.sync().map_err(|e| {
            io::Error::new(
                e.kind(),
                format!("{}: cannot sync the trace to disk: {e}", self.name),
            )
        })
    }

    /// Ends the trace with `# end: <reason>, <n> rows`, flushed and synced. A trace without it was cut.
    pub fn finish(&mut self, reason: &str) -> io::Result<()> {
        if self.broken {
            return Err(self.broken_error());
        }
        let line = format!("{END_MARKER}{}, {} rows\n", one_line(reason), self.rows);
        self.buf.extend_from_slice(line.as_bytes());
        self.sync()
    }

    /// Rows written so far (buffered or not).
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// The sink.
    pub fn get_mut(&mut self) -> &mut W {
        &mut self.out
    }
}

impl<W: TraceSink> Drop for TraceWriter<W> {
    fn drop(&mut self) {
        if !self.broken {
            let _ = self.flush();
        }
    }
}

/// The column header of a rig trace (its first line that is not a comment), if any.
pub fn header_line(text: &str) -> Option<&str> {
    text.lines().find(|l| !l.starts_with('#'))
}

/// The data lines of a rig trace (comment lines and the column header skipped), and whether it ends with
/// the end marker.
pub fn data_lines(text: &str) -> (Vec<&str>, Option<&str>) {
    let mut rows = Vec::new();
    let mut end = None;
    let mut header_seen = false;
    for l in text.lines() {
        if let Some(r) = l.strip_prefix(END_MARKER) {
            end = Some(r);
        } else if l.starts_with('#') {
        } else if !header_seen {
            header_seen = true;
        } else {
            rows.push(l);
        }
    }
    (rows, end)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::{Arc, Mutex};

    #[derive(Clone, Default)]
    struct Shared(Arc<Mutex<Vec<u8>>>, Arc<Mutex<u32>>);
    impl Write for Shared {
        fn write(&mut self, b: &[u8]) -> io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(b);
            Ok(b.len())
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }
    impl TraceSink for Shared {
        fn sync(&mut self) -> io::Result<()> {
            *self.1.lock().unwrap() += 1;
            Ok(())
        }
    }

    fn row8() -> TraceRow<'static> {
        TraceRow {
            values: &[0.0; 8],
            ..TraceRow::default()
        }
    }

    fn text(s: &Shared) -> String {
        String::from_utf8(s.0.lock().unwrap().clone()).unwrap()
    }

    #[test]
    fn flushes_every_n_and_on_fault() {
        let sink = Shared::default();
        let mut w = TraceWriter::new(sink.clone(), 3).unwrap();
        w.columns(&[]).unwrap();
        let lines = || text(&sink).lines().count();
        assert_eq!(lines(), 2, "version line and column header");
        for k in 0..2 {
            w.row(&TraceRow {
                values: &[k as f64; 8],
                ..TraceRow::default()
            })
            .unwrap();
        }
        assert_eq!(lines(), 2, "still buffered");
        w.row(&row8()).unwrap();
        assert_eq!(lines(), 5, "flushed after 3 rows");
        w.row(&TraceRow {
            fault: "limit: x = 1, too far",
            ..row8()
        })
        .unwrap();
        let t = text(&sink);
        assert_eq!(t.lines().count(), 6, "a fault row is flushed at once");
        let last = t.lines().last().unwrap();
        assert_eq!(last.split(',').count(), header_for(&[]).split(',').count());
        assert!(last.ends_with("limit: x = 1; too far"));
        assert!(
            w.row(&TraceRow {
                values: &[0.0; 3],
                ..TraceRow::default()
            })
            .is_err(),
            "a row that does not match the header is refused"
        );
    }

    #[test]
    fn header_carries_provenance_and_finish_adds_the_end_marker() {
        let sink = Shared::default();
        let inputs = [InputDigest {
            path: "scenes/a b.toml".into(),
            role: "scene".into(),
            sha256: "ab".repeat(32),
            bytes: 3,
        }];
        let mut w = TraceWriter::create(sink.clone(), 100, "out/trace.csv", &inputs).unwrap();
        let own = [Signal::new("g", "m", "adaptive", "")];
        w.columns(&own).unwrap();
        w.row(&TraceRow {
            values: &[0.0; 9],
            ..TraceRow::default()
        })
        .unwrap();
        w.row(&TraceRow {
            values: &[0.0; 9],
            ..TraceRow::default()
        })
        .unwrap();
        w.finish("complete").unwrap();
        assert_eq!(*sink.1.lock().unwrap(), 1, "finish syncs");
        let t = text(&sink);
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(
            lines[0],
            format!("# pneuflex {}, trace schema 2", env!("CARGO_PKG_VERSION"))
        );
        assert_eq!(
            lines[1],
            format!("# input scene scenes/a b.toml sha256 {}", "ab".repeat(32))
        );
        assert_eq!(
            lines[2],
            "t,f_ref,f_e,x,x_r,p_a,p_b,u,g,board_t,board_x,board_f_e,board_p_a,board_p_b,applied_t,\
             applied_u,wall_time,fault"
        );
        assert_eq!(*lines.last().unwrap(), "# end: complete, 2 rows");
        let (rows, end) = data_lines(&t);
        assert_eq!((rows.len(), end), (2, Some("complete, 2 rows")));
    }
}
