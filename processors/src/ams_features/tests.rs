//! The tests of `amsFeatures` as a whole: sizes, bands, errors, both banks against the
//! spec written out, the two framing paths against each other, chunking and reset. Apart
//! from the processor because, with the helpers they share, they are longer than it: in
//! one file the two would pass the house's 800 lines.

use super::*;
use afe_core::butter::{butter, ButterType};
use afe_core::Params;
use proptest::prelude::*;

fn ihc(fs: f64, channels: usize) -> SignalInfo {
    SignalInfo::time_frequency(fs, (0..channels).map(|c| 100.0 * (c + 1) as f64).collect())
}

/// Positive envelopes with a few modulation rates.
fn envelope(len: usize, channels: usize) -> Vec<f64> {
    (0..len)
        .flat_map(|t| {
            (0..channels).map(move |c| {
                let t = t as f64;
                1.0 + (0.01 * (c + 1) as f64 * t).sin() + 0.5 * (0.37 * t * t / 1e3).cos()
            })
        })
        .collect()
}

fn run(ams: &mut AmsFeatures, x: &[f64], nc: usize, chunks: &[usize]) -> Vec<f64> {
    let width = ams.channels * ams.bands;
    let then_the_rest = chunks.iter().copied().chain([usize::MAX]);
    crate::testing::feed(ams, x, nc, width, then_the_rest)
}

#[test]
fn derived_sizes_follow_the_spec() {
    for (fs, w, h, rate) in [
        (16000.0, 128, 64, 62.5),
        (44100.0, 352, 176, 11025.0 / 176.0),
    ] {
        let (ams, info) = AmsFeatures::new(&AmsParams::default(), &ihc(fs, 3)).expect("valid");
        assert_eq!((ams.win.len(), ams.frames.window()), (w, w));
        assert_eq!(info.fs_hz, rate, "hop {h}");
        assert_eq!(info.width(), 3 * 15);
        assert_eq!(info.mod_cf_hz()[0], 4.0);
        assert!((info.mod_cf_hz()[14] - 1024.0).abs() < 1e-9);
    }
    let lin = AmsParams {
        fb_type: AmsFbType::Lin,
        ..AmsParams::default()
    };
    let (ams, info) = AmsFeatures::new(&lin, &ihc(44100.0, 2)).expect("valid");
    assert!((info.mod_cf_hz()[0] - 67.75).abs() < 1e-12);
    let Bands::Lin { time, .. } = &ams.kind else {
        panic!("lin bank expected")
    };
    assert_eq!(time.len(), 1024);
}

#[test]
fn a_constant_envelope_lands_in_the_lowest_band() {
    let fs = 16000.0;
    let (mut ams, _) = AmsFeatures::new(&AmsParams::default(), &ihc(fs, 1)).expect("valid");
    let out = run(&mut ams, &vec![1.0; 64000], 1, &[]);
    let last = &out[out.len() - 15..];
    assert!((last[0] - 1.0).abs() < 1e-6, "{last:?}");
    assert!(last[1..].iter().all(|v| *v < 0.05), "{last:?}");
}

#[test]
fn a_modulated_envelope_peaks_at_its_rate_in_both_banks() {
    let fs = 16000.0;
    // 64 Hz modulation: log band 7 (4·2^(8/14·7) = 64 Hz; band 0, the low-pass, holds
    // the mean and is left out); lin triangle 0 (67.75 Hz).
    let x: Vec<f64> = (0..64000)
        .map(|t| 1.0 + (2.0 * std::f64::consts::PI * 64.0 * t as f64 / fs).sin())
        .collect();
    for (fb_type, from, expect) in [(AmsFbType::Log, 1, 7), (AmsFbType::Lin, 0, 0)] {
        let p = AmsParams {
            fb_type,
            ..AmsParams::default()
        };
        let (mut ams, _) = AmsFeatures::new(&p, &ihc(fs, 1)).expect("valid");
        let out = run(&mut ams, &x, 1, &[]);
        let last = &out[out.len() - 15..];
        let top = (from..15).max_by(|&a, &b| last[a].total_cmp(&last[b]));
        assert_eq!(top, Some(expect), "{fb_type:?}: {last:?}");
    }
}

