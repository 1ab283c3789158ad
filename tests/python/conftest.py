"""Shared fixtures: the project's own tools make the data (`fabrik synth`, `fabrik solve`)."""
import os
import subprocess

import pytest

SOURCE = os.environ.get("FABRIK_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
DEFAULT_CONFIG = os.path.join(SOURCE, "config", "default.json")


def fabrik_cli(*args):
    """Runs the `fabrik` CLI (FABRIK_BIN); its stdout."""
    binary = os.environ.get("FABRIK_BIN")
    if not binary:
        pytest.skip("FABRIK_BIN is not set (ctest sets it to the build's fabrik)")
    done = subprocess.run([binary, *map(str, args)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, f"fabrik {' '.join(map(str, args))}: {done.stderr}"
    return done.stdout


@pytest.fixture(scope="session")
def synth_trial(tmp_path_factory):
    """1 s at 100 Hz of the default model's markers with occlusion gaps (mm TRC)."""
    path = tmp_path_factory.mktemp("synth") / "walk.trc"
    fabrik_cli("synth", "--config", DEFAULT_CONFIG, "--output", path, "--seconds", 1,
               "--rate", 100, "--gaps", 3, "--seed", 4)
    return path


def shared_data(name):
    """A file of ../shared/data, or a skip saying it is missing."""
    base = os.environ.get("FABRIK_SHARED_DATA_DIR", os.path.join(SOURCE, "..", "shared", "data"))
    path = os.path.join(base, name)
    if not os.path.exists(path):
        pytest.skip(f"{path} is missing (the shared data set is not on this machine)")
    return path
