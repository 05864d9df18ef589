"""Every invalid graph of tests/invalid raises the CLI's error from Python: posthaste.GraphError
(ParameterError for a parameter), exit code 2, and the very line `posthaste run` prints."""

from pathlib import Path

import numpy as np
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


def test_thread_and_job_counts_are_bounded_as_the_cli_bounds_them(tmp_path):
    # A pool of 100000 threads failed every later EXR read of the process.
    for n in (-1, 1025, 100000):
        with pytest.raises(ValueError, match=f"threads: expected 0 \\(every core\\) to 1024, got {n}"):
            ph.set_threads(n)
    graph = ph.Graph.from_dict({"nodes": [
        {"id": "src", "type": "render", "params": {"scene": ph_scene(), "width": 8, "height": 8}},
        {"id": "out", "type": "write", "inputs": {"image": "src"},
         "params": {"path": str(tmp_path / "f.####.exr")}}]})
    with pytest.raises(ValueError, match="threads: expected"):
        graph.run(frames="1", threads=-3)
    with pytest.raises(ValueError, match="jobs: expected"):
        graph.run(frames="1", jobs=-3)


def test_an_int_attribute_must_fit_32_bits():
    import numpy as np
    with pytest.raises(ValueError, match='attribute "big": 1099511627776 does not fit'):
        ph.Frame(passes={"color": np.zeros((2, 2, 4), np.float32)}, attributes={"big": 2**40})
    with pytest.raises(ValueError, match='attribute "list": 8589934592 does not fit'):
        ph.Frame(passes={"color": np.zeros((2, 2, 4), np.float32)}, attributes={"list": [1, 2**33]})
    f = ph.Frame(passes={"color": np.zeros((2, 2, 4), np.float32)}, attributes={"edge": -2**31})
    assert f.attributes["edge"] == -2**31


def ph_scene():
    from conftest import SCENE
    return SCENE


def test_bad_arguments_name_what_they_are():
    # pybind11's own message named nothing: "Unable to cast Python instance to C++ type".
    import numpy as np
    f = ph.Frame(passes={"color": np.zeros((4, 4, 4), np.float32)})
    with pytest.raises(TypeError, match='posthaste.node\\("grade"\\): input "image": expected a posthaste.Frame, got ndarray'):
        ph.node("grade", np.ones((4, 4)))
    with pytest.raises(TypeError, match='posthaste.node\\("grade"\\): frame: expected an int \\(32 bits\\), got str'):
        ph.node("grade", f, frame="3")
    with pytest.raises(TypeError, match="frame: expected an int"):
        ph.node("grade", f, frame=2**40)
    with pytest.raises(ph.Error, match='input "image" given twice'):
        ph.node("grade", f, image=f)
    with pytest.raises(ValueError, match='param "seed": 1180591620717411303424 does not fit 64 bits'):
        ph.node("grain", f, seed=2**70)
    # NaN became JSON null, and the error said "got null".
    with pytest.raises(ValueError, match='param "exposure": expected a finite number, got nan'):
        ph.node("exposure", f, exposure=float("nan"))
    with pytest.raises(TypeError, match="posthaste.diff: expected a posthaste.Frame or a path, got NoneType"):
        ph.diff(f, None)
    with pytest.raises(TypeError, match="posthaste.diff: passes: expected a list of pass names, got a str"):
        ph.diff(f, f, passes="color")
    with pytest.raises(TypeError, match="posthaste.diff: fail: expected a number, got str"):
        ph.diff(f, f, fail="0.1")
    with pytest.raises(ph.Error, match="posthaste.diff: allow_failures: must be 0 or more, got -5"):
        ph.diff(f, f, allow_failures=-5)
    with pytest.raises(TypeError, match="Graph.load: path: expected a str or os.PathLike, got 5"):
        ph.Graph.load(5)


