//! The `afe stream` and `afe devices` command lines: a replayed file gives what `afe
//! extract` gives, the JSON report holds exact counts, and bad input is one clear line.

use crate::common;

use std::process::Output;
use std::time::{Duration, Instant};

use common::{afe, assert_clear_error, npz_arrays, tmp};

fn example() -> String {
    concat!(env!("CARGO_MANIFEST_DIR"), "/data/example_binaural.wav").to_string()
}

fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn report(out: &Output) -> serde_json::Value {
    serde_json::from_str(&ok(out)).expect("one JSON object")
}

#[test]
fn a_replayed_file_gives_what_extract_gives_bit_for_bit() {
    let streamed = tmp("streamed.npz");
    let extracted = tmp("extracted.npz");
    let wav = example();
    let source = format!("wav:{wav}");
    let out = afe(&[
        "stream",
        "--source",
        &source,
        "--fast",
        "--block-ms",
        "10",
        "-r",
        "ratemap,ild",
        "-o",
        streamed.to_str().expect("path"),
    ]);
    let summary = ok(&out);
    assert!(summary.contains("44100 frames"), "{summary}");
    ok(&afe(&[
        "extract",
        &wav,
        "-r",
        "ratemap,ild",
        "--chunk",
        "441",
        "-o",
        extracted.to_str().expect("path"),
    ]));
    let a = npz_arrays(&streamed);
    let names: Vec<&str> = a.iter().map(|x| x.0.as_str()).collect();
    assert_eq!(names, ["ratemap_left", "ratemap_right", "ild_mono"]);
    assert_eq!(a, npz_arrays(&extracted));
}

#[test]
fn the_json_report_counts_frames_blocks_and_losses() {
    let out = afe(&[
        "stream",
        "--source",
        "synth:fs=44100,tone=440,noise=0.1,itd_ms=0.4,ild_db=-6,seed=1",
        "--fast",
        "--for",
        "0.5",
        "--block-ms",
        "20",
        "-r",
        "ratemap,ild,itd,ic",
        "--json",
    ]);
    assert!(out.stderr.is_empty(), "no status line with --json");
    let r = report(&out);
    assert_eq!(r["frames"], 22050);
    assert_eq!(r["lost_frames"], 0);
    assert_eq!(r["blocks"], 25);
    assert_eq!(r["budget_ms"], 20.0);
    assert_eq!(r["pacing"], "fast");
    for key in [
        "deadline_misses",
        "compute_ms_p50",
        "compute_ms_p99",
        "x_realtime",
    ] {
        assert!(r[key].as_f64().is_some(), "{key} missing from {r}");
    }
    assert!(r["compute_ms_p50"].as_f64() <= r["compute_ms_p99"].as_f64());
    assert!(r["compute_ms_p99"].as_f64() <= r["compute_ms_max"].as_f64());
    assert!(r["x_realtime"].as_f64().expect("number") > 0.0);
    assert!(r["host"]["simd"].is_string() && r["host"]["cpu"].is_string());
    // the slowest block is named, the histogram holds every block, the missed ones are
    // listed (as many as counted, up to 100)
    assert!(r["slowest_block"].as_u64().expect("index") < 25);
    let histogram = r["compute_ms_histogram"].as_array().expect("bins");
    let counted: u64 = histogram
        .iter()
        .map(|b| b[1].as_u64().expect("count"))
        .sum();
    assert_eq!(counted, 25);
    let missed = r["missed_blocks"].as_array().expect("list").len() as u64;
    assert_eq!(Some(missed), r["deadline_misses"].as_u64());
}

#[test]
fn real_time_takes_the_audio_duration_and_a_loop_replays_the_file() {
    let start = Instant::now();
    let r = report(&afe(&[
        "stream",
        "--source",
        "synth:fs=16000,silence",
        "--for",
        "0.4",
        "-r",
        "ild",
        "--threads",
        "0",
        "--json",
    ]));
    assert!(start.elapsed() >= Duration::from_millis(400));
    assert_eq!(
        (r["frames"].clone(), r["pacing"].clone()),
        (6400.into(), "realtime".into())
    );
    assert_eq!(r["lost_frames"], 0);

    // the 1-s example, looped for 2.5 s
    let looped = tmp("looped.npz");
    let r = report(&afe(&[
        "stream",
        "--source",
        &format!("wav:{}", example()),
        "--loop",
        "--for",
        "2.5",
        "-r",
        "ratemap",
        "--json",
        "-o",
        looped.to_str().expect("path"),
    ]));
    assert_eq!(r["frames"], 110250);
    assert_eq!(npz_arrays(&looped)[0].1, vec![249, 31]);
}

