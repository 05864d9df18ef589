"""posthaste.node / read / write / nodes / diff: nodes run on frames in memory give the CLI's
pixels, defaults and messages."""

import json

import numpy as np
import pytest

import posthaste as ph
from conftest import run_cli


def run_graph_cli(tmp_path, node_type, params, source, extra_nodes=()):
    """`posthaste run` of read(source) -> node_type(params) -> write(float EXR); returns
    (exit code, error line, output path)."""
    out = tmp_path / f"cli_{node_type}.exr"
    graph = {"nodes": [
        {"id": "read", "type": "read", "params": {"path": str(source)}},
        {"id": node_type, "type": node_type, "inputs": {"image": "read"}, "params": params},
        *extra_nodes,
        {"id": "write", "type": "write", "inputs": {"image": node_type},
         "params": {"path": str(out), "storage": "float"}}]}
    path = tmp_path / f"{node_type}.json"
    path.write_text(json.dumps(graph))
    code, line = run_cli("run", path, "--quiet")
    return code, line, out


@pytest.mark.parametrize("node_type,params", [
    ("bloom", {"intensity": 0.3}),
    ("dof", {"fstop": 2.0, "samples": 16}),
    ("motion_blur", {}),
    ("ao", {}),
    ("grade", {"gain": [1.5, 1.0, 0.5], "saturation": 0.8}),
])
def test_a_node_gives_the_clis_pixels(tmp_path, small, node_type, params):
    code, line, out = run_graph_cli(tmp_path, node_type, params, small[1])
    assert code == 0, line
    cli = ph.read(out)
    mine = ph.node(node_type, ph.read(small[1]), **params)
    for name in ("color", "depth"):
        np.testing.assert_array_equal(mine.passes[name], cli.passes[name])


def test_read_write_round_trip_is_exact(tmp_path, small):
    frame = ph.read(small[1])
    path = tmp_path / "copy.exr"
    ph.write(frame, path)
    report = ph.diff(small[1], path, fail=0, warn=0)
    assert report["verdict"] == "PASS" and report["exit_code"] == 0
    again = ph.read(path)
    for name in frame.passes:
        np.testing.assert_array_equal(again.passes[name], frame.passes[name])


def test_read_a_pattern_takes_its_first_frame_or_the_one_asked(tmp_path, scene):
    for n in (4, 2):
        ph.write(ph.node("render", scene=scene, width=32, height=18, frame=n), tmp_path / f"s.{n:04d}.exr")
    assert ph.read(tmp_path / "s.####.exr").number == 2
    assert ph.read(tmp_path / "s.####.exr", frame=4).number == 4
    with pytest.raises(ph.RunError, match="s.0003.exr"):
        ph.read(tmp_path / "s.####.exr", frame=3)


def test_sources_and_sinks(tmp_path, scene):
    f = ph.node("render", scene=scene, width=32, height=18, frame=7)
    assert f.number == 7 and {"color", "depth", "normal", "motion"} <= set(f.passes)
    assert f.camera["worldToNDC"].shape == (4, 4)
    assert ph.node("write", f, path=str(tmp_path / "w.exr")) is None
    assert (tmp_path / "w.exr").exists()


def test_nodes_lists_every_type_with_its_parameters():
    types = {n.type: n for n in ph.nodes()}
    assert {"read", "write", "render", "grade", "dof", "ssgi", "cryptomatte"} <= set(types)
    gain = next(p for p in types["grade"].params if p.name == "gain")
    assert gain.type == "vec" and gain.default == [1.0, 1.0, 1.0] and gain.help
    width = next(p for p in types["render"].params if p.name == "width")
    assert (width.type, width.default, width.min, width.max, width.unit) == ("int", 1920, 1.0, 16384.0, "px")
    fstop = next(p for p in types["dof"].params if p.name == "fstop")
    assert fstop.header == "aperture" and fstop.default == 5.6
    method = next(p for p in types["ao"].params if p.name == "method")
    assert "gtao" in method.choices
    assert [i.name for i in types["grade"].inputs][:1] == ["image"] and types["grade"].maskable
    assert types["write"].sink


