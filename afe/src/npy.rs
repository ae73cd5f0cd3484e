//! Minimal NumPy `.npy` encoding and decoding (little-endian float64/float32, and
//! complex128, C order), and `.npz` writing (an uncompressed zip of `.npy` files), for
//! outputs and golden files.
//!
//! Complex arrays travel as their `(real, imaginary)` pairs of `f64`: `data` then holds
//! twice as many values as `shape` has elements (the layout of complex128 in memory, and
//! of afe's complex signals, e.g. the STFT).

use std::io::{Seek, Write};

use thiserror::Error;

/// A decoded array: shape and values in C order, widened to f64 (complex values as
/// `(real, imaginary)` pairs).
#[derive(Debug, Clone, PartialEq)]
pub struct Array {
    /// Dimensions, outermost first.
    pub shape: Vec<usize>,
    /// Values in C (row-major) order.
    pub data: Vec<f64>,
}

/// Problems reading an `.npy` file.
#[derive(Debug, Error)]
pub enum NpyError {
    /// Not an `.npy` file, or a header this reader does not handle.
    #[error("not a supported .npy file: {0}")]
    Format(String),
}

/// How values are stored: as computed (float64), or rounded to float32 (half the size).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Dtype {
    /// Little-endian float64 (complex128 for complex signals).
    #[default]
    Float64,
    /// Little-endian float32 (complex64), each value rounded to nearest.
    Float32,
}

impl Dtype {
    /// NumPy's name of the type, for real or complex values.
    pub fn name(self, complex: bool) -> &'static str {
        match (self, complex) {
            (Dtype::Float64, false) => "float64",
            (Dtype::Float64, true) => "complex128",
            (Dtype::Float32, false) => "float32",
            (Dtype::Float32, true) => "complex64",
        }
    }

    /// The `.npy` header's type descriptor.
    fn descr(self, complex: bool) -> &'static str {
        match (self, complex) {
            (Dtype::Float64, false) => "<f8",
            (Dtype::Float64, true) => "<c16",
            (Dtype::Float32, false) => "<f4",
            (Dtype::Float32, true) => "<c8",
        }
    }

    /// The first of `values` that this type cannot hold (finite in float64, beyond
    /// float32's ±3.4e38: rounding would store ±Inf), if any.
    pub fn first_unstorable(self, values: &[f64]) -> Option<f64> {
        match self {
            Dtype::Float64 => None,
            Dtype::Float32 => {
                let top = f64::from(f32::MAX);
                values
                    .iter()
                    .copied()
                    .find(|v| v.is_finite() && v.abs() > top)
            }
        }
    }

    /// An error naming output `key` if one of its `values` cannot be stored as this type.
    pub fn check(self, key: &str, values: &[f64]) -> afe_core::Result<()> {
        match self.first_unstorable(values) {
            None => Ok(()),
            Some(v) => Err(afe_core::Error::InvalidInput(format!(
                "{key} holds {v:e}, beyond what float32 can hold (±{:e}): store it as \
                 float64 (--dtype f64, dtype=\"float64\"), or scale the input down",
                f32::MAX
            ))),
        }
    }

    /// Bytes per stored value (a complex value is two).
    fn size(self) -> usize {
        match self {
            Dtype::Float64 => 8,
            Dtype::Float32 => 4,
        }
    }
}

/// Whether `data` holds the `(real, imaginary)` pairs of an array of `shape`.
pub fn is_complex(shape: &[usize], data: &[f64]) -> bool {
    let count: usize = shape.iter().product();
    count > 0 && data.len() == 2 * count
}

/// Encodes `data` with `shape` as a version-1.0 `.npy` file of little-endian float64, or
/// complex128 when `data` holds twice as many values as the shape (pairs).
///
/// # Panics
/// If `data` holds neither one nor two values per element of `shape`.
pub fn encode(shape: &[usize], data: &[f64]) -> Vec<u8> {
    encode_as(shape, data, Dtype::Float64)
}

/// As [`encode`], storing the values as `dtype`.
///
/// # Panics
/// As [`encode`].
pub fn encode_as(shape: &[usize], data: &[f64], dtype: Dtype) -> Vec<u8> {
    let mut out = Vec::with_capacity(128 + dtype.size() * data.len());
    // writing to a Vec cannot fail
    let _ = write_npy(&mut out, shape, data, dtype);
    out
}