def test_an_array_too_large_for_the_budget_is_a_posthaste_error():
    # numpy's float32 temporary failed first, and pybind11 reported its own internal error.
    import numpy as np
    huge = np.broadcast_to(np.float32(1), (16384, 16384, 64))
    with pytest.raises(ph.Error, match="too large|memory"):
        ph.Frame(passes={"x": huge})


def test_channel_names_and_camera_keys_are_checked():
    import numpy as np
    rgb = np.zeros((2, 2, 2), np.float32)
    # "a.b" came back from the file as a pass of its own; a misspelt key was ignored.
    with pytest.raises(ValueError, match='pass "spec": channel name "a.b" \\(names are unique, not empty, without a dot\\)'):
        ph.Frame(passes={"spec": rgb}, channels={"spec": ["a.b", "c"]})
    with pytest.raises(ValueError, match='channel name ""'):
        ph.Frame(passes={"spec": rgb}, channels={"spec": ["", "c"]})
    with pytest.raises(ValueError, match='channel name "c"'):
        ph.Frame(passes={"spec": rgb}, channels={"spec": ["c", "c"]})
    with pytest.raises(ValueError, match='channels: no pass "sepc" in passes'):
        ph.Frame(passes={"spec": rgb}, channels={"sepc": ["u", "v"]})
    with pytest.raises(TypeError, match='pass "spec": channels: expected a list of names, got a str'):
        ph.Frame(passes={"spec": rgb}, channels={"spec": "uv"})
    # The attribute replaced the camera's value in the file.
    with pytest.raises(ValueError, match='attribute "focalLength" is a camera value: give it in camera='):
        ph.Frame(passes={"spec": rgb}, camera={"focalLength": 50.0}, attributes={"focalLength": 35.0})
    with pytest.raises(TypeError, match='camera "focalLength": expected a number, got \'35\''):
        ph.Frame(passes={"spec": rgb}, camera={"focalLength": "35"})


def test_attributes_the_file_cannot_hold_are_refused(tmp_path):
    """What a write would drop or change is an error when given, not a surprise in the file:
    reserved names, int lists OpenEXR has no type for, floats beyond float's range, strings with
    a null; numpy's scalars are numbers like Python's."""
    color = {"color": np.zeros((2, 2, 4), np.float32)}
    for attrs, message in [
        ({"compression": "zip"}, 'attribute "compression" is not the picture\'s'),
        ({"": 1}, 'attribute "" is not the picture\'s'),
        ({"k": [7]}, 'attribute "k": OpenEXR holds 2 or 3 ints'),
        ({"k": [1, 2, 3, 4]}, 'attribute "k": OpenEXR holds 2 or 3 ints'),
        ({"k": 1e40}, 'attribute "k": 1e\\+40 does not fit an EXR float'),
        ({"k": [1.0, 1e40]}, 'attribute "k": 1e\\+40 does not fit an EXR float'),
        ({"k": "a\x00b"}, 'attribute "k": embedded null character'),
    ]:
        with pytest.raises(ValueError, match=message):
            ph.Frame(passes=color, attributes=attrs)
    f = ph.Frame(passes=color,
                 attributes={"f": np.float32(2.5), "i": np.int64(3), "b": np.bool_(True),
                             "v": [1, 2, 3], "w": [1.5] * 5})
    ph.write(f, tmp_path / "a.exr")
    back = ph.read(tmp_path / "a.exr").attributes
    assert back["f"] == 2.5 and back["i"] == 3 and back["b"] == 1
    assert list(back["v"]) == [1, 2, 3] and list(back["w"]) == [1.5] * 5


def test_paths_with_a_null_character_are_refused(tmp_path):
    """The system sees a path up to its null: "precious\\0.exr" wrote the file "precious"."""
    f = ph.Frame(passes={"color": np.zeros((2, 2, 4), np.float32)})
    target = tmp_path / "precious"
    target.write_text("keep")
    with pytest.raises(ValueError, match='param "path": embedded null character'):
        ph.write(f, str(target) + "\x00.exr")
    assert target.read_text() == "keep"
    with pytest.raises(ValueError, match="embedded null character"):
        ph.read(str(tmp_path / "a.exr") + "\x00junk")


