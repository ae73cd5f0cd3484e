//! The binary messages `afe serve` publishes: raw audio blocks and a subscription's new
//! frames. Every number is little-endian; every value an IEEE-754 `f64`, so a remote
//! client receives the server's numbers bit for bit.
//!
//! Header (40 bytes):
//!
//! | bytes | type | meaning |
//! |---|---|---|
//! | 0..4 | `b"AFEZ"` | magic |
//! | 4..6 | u16 | wire version ([`VERSION`]) |
//! | 6..8 | u16 | kind: 1 audio, 2 frames |
//! | 8..16 | u64 | message number on its key, from 0 (a gap is a lost message) |
//! | 16..24 | u64 | index of the block's first frame on the server's port |
//! | 24..28 | u32 | frames in the block |
//! | 28..32 | u32 | audio: channels; frames: signals |
//! | 32..40 | u64 | Unix time in ns at which the block's last frame was due on the port |
//!
//! An audio body is the block's samples, frame after frame, channel after channel within
//! a frame. A frames body has, per signal of the subscription (in the order of its
//! reply): u64 index of the signal's first new frame, u32 new frames, u32 `f64` values
//! per frame (a complex value is two: real, imaginary), then the values, time-major.

use thiserror::Error;

/// Wire version written in every header.
pub const VERSION: u16 = 1;
/// Header length, bytes.
pub const HEADER: usize = 40;
const MAGIC: &[u8; 4] = b"AFEZ";
/// Per-signal header of a frames body, bytes.
const SIGNAL_HEADER: usize = 16;

/// What a message carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Raw input samples.
    Audio = 1,
    /// A subscription's new frames.
    Frames = 2,
}

impl std::fmt::Display for Kind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Kind::Audio => "audio",
            Kind::Frames => "frames",
        })
    }
}

/// The fixed part of every message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// Audio or frames.
    pub kind: Kind,
    /// Message number on its key, from 0.
    pub seq: u64,
    /// Index of the block's first frame on the server's port.
    pub first_input_frame: u64,
    /// Frames in the block.
    pub input_frames: u32,
    /// Channels (audio) or signals (frames).
    pub count: u32,
    /// Unix time in ns at which the block's last frame was due on the port.
    pub t_ns: u64,
}

/// A message that is not what this version writes.
#[derive(Debug, Error, PartialEq, Eq)]
pub enum WireError {
    /// Shorter than its header or than its header announces.
    #[error("message of {got} bytes is cut short: expected {expected}")]
    Short {
        /// Bytes needed.
        expected: usize,
        /// Bytes received.
        got: usize,
    },
    /// Not an afe message, or from an unknown wire version.
    #[error(
        "not an afe {expected} message of wire version {VERSION} (magic {magic:?}, version {version})"
    )]
    Foreign {
        /// The first four bytes.
        magic: [u8; 4],
        /// The version field.
        version: u16,
        /// The kind the reader expected.
        expected: Kind,
    },
    /// A kind other than the one expected on this key.
    #[error("not an afe {1} message: its kind is {0}")]
    Kind(u16, Kind),
    /// An audio message whose samples are not the frames times the channels its header
    /// announces.
    #[error(
        "an audio message of {frames} frames of {channels} channels with {bytes} bytes of samples"
    )]
    AudioSize {
        /// Frames announced.
        frames: u32,
        /// Channels announced.
        channels: u32,
        /// Bytes of samples received.
        bytes: usize,
    },
    /// Bytes left after the last signal.
    #[error("{0} bytes after the end of the message")]
    Trailing(usize),
}

