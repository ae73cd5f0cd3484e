//! The one WAV reader of `afe`: a RIFF/WAVE walk (chunks of odd size keep their pad
//! byte, as the RIFF specification says), the `fmt ` chunk (PCM, IEEE float, or their
//! WAVE_FORMAT_EXTENSIBLE form), and the samples of the `data` chunk, read block by block.

use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

/// Why a file cannot be read as WAV.
#[derive(Debug, thiserror::Error)]
pub enum WavReadError {
    /// The file cannot be opened or read.
    #[error("cannot open '{path}': {source}")]
    Open {
        /// The path as given.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The file is not a WAV file this reader understands, or is corrupt.
    #[error("cannot read '{path}' as WAV: {reason}")]
    Format {
        /// The path as given.
        path: String,
        /// What is wrong.
        reason: String,
    },
}

/// How the samples of a WAV file are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WavFormat {
    /// Sampling rate in Hz.
    pub sample_rate: u32,
    /// Interleaved channels per frame.
    pub channels: u16,
    /// Bits per stored sample: 8, 16, 24 or 32 (integer), 32 (float).
    pub bits: u16,
    /// IEEE float samples (else integer PCM; 8-bit PCM is unsigned).
    pub float: bool,
}

impl WavFormat {
    fn bytes_per_sample(&self) -> usize {
        usize::from(self.bits / 8)
    }
}

/// Samples decoded from a WAV file, interleaved.
#[derive(Debug, Clone, PartialEq)]
pub enum WavSamples {
    /// Integer PCM at 32-bit full scale: a `b`-bit sample `v` is `v · 2^(32−b)`.
    Int(Vec<i32>),
    /// IEEE float samples.
    Float(Vec<f32>),
}

/// A WAV file open for reading its samples, block by block.
#[derive(Debug)]
pub struct WavReader {
    file: BufReader<std::fs::File>,
    path: String,
    format: WavFormat,
    /// Whole frames of the data chunk not read yet.
    frames_left: u64,
    frames: u64,
    /// Offset of the first sample in the file, in bytes.
    data_start: u64,
    bytes: Vec<u8>,
}

/// Largest `fmt ` chunk read (the extensible form has 40 bytes).
const MAX_FMT_LEN: u32 = 1024;

/// The sub-format GUID tail shared by PCM and IEEE float in WAVE_FORMAT_EXTENSIBLE.
const GUID_TAIL: [u8; 14] = [
    0x00, 0x00, 0x00, 0x00, 0x10, 0x00, 0x80, 0x00, 0x00, 0xaa, 0x00, 0x38, 0x9b, 0x71,
];

impl WavReader {
    /// Opens `path`, reads its header and finds its samples.
    pub fn open(path: &Path) -> Result<WavReader, WavReadError> {
        let shown = path.display().to_string();
        let open = |source| WavReadError::Open {
            path: shown.clone(),
            source,
        };
        let file = std::fs::File::open(path).map_err(open)?;
        let file_len = file.metadata().map_err(open)?.len();
        let mut file = BufReader::new(file);
        let bad = |reason: String| WavReadError::Format {
            path: shown.clone(),
            reason,
        };
        let (format, data_len) = read_header(&mut file, file_len).map_err(|e| match e {
            Header::Io(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
                bad("the file ends inside its header".into())
            }
            Header::Io(e) => bad(e.to_string()),
            Header::Bad(reason) => bad(reason),
        })?;
        let frame_bytes = format.bytes_per_sample() * usize::from(format.channels);
        let frames = data_len / frame_bytes as u64;
        let data_start = file.stream_position().map_err(|e| bad(e.to_string()))?;
        Ok(WavReader {
            file,
            path: shown,
            format,
            frames_left: frames,
            frames,
            data_start,
            bytes: Vec::new(),
        })
    }

    /// How the samples are stored.
    pub fn format(&self) -> WavFormat {
        self.format
    }