def test_inputs_and_windows_are_checked():
    """None leaves an input out (mask=None), anything else but a Frame on a port is a TypeError
    naming it; a window wider than 2^30 is refused (a width of 2^31 overflowed and reformat
    crashed); a pass map holds names only."""
    f = ph.Frame(passes={"color": np.full((2, 2, 4), 0.5, np.float32)})
    assert np.array_equal(np.asarray(ph.node("grade", f, mask=None).passes["color"]),
                          np.asarray(ph.node("grade", f).passes["color"]))
    with pytest.raises(TypeError, match='input "image": expected a Frame, got ndarray'):
        ph.node("grade", image=np.zeros((2, 2, 3)))
    with pytest.raises(ValueError, match="display_window: wider or taller than 2\\^30"):
        f.display_window = (-2**30, -2**30, 2**30, 2**30)
    assert 0 not in f.passes and "color" in f.passes


def test_reading_a_pass_over_and_over_keeps_its_memory():
    """Each writable array left a weak reference behind (84 MB a million reads)."""
    import resource
    f = ph.Frame(passes={"color": np.zeros((2, 2, 4), np.float32)})
    for _ in range(20000):
        f.passes["color"][0, 0, 0]
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    for _ in range(300000):
        f.passes["color"][0, 0, 0]
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 8 * 1024  # KiB


def test_wrong_types_name_the_argument(tmp_path):
    """pybind11's "Unable to cast Python instance to C++ type" named nothing."""
    color = {"color": np.zeros((2, 2, 4), np.float32)}
    with pytest.raises(TypeError, match='camera "origin": expected a string, got 5'):
        ph.Frame(passes=color, camera={"origin": 5})
    with pytest.raises(TypeError, match=r'pass "c": channels: expected a list of names, got \[1, 2\]'):
        ph.Frame(passes={"c": np.zeros((2, 2, 2), np.float32)}, channels={"c": [1, 2]})
    with pytest.raises(ph.GraphError, match="is a directory, not a graph file"):
        ph.Graph.load(tmp_path)
    g = ph.Graph.load(ph_scene().replace("samples/scenes/minecrappy.json", "graphs/minecrappy.json"))
    with pytest.raises(TypeError, match="Graph.run: frames: expected frame numbers \\(ints\\), got '1'"):
        g.run(frames=["1"])
    with pytest.raises(TypeError, match="got 1.0"):
        g.run(frames=1.0)
    with pytest.raises(ValueError, match="1099511627776 does not fit 32 bits"):
        g.run(frames=[2**40])


def test_arguments_of_the_wrong_type_are_named_on_one_line():
    """pybind11 listed the supported signatures over several lines and named no argument."""
    color = np.zeros((2, 2, 3), np.float32)
    f = ph.Frame(passes={"color": color})
    cases = [
        (lambda: ph.set_threads("2"), "set_threads(): threads: expected an int, got str '2'"),
        (lambda: setattr(f, "number", "x"), "posthaste.Frame.number: expected an int"),
        (lambda: ph.Frame(number="x"), "number: expected an int"),
        (lambda: ph.Frame(passes=[1]), "passes: expected a dict {name: array}, got list"),
        (lambda: ph.Frame(passes={1: color}), "passes: pass names are str, got int 1"),
        (lambda: f.passes[0], "posthaste.Passes: pass names are str, got int 0"),
        (lambda: f.passes.__setitem__(0, color), "posthaste.Passes: pass names are str"),
        (lambda: f.passes.__delitem__(0), "posthaste.Passes: pass names are str"),
        (lambda: f.passes.get(0), "posthaste.Passes.get: pass names are str"),
        (lambda: ph.read("x.exr", frame="1"), "frame: expected an int"),
        (lambda: ph.write(1, "x.exr"), "expected a posthaste.Frame, got int"),
        (lambda: ph.Graph.from_dict({"nodes": []}, base_dir=3), "base_dir: expected a str, got int 3"),
    ]
    for call, message in cases:
        with pytest.raises(TypeError) as e:
            call()
        assert message in str(e.value), str(e.value)
        assert "\n" not in str(e.value), str(e.value)
    f.number = 7  # the right types still work
    assert f.number == 7
    assert ph.Frame(passes={"color": color}, number=3).number == 3


