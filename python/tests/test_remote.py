"""Remote clients of `afe serve` over Zenoh (afe.connect) and the local block iterator
(afe.stream): the same afe.Frames, bit for bit what a local manager computes; errors;
subscriptions released when their client closes or is killed."""
import contextlib
import itertools
import os
import json
import signal
import struct
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import afe
from afe.frames import request_list
from afe.remote import RemoteError, _Meta, _read_audio, _read_frames
from conftest import connect, free_port, zenoh_peer

zenoh = pytest.importorskip("zenoh")

REQUESTS = ["ratemap", "ild", "itd", "ic"]
BLOCK = 441  # 10 ms at 44.1 kHz, the server's block


@pytest.fixture
def serve(cli):
    """Starts `afe serve` over a WAV file on a free loopback port; returns its endpoint.
    Every server started is killed at the end of the test."""
    started = []

    def start(wav, requests=None, seconds=20, stdout=subprocess.DEVNULL, extra=()):
        """``wav``: a file's path, or a ``synth:`` source; ``stdout``: where the server's
        final report (JSON) goes; ``extra``: more options."""
        endpoint = f"tcp/127.0.0.1:{free_port()}"
        source = wav if wav.startswith("synth:") else f"wav:{wav}"
        cmd = [cli, "serve", "--source", source, "--listen", endpoint,
               "--block-ms", "10", "--for", str(seconds), "--json"]
        if requests:
            cmd += ["-r", ",".join(requests)]
        cmd += list(extra)
        started.append(subprocess.Popen(cmd, stdout=stdout, stderr=subprocess.PIPE))
        return endpoint

    start.processes = started
    yield start
    for p in started:
        p.kill()
        p.wait()


@contextlib.contextmanager
def reports(endpoint, name="robot"):
    """A plain Zenoh subscriber to the server's report; yields a function that returns
    the next report (JSON) within a timeout."""
    session = zenoh_peer(endpoint)
    sub = session.declare_subscriber(f"afe/{name}/report", zenoh.handlers.RingChannel(16))

    def next_report(timeout=5.0):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            sample = sub.handler.try_recv()
            if sample is not None:
                return json.loads(sample.payload.to_bytes())
            time.sleep(0.01)
        raise AssertionError(f"no report from the server within {timeout} s")

    try:
        yield next_report
    finally:
        session.close()


def wait_for(next_report, predicate, timeout):
    """The first report satisfying ``predicate`` within ``timeout`` seconds."""
    end = time.monotonic() + timeout
    last = None
    while time.monotonic() < end:
        last = next_report(timeout=max(0.5, end - time.monotonic()))
        if predicate(last):
            return last
    raise AssertionError(f"no report as expected within {timeout} s; last: {last}")


def clients(report):
    return {s["client"] for s in report["subscriptions"]}


def reference(wav, requests, params=None):
    """Each output of `requests` over the file, fed in the server's 441-frame blocks."""
    x, fs = afe.read_wav(wav)
    mgr = afe.Manager(fs, 2, keep_history=False)
    for r in requests:
        mgr.add_request(r, params)
    rows = {}
    for start in range(0, x.shape[0], BLOCK):
        for k, v in mgr.process_chunk(x[start:start + BLOCK]).items():
            rows.setdefault(k, []).append(np.asarray(v))
    return {k: np.concatenate(v) for k, v in rows.items()}, x.shape[0]