def cli_tail(tmp_path, small, node_type, params):
    code, line, _ = run_graph_cli(tmp_path, node_type, params, small[1])
    return code, line.split(": ", 1)[1]


@pytest.mark.parametrize("params,kind", [
    ({"gian": 2}, ph.ParameterError),                   # unknown, with a hint
    ({"gain": "x"}, ph.ParameterError),                 # wrong type
    ({"saturation": -1}, ph.ParameterError),            # out of range
    ({"mask_channel": "q"}, ph.ParameterError),         # not a choice
])
def test_parameter_errors_are_the_clis(tmp_path, small, params, kind):
    code, tail = cli_tail(tmp_path, small, "grade", params)
    with pytest.raises(kind) as e:
        ph.node("grade", ph.read(small[1]), **params)
    assert e.value.exit_code == code == 2
    assert str(e.value).split(": ", 1)[1] == tail


def test_a_parameter_the_method_ignores_is_refused_as_in_a_graph(tmp_path, small):
    code, tail = cli_tail(tmp_path, small, "ao", {"method": "gtao", "rays": 8})
    with pytest.raises(ph.ParameterError) as e:
        ph.node("ao", ph.read(small[1]), method="gtao", rays=8)
    assert code == 2 and str(e.value).split(": ", 1)[1] == tail


def test_call_errors(small):
    frame = ph.read(small[1])
    with pytest.raises(ph.GraphError, match='unknown node type "grde" \\(did you mean "grade"\\?\\)'):
        ph.node("grde", frame)
    with pytest.raises(ph.GraphError, match="3 frames given, but it has 2 input port"):
        ph.node("grade", frame, frame, frame)
    with pytest.raises(ph.GraphError, match='no input port "matte"'):
        ph.node("grade", frame, matte=frame)
    with pytest.raises(ph.GraphError, match='input "image"'):
        ph.node("grade")
    with pytest.raises(TypeError, match="has no JSON form"):
        ph.node("grade", frame, gain=object())


def test_missing_pass_and_camera_are_run_errors(tmp_path, small, rgba):
    bare = ph.Frame(passes={"color": rgba})
    with pytest.raises(ph.RunError) as e:
        ph.node("ao", bare)
    assert e.value.exit_code == 1 and '"depth"' in str(e.value)
    with_depth = ph.Frame(passes={"color": rgba, "depth": np.full((16, 24), 3.0, np.float32),
                                  "normal": np.dstack([np.zeros((16, 24, 2)), np.ones((16, 24))]).astype(np.float32)})
    with pytest.raises(ph.RunError, match="camera"):
        ph.node("ao", with_depth)
    # The same refusal as the CLI gives for the same file.
    path = tmp_path / "bare.exr"
    ph.write(with_depth, path)
    code, line, _ = run_graph_cli(tmp_path, "ao", {}, path)
    with pytest.raises(ph.RunError) as e:
        ph.node("ao", ph.read(path))
    assert code == 1 and str(e.value).split(": ", 1)[1] == line.split(": ", 1)[1]


def test_file_errors_are_the_clis(tmp_path, small):
    truncated = tmp_path / "truncated.exr"
    truncated.write_bytes(small[1].read_bytes()[:3000])
    text = tmp_path / "text.exr"
    text.write_text("not an image\n")
    for path in (tmp_path / "missing.exr", truncated, text):
        code, line, _ = run_graph_cli(tmp_path, "grade", {}, path)
        with pytest.raises(ph.RunError) as e:
            ph.read(path)
        assert e.value.exit_code == code == 1
        assert str(e.value) == line, path
    # A folder that cannot be made (a file stands in its way): one line naming the output.
    (tmp_path / "a_file").write_text("")
    with pytest.raises(ph.RunError) as e:
        ph.write(ph.read(small[1]), tmp_path / "a_file" / "out.exr")
    assert e.value.exit_code == 1 and "out.exr" in str(e.value)