#[test]
fn every_bad_stream_is_one_clear_line() {
    let o = tmp("never.npz");
    let os = o.to_str().expect("path");
    let wav = format!("wav:{}", example());
    let run = |args: &[&str]| {
        let mut all = vec!["stream"];
        all.extend_from_slice(args);
        all.extend_from_slice(&["-o", os]);
        afe(&all)
    };
    assert_clear_error(
        &run(&["--source", "synth:tone=440", "-r", "ild"]),
        "never ends: give --for SECONDS",
        &o,
    );
    assert_clear_error(
        &run(&["--source", "mic:1", "-r", "ild"]),
        "unknown source 'mic:1'",
        &o,
    );
    assert_clear_error(
        &run(&["--source", "synth:tone=abc", "--for", "1", "-r", "ild"]),
        "tone=abc: expected a finite number",
        &o,
    );
    // issue 13, item 4: a finite amplitude that would overflow is refused, not NaN
    assert_clear_error(
        &run(&[
            "--source",
            "synth:tone=440,amp=1e200",
            "--for",
            "1",
            "-r",
            "ild",
        ]),
        "the processing overflows (full scale is 1.0: scale the input)",
        &o,
    );
    assert_clear_error(
        &run(&["--source", "wav:/nonexistent/x.wav", "-r", "ild"]),
        "cannot open '/nonexistent/x.wav'",
        &o,
    );
    assert_clear_error(
        &run(&["--source", &wav, "-r", "ratemapp"]),
        "unknown request 'ratemapp'",
        &o,
    );
    assert_clear_error(
        &run(&["--source", &wav, "--loop", "-r", "ild"]),
        "--loop replays the file forever",
        &o,
    );
    assert_clear_error(
        &run(&["--source", &wav, "--block-ms", "0", "-r", "ild"]),
        "block length 0 ms",
        &o,
    );
    assert_clear_error(
        &run(&["--source", &wav, "--rate", "48000", "-r", "ild"]),
        "--rate sets the ALSA capture rate",
        &o,
    );
}

#[test]
fn rt_asks_for_fifo_and_locked_memory_and_says_what_it_got() {
    let out = afe(&[
        "stream",
        "--rt",
        "--source",
        "synth:fs=16000,tone=440",
        "--realtime",
        "--for",
        "0.3",
        "-r",
        "ratemap",
        "--json",
    ]);
    let r = report(&out);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let described = r["rt"].as_str().expect("rt described");
    assert!(described.contains("SCHED_FIFO"), "{described}");
    match r["rt_complete"].as_bool() {
        Some(true) => assert!(
            stderr.contains("real time: SCHED_FIFO priority 50; memory locked"),
            "{stderr}"
        ),
        // without privilege: a warning that says what to do, and the stream still runs
        _ => assert!(
            stderr.contains("warning: --rt:") && stderr.contains("CAP_"),
            "{stderr}"
        ),
    }
    assert_eq!(r["frames"], 4800);
    // memory is sampled once per second of audio: the first sample is at the start
    assert!(r["rss_mib_end"].as_f64().is_some_and(|m| m > 1.0), "{r}");
    assert!(r["rss_mib_at_60s"].is_null());
    let fast = afe(&[
        "stream",
        "--rt",
        "--source",
        "synth:fs=16000",
        "--fast",
        "--for",
        "1",
        "-r",
        "ratemap",
    ]);
    assert_clear_error(
        &fast,
        "--rt) is for streams paced at real time",
        &tmp("none.npz"),
    );
}

#[cfg(not(feature = "alsa"))]
#[test]
fn without_alsa_devices_and_capture_say_how_to_get_it() {
    let o = tmp("never-alsa.npz");
    assert_clear_error(&afe(&["devices"]), "--features alsa", &o);
    assert_clear_error(
        &afe(&[
            "stream",
            "--source",
            "alsa:hw:1,0",
            "--for",
            "1",
            "-r",
            "ild",
            "-o",
            o.to_str().expect("path"),
        ]),
        "--features alsa",
        &o,
    );
}

