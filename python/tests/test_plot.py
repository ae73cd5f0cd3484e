"""afe.plot draws every representation: a non-blank PNG for each request, from a path,
an array or afe.process's output, and clear errors."""
import numpy as np
import pytest

import afe

pytest.importorskip("matplotlib")
from matplotlib.image import imread  # noqa: E402

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


def assert_content(fig, panels):
    """Each panel holds an image that is not constant, or a line with finite points."""
    drawn = 0
    for ax in fig.axes:
        images = [np.ma.filled(im.get_array(), np.nan) for im in ax.images]
        lines = [np.asarray(line.get_ydata(), dtype=float) for line in ax.lines]
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