/// At 4 kHz the decimated rate is 1 kHz, so the default top band (1024 Hz) is above
/// its Nyquist frequency: spec 15 weighs only bins `k ≤ nfft/2`, which leaves the
/// bands whose lower edge `mc_{j−1} = 4 + 63.75·(j − 1)` Hz is at or above 500 Hz
/// (`j ≥ 9`) silent, not an error.
#[test]
fn lin_bands_above_the_decimated_nyquist_frequency_are_silent() {
    let p = AmsParams {
        fb_type: AmsFbType::Lin,
        ..AmsParams::default()
    };
    let (mut ams, info) = AmsFeatures::new(&p, &ihc(4000.0, 2)).expect("valid");
    assert!(info.mod_cf_hz()[14] > 500.0);
    let out = run(&mut ams, &envelope(8000, 2), 2, &[]);
    assert!(out.len() >= 2 * 15 * 50, "{} values", out.len());
    for band in out.chunks_exact(15) {
        assert!(band[..8].iter().all(|v| v.is_finite() && *v >= 0.0));
        assert!(band[7] > 0.0, "{band:?}");
        assert!(band[8..].iter().all(|&v| v == 0.0), "{band:?}");
    }
}

#[test]
fn bands_past_nyquist_are_named_with_what_would_fit() {
    // 8 kHz input: the envelope decimated by 4 has its Nyquist frequency at 1000 Hz,
    // which the default band centred at 689.1 Hz reaches (edges 0.618 and 1.618 times
    // the centre: 1115.0 Hz)
    let err = AmsFeatures::new(&AmsParams::default(), &ihc(8000.0, 2))
        .expect_err("default bands reach 1657 Hz");
    let msg = err.to_string();
    assert!(
        msg.starts_with(
            "invalid value 1024 for parameter 'ams_highFreqHz': with ams_highFreqHz = 1024 \
             (the default), the modulation band centred at 689.1 Hz reaches 1115.0 Hz"
        ),
        "{msg}"
    );
    for part in [
        "Nyquist frequency (1000 Hz)",
        "ams_dsRatio = 4 (8000 Hz / 4)",
        "below 618.0 Hz",
    ] {
        assert!(msg.contains(part), "{part}: {msg}");
    }
    // what the message says fits does fit
    let fits = AmsParams {
        high_freq_hz: 617.9,
        ..AmsParams::default()
    };
    assert!(AmsFeatures::new(&fits, &ihc(8000.0, 2)).is_ok());
    let over = AmsParams {
        high_freq_hz: 618.1,
        ..AmsParams::default()
    };
    assert!(AmsFeatures::new(&over, &ihc(8000.0, 2)).is_err());
    // an explicit centre is named as given
    let explicit = AmsParams {
        cf_hz: vec![10.0, 900.0],
        ..AmsParams::default()
    };
    let msg = AmsFeatures::new(&explicit, &ihc(8000.0, 2))
        .expect_err("900 Hz reaches 1456 Hz")
        .to_string();
    assert!(
        msg.starts_with("invalid value 900 for parameter 'ams_cfHz'"),
        "{msg}"
    );
}

