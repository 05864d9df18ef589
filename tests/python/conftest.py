"""Fixtures of the Python module's tests: the module from the build tree (PYTHONPATH set by
ctest), the CLI binary beside it, and small frames rendered once per session."""

import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

import posthaste as ph

SOURCE_DIR = Path(__file__).resolve().parents[2]
SCENE = str(SOURCE_DIR / "samples" / "scenes" / "minecrappy.json")


def cli_binary():
    return os.environ.get("POSTHASTE_BINARY", str(SOURCE_DIR / "build" / "posthaste"))


def run_cli(*args, cwd=None):
    """Run the CLI; returns (exit code, its one error line without "error: ")."""
    p = subprocess.run([cli_binary(), *map(str, args)], capture_output=True, text=True, cwd=cwd)
    line = p.stderr.strip().splitlines()[-1] if p.stderr.strip() else ""
    return p.returncode, line.removeprefix("error: ")


@pytest.fixture(scope="session")
def scene():
    return SCENE


@pytest.fixture(scope="session")
def small(tmp_path_factory):
    """A 96x54 render of frame 3 with every pass, and its EXR on disk."""
    frame = ph.node("render", scene=SCENE, width=96, height=54, frame=3)
    path = tmp_path_factory.mktemp("small") / "small.0003.exr"
    ph.write(frame, path)
    return frame, path


@pytest.fixture
def rgba():
    rng = np.random.default_rng(7)
    return rng.random((16, 24, 4), dtype=np.float32)