/// Values converted per write of [`write_npy`]: 64 KiB of float64.
const WRITE_VALUES: usize = 8192;

/// Writes what [`encode_as`] returns to `out`, converting the values a slice at a time
/// (no copy of the whole array: a whole signal's outputs are written as they are).
///
/// # Panics
/// As [`encode`].
pub fn write_npy<W: Write>(
    out: &mut W,
    shape: &[usize],
    data: &[f64],
    dtype: Dtype,
) -> std::io::Result<()> {
    let complex = is_complex(shape, data);
    assert!(
        complex || data.len() == shape.iter().product::<usize>(),
        "{} values for shape {shape:?}",
        data.len()
    );
    let descr = dtype.descr(complex);
    let dims: String = shape.iter().map(|d| format!("{d}, ")).collect();
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': ({dims}), }}");
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    header.push('\n');
    out.write_all(b"\x93NUMPY\x01\x00")?;
    out.write_all(&(header.len() as u16).to_le_bytes())?;
    out.write_all(header.as_bytes())?;
    let mut bytes = Vec::with_capacity(WRITE_VALUES * dtype.size());
    for slice in data.chunks(WRITE_VALUES) {
        bytes.clear();
        match dtype {
            Dtype::Float64 => slice
                .iter()
                .for_each(|v| bytes.extend_from_slice(&v.to_le_bytes())),
            Dtype::Float32 => slice
                .iter()
                .for_each(|v| bytes.extend_from_slice(&(*v as f32).to_le_bytes())),
        }
        out.write_all(&bytes)?;
    }
    Ok(())
}

/// Decodes an `.npy` file of little-endian float64 or float32 in C order.
pub fn decode(bytes: &[u8]) -> Result<Array, NpyError> {
    let bad = |m: &str| NpyError::Format(m.to_string());
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err(bad("missing magic string"));
    }
    let (hlen, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        _ => return Err(bad("unknown version")),
    };
    let header = std::str::from_utf8(
        bytes
            .get(start..start + hlen)
            .ok_or_else(|| bad("short header"))?,
    )
    .map_err(|_| bad("header is not text"))?;
    if header.contains("'fortran_order': True") {
        return Err(bad("Fortran order"));
    }
    let (width, per_element) = if header.contains("'<f8'") {
        (8, 1)
    } else if header.contains("'<f4'") {
        (4, 1)
    } else if header.contains("'<c16'") {
        (8, 2)
    } else if header.contains("'<c8'") {
        (4, 2)
    } else {
        return Err(bad("dtype is not <f8, <f4, <c16 or <c8"));
    };
    let shape_txt = header
        .split("'shape':")
        .nth(1)
        .and_then(|s| s.split('(').nth(1))
        .and_then(|s| s.split(')').next())
        .ok_or_else(|| bad("no shape"))?;
    let shape: Vec<usize> = shape_txt
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().map_err(|_| bad("bad shape")))
        .collect::<Result<_, _>>()?;
    let count = shape.iter().product::<usize>() * per_element;
    let body = &bytes[start + hlen..];
    if body.len() < count * width {
        return Err(bad("truncated data"));
    }
    let data = body[..count * width]
        .chunks_exact(width)
        .map(|c| {
            if width == 8 {
                f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]])
            } else {
                f64::from(f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            }
        })
        .collect();
    Ok(Array { shape, data })
}

/// Name of the `.npz` entry holding the arrays' descriptions as JSON text (a 0-d numpy
/// unicode array: `json.loads(str(np.load(f)["afe_metadata"]))`). No output is named so:
/// output names start with a request name.
pub const METADATA_ENTRY: &str = "afe_metadata";

/// Encodes `text` as a version-1.0 `.npy` file of a 0-d numpy unicode string
/// (`<U{n}`, UTF-32), which `numpy.load` reads without pickling.
pub fn encode_text(text: &str) -> Vec<u8> {
    let chars = text.chars().count().max(1);
    let mut header = format!("{{'descr': '<U{chars}', 'fortran_order': False, 'shape': (), }}");
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + 4 * chars);
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for c in text.chars() {
        out.extend_from_slice(&u32::from(c).to_le_bytes());
    }
    out.resize(10 + header.len() + 4 * chars, 0);
    out
}