def test_non_finite_pixels_stay_finite_through_a_node(rgba):
    bad = rgba.copy()
    bad[0, 0, 0] = np.nan
    bad[1, 1, 1] = np.inf
    out = ph.node("bloom", ph.Frame(passes={"color": bad}), intensity=0.2)
    assert out.passes["color"].shape == bad.shape


def test_diff_reports_metrics(rgba):
    a = ph.Frame(passes={"color": rgba})
    b = ph.Frame(passes={"color": rgba + 0.5})
    report = ph.diff(a, b, fail=0.1, warn=0.01)
    assert report["verdict"] == "FAILURE" and report["exit_code"] == 2
    color = report["passes"][0]
    assert color["name"] == "color" and color["verdict"] == "FAILURE"
    assert abs(color["stats"]["max_error"] - 0.5) < 1e-6 and color["stats"]["rms_error"] > 0.3
    assert ph.diff(a, a)["verdict"] == "PASS"
    with pytest.raises(ph.GraphError, match='unknown option "failz"'):
        ph.diff(a, b, failz=1)


@pytest.mark.parametrize("node_type,extra", [("fog", {"model": "height"}), ("ssr", {}), ("ssgi", {})])
def test_a_zero_sun_is_refused_alike_by_every_node_that_reads_it(small, node_type, extra):
    with pytest.raises(ph.RunError) as e:
        ph.node(node_type, ph.read(small[1]), sun_direction=[0, 0, 0], **extra)
    assert str(e.value).endswith(': param "sun_direction" (header posthaste:sunDirection) must be '
                                 "a non-zero finite vector")
    if node_type != "fog":
        # A negative irradiance in the graph is refused with the graph, before any frame runs
        # (one from the header at the frame, naming the header attribute).
        with pytest.raises(ph.ParameterError, match='param "sun_irradiance": expected array of 3 '
                                                    "numbers >= 0"):
            ph.node(node_type, ph.read(small[1]), sun_irradiance=[1, -1, 1], **extra)


def test_a_cycles_frame_reads_with_its_solved_camera_and_gives_the_clis_pixels(tmp_path):
    # A Blender 3.4 / Cycles render (samples/cycles): no camera in its header, filtered passes.
    from conftest import SOURCE_DIR
    source = SOURCE_DIR / "samples" / "cycles" / "yard.passes.exr"
    frame = ph.read(source)
    assert frame.camera["origin"].startswith("solved from position + depth")
    assert frame.camera["worldToNDC"].shape == (4, 4)
    code, line, out = run_graph_cli(tmp_path, "ao", {"radius": 2.0}, source)
    assert code == 0, line
    mine = ph.node("ao", frame, radius=2.0)
    np.testing.assert_array_equal(mine.passes["color"], ph.read(out).passes["color"])


def test_an_edited_file_is_loaded_again(tmp_path, scene):
    # ph.node keeps a node's state between calls (a scene, a LUT); an edit of the file between
    # calls is seen (the scene rendered as before, bit for bit).
    import shutil
    copy = tmp_path / "scene.json"
    shutil.copy(scene, copy)
    first = ph.node("render", scene=str(copy), width=16, height=12, frame=1).passes["color"].copy()
    again = ph.node("render", scene=str(copy), width=16, height=12, frame=1).passes["color"]
    np.testing.assert_array_equal(first, again)
    data = json.loads(copy.read_text())
    data["sky_ambient"] = data.get("sky_ambient", 1.0) * 3.0 + 1.0
    copy.write_text(json.dumps(data))
    edited = ph.node("render", scene=str(copy), width=16, height=12, frame=1).passes["color"]
    assert not np.array_equal(first, edited)
