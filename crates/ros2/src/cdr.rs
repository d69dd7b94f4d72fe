//! CDR as ROS 2 puts it on the wire and in a bag (OMG DDS-XTypes 1.3 §7.4.1, "XCDR1", plain CDR of
//! CORBA 3.0 ch. 15.3): a 4-byte encapsulation header `00 01 00 00` (CDR_LE: representation identifier
//! 0x0001 big-endian, then two option bytes), then the fields in declaration order, little-endian, each
//! primitive aligned to its own size counted from the first byte after the header. A string is a u32
//! length that counts its NUL, the bytes, the NUL; a sequence is a u32 count then the elements. A sequence
//! of no elements is its count alone (Fast-CDR aligns only when there is an element to write).

use crate::Ros2Error;

/// The encapsulation header of little-endian plain CDR.
pub const CDR_LE: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// Serialises one message.
#[derive(Clone, Debug)]
pub struct CdrWriter {
    buf: Vec<u8>,
}

impl Default for CdrWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl CdrWriter {
    /// An empty message: the encapsulation header alone.
    pub fn new() -> Self {
        Self {
            buf: CDR_LE.to_vec(),
        }
    }

    /// Pads with zeros to a multiple of `n` bytes after the header.
    fn align(&mut self, n: usize) {
        let pos = self.buf.len() - CDR_LE.len();
        let pad = (n - pos % n) % n;
        self.buf.resize(self.buf.len() + pad, 0);
    }

    /// An `int32`.
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `uint32`.
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `float64`.
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `string`.
    pub fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }

    /// A sequence's length.
    pub fn len(&mut self, n: usize) {
        self.u32(n as u32);
    }

    /// A `string[]`.
    pub fn strings(&mut self, v: &[String]) {
        self.len(v.len());
        for s in v {
            self.string(s);
        }
    }

    /// A `float64[]`.
    pub fn f64s(&mut self, v: &[f64]) {
        self.len(v.len());
        for &x in v {
            self.f64(x);
        }
    }

    /// The message's bytes, header included.
    pub fn finish(self) -> Vec<u8> {
        self.buf
    }
}

/// Reads one message.
#[derive(Clone, Debug)]
pub struct CdrReader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> CdrReader<'a> {
    /// Checks the encapsulation header: little-endian plain CDR is the only one read.
    pub fn new(data: &'a [u8]) -> Result<Self, Ros2Error> {
        match data.get(..4) {
            Some([0x00, 0x01, _, _]) => Ok(Self { data, pos: 4 }),
            Some(h) => Err(Ros2Error::Cdr(format!(
                "encapsulation {:02x} {:02x}: only little-endian plain CDR (00 01) is read",
                h[0], h[1]
            ))),
            None => Err(Ros2Error::Cdr(format!(
                "{} bytes: shorter than the encapsulation header",
                data.len()
            ))),
        }
    }

    fn align(&mut self, n: usize) {
        let pos = self.pos - CDR_LE.len();
        self.pos += (n - pos % n) % n;
    }

    fn take<const N: usize>(&mut self, what: &str) -> Result<[u8; N], Ros2Error> {
        self.align(N);
        let bytes = self.data.get(self.pos..self.pos + N).ok_or_else(|| {
            Ros2Error::Cdr(format!("message ends inside {what} at byte {}", self.pos))
        })?;
        self.pos += N;
        Ok(bytes.try_into().expect("N bytes"))
    }

    /// An `int32`.
    pub fn i32(&mut self) -> Result<i32, Ros2Error> {
        self.take::<4>("an int32").map(i32::from_le_bytes)
    }

    /// A `uint32`.
    pub fn u32(&mut self) -> Result<u32, Ros2Error> {
        self.take::<4>("a uint32").map(u32::from_le_bytes)
    }

    /// A `float64`.
    pub fn f64(&mut self) -> Result<f64, Ros2Error> {
        self.take::<8>("a float64").map(f64::from_le_bytes)
    }

    /// A sequence's length, checked against what is left (each element takes at least `min_size` bytes).
    pub fn len(&mut self, min_size: usize) -> Result<usize, Ros2Error> {
        let n = self.u32()? as usize;
        let left = self.data.len() - self.pos.min(self.data.len());
        if n.saturating_mul(min_size) > left {
            return Err(Ros2Error::Cdr(format!(
                "a sequence of {n} elements at byte {}: only {left} bytes left",
                self.pos
            )));
        }
        Ok(n)
    }

    /// A `string`.
    pub fn string(&mut self) -> Result<String, Ros2Error> {
        let n = self.len(1)?;
        let bytes = &self.data[self.pos..self.pos + n];
        self.pos += n;
        let text = bytes.strip_suffix(&[0]).ok_or_else(|| {
            Ros2Error::Cdr(format!(
                "a string at byte {} does not end in NUL",
                self.pos - n
            ))
        })?;
        String::from_utf8(text.to_vec())
            .map_err(|e| Ros2Error::Cdr(format!("a string that is not UTF-8: {e}")))
    }

    /// A `string[]`.
    pub fn strings(&mut self) -> Result<Vec<String>, Ros2Error> {
        let n = self.len(5)?;
        (0..n).map(|_| self.string()).collect()
    }

    /// A `float64[]`.
    pub fn f64s(&mut self) -> Result<Vec<f64>, Ros2Error> {
        let n = self.len(8)?;
        (0..n).map(|_| self.f64()).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A string of 1 byte then a float64: the length (4), 'a' and NUL (2), 2 bytes of padding to reach 8,
    /// the float. Laid out by hand from the alignment rule.
    #[test]
    fn a_float_after_a_string_is_aligned_to_eight_after_the_header() {
        let mut w = CdrWriter::new();
        w.string("a");
        w.f64(1.5);
        let bytes = w.finish();
        let mut want = vec![0, 1, 0, 0, 2, 0, 0, 0, b'a', 0, 0, 0];
        want.extend_from_slice(&1.5f64.to_le_bytes());
        assert_eq!(bytes, want);
        let mut r = CdrReader::new(&bytes).unwrap();
        assert_eq!(r.string().unwrap(), "a");
        assert_eq!(r.f64().unwrap(), 1.5);
    }

    #[test]
    fn an_empty_float_sequence_is_its_count_alone() {
        let mut w = CdrWriter::new();
        w.i32(-1);
        w.f64s(&[]);
        w.u32(7);
        assert_eq!(
            w.finish(),
            vec![0, 1, 0, 0, 255, 255, 255, 255, 0, 0, 0, 0, 7, 0, 0, 0]
        );
    }

    #[test]
    fn a_big_endian_or_cut_message_is_refused() {
        assert!(CdrReader::new(&[0, 0, 0, 0]).is_err());
        let mut r = CdrReader::new(&[0, 1, 0, 0, 200, 0, 0, 0]).unwrap();
        let e = r.f64s().unwrap_err().to_string();
        assert!(e.contains("200 elements"), "{e}");
    }
}
