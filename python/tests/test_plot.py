"""afe.plot draws every representation: a non-blank PNG for each request, from a path,
an array or afe.process's output, audio-rate signals as stacked waveforms reduced to the
figure's pixel columns without losing a peak, Signal.plot, and clear errors."""
import numpy as np
import pytest

import afe

pytest.importorskip("matplotlib")
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.image import imread  # noqa: E402

from afe.plot import envelope  # noqa: E402

FS = 16000


def binaural(seconds=0.6):
    rng = np.random.default_rng(4)
    t = np.arange(int(seconds * FS)) / FS
    voice = np.sin(2 * np.pi * 180 * t) * (1 + 0.5 * np.sin(2 * np.pi * 4 * t)) * (t > 0.1) * (t < 0.45)  # an onset and an offset
    left = 0.2 * voice + 0.02 * rng.standard_normal(len(t))
    right = 0.5 * np.concatenate([np.zeros(5), left[:-5]])
    return np.column_stack([left, right])


def assert_drawn(path, panels):
    img = imread(str(path))
    height, width = img.shape[:2]
    assert width == 1000 and height >= 200 * panels, img.shape
    rgb = img[..., :3].reshape(-1, 3)
    # not blank: many colours, and a good share of pixels that are not the background
    assert len(np.unique((rgb * 255).astype(np.uint8), axis=0)) > 50
    assert np.mean(np.any(np.abs(rgb - 1.0) > 0.05, axis=1)) > 0.02


def collections(ax):
    return [c for c in ax.collections if isinstance(c, LineCollection)]


def assert_content(fig, panels):
    """Each panel holds an image that is not constant, or a line (or stacked traces) with
    finite points."""
    drawn = 0
    for ax in fig.axes:
        images = [np.ma.filled(im.get_array(), np.nan) for im in ax.images]
        lines = [np.asarray(line.get_ydata(), dtype=float) for line in ax.lines]
        lines += [seg[:, 1] for c in collections(ax) for seg in c.get_segments()]
        if any(np.nanstd(a) > 0 for a in images) or any(np.isfinite(y).sum() > 1 for y in lines):
            drawn += 1
    assert drawn >= panels, f"{drawn} of {panels} panels drawn"


@pytest.mark.parametrize("request_name", afe.requests())
def test_every_request_is_drawn(request_name, tmp_path):
    # the maps keep events spanning enough channels: the default 32 channels find them
    channels = 32 if request_name.endswith("Map") else 16
    out = afe.process(binaural(), FS, [request_name], {"fb_nChannels": channels})
    png = tmp_path / f"{request_name}.png"
    fig = afe.plot(out, out=png)
    assert_content(fig, len(out))
    assert_drawn(png, len(out))


def test_from_a_path_with_svg_and_a_chosen_time(example_wav, tmp_path):
    svg = tmp_path / "cues.svg"
    afe.plot(example_wav, ["ratemap", "ild", "crosscorrelation"], out=svg, at=0.5)
    text = svg.read_text()
    assert text.startswith("<?xml") and "crosscorrelation_mono at 0.5" in text
    png = tmp_path / "cues.png"
    afe.plot(example_wav, "ild,itd", {"fb_nChannels": 16}, out=png)
    assert_drawn(png, 2)


def test_clear_errors(tmp_path):
    x = binaural()
    with pytest.raises(ValueError, match="requests"):
        afe.plot(x, fs=FS)
    with pytest.raises(ValueError, match="outside"):
        afe.plot(x, ["crosscorrelation"], fs=FS, at=5.0)
    with pytest.raises(ValueError, match="plain array"):
        afe.plot({"ild_mono": np.zeros((3, 4))})


AUDIO_RATE = [("time", {}), ("filterbank", {}), ("innerhaircell", {}), ("adaptation", {}),
              ("filterbank", {"fb_type": "drnl"}), ("butterworth", {})]