def test_remote_frames_are_the_local_managers_bit_for_bit(serve, tiled_wav):
    endpoint = serve(tiled_wav, REQUESTS)
    with connect(endpoint) as robot:
        assert robot.name == "robot" and robot.fs_hz == 44100.0 and robot.ears == 2
        assert robot.block_frames == BLOCK and robot.catalogue["wire_version"] == 1
        with robot.subscribe(REQUESTS) as sub:
            blocks = []
            while len(blocks) < 50:
                frames = sub.recv(timeout=5.0)
                assert frames is not None, "no block within 5 s"
                blocks.append(frames)
            assert sub.lost_messages == 0
            assert set(sub.lost_frames.values()) == {0}
    ref, length = reference(tiled_wav, REQUESTS)
    assert sub.keys == list(blocks[0].keys()) and set(sub.keys) == set(ref)
    assert blocks[-1].first_input_frame + blocks[-1].input_frames <= length, "subscribed too late"
    assert [b.seq for b in blocks] == list(range(blocks[0].seq, blocks[0].seq + 50))
    assert blocks[0].first_input_frame == sub.reply["start_frame"]
    assert all(b.lost_messages == 0 and b.input_frames == BLOCK for b in blocks)
    assert all(b.first_input_frame % BLOCK == 0 for b in blocks)
    rows = 0
    for b in blocks:
        assert isinstance(b, afe.Frames)
        assert abs(b.t_ns * 1e-9 - time.time()) < 60  # a Unix time, in ns
        for k, s in b.items():
            assert isinstance(s, afe.Signal) and s.dtype == np.float64 and s.key == k
            f = s.first_frame
            assert f + s.shape[0] <= ref[k].shape[0]
            assert np.array_equal(np.asarray(s), ref[k][f:f + s.shape[0]]), (k, b.seq)
            assert s.first_time_s == pytest.approx(f / s.fs_hz)
            rows += s.shape[0]
    assert rows > 0
    # consecutive blocks continue each other
    for a, b in zip(blocks, blocks[1:]):
        for k in a:
            assert b[k].first_frame == a[k].first_frame + a[k].shape[0]
    # the descriptions are the local ones
    local = afe.process(tiled_wav, None, ["ratemap"])["ratemap_left"]
    assert np.array_equal(blocks[0]["ratemap_left"].cf_hz, local.cf_hz)
    assert blocks[0]["ratemap_left"].parameters == local.parameters
    # the local iterator gives the same blocks: same class, keys, indices and values
    first = blocks[0].first_input_frame // BLOCK
    local = list(itertools.islice(afe.stream(tiled_wav, REQUESTS), first, first + len(blocks)))
    assert len(local) == len(blocks)
    for lb, rb in zip(local, blocks):
        assert type(lb) is type(rb) and list(lb.keys()) == list(rb.keys())
        assert (lb.first_input_frame, lb.input_frames) == (rb.first_input_frame, rb.input_frames)
        for k in lb:
            assert lb[k].first_frame == rb[k].first_frame
            assert np.array_equal(np.asarray(lb[k]), np.asarray(rb[k]))


def test_the_servers_audio_feeds_a_local_front_end(serve, tiled_wav):
    endpoint = serve(tiled_wav)
    x, fs = afe.read_wav(tiled_wav)
    with connect(endpoint) as robot:
        with robot.audio() as audio:
            assert (audio.fs_hz, audio.ears, audio.block_frames) == (fs, 2, BLOCK)
            blocks = [audio.recv(timeout=5.0) for _ in range(100)]
            assert all(isinstance(b, afe.AudioBlock) for b in blocks), "no block within 5 s"
            assert (audio.lost_messages, audio.lost_frames) == (0, 0)
        assert audio.ended and audio.recv(timeout=0.1) is None
        first = blocks[0].first_frame
        assert [b.first_frame for b in blocks] == list(range(first, first + 100 * BLOCK, BLOCK))
        assert [b.seq for b in blocks] == list(range(blocks[0].seq, blocks[0].seq + 100))
        got = np.concatenate([b.samples for b in blocks])
        # the server's port replays the file in a loop: its samples, bit for bit
        assert np.array_equal(got, x[np.arange(first, first + got.shape[0]) % x.shape[0]])
        # a local front-end on the server's audio gives what it gives on the file
        remote = list(itertools.islice(afe.stream(robot.audio(), REQUESTS), 50))
    start = remote[0].first_input_frame
    assert [b.first_input_frame for b in remote] == list(range(start, start + 50 * BLOCK, BLOCK))
    assert all(b.lost_messages == 0 for b in remote)
    local = list(afe.stream(x[np.arange(start, start + 50 * BLOCK) % x.shape[0]], REQUESTS, fs_hz=fs))
    assert len(local) == len(remote)
    for lb, rb in zip(local, remote):
        assert list(lb.keys()) == list(rb.keys())
        for k in lb:
            assert lb[k].first_frame == rb[k].first_frame
            assert np.array_equal(np.asarray(lb[k]), np.asarray(rb[k])), (k, rb.seq)
    with pytest.raises(ConnectionError, match="closed"):
        robot.audio()


