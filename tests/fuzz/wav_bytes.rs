//! Target 1: WAV bytes into the reader and the extract path.

use std::path::Path;

use afe::bass_source::{WavReader, WavSamples};
use afe::extract::{run_source, Job};
use afe::{Error, Manager, ParamMap};
use serde_json::{json, Value};

use super::draws::random_params;
use super::{check_error, count, fuzz, note, Rng, CASE_LIMIT, MAX_FRAMES};

/// A valid WAV file of random format and content, with random extra chunks (odd ones
/// padded), built in memory.
fn valid_wav(rng: &mut Rng) -> Vec<u8> {
    let channels: u16 = *rng.pick(&[1, 1, 2, 2, 2, 3]);
    let (bits, float): (u16, bool) = *rng.pick(&[
        (8, false),
        (16, false),
        (24, false),
        (32, false),
        (32, true),
    ]);
    let extensible = rng.one_in(3);
    let rate: u32 = if rng.one_in(8) {
        1 + rng.below(200_000) as u32
    } else {
        *rng.pick(&[8000, 16000, 22050, 44100, 48000, 96000])
    };
    let frames = match rng.below(4) {
        0 => rng.below(8),
        _ => rng.below(3000),
    };
    let width = usize::from(bits / 8);
    let block = usize::from(channels) * width;
    let mut fmt = Vec::new();
    fmt.extend_from_slice(
        &(if extensible {
            0xFFFEu16
        } else if float {
            3
        } else {
            1
        })
        .to_le_bytes(),
    );
    fmt.extend_from_slice(&channels.to_le_bytes());
    fmt.extend_from_slice(&rate.to_le_bytes());
    fmt.extend_from_slice(&(rate * block as u32).to_le_bytes());
    fmt.extend_from_slice(&(block as u16).to_le_bytes());
    fmt.extend_from_slice(&bits.to_le_bytes());
    if extensible {
        fmt.extend_from_slice(&22u16.to_le_bytes());
        fmt.extend_from_slice(&bits.to_le_bytes());
        fmt.extend_from_slice(&(if channels == 2 { 3u32 } else { 4 }).to_le_bytes());
        fmt.extend_from_slice(&(if float { 3u16 } else { 1 }).to_le_bytes());
        fmt.extend_from_slice(&[0, 0, 0, 0, 0x10, 0, 0x80, 0, 0, 0xaa, 0, 0x38, 0x9b, 0x71]);
    } else if rng.one_in(3) {
        fmt.extend_from_slice(&0u16.to_le_bytes()); // cbSize
    }
    let mut data = Vec::with_capacity(frames * block);
    for _ in 0..frames * usize::from(channels) {
        if float {
            let v = match rng.below(20) {
                0 => f32::from_bits(rng.next() as u32),
                1 => *rng.pick(&[f32::NAN, f32::INFINITY, f32::MAX, 1e30, -1.0, 0.0]),
                _ => (rng.unit() * 2.0 - 1.0) as f32,
            };
            data.extend_from_slice(&v.to_le_bytes());
        } else {
            for _ in 0..width {
                data.push(rng.byte());
            }
        }
    }
    let mut body = b"WAVE".to_vec();
    let extra = |rng: &mut Rng, body: &mut Vec<u8>| {
        for _ in 0..rng.below(3) {
            let id = *rng.pick(&[b"LIST", b"junk", b"fact", b"bext", b"PAD ", b"cue "]);
            let len = rng.below(70);
            let payload: Vec<u8> = (0..len).map(|_| rng.byte()).collect();
            chunk(body, id, &payload, !rng.one_in(20));
        }
    };
    extra(rng, &mut body);
    chunk(&mut body, b"fmt ", &fmt, true);
    extra(rng, &mut body);
    let data_at = body.len() + 4;
    chunk(&mut body, b"data", &data, true);
    match rng.below(12) {
        // the open sizes of streaming writers
        0 => body[data_at..data_at + 4].copy_from_slice(&0u32.to_le_bytes()),
        1 => body[data_at..data_at + 4].copy_from_slice(&u32::MAX.to_le_bytes()),
        _ => {}
    }
    if rng.one_in(3) {
        extra(rng, &mut body);
    }
    let mut out = b"RIFF".to_vec();
    out.extend_from_slice(&(body.len() as u32).to_le_bytes());
    out.extend(body);
    out
}

/// Appends a RIFF chunk, with its pad byte after an odd payload if `pad`.
fn chunk(body: &mut Vec<u8>, id: &[u8; 4], payload: &[u8], pad: bool) {
    body.extend_from_slice(id);
    body.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    body.extend_from_slice(payload);
    if pad && payload.len() % 2 == 1 {
        body.push(0);
    }
}

/// The chunks of a RIFF file as its sizes lay them out: (start of the chunk header, end
/// of the chunk with its pad byte), cut at the end of the bytes.
fn chunk_spans(b: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut at = 12;
    while at + 8 <= b.len() {
        let size = u32::from_le_bytes([b[at + 4], b[at + 5], b[at + 6], b[at + 7]]) as usize;
        let end = (at + 8).saturating_add(size + (size & 1)).min(b.len());
        spans.push((at, end));
        at = end;
    }
    spans
}

