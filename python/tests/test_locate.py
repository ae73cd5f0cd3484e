"""afe.locate and afe.render (issue 59): renders through the rigid sphere, made here, are
located within 5 degrees after front-back folding; bad input raises ValueError naming it."""

import numpy as np
import pytest

import afe

FS = 24414.0


def folded(az):
    """The lateral angle of ``az`` in [-90, 90]: a sphere cannot tell it from its mirror."""
    a = (az + 180.0) % 360.0 - 180.0
    return 180.0 - a if a > 90 else (-180.0 - a if a < -90 else a)


def noise(n, seed=3):
    return np.random.default_rng(seed).uniform(-0.5, 0.5, n)


@pytest.mark.parametrize("az", [0.0, 25.0, 52.5, 95.0, 233.0, 305.0])
def test_a_sphere_render_is_located_within_5_degrees(az):
    ears = afe.render(noise(int(FS)), FS, az, head="sphere")
    assert ears.shape == (int(FS), 2)
    found = afe.locate(ears, FS, head="sphere", sources=1)
    src = found["sources"][0]
    assert abs(folded(src["azimuth_deg"]) - folded(az)) <= 5.0, found["sources"]
    assert 0.0 <= src["azimuth_deg"] < 360.0 and src["salience"] > 0.5
    assert found["t_s"].shape == found["azimuth_deg"].shape == found["active"].shape
    assert found["active"].dtype == bool and found["active"].any()
    assert found["mean_score"].shape == found["azimuths_deg"].shape == (360,)


def test_the_left_ear_leads_for_a_source_on_the_left():
    x = np.zeros(4096)
    x[2048] = 1.0
    ears = afe.render(x, FS, 90.0, head="sphere:radius=0.0875")
    lead = np.argmax(np.abs(ears[:, 1])) - np.argmax(np.abs(ears[:, 0]))
    # Woodworth: (a/c)(pi/2 + 1) = 0.656 ms, 16 samples at 24414 Hz
    assert 13 <= lead <= 19, lead


def test_a_yaw_track_turns_the_azimuths_into_the_world():
    ears = afe.render(noise(int(FS)), FS, 40.0, head="sphere")
    found = afe.locate(ears, FS, head="sphere", sources=1, head_yaw=[[0.0, 30.0]])
    assert np.all(found["yaw_deg"] == 30.0)
    world = found["sources"][0]["azimuth_deg"]
    # the head, turned 30 deg to the left, hears the source 40 deg to its left (or its
    # front-back image: the track holds still)
    assert abs(folded(world - 30.0) - 40.0) <= 5.0, found["sources"]
    still = afe.locate(ears, FS, head="sphere", sources=1)
    assert np.all(still["yaw_deg"] == 0.0)


def test_heads_are_listed():
    names = [n for n, _ in afe.heads()]
    assert names[0] == "kemar" and names[1].startswith("sphere:")