impl Header {
    /// Appends the header to `out`.
    pub fn write(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&VERSION.to_le_bytes());
        out.extend_from_slice(&(self.kind as u16).to_le_bytes());
        out.extend_from_slice(&self.seq.to_le_bytes());
        out.extend_from_slice(&self.first_input_frame.to_le_bytes());
        out.extend_from_slice(&self.input_frames.to_le_bytes());
        out.extend_from_slice(&self.count.to_le_bytes());
        out.extend_from_slice(&self.t_ns.to_le_bytes());
    }

    /// Reads the header of a message of kind `kind`; returns it and the body.
    pub fn read(bytes: &[u8], kind: Kind) -> Result<(Header, &[u8]), WireError> {
        let short = WireError::Short {
            expected: HEADER,
            got: bytes.len(),
        };
        let (head, body) = bytes.split_at_checked(HEADER).ok_or(short)?;
        let mut r = Cursor(head);
        let magic: [u8; 4] = r.array();
        let version = u16::from_le_bytes(r.array());
        if &magic != MAGIC || version != VERSION {
            return Err(WireError::Foreign {
                magic,
                version,
                expected: kind,
            });
        }
        let k = u16::from_le_bytes(r.array());
        if k != kind as u16 {
            return Err(WireError::Kind(k, kind));
        }
        let header = Header {
            kind,
            seq: u64::from_le_bytes(r.array()),
            first_input_frame: u64::from_le_bytes(r.array()),
            input_frames: u32::from_le_bytes(r.array()),
            count: u32::from_le_bytes(r.array()),
            t_ns: u64::from_le_bytes(r.array()),
        };
        Ok((header, body))
    }
}

/// Reads fixed-size fields off a slice known to be long enough.
struct Cursor<'a>(&'a [u8]);

impl Cursor<'_> {
    fn array<const N: usize>(&mut self) -> [u8; N] {
        let mut a = [0; N];
        a.copy_from_slice(&self.0[..N]);
        self.0 = &self.0[N..];
        a
    }
}

/// Appends `values` as little-endian `f64`.
pub fn put_values(out: &mut Vec<u8>, values: impl IntoIterator<Item = f64>) {
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

/// Appends one signal of a frames body: its first new frame, its rows of `width` values.
pub fn put_signal(out: &mut Vec<u8>, first_frame: u64, width: usize, values: &[f64]) {
    let rows = values.len().checked_div(width).unwrap_or(0);
    out.extend_from_slice(&first_frame.to_le_bytes());
    out.extend_from_slice(&(rows as u32).to_le_bytes());
    out.extend_from_slice(&(width as u32).to_le_bytes());
    put_values(out, values.iter().copied());
}

/// Decodes `n` little-endian `f64` from the front of `body`; returns them and the rest.
fn take_values(body: &[u8], n: usize) -> Result<(Vec<f64>, &[u8]), WireError> {
    let bytes = n.saturating_mul(8);
    let (values, rest) = body.split_at_checked(bytes).ok_or(WireError::Short {
        expected: bytes,
        got: body.len(),
    })?;
    let decoded = values
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().unwrap_or([0; 8])))
        .collect();
    Ok((decoded, rest))
}

/// The samples of an audio message, interleaved (frame-major).
pub fn read_audio(bytes: &[u8]) -> Result<(Header, Vec<f64>), WireError> {
    let (h, body) = Header::read(bytes, Kind::Audio)?;
    let n = h.input_frames as usize * h.count as usize;
    if body.len() != n.saturating_mul(8) {
        return Err(WireError::AudioSize {
            frames: h.input_frames,
            channels: h.count,
            bytes: body.len(),
        });
    }
    let (samples, _) = take_values(body, n)?;
    Ok((h, samples))
}

/// One signal's part of a frames message.
#[derive(Debug, Clone, PartialEq)]
pub struct SignalPart {
    /// Index of the signal's first new frame among all its frames.
    pub first_frame: u64,
    /// New frames.
    pub rows: usize,
    /// `f64` values per frame.
    pub width: usize,
    /// The values, time-major.
    pub values: Vec<f64>,
}