/// Issue 44, item 4: a window of 1500 s over 32 channels and 15 bands asked for 61.5 GB;
/// it is refused before anything is allocated, in the words of the other framed
/// processors. The sums over two rectangular hops (no frame buffer) take any window
/// the sample count allows, and a frame buffer up to the bound is accepted.
#[test]
fn a_window_whose_frame_buffer_exceeds_the_bound_is_refused() {
    let info = ihc(44100.0, 32);
    let long = AmsParams {
        w_size_sec: 1500.0,
        ..AmsParams::default()
    };
    let msg = AmsFeatures::new(&long, &info)
        .expect_err("61.5 GB")
        .to_string();
    assert!(
        msg.starts_with("invalid value 1500 for parameter 'ams_wSizeSec'")
            && msg.contains("over 480 channels would buffer")
            && msg.contains("shorten the window or use fewer channels"),
        "{msg}"
    );
    let lin = AmsParams {
        fb_type: AmsFbType::Lin,
        ..long.clone()
    };
    let msg = AmsFeatures::new(&lin, &info).expect_err("lin").to_string();
    assert!(msg.contains("over 32 channels would buffer"), "{msg}");
    let two_hops = AmsParams {
        h_size_sec: 750.0,
        ..long
    };
    assert!(AmsFeatures::new(&two_hops, &info).is_ok());
    // 4 channels × 15 bands × 2^19 samples (47.6 s at 11025 Hz) = 2^24 · 1.875: over;
    // a window of 2^18 samples (2^24 · 0.94) fits
    let at = |samples: f64| AmsParams {
        w_size_sec: samples / 11025.0,
        ..AmsParams::default()
    };
    assert!(AmsFeatures::new(&at(524_288.0), &ihc(44100.0, 4)).is_err());
    assert!(AmsFeatures::new(&at(262_144.0), &ihc(44100.0, 4)).is_ok());
}

#[test]
fn bad_parameters_name_themselves() {
    let info = ihc(16000.0, 2);
    let d = AmsParams::default();
    let cases = [
        (
            // found by fuzzing: 2000 explicit frequencies asked for 1.3 GB
            "ams_cfHz",
            AmsParams {
                cf_hz: vec![100.0; 2000],
                ..d.clone()
            },
        ),
        (
            // found by fuzzing: 2^32 filters asked for 34 GB
            "ams_nFilters",
            AmsParams {
                n_filters: 1 << 32,
                ..d.clone()
            },
        ),
        (
            "ams_lowFreqHz",
            AmsParams {
                low_freq_hz: 0.0,
                ..d.clone()
            },
        ),
        (
            "ams_highFreqHz",
            AmsParams {
                high_freq_hz: 2.0,
                ..d.clone()
            },
        ),
        (
            "ams_highFreqHz",
            AmsParams {
                high_freq_hz: 1900.0,
                ..d.clone()
            },
        ),
        (
            "ams_wSizeSec",
            AmsParams {
                w_size_sec: 0.0,
                ..d.clone()
            },
        ),
        (
            "ams_hSizeSec",
            AmsParams {
                h_size_sec: 1e9,
                ..d.clone()
            },
        ),
        (
            "ams_hSizeSec",
            AmsParams {
                h_size_sec: -1.0,
                ..d.clone()
            },
        ),
        (
            "ams_dsRatio",
            AmsParams {
                ds_ratio: 0,
                ..d.clone()
            },
        ),
        (
            "ams_nFilters",
            AmsParams {
                n_filters: 0,
                ..d.clone()
            },
        ),
        (
            "ams_cfHz",
            AmsParams {
                cf_hz: vec![4.0, -8.0],
                ..d.clone()
            },
        ),
        (
            "ams_cfHz",
            AmsParams {
                cf_hz: vec![4.0, 5000.0],
                ..d.clone()
            },
        ),
        (
            "ams_cfHz",
            AmsParams {
                cf_hz: vec![4.0],
                fb_type: AmsFbType::Lin,
                ..d.clone()
            },
        ),
    ];
    for (name, p) in cases {
        let e = AmsFeatures::new(&p, &info).unwrap_err().to_string();
        assert!(e.contains(name), "{name}: {e}");
    }
    let mut map = d.to_map();
    map.insert("ams_fbType".into(), serde_json::json!("mel"));
    let e = AmsParams::from_map(&map).unwrap_err().to_string();
    assert!(e.contains("ams_fbType"), "{e}");
}

