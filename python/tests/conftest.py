"""Shared fixtures: paths of the repository's data and of the `afe` CLI binary."""
import os
import shutil
import socket
import subprocess
import sys
import time

import pytest
import wave

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


@pytest.fixture(scope="session")
def root():
    return ROOT


@pytest.fixture(scope="session")
def example_wav():
    return os.path.join(ROOT, "data", "example_binaural.wav")


@pytest.fixture(scope="session")
def cli():
    """The `afe` binary: $AFE_CLI, else target/release/afe, else target/debug/afe."""
    candidates = [os.environ.get("AFE_CLI")] + [
        os.path.join(ROOT, "target", p, "afe") for p in ("release", "debug")
    ]
    for c in candidates:
        if c and os.path.isfile(c):
            return c
    found = shutil.which("afe")
    if found:
        return found
    pytest.fail("the afe CLI is not built: run `cargo build --release` (or set AFE_CLI)")


def under_address_limit(setup, call, headroom_bytes, timeout):
    """Runs `setup` (Python source, which may define `x`), then, under an address-space
    limit of what the interpreter then holds plus `headroom_bytes`, `call` (one
    expression), in an interpreter of its own without AFE_MEMORY_AVAILABLE_GB; prints
    `computed` or `refused: <the MemoryError>`. Returns the finished process."""
    code = (
        "import resource, numpy as np, afe\n"
        f"{setup}\n"
        "used = int(open('/proc/self/status').read().split('VmSize:')[1].split()[0]) * 1024\n"
        f"resource.setrlimit(resource.RLIMIT_AS, (used + {headroom_bytes}, resource.RLIM_INFINITY))\n"
        "try:\n"
        f"    {call}\n"
        "    print('computed')\n"
        "except MemoryError as e:\n"
        "    print('refused:', e)\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "AFE_MEMORY_AVAILABLE_GB"}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, timeout=timeout)


def connect(endpoint, deadline_s=15.0):
    """afe.connect, retried until the server answers (its Zenoh side may start after its
    other ports)."""
    import afe
    from afe.remote import RemoteError

    start = time.monotonic()
    while True:
        try:
            return afe.connect(endpoint, timeout=5.0)
        except (ConnectionError, RemoteError):
            if time.monotonic() - start > deadline_s:
                raise
            time.sleep(0.05)


def free_port():
    """A TCP port free on loopback now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def zenoh_peer(endpoint):
    """A Zenoh peer session connected to ``endpoint`` alone (no scouting), as a client of
    `afe serve` opens it."""
    import json

    import zenoh

    config = zenoh.Config()
    config.insert_json5("mode", '"peer"')
    config.insert_json5("listen/endpoints", "[]")
    config.insert_json5("connect/endpoints", json.dumps([endpoint]))
    config.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(config)


@pytest.fixture(scope="session")
def tiled_wav(tmp_path_factory, example_wav):
    """The example (1 s) tiled 10 times: a first pass long enough for a server's clients
    to subscribe in and compare their frames with the file's."""
    path = str(tmp_path_factory.mktemp("tiled") / "tiled10.wav")
    with wave.open(example_wav) as w:
        params, pcm = w.getparams(), w.readframes(w.getnframes())
    with wave.open(path, "wb") as w:
        w.setparams(params)
        w.writeframes(pcm * 10)
    return path