    /// Whole frames in the data chunk (an incomplete last frame is not counted).
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Goes back to the first frame (to replay the file again).
    pub fn rewind(&mut self) -> Result<(), WavReadError> {
        self.file
            .seek(SeekFrom::Start(self.data_start))
            .map_err(|e| WavReadError::Format {
                path: self.path.clone(),
                reason: format!("cannot go back to the first sample ({e})"),
            })?;
        self.frames_left = self.frames;
        Ok(())
    }

    /// Reads up to `frames` more frames, interleaved, into `out` (replaced; it must be of
    /// the file's kind, [`WavSamples::Int`] or [`WavSamples::Float`], else it is made
    /// so) and returns how many frames it read: 0 at the end of the data.
    pub fn read(&mut self, frames: usize, out: &mut WavSamples) -> Result<usize, WavReadError> {
        match (self.format.float, &*out) {
            (true, WavSamples::Int(_)) => *out = WavSamples::Float(Vec::new()),
            (false, WavSamples::Float(_)) => *out = WavSamples::Int(Vec::new()),
            _ => {}
        }
        let n = self.frames_left.min(frames as u64) as usize;
        let width = self.format.bytes_per_sample();
        self.bytes
            .resize(n * usize::from(self.format.channels) * width, 0);
        self.file
            .read_exact(&mut self.bytes)
            .map_err(|e| WavReadError::Format {
                path: self.path.clone(),
                reason: format!("the samples cannot be read ({e})"),
            })?;
        self.frames_left -= n as u64;
        let raw = self.bytes.chunks_exact(width);
        match out {
            WavSamples::Float(v) => {
                v.clear();
                v.extend(raw.map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])));
            }
            WavSamples::Int(v) => {
                v.clear();
                v.extend(raw.map(|b| match b.len() {
                    1 => (i32::from(b[0]) - 128) << 24,
                    2 => i32::from(i16::from_le_bytes([b[0], b[1]])) << 16,
                    3 => i32::from_le_bytes([0, b[0], b[1], b[2]]),
                    _ => i32::from_le_bytes([b[0], b[1], b[2], b[3]]),
                }));
            }
        }
        Ok(n)
    }
}

enum Header {
    Io(std::io::Error),
    Bad(String),
}