/// Spec 15 written out for both banks: decimation by 3 (4800 → 1600 Hz), frames of
/// 64 samples every 32 with a Hann window; `log`: five filters from 4 to 200 Hz run
/// as difference equations on the Butterworth designs, mean |w·v| per frame; `lin`:
/// six triangles from 20 to 500 Hz on a plain DFT of 128 points, over `nfft`.
#[test]
fn both_banks_match_the_spec_written_out() {
    use std::f64::consts::PI;
    let (fs, ratio, nc) = (4800.0, 3, 2);
    let x = envelope(3000, nc);
    let decimated: Vec<&[f64]> = x.chunks_exact(nc).step_by(ratio).collect();
    let (w, hop) = (64, 32);
    let hann: Vec<f64> = (0..w)
        .map(|k| 0.5 * (1.0 - (2.0 * PI * k as f64 / (w - 1) as f64).cos()))
        .collect();
    let frames = (decimated.len() - (w - hop)) / hop;
    let base = AmsParams {
        ds_ratio: ratio,
        w_size_sec: 0.04,
        h_size_sec: 0.02,
        wname: Window::Hann,
        ..AmsParams::default()
    };
    let compare = |p: &AmsParams, want: &[f64]| {
        let (mut ams, info) = AmsFeatures::new(p, &ihc(fs, nc)).expect("valid");
        assert_eq!(info.fs_hz, 50.0);
        let got = run(&mut ams, &x, nc, &[777]);
        assert_eq!(got.len(), want.len());
        let top = want.iter().fold(0.0, |m: f64, v| m.max(v.abs()));
        let worst = got
            .iter()
            .zip(want)
            .map(|(g, v)| (g - v).abs())
            .fold(0.0, f64::max);
        assert!(
            worst <= 1e-12 * top,
            "{:?}: off by {worst} of {top}",
            p.fb_type
        );
    };

    // log: band j of channel c at out[t][c·5 + j].
    let (lo, hi, nb) = (4.0f64, 200.0f64, 5);
    let nyq = 800.0;
    let mut want = vec![0.0; frames * nc * nb];
    for j in 0..nb {
        let mf = lo * (hi / lo).powf(j as f64 / (nb - 1) as f64);
        let (b, a) = if j == 0 {
            butter(1, &[mf / nyq], ButterType::Low)
        } else {
            let edge = |s: f64| mf * (1.25f64.sqrt() + s * 0.5) / nyq;
            butter(1, &[edge(-1.0), edge(1.0)], ButterType::BandPass)
        };
        for c in 0..nc {
            let mut y = vec![0.0; decimated.len()];
            for n in 0..y.len() {
                let mut acc = 0.0;
                for m in 0..b.len().min(n + 1) {
                    acc += b[m] * decimated[n - m][c];
                    if m > 0 {
                        acc -= a[m] * y[n - m];
                    }
                }
                y[n] = acc / a[0];
            }
            for t in 0..frames {
                let s: f64 = (0..w).map(|m| (hann[m] * y[t * hop + m]).abs()).sum();
                want[(t * nc + c) * nb + j] = s / w as f64;
            }
        }
    }
    compare(
        &AmsParams {
            n_filters: nb,
            high_freq_hz: hi,
            ..base.clone()
        },
        &want,
    );

    // lin: triangles of Δ = 480/7 Hz on bins of 12.5 Hz.
    let (fl, fh, nb, nfft) = (20.0, 500.0, 6, 128);
    let delta = (fh - fl) / 7.0;
    let mut want = vec![0.0; frames * nc * nb];
    for c in 0..nc {
        for t in 0..frames {
            let frame: Vec<f64> = (0..w)
                .map(|m| hann[m] * decimated[t * hop + m][c])
                .collect();
            let magnitude: Vec<f64> = crate::testing::plain_dft(&frame, nfft)
                .iter()
                .map(|s| s.norm() / nfft as f64)
                .collect();
            for j in 0..nb {
                want[(t * nc + c) * nb + j] = (0..=nfft / 2)
                    .map(|k| {
                        let f = k as f64 * 1600.0 / nfft as f64;
                        let tri = 1.0 - ((f - fl) / delta - (j + 1) as f64).abs();
                        if f > fl && f < fh && tri > 0.0 {
                            tri * magnitude[k]
                        } else {
                            0.0
                        }
                    })
                    .sum();
            }
        }
    }
    compare(
        &AmsParams {
            fb_type: AmsFbType::Lin,
            n_filters: nb,
            low_freq_hz: fl,
            high_freq_hz: fh,
            ..base
        },
        &want,
    );
}