/// Decodes a 0-d numpy unicode string written by [`encode_text`] (`<U{n}`, UTF-32;
/// numpy drops trailing NULs).
pub fn decode_text(bytes: &[u8]) -> Result<String, NpyError> {
    let bad = |m: &str| NpyError::Format(m.to_string());
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" || bytes[6] != 1 {
        return Err(bad("not a version-1.0 .npy file"));
    }
    let start = 10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = bytes.get(10..start).ok_or_else(|| bad("short header"))?;
    if !String::from_utf8_lossy(header).contains("'<U") {
        return Err(bad("dtype is not <U"));
    }
    bytes[start..]
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .take_while(|&u| u != 0)
        .map(|u| char::from_u32(u).ok_or_else(|| bad("not UTF-32")))
        .collect()
}

/// Writes named arrays as an `.npz` archive (entries `<name>.npy`, stored uncompressed),
/// and `metadata`, if given, as the text entry [`METADATA_ENTRY`].
pub fn write_npz<W: Write + Seek>(
    out: W,
    arrays: &[(String, Vec<usize>, &[f64])],
    metadata: Option<&str>,
) -> std::io::Result<()> {
    write_npz_as(out, arrays, metadata, Dtype::Float64)
}

/// As [`write_npz`], storing the arrays' values as `dtype`.
pub fn write_npz_as<W: Write + Seek>(
    out: W,
    arrays: &[(String, Vec<usize>, &[f64])],
    metadata: Option<&str>,
    dtype: Dtype,
) -> std::io::Result<()> {
    let mut first_error = None;
    let result = (|| {
        let mut zip = zip::ZipWriter::new(FirstError {
            inner: out,
            error: &mut first_error,
            pos: 0,
            end: 0,
        });
        for (name, shape, data) in arrays {
            let options = zip::write::SimpleFileOptions::default()
                .compression_method(zip::CompressionMethod::Stored)
                .large_file(data.len() * dtype.size() > u32::MAX as usize / 2);
            zip.start_file(format!("{name}.npy"), options)?;
            write_npy(&mut zip, shape, data, dtype)?;
        }
        if let Some(text) = metadata {
            let options = zip::write::SimpleFileOptions::default()
                .compression_method(zip::CompressionMethod::Stored);
            zip.start_file(format!("{METADATA_ENTRY}.npy"), options)?;
            zip.write_all(&encode_text(text))?;
        }
        zip.finish()?;
        Ok::<(), zip::result::ZipError>(())
    })();
    match (first_error, result) {
        // the I/O error as the system gave it ("No space left on device")
        (Some(e), _) => Err(e),
        (None, r) => r.map_err(std::io::Error::other),
    }
}

/// Keeps the first I/O error and swallows the writes after it (moving a virtual
/// position as they would): the zip writer then drops quietly (it would print "ZipWriter
/// drop failed" to stderr trying to finish on a failed file), and the caller reports the
/// original error. The writer starts at position 0 (a new file or buffer).
struct FirstError<'a, W> {
    inner: W,
    error: &'a mut Option<std::io::Error>,
    pos: u64,
    end: u64,
}

impl<W: Write> Write for FirstError<'_, W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = if self.error.is_some() {
            buf.len()
        } else {
            self.inner.write(buf).map_err(|e| self.keep(e))?
        };
        self.pos += n as u64;
        self.end = self.end.max(self.pos);
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        if self.error.is_some() {
            return Ok(());
        }
        self.inner.flush().map_err(|e| self.keep(e))
    }
}

impl<W: Seek> Seek for FirstError<'_, W> {
    fn seek(&mut self, to: std::io::SeekFrom) -> std::io::Result<u64> {
        use std::io::SeekFrom;
        self.pos = if self.error.is_some() {
            let target = match to {
                SeekFrom::Start(n) => Some(n),
                SeekFrom::Current(d) => self.pos.checked_add_signed(d),
                SeekFrom::End(d) => self.end.checked_add_signed(d),
            };
            target.ok_or_else(|| std::io::Error::from(std::io::ErrorKind::InvalidInput))?
        } else {
            self.inner.seek(to).map_err(|e| self.keep(e))?
        };
        self.end = self.end.max(self.pos);
        Ok(self.pos)
    }
}

