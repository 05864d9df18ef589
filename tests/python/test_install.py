"""`cmake --install` puts the module and its stubs where the interpreter imports them from: into
the site folder under the install prefix."""

import os
import subprocess
import sys
from pathlib import Path

import pytest


def test_cmake_install_gives_an_importable_module(tmp_path):
    build = os.environ.get("POSTHASTE_BUILD_DIR")
    if not build:
        pytest.skip("POSTHASTE_BUILD_DIR is not set (ctest sets it)")
    subprocess.run(["cmake", "--install", build, "--prefix", str(tmp_path)], check=True,
                   capture_output=True)
    modules = list(tmp_path.glob("lib/python3*/*-packages/posthaste*.so"))
    assert len(modules) == 1, list(tmp_path.rglob("*"))
    site = modules[0].parent
    assert (site / "posthaste.pyi").is_file() and (tmp_path / "bin" / "posthaste").is_file()
    code = "import posthaste, sys; print(posthaste.__file__); print(len(posthaste.nodes()))"
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(site)
    out = subprocess.run([sys.executable, "-c", code], env=env, check=True, capture_output=True,
                         text=True, cwd=tmp_path).stdout.split()
    assert Path(out[0]).parent == site and int(out[1]) > 20