def test_stream_gives_what_process_gives(example_wav):
    want = afe.process(example_wav, None, REQUESTS)
    blocks = list(afe.stream(example_wav, REQUESTS))
    x, fs = afe.read_wav(example_wav)
    assert len(blocks) == -(-x.shape[0] // BLOCK)
    assert [b.first_input_frame for b in blocks] == list(range(0, x.shape[0], BLOCK))
    assert all(isinstance(b, afe.Frames) and b.lost_messages == 0 for b in blocks)
    assert list(blocks[0].keys()) == ["ratemap_left", "ratemap_right", "ild_mono", "itd_mono", "ic_mono"]
    for k, v in want.items():
        got = np.concatenate([np.asarray(b[k]) for b in blocks])
        assert np.array_equal(got, np.asarray(v)), k
        # each block's rows are indexed and timed in the stream
        n = 0
        for b in blocks:
            assert b[k].first_frame == n
            n += b[k].shape[0]
        b = next(b for b in blocks if b[k].shape[0])
        assert np.allclose(b[k].t_s, v.t_s[b[k].first_frame:b[k].first_frame + b[k].shape[0]])
    # an array in either orientation, with its rate; other blocks; one's own parameters
    a = list(afe.stream(x, "ratemap", {"fb_nChannels": 8}, block_ms=25, fs_hz=fs))
    b = list(afe.stream(x.T, [("ratemap", {"fb_nChannels": 8})], block_ms=25, fs_hz=fs))
    assert a[1].input_frames == round(0.025 * fs) and a[1]["ratemap_left"].shape[1] == 8
    for k in ("ratemap_left", "ratemap_right"):
        assert np.array_equal(np.concatenate([f[k] for f in a]), np.concatenate([f[k] for f in b]))
    assert "ratemap_left" in repr(a[0]) and len(a[0]) == 2 and "ild_mono" not in a[0]
    with pytest.raises(KeyError, match="ratemap_left"):
        a[0]["ild_mono"]
    # complex spectra stay complex, rows or not
    spectra = list(afe.stream(x[:4410], ["stft"], fs_hz=fs))
    assert all(np.iscomplexobj(f["stft_left"]) for f in spectra)
    with pytest.raises(ValueError, match="fs_hz is required"):
        afe.stream(x, ["ratemap"])
    with pytest.raises(ValueError, match="nosuch"):
        afe.stream(x, ["nosuch"], fs_hz=fs)
    with pytest.raises(ValueError, match="no request"):
        afe.stream(x, [], fs_hz=fs)


def test_refusals_and_unreachable_servers(serve, example_wav):
    endpoint = serve(example_wav, ["ratemap"])
    with connect(endpoint) as robot:
        with pytest.raises(RemoteError, match="nosuch") as e:
            robot.subscribe(["nosuch"])
        assert isinstance(e.value, RuntimeError) and "unknown request" in e.value.message
        with pytest.raises(RemoteError, match="fb_nChannels"):
            robot.subscribe(["ratemap"], {"fb_nChannels": "many"})
        with pytest.raises(RemoteError, match="fb_nchannels"):
            robot.subscribe(["ratemap"], {"fb_nchannels": 8})
        with pytest.raises(ValueError, match="finite"):
            robot.subscribe(["ratemap"], {"fb_lowFreqHz": float("nan")})
        # a refusal leaves the connection usable; requests with their own parameters
        # start with the subscription; spectra come complex
        with robot.subscribe([("stft", None), ("ratemap", {"fb_nChannels": 8})]) as sub:
            assert sub.keys == ["stft_left", "stft_right", "ratemap_2_left", "ratemap_2_right"]
            first = sub.recv(timeout=5.0)
            assert first.first_input_frame == sub.reply["start_frame"]
            for k, s in first.items():
                assert s.first_frame == 0 and s.first_time_s == first.first_input_frame / 44100
                assert s.shape[1:] == tuple(sub.descriptions[k]["frame_shape"])
            assert first["ratemap_2_left"].shape[1] == 8 and first["ratemap_2_left"].n_channels == 8
            while not first["stft_left"].shape[0]:
                first = sub.recv(timeout=5.0)
            assert first["stft_left"].dtype == np.complex128 and first["stft_left"].kind == "spectrum"
        with pytest.raises(ConnectionError):
            afe.connect(endpoint, name="another", timeout=1.0)
    start = time.monotonic()
    with pytest.raises(ConnectionError, match="cannot reach"):
        afe.connect(f"tcp/127.0.0.1:{free_port()}")
    assert time.monotonic() - start < 15
    with pytest.raises(ValueError, match="server name"):
        afe.connect(endpoint, name="a/b")


CLIENT = """
import sys, time, afe
robot = afe.connect(sys.argv[1])
sub = robot.subscribe(["ratemap"], {"fb_nChannels": 8})
assert sub.recv(timeout=5.0) is not None
print(robot.id, flush=True)
time.sleep(60)
"""


def test_a_killed_clients_subscription_is_released(serve, example_wav):
    endpoint = serve(example_wav, ["ratemap"])
    connect(endpoint).close()  # the server is up
    with reports(endpoint) as next_report:
        baseline = next_report()
        client = subprocess.Popen([sys.executable, "-c", CLIENT, endpoint],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            client_id = client.stdout.readline().strip()
            assert client_id, client.stderr.read()
            held = wait_for(next_report, lambda r: client_id in clients(r), 10)
            assert held["processors"] > baseline["processors"]
            client.send_signal(signal.SIGKILL)
            client.wait()
            released = wait_for(next_report, lambda r: client_id not in clients(r), 15)
            # its 8-channel processors go with it
            assert released["processors"] == baseline["processors"]
        finally:
            client.kill()
            client.wait()


def test_leaving_with_closes_the_subscription(serve, example_wav):
    endpoint = serve(example_wav, ["ratemap"])
    with reports(endpoint) as next_report:
        with connect(endpoint) as robot, robot.subscribe(["ild"]) as sub:
            blocks = [f for _, f in zip(range(3), sub)]
            client_id = robot.id
            wait_for(next_report, lambda r: client_id in clients(r), 10)
        assert [f.seq for f in blocks] == [blocks[0].seq + i for i in range(3)]
        assert sub.ended and robot.closed and "ended" in repr(sub)
        assert sub.recv(timeout=0.1) is None and list(sub) == []
        sub.close()
        robot.close()  # closing again does nothing
        with pytest.raises(ConnectionError, match="closed"):
            robot.subscribe(["ild"])
        wait_for(next_report, lambda r: client_id not in clients(r), 10)


def test_a_dropped_subscription_is_released(serve, example_wav):
    endpoint = serve(example_wav, ["ratemap"])
    with reports(endpoint) as next_report, connect(endpoint) as robot:
        kept = robot.subscribe(["ratemap"])
        dropped = robot.subscribe(["ild"])
        held = wait_for(next_report, lambda r: len(r["subscriptions"]) == 2, 10)
        assert {s["client"] for s in held["subscriptions"]} == {robot.id}
        del dropped
        left = wait_for(next_report, lambda r: len(r["subscriptions"]) == 1, 10)
        assert left["subscriptions"][0]["subscription"] == kept.id
        assert left["subscriptions"][0]["requests"] == ["ratemap"]


def test_another_session_cannot_cancel_or_add_to_a_clients_subscriptions(serve, example_wav):
    """The client's id is public (the report names it); its subscriptions are changed only
    with the secret token the server gave it, which the report never shows."""
    endpoint = serve(example_wav, ["ratemap"])
    with reports(endpoint) as next_report, connect(endpoint) as robot, connect(endpoint) as other:
        sub = robot.subscribe(["ild"])
        held = wait_for(next_report, lambda r: robot.id in clients(r), 10)
        assert "token" not in json.dumps(held)
        body = {"client": robot.id, "subscription": sub.id}
        with pytest.raises(RemoteError, match="needs the \"token\""):
            other._query("unsubscribe", body)
        with pytest.raises(RemoteError, match="only the client that subscribed"):
            other._query("unsubscribe", dict(body, token="0" * 32))
        spec = {"client": robot.id, "requests": [{"name": "ratemap", "params": {}}]}
        with pytest.raises(RemoteError, match="the \"token\" is missing"):
            other._query("subscribe", spec)
        with pytest.raises(RemoteError, match="held by another session"):
            other._query("subscribe", dict(spec, token="0" * 32))
        assert next_report()["subscriptions"][0]["subscription"] == sub.id
        assert sub.recv(timeout=5) is not None
        sub.close()  # with its token: released
        wait_for(next_report, lambda r: not r["subscriptions"], 10)


def test_a_reader_that_lags_loses_blocks_counted(serve, example_wav):
    endpoint = serve(example_wav, ["ratemap"])
    with connect(endpoint) as robot, robot.subscribe(["ratemap"], capacity=4) as sub:
        first = sub.recv(timeout=5.0)
        time.sleep(0.5)  # 50 blocks come; 4 are kept
        # the connection is not held up meanwhile
        with robot.subscribe(["ild"]) as other:
            assert other.recv(timeout=5.0) is not None
        kept = [sub.recv(timeout=5.0) for _ in range(4)]
        assert kept[0].seq > first.seq + 40 and kept[0].lost_messages == kept[0].seq - first.seq - 1
        assert [f.seq for f in kept] == list(range(kept[0].seq, kept[0].seq + 4))
        assert sub.lost_messages == kept[0].lost_messages
        gap = kept[0]["ratemap_left"].first_frame - first["ratemap_left"].first_frame - 1
        assert sub.lost_frames == {"ratemap_left": gap, "ratemap_right": gap} and gap > 30


LOAD_SETS = [
    ["ratemap", "ild", "itd", "ic"],
    ["ratemap"],
    ["ild"],
    ["itd", "ic"],
    ["onsetMap"],
    ["crosscorrelation"],
    ["onsetStrength"],
    ["spectralFeatures"],
]


def test_eight_clients_lose_nothing_for_30_s_while_a_stalled_one_loses_counted_frames(
        serve, tmp_path):
    seconds = 30
    blocks = seconds * 100
    with open(tmp_path / "report.json", "wb") as out:
        endpoint = serve("synth:fs=44100,tone=500,noise=0.1,itd_ms=0.3,seed=5",
                         seconds=seconds + 30, stdout=out)
    server = serve.processes[-1]
    connect(endpoint).close()  # the server is up
    results = [None] * len(LOAD_SETS)
    failures = []

    def keep_up(i):
        try:
            with connect(endpoint) as robot, robot.subscribe(LOAD_SETS[i]) as sub:
                first = None
                for n, frames in enumerate(sub):
                    first = first or frames
                    if n + 1 == blocks:
                        break
                results[i] = (n + 1, first, frames, sub.lost_messages, sub.lost_frames,
                              sub.reply)
        except BaseException as e:  # reported by the main thread
            failures.append((LOAD_SETS[i], e))

    threads = [threading.Thread(target=keep_up, args=(i,)) for i in range(len(LOAD_SETS))]
    for t in threads:
        t.start()
    # a client that reads nothing for 4 s of full-rate frames, keeping 16 blocks: it loses
    # the rest, here or on the server's side, and counts them from its first block on
    with connect(endpoint) as robot, robot.subscribe(["innerhaircell"], capacity=16) as slow:
        time.sleep(4.0)
        got = []
        resumed = time.monotonic()
        while time.monotonic() - resumed < 2.0:
            frames = slow.recv(timeout=0.1)
            if frames is not None:
                got.append(frames)
        assert got, "the stalled client got nothing after it resumed"
        lost = slow.lost_messages
        # (blocks can still be lost after it resumed, on a loaded machine: the count
        # covers every block up to the last received)
        assert lost > 0 and got[0].seq > 0, (lost, [f.seq for f in got[:3]])
        assert lost == got[-1].seq + 1 - len(got), "each block not received is counted once"
        assert slow.lost_frames == {"innerhaircell_left": lost * BLOCK,
                                    "innerhaircell_right": lost * BLOCK}, \
            "441 frames per 10-ms block: every lost block counts its frames"
    for t in threads:
        t.join(timeout=seconds + 60)
    assert not failures, failures
    for requests, (n, first, last, lost_messages, lost_frames, reply) in zip(LOAD_SETS, results):
        assert n == blocks and lost_messages == 0, (requests, lost_messages)
        assert set(lost_frames.values()) == {0}, (requests, lost_frames)
        assert (first.seq, last.seq) == (0, blocks - 1), requests
        assert first.first_input_frame == reply["start_frame"], requests
        assert last.first_input_frame == reply["start_frame"] + (blocks - 1) * BLOCK, requests
    server.send_signal(signal.SIGINT)
    server.wait(timeout=30)
    report = json.loads((tmp_path / "report.json").read_text())
    # As tests/remote.rs: how fast the blocks ran is `afe bench`'s to measure, not a test's;
    # the report accounts for every block, each miss listed (up to 100), and nothing is lost.
    misses = report["deadline_misses"]
    assert len(report["missed_blocks"]) == min(misses, 100), report
    assert misses > 0 or report["compute_ms_max"] <= report["budget_ms"], report
    assert report["compute_ms_p50"] <= report["compute_ms_p99"], report
    assert report["lost_frames"] == 0, report
    assert report["blocks"] >= blocks


def test_iteration_ends_when_the_server_goes(serve, example_wav):
    endpoint = serve(example_wav)
    server = serve.processes[-1]
    with connect(endpoint) as robot:
        sub = robot.subscribe(["ratemap"], {"fb_nChannels": 8})
        n = 0
        for _ in sub:
            n += 1
            if n == 5:
                server.kill()
                killed = time.monotonic()
        assert time.monotonic() - killed < 10
        assert sub.ended and robot.server_gone
        with pytest.raises(ConnectionError, match="has gone"):
            robot.subscribe(["ratemap"])


def message(seq, parts, count=None, magic=b"AFEZ", version=1, kind=2):
    body = b"".join(struct.pack("<QII", f, rows, width) + np.asarray(v, "<f8").tobytes()
                    for f, rows, width, v in parts)
    head = struct.pack("<4sHHQQIIQ", magic, version, kind, seq, 882, 441,
                       len(parts) if count is None else count, 1_700_000_000_000_000_000)
    return head + body


def test_the_wire_format_is_read_and_checked():
    metas = [
        _Meta({"key": "ratemap_left", "frame_shape": [3], "dtype": "float64", "fs_hz": 100.0,
               "first_frame": 4, "first_time_s": 0.04}),
        _Meta({"key": "stft_left", "frame_shape": [2], "dtype": "complex128", "fs_hz": 100.0}),
        _Meta({"key": "time_left", "frame_shape": [], "dtype": "float64", "fs_hz": 44100.0}),
    ]
    good = [(7, 2, 3, np.arange(6.0)), (3, 1, 4, [1.0, -2.0, 0.5, 0.25]), (0, 0, 1, [])]
    (seq, first, n, t_ns), parts = _read_frames(message(9, good), metas)
    assert (seq, first, n, t_ns) == (9, 882, 441, 1_700_000_000_000_000_000)
    assert parts[0][0] == 7 and np.array_equal(parts[0][1], np.arange(6.0).reshape(2, 3))
    assert parts[1][1].dtype == np.complex128 and parts[1][1].tolist() == [[1 - 2j, 0.5 + 0.25j]]
    assert parts[2][1].shape == (0,)
    parts[0][1][0, 0] = 1.0  # writable
    bad = {
        "cut short": message(9, good)[:-8],
        "after the end": message(9, good) + b"\0",
        "not an afe frames message": message(9, good, magic=b"XXXX"),
        "wire version": message(9, good, version=2),
        "signals in a message": message(9, good[:2], count=2),
        "values per frame": message(9, [(7, 2, 2, np.arange(4.0))] + good[1:]),
    }
    for what, data in bad.items():
        with pytest.raises(RemoteError, match=what):
            _read_frames(data, metas)
    with pytest.raises(RemoteError, match="cut short"):
        _read_frames(b"AFEZ", metas)


def test_audio_messages_are_read_and_checked():
    samples = np.arange(441 * 2.0).reshape(441, 2) / 1000
    head = struct.pack("<4sHHQQIIQ", b"AFEZ", 1, 1, 5, 882, 441, 2, 1_700_000_000_000_000_000)
    (seq, first, n, t_ns), got = _read_audio(head + samples.astype("<f8").tobytes(), 2)
    assert (seq, first, n, t_ns) == (5, 882, 441, 1_700_000_000_000_000_000)
    assert got.dtype == np.float64 and np.array_equal(got, samples)
    bad = {
        "of 2 channels from a server of 1": (head + samples.tobytes(), 1),
        "with 7048 bytes of samples": (head + samples.tobytes()[:-8], 2),
        "not an afe audio message": (message(9, [(0, 0, 1, [])]), 2),
        "cut short": (head[:20], 2),
    }
    for what, (data, ears) in bad.items():
        with pytest.raises(RemoteError, match=what):
            _read_audio(data, ears)


def test_requests_are_names_or_pairs():
    assert request_list("ratemap, ild", {"fb_nChannels": 8}) == [
        ("ratemap", {"fb_nChannels": 8}), ("ild", {"fb_nChannels": 8})]
    assert request_list([("ratemap", {"fb_nChannels": 16}), "ild"], {"fb_nChannels": 8}) == [
        ("ratemap", {"fb_nChannels": 16}), ("ild", {"fb_nChannels": 8})]
    with pytest.raises(ValueError, match="no request"):
        request_list(" , ")
    with pytest.raises(ValueError, match="name or a"):
        request_list([3])


def test_a_client_reads_the_robots_platform_and_a_mismatched_one_is_refused(serve, cli):
    """`afe serve --platform` publishes the robot's descriptor in its catalogue, and
    refuses a source that is not the robot's (issue 60)."""
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    ball = os.path.join(root, "data", "platforms", "ball-15cm.json")
    endpoint = serve("synth:fs=24414,tone=500,noise=0.1,seed=1", extra=["--platform", ball])
    with connect(endpoint) as remote:
        p = remote.platform
        assert p is not None and p["robot"] == "seed robot: a 15-cm ball on a pan unit", p
        assert p["audio"]["sample_rate_hz"] == remote.fs_hz == 24414
        assert [c["role"] for c in p["audio"]["channels"]] == ["left-ear", "right-ear"]
        assert p["joints"][0]["kind"] == "yaw"
    wrong = subprocess.run(
        [cli, "serve", "--source", "synth:fs=44100,tone=500", "--listen", f"tcp/127.0.0.1:{free_port()}",
         "--for", "1", "--platform", ball],
        capture_output=True, text=True, timeout=60,
    )
    assert wrong.returncode != 0
    assert "captures at 24414 Hz; the source is at 44100 Hz" in wrong.stderr, wrong.stderr