/// Sizes that break readers: none, one, odd, sign bit, all ones.
const SIZES: [u32; 8] = [
    0,
    1,
    3,
    0x7FFF_FFFF,
    0x8000_0000,
    0xFFFF_FFFF,
    0xFFFF_FFFE,
    40,
];

/// Applies 1 to 4 random mutations: bit flips (mostly in the header), bytes set to
/// extreme values, truncation, chunk-size and RIFF-size fields set to 0/huge/odd, format
/// fields overwritten, chunks duplicated, removed or swapped, bytes inserted.
fn mutate(rng: &mut Rng, b: &mut Vec<u8>) {
    for _ in 0..1 + rng.below(4) {
        let len = b.len();
        let spans = chunk_spans(b);
        match rng.below(10) {
            0 if len > 0 => {
                let at = if rng.one_in(2) {
                    rng.below(len.min(80))
                } else {
                    rng.below(len)
                };
                b[at] ^= 1 << rng.below(8);
            }
            1 if len > 0 => {
                let at = rng.below(len.min(120));
                b[at] = *rng.pick(&[0, 1, 0x7F, 0x80, 0xFE, 0xFF]);
            }
            2 => b.truncate(rng.below(len + 1)),
            3 if !spans.is_empty() => {
                let (at, end) = *rng.pick(&spans);
                let old = (end - at - 8) as u32;
                let size = match rng.below(4) {
                    0 => old.wrapping_add(1),
                    1 => old.wrapping_sub(1),
                    2 => rng.next() as u32,
                    _ => *rng.pick(&SIZES),
                };
                b[at + 4..at + 8].copy_from_slice(&size.to_le_bytes());
            }
            4 if len >= 8 => {
                let size = if rng.one_in(2) {
                    *rng.pick(&SIZES)
                } else {
                    rng.next() as u32
                };
                b[4..8].copy_from_slice(&size.to_le_bytes());
            }
            5 => {
                // a field of the fmt chunk: tag, channels, rate, byte rate, block
                // align, bits, cbSize, valid bits, mask, sub-format tag
                if let Some(&(at, end)) = spans.iter().find(|(at, _)| &b[*at..*at + 4] == b"fmt ") {
                    let field = at + 8 + *rng.pick(&[0, 2, 4, 8, 12, 14, 16, 18, 20, 24]);
                    let value = *rng.pick(&[
                        0u32,
                        1,
                        2,
                        3,
                        0xFFFE,
                        0xFFFF,
                        7,
                        64,
                        65535,
                        u32::MAX,
                        0x8000_0000,
                    ]);
                    let bytes = value.to_le_bytes();
                    for (i, v) in bytes
                        .iter()
                        .enumerate()
                        .take(if rng.one_in(2) { 2 } else { 4 })
                    {
                        if field + i < end {
                            b[field + i] = *v;
                        }
                    }
                }
            }
            6 if !spans.is_empty() => {
                let (at, end) = *rng.pick(&spans);
                let copy = b[at..end].to_vec();
                let (to, _) = *rng.pick(&spans);
                b.splice(to..to, copy);
            }
            7 if !spans.is_empty() => {
                let (at, end) = *rng.pick(&spans);
                b.drain(at..end);
            }
            8 if spans.len() >= 2 => {
                let i = rng.below(spans.len() - 1);
                let (a0, a1) = spans[i];
                let (_, b1) = spans[i + 1];
                let first = b[a0..a1].to_vec();
                b.copy_within(a1..b1, a0);
                let at = a0 + (b1 - a1);
                b[at..b1].copy_from_slice(&first);
            }
            _ => {
                let at = rng.below(len + 1);
                let n = 1 + rng.below(16);
                let junk: Vec<u8> = (0..n).map(|_| rng.byte()).collect();
                b.splice(at..at, junk);
            }
        }
    }
}

/// Random bytes, often behind a RIFF/WAVE header (and a `fmt ` id) to get past the magic.
fn random_bytes(rng: &mut Rng) -> Vec<u8> {
    let mut b = Vec::new();
    if rng.one_in(2) {
        b.extend_from_slice(b"RIFF");
        b.extend_from_slice(&(rng.next() as u32).to_le_bytes());
        b.extend_from_slice(b"WAVE");
        if rng.one_in(2) {
            b.extend_from_slice(b"fmt ");
        }
    }
    let most = if rng.one_in(4) { 4000 } else { 120 };
    let n = rng.below(most);
    b.extend((0..n).map(|_| rng.byte()));
    b
}