def test_a_crop_to_the_display_window_with_no_pixel_inside_is_refused(tmp_path):
    """The data window lay wholly outside the display window and was written uncut."""
    f = ph.Frame(passes={"color": np.ones((4, 4, 3), np.float32)},
                 display_window=(0, 0, 8, 8), data_window=(20, 20, 24, 24))
    out = tmp_path / "x.exr"
    with pytest.raises(ph.Error, match=r"crop display: the data window \(20,20\)-\(23,23\) lies "
                       r"outside the display window \(0,0\)-\(7,7\)"):
        ph.write(f, str(out), crop="display")
    assert not out.exists()
    ph.write(f, str(out))  # uncut: the overscan as it is
    assert ph.read(str(out)).data_window == (20, 20, 24, 24)


def test_a_preview_without_colour_names_its_file_once(tmp_path):
    """The node's prefix came twice ("node "write" (write), frame 1: node "write" ...")."""
    f = ph.Frame(passes={"depth": np.ones((4, 4), np.float32)})
    out = tmp_path / "x.png"
    with pytest.raises(ph.Error) as e:
        ph.write(f, str(out))
    message = str(e.value)
    assert message.count('node "write"') == 1, message
    assert str(out) in message and 'no pass "color"' in message, message
    assert not out.exists()


def test_a_byte_that_is_not_utf8_comes_back_escaped(tmp_path):
    # nlohmann's error quotes the bytes it last read; a raw 0xff made the message undecodable.
    graph = tmp_path / "bad_byte.json"
    graph.write_bytes(b'{"nodes": [{"id": "a\xff"}]}')
    with pytest.raises(ph.GraphError) as e:
        ph.Graph.load(str(graph))
    assert "last read: '\"a\\xff'" in str(e.value)


def test_a_name_that_is_not_utf8_is_a_value_error_naming_the_parameter():
    # os.fsdecode gives a file name's non-UTF-8 bytes as lone surrogates; pybind11 said only
    # "Unable to cast Python instance to C++ type".
    with pytest.raises(ValueError, match='param "path": not valid UTF-8 text'):
        ph.read("/tmp/x\udcff.exr")


def test_node_names_and_parameters_with_a_null_or_a_lone_surrogate_are_refused():
    """A null cut the node type ("unknown node type "gr") or a parameter's name (a GraphError with
    a path and no reason); a lone surrogate or a non-str type was pybind11's "Unable to cast"
    or its several-line TypeError."""
    f = ph.Frame(passes={"color": np.zeros((2, 2, 4), np.float32)})
    for call, error, message in [
        (lambda: ph.node("gr\x00ade", f), ValueError, "posthaste.node: type: embedded null character"),
        (lambda: ph.node("\ud800", f), ValueError, "posthaste.node: type: not valid UTF-8"),
        (lambda: ph.node(5, f), TypeError, "posthaste.node: type: expected a node type \\(str\\), got int 5"),
        (lambda: ph.node("grade", f, **{"a\x00b": 1}), ValueError,
         "posthaste.node\\(\"grade\"\\): param 'a\\\\x00b': embedded null character"),
        (lambda: ph.node("grade", f, **{"\ud800": 1}), ValueError,
         "posthaste.node\\(\"grade\"\\): param '\\\\ud800': not valid UTF-8"),
        (lambda: ph.diff(f, f, **{"\ud800": 1}), ValueError, "posthaste.diff: option '\\\\ud800'"),
    ]:
        with pytest.raises(error, match=message) as e:
            call()
        assert "\n" not in str(e.value), str(e.value)
    assert ph.node("grade", f, gain=[2, 2, 2]).passes["color"].shape == (2, 2, 4)