/// The header and the signals of a frames message.
pub fn read_frames(bytes: &[u8]) -> Result<(Header, Vec<SignalPart>), WireError> {
    let (h, mut body) = Header::read(bytes, Kind::Frames)?;
    let mut parts = Vec::with_capacity(h.count.min(1024) as usize);
    for _ in 0..h.count {
        let (head, rest) = body
            .split_at_checked(SIGNAL_HEADER)
            .ok_or(WireError::Short {
                expected: SIGNAL_HEADER,
                got: body.len(),
            })?;
        let mut r = Cursor(head);
        let first_frame = u64::from_le_bytes(r.array());
        let rows = u32::from_le_bytes(r.array()) as usize;
        let width = u32::from_le_bytes(r.array()) as usize;
        let (values, rest) = take_values(rest, rows.saturating_mul(width))?;
        parts.push(SignalPart {
            first_frame,
            rows,
            width,
            values,
        });
        body = rest;
    }
    if !body.is_empty() {
        return Err(WireError::Trailing(body.len()));
    }
    Ok((h, parts))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(kind: Kind, count: u32) -> Header {
        Header {
            kind,
            seq: 7,
            first_input_frame: (1 << 40) + 3,
            input_frames: 2,
            count,
            t_ns: 1_700_000_000_123_456_789,
        }
    }

    #[test]
    fn audio_round_trips_bit_for_bit() {
        let mut out = Vec::new();
        header(Kind::Audio, 2).write(&mut out);
        let samples = [0.1, -0.0, f64::MIN_POSITIVE, 1.0 / 3.0];
        put_values(&mut out, samples);
        assert_eq!(out.len(), HEADER + 32);
        let (h, got) = read_audio(&out).expect("decodes");
        assert_eq!(h, header(Kind::Audio, 2));
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&got), bits(&samples));
    }

    #[test]
    fn frames_carry_each_signals_index_and_shape() {
        let mut out = Vec::new();
        header(Kind::Frames, 2).write(&mut out);
        put_signal(&mut out, 41, 3, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        put_signal(&mut out, 0, 4, &[]);
        let (h, parts) = read_frames(&out).expect("decodes");
        assert_eq!(h.count, 2);
        assert_eq!(
            (parts[0].first_frame, parts[0].rows, parts[0].width),
            (41, 2, 3)
        );
        assert_eq!(parts[0].values[5], 6.0);
        assert_eq!((parts[1].rows, parts[1].width), (0, 4));
    }

    #[test]
    fn malformed_messages_are_named_errors() {
        let mut out = Vec::new();
        header(Kind::Frames, 1).write(&mut out);
        put_signal(&mut out, 0, 2, &[1.0, 2.0]);
        assert!(matches!(
            read_audio(&out),
            Err(WireError::Kind(2, Kind::Audio))
        ));
        assert!(matches!(
            read_frames(&out[..out.len() - 1]),
            Err(WireError::Short { .. })
        ));
        assert!(matches!(
            read_frames(&out[..10]),
            Err(WireError::Short { .. })
        ));
        let mut longer = out.clone();
        longer.push(0);
        assert_eq!(read_frames(&longer), Err(WireError::Trailing(1)));
        let mut foreign = out.clone();
        foreign[4] = 9;
        assert!(matches!(
            read_frames(&foreign),
            Err(WireError::Foreign { version: 9, .. })
        ));
        // a header announcing more values than any message holds is refused, not allocated
        let mut huge = Vec::new();
        Header {
            input_frames: u32::MAX,
            count: u32::MAX,
            ..header(Kind::Audio, 0)
        }
        .write(&mut huge);
        assert!(matches!(
            read_audio(&huge),
            Err(WireError::AudioSize { bytes: 0, .. })
        ));
        // the messages say what was expected, in words a reader can act on
        assert_eq!(
            read_audio(&out).map(|_| ()).unwrap_err().to_string(),
            "not an afe audio message: its kind is 2"
        );
        assert!(read_frames(&foreign)
            .unwrap_err()
            .to_string()
            .starts_with("not an afe frames message of wire version 1"));
    }
}
