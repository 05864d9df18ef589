"""Every invalid graph of tests/invalid raises the CLI's error from Python: posthaste.GraphError
(ParameterError for a parameter), exit code 2, and the very line `posthaste run` prints."""

from pathlib import Path

import pytest

import posthaste as ph
from conftest import run_cli

INVALID = Path(__file__).resolve().parents[1] / "invalid"
GRAPHS = sorted(INVALID.glob("*.json"))


@pytest.mark.parametrize("path", GRAPHS, ids=[p.stem for p in GRAPHS])
def test_invalid_graph(path):
    expect = (INVALID / (path.stem + ".expect")).read_text().strip()
    code, line = run_cli("run", path, "--quiet", cwd=INVALID)
    assert code == 2
    with pytest.raises(ph.GraphError) as e:
        ph.Graph.load(path).run()
    assert e.value.exit_code == 2
    assert expect in str(e.value)
    assert str(e.value) == line
    assert isinstance(e.value, ph.ParameterError) == ('param "' in line)


def test_the_invalid_set_is_there():
    assert len(GRAPHS) >= 25