impl<W> FirstError<'_, W> {
    /// Records `e` and returns an error of the same kind for the zip writer.
    fn keep(&mut self, e: std::io::Error) -> std::io::Error {
        let kind = e.kind();
        *self.error = Some(e);
        std::io::Error::from(kind)
    }
}

#[cfg(test)]
mod tests {
    /// A file that fills up after `room` bytes.
    struct Full {
        room: usize,
        at: u64,
    }

    impl std::io::Write for Full {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            if buf.len() > self.room {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::StorageFull,
                    "disk full",
                ));
            }
            self.room -= buf.len();
            self.at += buf.len() as u64;
            Ok(buf.len())
        }

        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    impl std::io::Seek for Full {
        fn seek(&mut self, _: std::io::SeekFrom) -> std::io::Result<u64> {
            Ok(self.at)
        }
    }

    #[test]
    fn text_round_trips_through_a_numpy_string() {
        for text in ["{\"cf_hz\": [80.0]}", "ü → ∞", ""] {
            let bytes = super::encode_text(text);
            assert_eq!(
                (10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize) % 64,
                0
            );
            assert_eq!(super::decode_text(&bytes).expect("text"), text);
        }
        assert!(super::decode_text(&super::encode(&[1], &[0.5])).is_err());
    }

    #[test]
    fn a_full_disk_is_reported_as_the_system_said() {
        let data = vec![0.5; 1000];
        for room in [0, 10, 100, 5000, 7990] {
            let e = super::write_npz(
                Full { room, at: 0 },
                &[("x".into(), vec![1000], &data)],
                Some("{}"),
            )
            .expect_err("no room");
            assert_eq!(e.kind(), std::io::ErrorKind::StorageFull, "room {room}");
            assert_eq!(e.to_string(), "disk full");
        }
        assert!(super::write_npz(
            Full {
                room: 1 << 20,
                at: 0
            },
            &[("x".into(), vec![1000], &data)],
            None
        )
        .is_ok());
    }
    /// The zip writer's drop writes to the process's stderr directly: run the case in a
    /// child test process and read what it printed.
    #[test]
    fn a_full_disk_prints_nothing_of_its_own() {
        if std::env::var_os("AFE_NPZ_FULL_CHILD").is_some() {
            let data = vec![0.5; 1000];
            for room in [0, 100, 5000] {
                let arrays = [("x".to_string(), vec![1000], data.as_slice())];
                assert!(super::write_npz(Full { room, at: 0 }, &arrays, None).is_err());
            }
            return;
        }
        let exe = std::env::current_exe().expect("test binary");
        let out = std::process::Command::new(exe)
            .args([
                "--exact",
                "npy::tests::a_full_disk_prints_nothing_of_its_own",
                "--nocapture",
            ])
            .env("AFE_NPZ_FULL_CHILD", "1")
            .output()
            .expect("child");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        assert!(!stderr.contains("drop failed"), "{stderr}");
    }

    use super::*;

    #[test]
    fn round_trip_and_header_alignment() {
        let data = [1.0, -2.5, 3.25, 4.0, 5.0, 6.0];
        let bytes = encode(&[2, 3], &data);
        let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        assert_eq!((10 + header_len) % 64, 0);
        let a = decode(&bytes).expect("valid");
        assert_eq!(a.shape, vec![2, 3]);
        assert_eq!(a.data, data.to_vec());
        let one_d = decode(&encode(&[6], &data)).expect("valid");
        assert_eq!(one_d.shape, vec![6]);
        // three complex values
        let bytes = encode(&[3], &data);
        assert!(String::from_utf8_lossy(&bytes[..64]).contains("'<c16'"));
        let c = decode(&bytes).expect("valid");
        assert_eq!((c.shape, c.data), (vec![3], data.to_vec()));
        assert!(decode(b"not numpy").is_err());
    }
}
