"""posthaste.pyi: the stubs parse as Python and give node() one overload per node type, with its
ports and parameters (so an editor completes them) and their help as the docstring."""

import ast

import posthaste as ph


def test_stubs_have_an_overload_per_node_type():
    tree = ast.parse(ph._stub_text())
    overloads = {}
    for f in tree.body:
        if isinstance(f, ast.FunctionDef) and f.name == "node" and f.decorator_list:
            literal = f.args.posonlyargs[0].annotation.slice.value
            overloads[literal] = f
    assert set(overloads) == {n.type for n in ph.nodes()}
    grade = overloads["grade"]
    assert [a.arg for a in grade.args.args] == ["image", "mask"]
    keywords = [a.arg for a in grade.args.kwonlyargs]
    assert {"frame", "gain", "saturation", "lut", "mask_pass"} <= set(keywords)
    doc = ast.get_docstring(grade)
    assert doc.startswith("Color grade") and "gain (array of 3 numbers, default [1, 1, 1])" in doc
    ao = overloads["ao"]
    method = next(a for a in ao.args.kwonlyargs if a.arg == "method")
    assert "gtao" in ast.unparse(method.annotation)


def test_the_built_stub_file_is_the_modules():
    from pathlib import Path
    stub = Path(ph.__file__).with_name("posthaste.pyi")
    assert stub.read_text() == ph._stub_text()