def test_bad_input_is_named():
    ears = afe.render(noise(8000), FS, 30.0)
    with pytest.raises(ValueError, match="unknown head 'cube'"):
        afe.locate(ears, FS, head="cube")
    with pytest.raises(ValueError, match="locating needs two"):
        afe.locate(ears[:, :1], FS, head="sphere")
    with pytest.raises(ValueError, match="shorter than one"):
        afe.locate(ears[:100], FS, head="sphere")
    with pytest.raises(ValueError, match="sources = 0"):
        afe.locate(ears, FS, head="sphere", sources=0)
    with pytest.raises(ValueError, match="fs is required"):
        afe.locate(ears, head="sphere")
    bad = ears.copy()
    bad[10, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        afe.locate(bad, FS, head="sphere")
    with pytest.raises(ValueError, match="rows of \\(t_s, yaw_deg\\)"):
        afe.locate(ears, FS, head="sphere", head_yaw=[0.0, 1.0])
    with pytest.raises(ValueError, match="times must increase"):
        afe.locate(ears, FS, head="sphere", head_yaw=[[1.0, 0.0], [0.5, 10.0]])
    with pytest.raises(ValueError, match="render takes a mono signal"):
        afe.render(ears, FS, 30.0)
    with pytest.raises(ValueError, match="bad sphere parameter"):
        afe.render(noise(100), FS, 30.0, head="sphere:ears=500")

def test_the_localisation_request_gives_a_posterior_over_azimuth_per_frame():
    ears = afe.render(noise(int(FS)), FS, 52.5, head="sphere")
    out = afe.process(ears, FS, "localisation")
    post, act = out["localisation_mono"], out["localisation_activity_mono"]
    assert post.axes == ["frame", "azimuth"] and post.hop_s == pytest.approx(0.02, abs=1e-4)
    azimuths = np.asarray(post.frame_axes[0]["values"])
    assert post.frame_axes[0]["unit"] == "deg" and azimuths.shape == (post.shape[1],)
    np.testing.assert_allclose(post.sum(axis=1), 1.0, atol=1e-12)
    # every frame after the first peaks within 2 degrees of the truth, folded
    best = azimuths[np.argmax(post[1:], axis=1)]
    assert max(abs(folded(b) - 52.5) for b in best) <= 2.0
    assert act.features == ["level_db", "active"] and np.all(act[1:, 1] == 1.0)
    assert post.plan["panel"] == "over-time" and post.plan["rows"]["label"] == "azimuth (deg)"
    # the same as afe.locate's frames: one estimator, run in the graph
    frames = afe.locate(ears, FS, head="sphere", sources=1)["azimuth_deg"]
    assert len(frames) == len(post)


def test_the_localisation_request_names_a_bad_head():
    with pytest.raises(ValueError, match="loc_head.*unknown head 'dummy'"):
        afe.process(np.zeros((4000, 2)), FS, "localisation", {"loc_head": "dummy"})


def test_tracking_keeps_a_source_and_its_image_apart_until_the_head_turns():
    ears = afe.render(noise(2 * int(FS)), FS, 150.0, head="sphere")
    still = afe.locate(ears, FS, head="sphere", track=True)["tracked"]
    assert len(still) >= 10 and still[-1]["t_s"] == pytest.approx(2.0, abs=0.05)
    last = sorted(still[-1]["tracks"], key=lambda t: -t["mass"])
    assert len(last) == 2, last
    assert sorted(round(folded(t["azimuth_deg"])) for t in last) == [30, 30]
    assert not any(t["resolved"] for t in last), last
    # the two are mirror images on the left: a turn to the left would tell them apart
    turn = still[-1]["suggested_turn"]
    assert turn["why"] == "mirror" and sorted(turn["ids"]) == sorted(t["id"] for t in last)
    assert (turn["turn_deg"], turn["target_yaw_deg"]) == (20.0, 20.0), turn
    assert "tracked" not in afe.locate(ears, FS, head="sphere")


def test_a_manager_tracks_in_the_world_by_the_yaw_it_is_told():
    # a talker at 150 deg on the sphere, the head turning 30 deg to the left and back over
    # 2 s; Manager.set_head_yaw reports it, and the `tracking` frames carry the yaw and
    # resolve the talker in the world; a yaw going back in time is refused
    t = np.arange(2 * int(FS)) / FS
    yaw = 15.0 * (1.0 - np.cos(np.pi * t))
    x = noise(len(t))
    hop = int(0.05 * FS)
    ears = np.concatenate([
        afe.render(x[k:k + hop], FS, 150.0 - yaw[k + hop // 2], head="sphere")
        for k in range(0, len(t) - hop + 1, hop)
    ])
    m = afe.Manager(FS, 2)
    m.add_request("tracking")
    for k in range(0, len(t), hop):
        m.set_head_yaw(k / FS, yaw[k])
    with pytest.raises(ValueError, match="times must increase"):
        m.set_head_yaw(0.5, 0.0)
    for k in range(0, len(ears), 4096):
        m.process_chunk(ears[k:k + 4096])
    out = m.outputs()["tracking_mono"]
    names = out.meta["features"]
    rows = np.asarray(out)
    head = rows[:, names.index("head_yaw_deg")]
    assert head.max() == pytest.approx(30.0, abs=0.5) and abs(head[-1]) < 1.0
    last = rows[-1]
    az, resolved = last[names.index("track1_azimuth_deg")], last[names.index("track1_resolved")]
    assert abs((az - 150.0 + 180.0) % 360.0 - 180.0) <= 5.0 and resolved == 1.0, last