def test_audio_rate_signals_are_stacked_waveforms_by_default(tmp_path):
    out = afe.process(binaural(), FS, AUDIO_RATE, {"fb_nChannels": 16})
    # the description says which are at the input's rate: here every output
    assert all(s.fs_hz == s.audio_fs_hz == FS for s in out.values())
    png = tmp_path / "waves.png"
    fig = afe.plot(out, out=png)
    assert_drawn(png, len(out))
    for ax, s in zip(fig.axes, out.values()):
        assert not ax.images, s.key
        if s.ndim == 1:
            assert len(ax.lines) == 1 and not collections(ax), s.key
            continue
        # one trace per channel, each reduced to the figure's 1000 pixel columns
        (traces,) = collections(ax)
        segments = traces.get_segments()
        assert len(segments) == s.shape[1] and all(len(seg) == 2000 for seg in segments), s.key
        # channel k's trace is centred on height k, labelled with centre frequencies
        assert [round(float(np.mean(seg[:, 1]))) for seg in segments] == list(range(s.shape[1])), s.key
        labels = [t.get_text() for t in ax.get_yticklabels()]
        assert labels[0] == f"{s.cf_hz[0]:.0f}" and labels[-1] == f"{s.cf_hz[-1]:.0f}"


def test_audio_rate_signals_as_images_in_db_when_asked(tmp_path):
    out = afe.process(binaural(), FS, ["innerhaircell", "butterworth"], {"fb_nChannels": 16})
    png = tmp_path / "images.png"
    fig = afe.plot(out, out=png, waveforms=False)
    assert_drawn(png, len(out))
    ihc = out["innerhaircell_left"]
    (image,) = fig.axes[0].images
    assert image.get_array().shape == (16, 1000) and not collections(fig.axes[0])
    # each cell is the largest magnitude of its pixel column, in dB over the display's range
    starts = np.arange(1000) * len(ihc) // 1000
    middle = 20 * np.log10(np.max(np.abs(np.asarray(ihc)[starts[500]:starts[501]]), axis=0))
    np.testing.assert_allclose(image.get_array()[:, 500], middle)
    assert image.get_clim()[1] - image.get_clim()[0] == pytest.approx(ihc.display["range_db"])
    # a mono waveform stays a line
    assert len(fig.axes[2].lines) == 1 and not fig.axes[2].images


def test_the_envelope_keeps_each_columns_smallest_and_largest_value():
    rng = np.random.default_rng(7)
    x = rng.standard_normal((10007, 3))
    x[5003, 1] = 40.0  # a one-sample peak
    x[17, 2] = np.nan  # ignored beside the column's other values
    starts, lo, hi = envelope(x, 333)
    assert len(starts) == 333 and starts[0] == 0 and np.all(np.diff(starts) >= 30)
    ends = np.append(starts[1:], len(x))
    for c, (a, b) in enumerate(zip(starts, ends)):
        np.testing.assert_array_equal(lo[c], np.nanmin(x[a:b], axis=0))
        np.testing.assert_array_equal(hi[c], np.nanmax(x[a:b], axis=0))
    assert hi[:, 1].max() == 40.0
    # with no more rows than columns, every row is its own column
    starts, lo, hi = envelope(x[:100], 333)
    assert np.array_equal(starts, np.arange(100)) and np.array_equal(lo, x[:100], equal_nan=True)


def test_a_one_sample_peak_survives_the_drawing():
    x = np.zeros(FS * 10)
    x[123457] = 0.9
    x[150001] = -0.4
    out = afe.process(np.column_stack([x, x]), FS, ["time"], {"pp_bRemoveDC": False, "pp_bPreEmphasis": False})
    fig = out["time_left"].plot()
    (line,) = fig.axes[0].lines
    y = line.get_ydata()
    assert len(y) == 2000
    peak = out["time_left"][123457]
    assert peak != 0 and np.max(y) == peak and np.min(y) == out["time_left"].min()


def test_signal_plot_on_a_new_figure_or_given_axes():
    from matplotlib.figure import Figure

    out = afe.process(binaural(), FS, ["filterbank", "ild"], {"fb_nChannels": 8})
    fig = out["filterbank_left"].plot(width=6)
    assert fig.get_figwidth() == 6 and len(collections(fig.axes[0])) == 1
    mine = Figure()
    left, right = mine.subplots(1, 2)
    assert out["ild_mono"].plot(ax=right) is mine
    assert right.images and not left.images
    assert right.get_title(loc="left") == "ild_mono"
