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
    let complex = is_complex(shape, data);
    assert!(
        complex || data.len() == shape.iter().product::<usize>(),
        "{} values for shape {shape:?}",
        data.len()
    );
    let descr = if complex { "<c16" } else { "<f8" };
    let dims: String = shape.iter().map(|d| format!("{d}, ")).collect();
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': ({dims}), }}");
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + 8 * data.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
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
    } else {
        return Err(bad("dtype is not <f8, <f4 or <c16"));
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

/// Writes named arrays as an `.npz` archive (entries `<name>.npy`, stored uncompressed).
pub fn write_npz<W: Write + Seek>(
    out: W,
    arrays: &[(String, Vec<usize>, &[f64])],
) -> std::io::Result<()> {
    let mut zip = zip::ZipWriter::new(out);
    for (name, shape, data) in arrays {
        let options = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Stored)
            .large_file(data.len() * 8 > u32::MAX as usize / 2);
        zip.start_file(format!("{name}.npy"), options)?;
        zip.write_all(&encode(shape, data))?;
    }
    zip.finish()?;
    Ok(())
}

#[cfg(test)]
mod tests {
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
