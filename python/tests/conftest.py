"""Shared fixtures: paths of the repository's data and of the `afe` CLI binary."""
import os
import shutil

import pytest

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