/// The reader accepts or refuses the file; once it accepts, it reads exactly the frames it
/// declares, in any block sizes, and those fit in the file.
fn check_reader(rng: &mut Rng, path: &Path, file_len: u64) -> Result<(), String> {
    let Ok(mut reader) = WavReader::open(path) else {
        count("reader: refused");
        return Ok(());
    };
    count("reader: opened");
    let format = reader.format();
    let frame_bytes = u64::from(format.channels) * u64::from(format.bits / 8);
    if reader.frames().saturating_mul(frame_bytes) > file_len {
        return Err(format!(
            "the reader declares {} frames of {frame_bytes} bytes in a file of {file_len} bytes",
            reader.frames()
        ));
    }
    let mut out = if rng.one_in(2) {
        WavSamples::Int(Vec::new())
    } else {
        WavSamples::Float(Vec::new())
    };
    let mut total = 0u64;
    loop {
        let ask = if rng.one_in(8) {
            usize::MAX
        } else {
            1 + rng.below(900)
        };
        let got = reader
            .read(ask, &mut out)
            .map_err(|e| format!("a file the reader opened fails to read: {e}"))?;
        let (len, float) = match &out {
            WavSamples::Int(v) => (v.len(), false),
            WavSamples::Float(v) => (v.len(), true),
        };
        if got > ask || len != got * usize::from(format.channels) || float != format.float {
            return Err(format!(
                "read({ask}) gave {got} frames in {len} {} samples ({:?})",
                if float { "float" } else { "integer" },
                format
            ));
        }
        if got == 0 {
            break;
        }
        total += got as u64;
    }
    if total != reader.frames() {
        return Err(format!(
            "read {total} frames, the reader declared {}",
            reader.frames()
        ));
    }
    Ok(())
}

/// The library path of `afe extract`: open the input, build a manager, run a request (any,
/// on 4 channels) on at most [`MAX_FRAMES`] frames read block by block.
fn check_extract(rng: &mut Rng, path: &Path) -> Result<(), String> {
    let Ok(mut wav) = afe::wav::open_input(path) else {
        return Ok(());
    };
    count("extract: input taken");
    let ears = wav.channels();
    let threads = if rng.one_in(8) { 2 } else { 0 };
    let mut mgr = match Manager::with_threads(wav.fs(), ears, threads) {
        Ok(m) => m,
        Err(e) => return check_error(&e),
    };
    mgr.set_stall_timeout(CASE_LIMIT);
    let params: ParamMap = [("fb_nChannels".to_string(), json!(4))]
        .into_iter()
        .collect();
    let job = Job {
        // any request at the header's rate (binaural ones refuse mono files)
        requests: vec![if rng.one_in(2) {
            "ratemap".into()
        } else {
            rng.pick(afe::requests()).name.into()
        }],
        params,
        chunk: if rng.one_in(3) {
            None
        } else {
            Some(1 + rng.below(2000))
        },
        ..Job::default()
    };
    let mut left = MAX_FRAMES;
    let result = run_source(&mut mgr, &job, ears, |frames, out| {
        let got = wav
            .read(frames.min(left), out)
            .map_err(|e| Error::InvalidInput(e.to_string()))?;
        left -= got;
        Ok(got)
    });
    match result {
        Ok(rec) => {
            count("extract: computed");
            if rec.signals().is_empty() {
                return Err("extract succeeded and recorded nothing".into());
            }
            Ok(())
        }
        Err(e) => check_error(&e),
    }
}

/// The `afe extract` binary on the file, with the ratemap on 4 channels or a random
/// request with random `-p NAME=VALUE` parameters: any exit but a panic's (101) or a
/// signal's.
fn check_cli(rng: &mut Rng, path: &Path, dir: &Path) -> Result<(), String> {
    let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_afe"));
    cmd.arg("extract")
        .arg(path)
        .arg("-o")
        .arg(dir.join("out.npz"));
    if rng.one_in(2) {
        cmd.args(["-r", "ratemap", "-p", "fb_nChannels=4"]);
    } else {
        let name = rng.pick(afe::requests()).name;
        let entries = rng.below(4);
        cmd.args(["-r", name]);
        for (k, v) in random_params(rng, name, entries) {
            let arg = match v {
                Value::String(s) if rng.one_in(2) => format!("{k}={s}"),
                v => format!("{k}={v}"),
            };
            // a command line cannot carry a NUL byte
            if !arg.contains('\0') {
                cmd.arg("-p").arg(arg);
            }
        }
        if rng.one_in(3) {
            cmd.arg("--chunk").arg((1 + rng.below(3000)).to_string());
        }
    }
    note(|| format!("{cmd:?}"));
    let out = cmd.output().map_err(|e| format!("cannot run afe: {e}"))?;
    let stderr = String::from_utf8_lossy(&out.stderr);
    match out.status.code() {
        Some(101) | None => Err(format!("afe extract ended with {}: {stderr}", out.status)),
        _ if stderr.contains("panicked") => Err(format!("afe extract panicked: {stderr}")),
        _ => Ok(()),
    }
}

#[test]
fn wav_bytes() {
    fuzz("wav_bytes", |rng, dir| {
        let bytes = if rng.one_in(6) {
            random_bytes(rng)
        } else {
            let mut b = valid_wav(rng);
            if !rng.one_in(8) {
                mutate(rng, &mut b);
            }
            b
        };
        let path = dir.join("input.wav");
        std::fs::write(&path, &bytes)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        check_reader(rng, &path, bytes.len() as u64)?;
        check_extract(rng, &path)?;
        if rng.one_in(64) {
            count("afe extract runs");
            check_cli(rng, &path, dir)?;
        }
        Ok(())
    });
}