/// ALSA without hardware: a `file` PCM over a `null` slave captures a raw file's frames.
#[cfg(feature = "alsa")]
mod alsa {
    use std::path::PathBuf;

    use super::common::afe_env;
    use super::*;

    const FRAMES: usize = 8820;

    fn sample(t: usize, c: usize) -> i32 {
        let x = (0.031 * t as f64 * (c + 1) as f64).sin() * 0.4;
        (x * 2_147_483_648.0) as i32
    }

    /// Writes the raw file, the same samples as a 32-bit WAV, and the ALSA configuration.
    fn setup() -> (PathBuf, PathBuf) {
        let raw = tmp("capture.raw");
        let bytes: Vec<u8> = (0..FRAMES)
            .flat_map(|t| [sample(t, 0), sample(t, 1)])
            .flat_map(i32::to_ne_bytes)
            .collect();
        std::fs::write(&raw, bytes).expect("raw");
        let wav = tmp("capture.wav");
        let spec = hound::WavSpec {
            channels: 2,
            sample_rate: 44100,
            bits_per_sample: 32,
            sample_format: hound::SampleFormat::Int,
        };
        let mut w = hound::WavWriter::create(&wav, spec).expect("wav");
        for t in 0..FRAMES {
            w.write_sample(sample(t, 0)).expect("write");
            w.write_sample(sample(t, 1)).expect("write");
        }
        w.finalize().expect("finalize");
        let conf = tmp("asound.conf");
        std::fs::write(
            &conf,
            format!(
                "pcm.afetest {{\n  type file\n  slave.pcm {{ type null }}\n  file \"/dev/null\"\n  \
                 infile \"{}\"\n  format \"raw\"\n  hint {{ show on description \"afe test capture\" }}\n}}\n",
                raw.display()
            ),
        )
        .expect("conf");
        (conf, wav)
    }

    #[test]
    fn devices_list_the_configured_capture_pcm() {
        let (conf, _) = setup();
        let out = afe_env(&["devices"], &[("ALSA_CONFIG_PATH", &conf)]);
        let text = ok(&out);
        assert!(
            text.lines()
                .any(|l| l.starts_with("afetest") && l.contains("afe test capture")),
            "{text}"
        );
    }

    #[test]
    fn captured_frames_give_what_extract_gives_on_the_same_samples() {
        let (conf, wav) = setup();
        let captured = tmp("captured.npz");
        let out = afe_env(
            &[
                "stream",
                "--source",
                "alsa:afetest",
                "--fast",
                "--for",
                "0.2",
                "-r",
                "ratemap,ild",
                "--json",
                "-o",
                captured.to_str().expect("path"),
            ],
            &[("ALSA_CONFIG_PATH", &conf)],
        );
        let r = report(&out);
        assert_eq!(
            (r["frames"].clone(), r["lost_frames"].clone()),
            (8820.into(), 0.into())
        );
        let extracted = tmp("capture-extracted.npz");
        ok(&afe(&[
            "extract",
            wav.to_str().expect("path"),
            "-r",
            "ratemap,ild",
            "--chunk",
            "441",
            "-o",
            extracted.to_str().expect("path"),
        ]));
        assert_eq!(npz_arrays(&captured), npz_arrays(&extracted));

        // At real time, the null device delivers faster than real time: the port
        // overflows, and every frame is processed or counted as lost.
        let r = report(&afe_env(
            &[
                "stream",
                "--source",
                "alsa:afetest",
                "--for",
                "0.2",
                "-r",
                "ild",
                "--json",
            ],
            &[("ALSA_CONFIG_PATH", &conf)],
        ));
        let frames = r["frames"].as_u64().expect("frames");
        let lost = r["lost_frames"].as_u64().expect("lost");
        assert_eq!(frames + lost, 8820, "{r}");

        let o = tmp("never-captured.npz");
        let out = afe_env(
            &[
                "stream",
                "--source",
                "alsa:nosuchpcm",
                "--for",
                "1",
                "-r",
                "ild",
                "-o",
                o.to_str().expect("path"),
            ],
            &[("ALSA_CONFIG_PATH", &conf)],
        );
        assert_clear_error(&out, "cannot open ALSA capture device 'nosuchpcm'", &o);
    }
}
