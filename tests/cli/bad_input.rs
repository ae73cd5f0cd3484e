//! Every kind of bad input to `afe extract` is one clear error line, and no output file.

use crate::common;

use common::{afe, assert_clear_error, npz_arrays, tmp, tone, write_wav};

#[test]
fn every_bad_input_is_one_clear_line() {
    let good = tmp("good.wav");
    write_wav(&good, 2, 16000, 3200, tone);
    let g = good.to_str().expect("path");
    let o = tmp("never.npz");
    let os = o.to_str().expect("path");

    assert_clear_error(
        &afe(&["extract", g, "-r", ",", "-o", os]),
        "no request given",
        &o,
    );
    assert_clear_error(
        &afe(&["extract", g, "-r", "ratemapp", "-o", os]),
        "unknown request 'ratemapp'",
        &o,
    );
    assert_clear_error(
        &afe(&[
            "extract",
            g,
            "-r",
            "ratemap",
            "-p",
            "rm_wsize=0.1",
            "-o",
            os,
        ]),
        "unknown parameter 'rm_wsize'",
        &o,
    );
    assert_clear_error(
        &afe(&[
            "extract",
            g,
            "-r",
            "ratemap",
            "-p",
            "ihc_method=daux",
            "-o",
            os,
        ]),
        "'dau'",
        &o,
    );
    assert_clear_error(
        &afe(&[
            "extract",
            g,
            "-r",
            "ratemap",
            "-p",
            "fb_nChannels=abc",
            "-o",
            os,
        ]),
        "fb_nChannels",
        &o,
    );
    assert_clear_error(
        &afe(&[
            "extract",
            g,
            "-r",
            "ratemap",
            "-p",
            "rm_hSizeSec=0",
            "-o",
            os,
        ]),
        "rm_hSizeSec",
        &o,
    );
    assert_clear_error(
        &afe(&["extract", "/nonexistent/x.wav", "-r", "ratemap", "-o", os]),
        "cannot open '/nonexistent/x.wav'",
        &o,
    );

    let text = tmp("notwav.wav");
    std::fs::write(&text, "this is not audio").expect("write");
    assert_clear_error(
        &afe(&[
            "extract",
            text.to_str().expect("path"),
            "-r",
            "ratemap",
            "-o",
            os,
        ]),
        "as WAV",
        &o,
    );

    let three = tmp("three.wav");
    write_wav(&three, 3, 16000, 100, tone);
    assert_clear_error(
        &afe(&[
            "extract",
            three.to_str().expect("path"),
            "-r",
            "ratemap",
            "-o",
            os,
        ]),
        "3 channels",
        &o,
    );

    let nan = tmp("nan.wav");
    write_wav(
        &nan,
        2,
        16000,
        100,
        |i| if i == 51 { f32::NAN } else { 0.1 },
    );
    assert_clear_error(
        &afe(&[
            "extract",
            nan.to_str().expect("path"),
            "-r",
            "ratemap",
            "-o",
            os,
        ]),
        "sample 25 of the right channel is NaN",
        &o,
    );

    // read block by block: the position is still the one in the whole file
    let late_nan = tmp("late-nan.wav");
    write_wav(&late_nan, 2, 16000, 6000, |i| {
        if i == 2 * 5000 {
            f32::NAN
        } else {
            0.1
        }
    });
    assert_clear_error(
        &afe(&[
            "extract",
            late_nan.to_str().expect("path"),
            "-r",
            "ratemap",
            "-o",
            os,
        ]),
        "sample 5000 of the left channel is NaN",
        &o,
    );

    let empty = tmp("empty.wav");
    write_wav(&empty, 2, 16000, 0, tone);
    assert_clear_error(
        &afe(&[
            "extract",
            empty.to_str().expect("path"),
            "-r",
            "ratemap",
            "-o",
            os,
        ]),
        "holds no samples",
        &o,
    );

    let mono = tmp("mono.wav");
    write_wav(&mono, 1, 16000, 1000, tone);
    assert_clear_error(
        &afe(&[
            "extract",
            mono.to_str().expect("path"),
            "-r",
            "itd",
            "-o",
            os,
        ]),
        "needs a binaural",
        &o,
    );
    let mono_out = tmp("mono.npz");
    let ok = afe(&[
        "extract",
        mono.to_str().expect("path"),
        "-r",
        "ratemap",
        "-o",
        mono_out.to_str().expect("path"),
    ]);
    assert!(ok.status.success());
    assert_eq!(npz_arrays(&mono_out)[0].0, "ratemap_mono");
}
