//! Measured heads from SOFA files (AES69, convention `SimpleFreeFieldHRIR`), read with the
//! pure-Rust HDF5 parser of `sofar`: the horizontal plane's impulse responses at the
//! file's own rate, in double precision.

use std::path::Path;

use sofar::hdf::{self, DataObject, DataType, ParsedHdf};

use crate::SpatialError;

/// Largest SOFA file read, bytes: the MIT KEMAR set is 1.4 MB, dense sets some 100 MB.
pub const MAX_FILE_BYTES: u64 = 256 << 20;
/// Largest elevation taken as the horizontal plane, deg.
const HORIZONTAL_DEG: f64 = 0.5;

/// The horizontal plane of a measured head: its azimuths and responses.
#[derive(Debug, Clone)]
pub struct Measured {
    /// Sampling rate of the responses, Hz.
    pub fs_hz: f64,
    /// Azimuths, deg in [0, 360) (0 = front, 90 = left), ascending.
    pub azimuths_deg: Vec<f64>,
    /// Per azimuth, the left and the right ear's impulse response.
    pub responses: Vec<[Vec<f64>; 2]>,
}

/// Reads the horizontal plane of the `SimpleFreeFieldHRIR` file at `path`.
pub fn read(path: &Path) -> Result<Measured, SpatialError> {
    let bad = |why: String| SpatialError::Sofa {
        path: path.display().to_string(),
        why,
    };
    let size = std::fs::metadata(path)
        .map_err(|e| bad(format!("cannot read it: {e}")))?
        .len();
    if size > MAX_FILE_BYTES {
        return Err(bad(format!(
            "it has {size} bytes, more than the {MAX_FILE_BYTES} a head file may have"
        )));
    }
    let bytes = std::fs::read(path).map_err(|e| bad(format!("cannot read it: {e}")))?;
    parse(&bytes).map_err(bad)
}

/// The horizontal plane of a `SimpleFreeFieldHRIR` file's bytes; the error says why not.
pub fn parse(bytes: &[u8]) -> Result<Measured, String> {
    let file = hdf::parse_with_children(bytes)
        .map_err(|_| "not a SOFA file (no HDF5 structure could be read)".to_string())?;
    let conventions = attribute(&file.root, "SOFAConventions");
    if conventions != Some("SimpleFreeFieldHRIR") {
        return Err(format!(
            "its convention is {}, not SimpleFreeFieldHRIR (head-related impulse responses \
             of a free field)",
            conventions.map_or("missing".to_string(), |c| format!("'{c}'"))
        ));
    }
    let fs_hz = *floats(&file, "Data.SamplingRate")?
        .0
        .first()
        .ok_or("Data.SamplingRate is empty")?;
    if !(fs_hz.is_finite() && fs_hz >= 8000.0) {
        return Err(format!("its sampling rate {fs_hz} Hz is not one of audio"));
    }
    let (ir, dims) = floats(&file, "Data.IR")?;
    let [m, r, n] = match dims[..] {
        [m, r, n] => [m, r, n],
        _ => {
            return Err(format!(
                "Data.IR has {} dimensions, not 3 (M, R, N)",
                dims.len()
            ))
        }
    };
    if r != 2 {
        return Err(format!("Data.IR has {r} receivers, not 2 ears"));
    }
    let (positions, pdims) = floats(&file, "SourcePosition")?;
    if pdims.first() != Some(&m) || positions.len() != 3 * m {
        return Err(format!(
            "SourcePosition holds {} values for {m} measurements, not 3 each",
            positions.len()
        ));
    }
    let spherical = position_type(&file)?;
    let mut plane: Vec<(f64, [Vec<f64>; 2])> = Vec::new();
    for k in 0..m {
        let p = &positions[3 * k..3 * k + 3];
        let (azimuth, elevation) = if spherical {
            (p[0], p[1])
        } else {
            let (x, y, z) = (p[0], p[1], p[2]);
            (y.atan2(x).to_degrees(), z.atan2(x.hypot(y)).to_degrees())
        };
        if elevation.abs() > HORIZONTAL_DEG {
            continue;
        }
        let at = |ear: usize| ir[(k * 2 + ear) * n..(k * 2 + ear + 1) * n].to_vec();
        plane.push((azimuth.rem_euclid(360.0), [at(0), at(1)]));
    }
    if plane.len() < 4 {
        return Err(format!(
            "it has {} directions on the horizontal plane (elevation 0), too few to locate on",
            plane.len()
        ));
    }
    plane.sort_by(|a, b| a.0.total_cmp(&b.0));
    plane.dedup_by(|a, b| (a.0 - b.0).abs() < 1e-9);
    if plane
        .iter()
        .any(|(_, [l, r])| l.iter().chain(r).any(|v| !v.is_finite()))
    {
        return Err("its responses hold NaN or Inf".into());
    }
    let (azimuths_deg, responses) = plane.into_iter().unzip();
    Ok(Measured {
        fs_hz,
        azimuths_deg,
        responses,
    })
}

