"""The worked examples of docs/PYTHON.md run as they are written, from a folder that holds the
repository's samples (and gets their out/)."""

import os
import re

import pytest

from conftest import SOURCE_DIR

DOC = SOURCE_DIR / "docs" / "PYTHON.md"
EXAMPLES = re.findall(r"```python\n(.*?)```", DOC.read_text(), re.S)


def test_the_doc_has_its_three_examples():
    assert len(EXAMPLES) == 3


@pytest.mark.parametrize("index", range(len(EXAMPLES)))
def test_example(index, tmp_path, monkeypatch):
    (tmp_path / "samples").symlink_to(SOURCE_DIR / "samples")
    monkeypatch.chdir(tmp_path)
    exec(compile(EXAMPLES[index], f"{DOC}:example {index + 1}", "exec"), {"__name__": "example"})
    assert (tmp_path / "out").exists() or index == 2
