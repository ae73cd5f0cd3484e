//! Little-endian CDR (XCDR1), the payload of every ROS 2 message: a 4-byte encapsulation
//! header, then the fields in order, each aligned to its own size (at most 8) from the
//! end of the header; strings as a length with the closing NUL, sequences as a count.

/// The encapsulation header of little-endian plain CDR.
const HEADER: [u8; 4] = [0, 1, 0, 0];

/// Writes one message into a buffer (which it clears), without allocating once the
/// buffer has grown to the message's size.
pub struct Writer<'a> {
    buf: &'a mut Vec<u8>,
}

impl<'a> Writer<'a> {
    /// Starts a message in `buf`.
    pub fn new(buf: &'a mut Vec<u8>) -> Self {
        buf.clear();
        buf.extend_from_slice(&HEADER);
        Writer { buf }
    }

    fn align(&mut self, n: usize) {
        while !(self.buf.len() - HEADER.len()).is_multiple_of(n) {
            self.buf.push(0);
        }
    }

    /// A `uint8` (or `bool`, as 0 or 1).
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    /// A `uint32`.
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// An `int32`.
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `uint64`.
    pub fn u64(&mut self, v: u64) {
        self.align(8);
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

    /// The count of a sequence, before its elements.
    pub fn count(&mut self, n: usize) {
        self.u32(n as u32);
    }

    /// A `float64[]`.
    pub fn f64s(&mut self, values: impl ExactSizeIterator<Item = f64>) {
        self.count(values.len());
        self.f64_elements(values);
    }

    /// The elements of a `float64[]` whose count is written already (aligned only if
    /// there is one: an empty sequence ends at its count).
    pub fn f64_elements(&mut self, values: impl Iterator<Item = f64>) {
        let mut values = values.peekable();
        if values.peek().is_some() {
            self.align(8);
        }
        for v in values {
            self.buf.extend_from_slice(&v.to_le_bytes());
        }
    }

    /// A `uint32[]`.
    pub fn u32s(&mut self, values: impl ExactSizeIterator<Item = u32>) {
        self.count(values.len());
        for v in values {
            self.buf.extend_from_slice(&v.to_le_bytes());
        }
    }

    /// A `string[]`.
    pub fn strings<'s>(&mut self, values: impl ExactSizeIterator<Item = &'s str>) {
        self.count(values.len());
        for s in values {
            self.string(s);
        }
    }
}

/// Why a payload could not be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Malformed(pub String);

/// Reads one message, checking every length against what is there.
pub struct Reader<'a> {
    data: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    /// Checks the encapsulation header (little-endian plain CDR only).
    pub fn new(payload: &'a [u8]) -> Result<Self, Malformed> {
        match payload.get(..4) {
            Some(h) if h[..2] == HEADER[..2] => Ok(Reader {
                data: &payload[4..],
                at: 0,
            }),
            Some(h) => Err(Malformed(format!(
                "the CDR encapsulation is {:02x} {:02x}: this node reads little-endian plain CDR (00 01)",
                h[0], h[1]
            ))),
            None => Err(Malformed(format!(
                "{} bytes: a CDR payload starts with a 4-byte header",
                payload.len()
            ))),
        }
    }

    fn take(&mut self, n: usize, align: usize) -> Result<&'a [u8], Malformed> {
        let start = self.at.next_multiple_of(align);
        match self.data.get(start..start.saturating_add(n)) {
            Some(b) => {
                self.at = start + n;
                Ok(b)
            }
            None => Err(Malformed(format!(
                "the payload ends at byte {} where {n} more were due",
                self.data.len() + 4
            ))),
        }
    }

    /// A `uint8` (or `bool`).
    pub fn u8(&mut self) -> Result<u8, Malformed> {
        Ok(self.take(1, 1)?[0])
    }

    /// A `uint32`.
    pub fn u32(&mut self) -> Result<u32, Malformed> {
        let b = self.take(4, 4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// A `uint64`.
    pub fn u64(&mut self) -> Result<u64, Malformed> {
        let b = self.take(8, 8)?;
        let mut a = [0; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }

    /// A `string`: UTF-8 with its closing NUL.
    pub fn string(&mut self) -> Result<String, Malformed> {
        let n = self.u32()? as usize;
        let b = self.take(n, 1)?;
        match b.split_last() {
            Some((0, text)) => String::from_utf8(text.to_vec())
                .map_err(|_| Malformed("a string is not UTF-8".into())),
            _ => Err(Malformed("a string lacks its closing NUL".into())),
        }
    }

    /// The count of a sequence whose elements take at least `least` bytes each.
    pub fn count(&mut self, least: usize) -> Result<usize, Malformed> {
        let n = self.u32()? as usize;
        let left = self.data.len().saturating_sub(self.at);
        if n.saturating_mul(least) > left {
            return Err(Malformed(format!(
                "a sequence of {n} elements in {left} bytes"
            )));
        }
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_aligned_from_the_end_of_the_header() {
        let mut buf = Vec::new();
        let mut w = Writer::new(&mut buf);
        w.u8(1);
        w.u64(2);
        w.string("ab");
        w.f64s([0.5].into_iter());
        assert_eq!(&buf[..4], &HEADER);
        assert_eq!(buf[4], 1);
        assert_eq!(&buf[5..12], &[0; 7], "the u64 starts at offset 8");
        assert_eq!(&buf[12..20], &2u64.to_le_bytes());
        assert_eq!(&buf[20..27], &[3, 0, 0, 0, b'a', b'b', 0]);
        assert_eq!(&buf[27..32], &[0, 1, 0, 0, 0], "padding, then the count");
        assert_eq!(&buf[32..36], &[0; 4], "the f64 starts at offset 32");
        assert_eq!(&buf[36..44], &0.5f64.to_le_bytes());
    }

    #[test]
    fn an_empty_float_sequence_is_its_count_alone() {
        let mut buf = Vec::new();
        let mut w = Writer::new(&mut buf);
        w.f64s(std::iter::empty());
        w.u32(9);
        assert_eq!(&buf[4..], &[0, 0, 0, 0, 9, 0, 0, 0]);
    }

    #[test]
    fn a_reader_reads_what_a_writer_wrote_and_refuses_what_is_cut_short() {
        let mut buf = Vec::new();
        let mut w = Writer::new(&mut buf);
        w.u64(7);
        w.string("ratemap");
        w.u32(3);
        let mut r = Reader::new(&buf).unwrap();
        assert_eq!(r.u64().unwrap(), 7);
        assert_eq!(r.string().unwrap(), "ratemap");
        assert_eq!(r.u32().unwrap(), 3);
        assert!(r.u32().is_err());
        for cut in 0..buf.len() - 1 {
            let read =
                Reader::new(&buf[..cut]).and_then(|mut r| Ok((r.u64()?, r.string()?, r.u32()?)));
            assert!(read.is_err(), "cut at {cut}");
        }
    }

    #[test]
    fn a_count_beyond_the_payload_and_a_big_endian_header_are_refused() {
        let mut buf = Vec::new();
        Writer::new(&mut buf).u32(u32::MAX);
        assert!(Reader::new(&buf).unwrap().count(1).is_err());
        assert!(Reader::new(&[0, 0, 0, 0, 1]).is_err());
    }
}