/// A text attribute of an object.
fn attribute<'a>(object: &'a DataObject, name: &str) -> Option<&'a str> {
    object
        .parsed_attributes
        .iter()
        .find(|a| a.name == name)
        .and_then(|a| a.value.as_deref())
}

/// Whether `SourcePosition` is spherical (azimuth, elevation in degrees, distance) rather
/// than cartesian.
fn position_type(file: &ParsedHdf<'_>) -> Result<bool, String> {
    let object = child(file, "SourcePosition")?;
    match attribute(&object, "Type") {
        Some(t) if t.eq_ignore_ascii_case("spherical") => Ok(true),
        Some(t) if t.eq_ignore_ascii_case("cartesian") => Ok(false),
        other => Err(format!(
            "SourcePosition's Type is {}, neither spherical nor cartesian",
            other.map_or("missing".to_string(), |t| format!("'{t}'"))
        )),
    }
}

fn child(file: &ParsedHdf<'_>, name: &str) -> Result<DataObject, String> {
    file.get_child(name)
        .ok_or_else(|| format!("it has no {name}"))?
        .map_err(|_| format!("its {name} cannot be read"))
}

/// The floating-point values of a variable with its dimensions.
fn floats(file: &ParsedHdf<'_>, name: &str) -> Result<(Vec<f64>, Vec<usize>), String> {
    let object = child(file, name)?;
    let values = decode(&object.data, &object.dt)
        .ok_or_else(|| format!("its {name} is not floating point"))?;
    let dims: Vec<usize> = object
        .ds
        .dimension_size
        .iter()
        .map(|&d| d as usize)
        .collect();
    if dims.iter().product::<usize>() != values.len() {
        return Err(format!(
            "its {name} holds {} values for dimensions {dims:?}",
            values.len()
        ));
    }
    Ok((values, dims))
}

/// IEEE floats of 4 or 8 bytes, in the byte order the type gives.
fn decode(data: &[u8], dt: &DataType) -> Option<Vec<f64>> {
    // class 1: floating point; bit 0 of its fields: big-endian
    if dt.class_and_version & 0x0F != 1 {
        return None;
    }
    let big = dt.class_bit_field & 1 == 1;
    match dt.size {
        8 => Some(
            data.chunks_exact(8)
                .map(|b| {
                    let b: [u8; 8] = b.try_into().unwrap_or([0; 8]);
                    if big {
                        f64::from_be_bytes(b)
                    } else {
                        f64::from_le_bytes(b)
                    }
                })
                .collect(),
        ),
        4 => Some(
            data.chunks_exact(4)
                .map(|b| {
                    let b: [u8; 4] = b.try_into().unwrap_or([0; 4]);
                    f64::from(if big {
                        f32::from_be_bytes(b)
                    } else {
                        f32::from_le_bytes(b)
                    })
                })
                .collect(),
        ),
        _ => None,
    }
}