impl From<std::io::Error> for Header {
    fn from(e: std::io::Error) -> Self {
        Header::Io(e)
    }
}

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Walks the RIFF chunks up to `data`: the format, and the data length in bytes (the
/// rest of the file where the header leaves it open, 0 or 0xFFFFFFFF, as streaming
/// writers do). The reader is left at the first sample.
fn read_header(
    file: &mut BufReader<std::fs::File>,
    file_len: u64,
) -> Result<(WavFormat, u64), Header> {
    let mut riff = [0u8; 12];
    file.read_exact(&mut riff).map_err(|e| match e.kind() {
        std::io::ErrorKind::UnexpectedEof => {
            Header::Bad("not a WAV file (shorter than a RIFF/WAVE header)".into())
        }
        _ => Header::Io(e),
    })?;
    if &riff[0..4] != b"RIFF" || &riff[8..12] != b"WAVE" {
        return Err(Header::Bad("not a WAV file (no RIFF/WAVE header)".into()));
    }
    let mut format = None;
    let mut at = 12u64;
    loop {
        let mut head = [0u8; 8];
        file.read_exact(&mut head).map_err(|e| match e.kind() {
            std::io::ErrorKind::UnexpectedEof => Header::Bad("no data chunk".into()),
            _ => Header::Io(e),
        })?;
        at += 8;
        let size = u32_at(&head, 4);
        match &head[0..4] {
            b"fmt " => {
                if !(16..=MAX_FMT_LEN).contains(&size) {
                    return Err(Header::Bad(format!("a fmt chunk of {size} bytes")));
                }
                let mut fmt = vec![0u8; size as usize + (size & 1) as usize];
                file.read_exact(&mut fmt)?;
                format = Some(parse_fmt(&fmt)?);
            }
            b"data" => {
                let Some(format) = format else {
                    return Err(Header::Bad(
                        "the data chunk comes before the fmt chunk".into(),
                    ));
                };
                let rest = file_len.saturating_sub(at);
                let len = match size {
                    0 | u32::MAX => rest,
                    n if u64::from(n) > rest => {
                        return Err(Header::Bad(format!(
                            "the data chunk declares {n} bytes but the file holds {rest} \
                             after its header (a truncated file?)"
                        )))
                    }
                    n => u64::from(n),
                };
                return Ok((format, len));
            }
            _ => {
                let skip = u64::from(size) + u64::from(size & 1);
                file.seek_relative(skip as i64)?;
            }
        }
        at += u64::from(size) + u64::from(size & 1);
        if at > file_len {
            return Err(Header::Bad("no data chunk".into()));
        }
    }
}

/// The format of a `fmt ` chunk's bytes.
fn parse_fmt(b: &[u8]) -> Result<WavFormat, Header> {
    let mut tag = u16_at(b, 0);
    let channels = u16_at(b, 2);
    let sample_rate = u32_at(b, 4);
    let bits = u16_at(b, 14);
    if tag == 0xFFFE {
        if b.len() < 40 {
            return Err(Header::Bad(
                "an extensible fmt chunk shorter than 40 bytes".into(),
            ));
        }
        if b[26..40] != GUID_TAIL {
            return Err(Header::Bad(
                "an extensible format that is not PCM or float".into(),
            ));
        }
        tag = u16_at(b, 24);
    }
    let float = match (tag, bits) {
        (1, 8 | 16 | 24 | 32) => false,
        (3, 32) => true,
        (1 | 3, _) => {
            return Err(Header::Bad(format!(
                "{bits}-bit {} samples are not supported (integer: 8, 16, 24, 32 bits; float: 32)",
                if tag == 3 { "float" } else { "integer" }
            )))
        }
        _ => {
            return Err(Header::Bad(format!(
                "format tag {tag} is not supported (PCM or IEEE float)"
            )))
        }
    };
    if channels == 0 {
        return Err(Header::Bad("the file declares 0 channels".into()));
    }
    if sample_rate == 0 {
        return Err(Header::Bad(
            "the file declares a sampling rate of 0 Hz".into(),
        ));
    }
    Ok(WavFormat {
        sample_rate,
        channels,
        bits,
        float,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A path `name` in a folder of its own, removed with the returned guard.
    fn temp(name: &str) -> (tempfile::TempDir, std::path::PathBuf) {
        let dir = tempfile::tempdir().expect("temporary folder");
        let path = dir.path().join(name);
        (dir, path)
    }

    /// A 16-bit stereo file at 8 kHz with `extra` chunks (id, payload) before `data`,
    /// each followed by a pad byte if `pad` and its payload is odd.
    fn file(extra: &[(&[u8; 4], &[u8])], pad: bool, samples: &[i16]) -> Vec<u8> {
        let mut body = b"WAVE".to_vec();
        let mut chunk = |id: &[u8; 4], payload: &[u8], pad: bool| {
            body.extend_from_slice(id);
            body.extend_from_slice(&(payload.len() as u32).to_le_bytes());
            body.extend_from_slice(payload);
            if pad && payload.len() % 2 == 1 {
                body.push(0);
            }
        };
        let mut fmt = vec![1, 0, 2, 0];
        fmt.extend_from_slice(&8000u32.to_le_bytes());
        fmt.extend_from_slice(&32000u32.to_le_bytes());
        fmt.extend_from_slice(&[4, 0, 16, 0]);
        chunk(b"fmt ", &fmt, true);
        for (id, payload) in extra {
            chunk(id, payload, pad);
        }
        let data: Vec<u8> = samples.iter().flat_map(|s| s.to_le_bytes()).collect();
        chunk(b"data", &data, true);
        let mut out = b"RIFF".to_vec();
        out.extend_from_slice(&(body.len() as u32).to_le_bytes());
        out.extend(body);
        out
    }

    fn read(bytes: &[u8], name: &str) -> Result<(WavFormat, Vec<i32>), WavReadError> {
        let (_dir, p) = temp(name);
        std::fs::write(&p, bytes).expect("write");
        let mut r = WavReader::open(&p)?;
        let mut s = WavSamples::Float(Vec::new());
        r.read(usize::MAX, &mut s)?;
        match s {
            WavSamples::Int(v) => Ok((r.format(), v)),
            WavSamples::Float(_) => panic!("an integer file"),
        }
    }

    /// Issue 13, item 6: an odd-sized chunk with its pad byte (valid RIFF) is read; the
    /// unpadded form (invalid) is an error, not misread samples.
    #[test]
    fn odd_sized_chunks_keep_their_pad_byte() {
        let samples = [1i16, -2, 300, -32768];
        let want: Vec<i32> = samples.iter().map(|s| i32::from(*s) << 16).collect();
        let list: &[u8] = b"INFOISFT\x05\x00\x00\x00afe!\x00";
        let odd = [(b"LIST", list), (b"junk", &b"abc"[..])];
        let (format, got) = read(&file(&odd, true, &samples), "padded.wav").expect("valid");
        assert_eq!(
            (format.sample_rate, format.channels, format.bits),
            (8000, 2, 16)
        );
        assert_eq!(got, want);
        assert!(read(&file(&odd, false, &samples), "unpadded.wav").is_err());
    }

    #[test]
    fn widths_and_extensible_format_decode_to_full_scale() {
        // 24-bit extensible, mono: the sub-format GUID names PCM
        let mut fmt = vec![0xFE, 0xFF, 1, 0];
        fmt.extend_from_slice(&48000u32.to_le_bytes());
        fmt.extend_from_slice(&144000u32.to_le_bytes());
        fmt.extend_from_slice(&[3, 0, 24, 0, 22, 0, 24, 0, 4, 0, 0, 0, 1, 0]);
        fmt.extend_from_slice(&GUID_TAIL);
        let data = [0x00, 0x00, 0x80, 0xff, 0xff, 0x7f, 0x01, 0x00, 0x00];
        let mut body = b"WAVEfmt ".to_vec();
        body.extend_from_slice(&(fmt.len() as u32).to_le_bytes());
        body.extend(fmt);
        body.extend_from_slice(b"data");
        body.extend_from_slice(&(data.len() as u32).to_le_bytes());
        body.extend_from_slice(&data);
        body.push(0);
        let mut bytes = b"RIFF".to_vec();
        bytes.extend_from_slice(&(body.len() as u32).to_le_bytes());
        bytes.extend(body);
        let (format, got) = read(&bytes, "ext24.wav").expect("valid");
        assert_eq!((format.bits, format.float), (24, false));
        assert_eq!(got, [i32::MIN, 0x7fff_ff00, 0x0000_0100]);
    }

    #[test]
    fn corrupt_headers_are_errors_naming_the_problem() {
        let samples = [0i16; 4];
        let good = file(&[], true, &samples);
        let cases: [(Vec<u8>, &str); 5] = [
            (b"RIFF".to_vec(), "not a WAV file"),
            (good[..30].to_vec(), "ends inside its header"),
            (
                {
                    let mut b = good.clone();
                    b[20] = 2; // format tag 2 (ADPCM)
                    b
                },
                "format tag 2",
            ),
            (
                {
                    let mut b = good.clone();
                    b.truncate(b.len() - 2); // data declares more than the file holds
                    b
                },
                "truncated",
            ),
            (
                {
                    let mut b = good.clone();
                    b[22] = 0; // 0 channels
                    b
                },
                "0 channels",
            ),
        ];
        for (k, (bytes, needle)) in cases.iter().enumerate() {
            let e = read(bytes, &format!("bad{k}.wav")).expect_err(needle);
            assert!(e.to_string().contains(needle), "{needle}: {e}");
        }
    }
}