#[test]
fn explicit_centre_frequencies_are_kept_and_debug_names_the_sizes() {
    let p = AmsParams {
        cf_hz: vec![5.0, 12.0, 40.0],
        ..AmsParams::default()
    };
    let (ams, info) = AmsFeatures::new(&p, &ihc(16000.0, 2)).expect("valid");
    assert_eq!(info.mod_cf_hz(), [5.0, 12.0, 40.0]);
    assert_eq!(info.width(), 6);
    let shown = format!("{ams:?}");
    assert!(
        shown.contains("channels: 2")
            && shown.contains("bands: 3")
            && shown.contains("window: 128"),
        "{shown}"
    );
}

#[test]
fn reset_restarts_the_stream() {
    let x = envelope(3000, 2);
    let (mut ams, _) = AmsFeatures::new(&AmsParams::default(), &ihc(16000.0, 2)).expect("valid");
    let first = run(&mut ams, &x, 2, &[1001]);
    ams.reset();
    assert_eq!(run(&mut ams, &x, 2, &[1001]), first);
}

#[test]
fn hop_sums_give_the_framed_sums() {
    let x = envelope(4000, 3);
    let info = ihc(8000.0, 3);
    let p = AmsParams {
        high_freq_hz: 256.0,
        ..AmsParams::default()
    };
    let (mut hops, _) = AmsFeatures::new(&p, &info).expect("valid");
    assert!(
        hops.hop_sums.is_some(),
        "the default window is summed by hops"
    );
    // the same processor on the framing path, with that path's buffers
    let (mut framed, _) = AmsFeatures::new(&p, &info).expect("valid");
    let hop = framed.hop_sums.take().expect("summed by hops").hop;
    let width = framed.channels * framed.bands;
    framed.frames = FrameBuffer::new(width, framed.win.len(), hop);
    framed.sums = vec![0.0; width];
    let b = run(&mut framed, &x, 3, &[]);
    assert!(b.iter().any(|v| *v > 0.0));
    for chunks in [&[][..], &[1, 37, 200, 999][..]] {
        let a = run(&mut hops, &x, 3, chunks);
        hops.reset();
        assert_eq!(a.len(), b.len());
        for (i, (a, b)) in a.iter().zip(&b).enumerate() {
            assert!(
                (a - b).abs() <= 1e-14 * b.abs(),
                "value {i}: {a} against {b}"
            );
        }
    }
    for (wname, h_size_sec) in [(Window::Hann, 0.016), (Window::Rectwin, 0.01)] {
        let other = AmsParams {
            wname,
            h_size_sec,
            ..p.clone()
        };
        let (a, _) = AmsFeatures::new(&other, &info).expect("valid");
        assert!(a.hop_sums.is_none(), "{wname}, hop {h_size_sec} s: framed");
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn any_chunking_is_bit_identical(
        chunks in prop::collection::vec(prop_oneof![Just(1usize), 1usize..100, 100usize..1500], 1..20),
        lin in any::<bool>(),
        ratio in 1usize..6,
    ) {
        let x = envelope(4000, 9);
        let p = AmsParams {
            fb_type: if lin { AmsFbType::Lin } else { AmsFbType::Log },
            ds_ratio: ratio,
            high_freq_hz: 256.0,
            ..AmsParams::default()
        };
        let info = ihc(8000.0, 9);
        let (mut a, _) = AmsFeatures::new(&p, &info).expect("valid");
        let (mut b, _) = AmsFeatures::new(&p, &info).expect("valid");
        prop_assert_eq!(run(&mut a, &x, 9, &[]), run(&mut b, &x, 9, &chunks));
    }
}
