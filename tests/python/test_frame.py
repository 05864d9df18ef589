"""posthaste.Frame: passes as numpy arrays over the frame's own memory, copy-on-write when shared,
frames made from numpy, camera, attributes and windows."""

import numpy as np
import pytest

import posthaste as ph


def test_pass_arrays_view_the_frames_memory(small):
    frame = ph.read(small[1])
    color = frame.passes["color"]
    assert color.dtype == np.float32 and color.shape == (54, 96, 4)
    # No copy: the array's data is the pass image's memory, and asking again gives the same.
    assert color.ctypes.data == frame._data_address("color")
    assert frame.passes["color"].ctypes.data == color.ctypes.data
    assert frame.owns("color") and color.flags.writeable


def test_a_write_through_the_array_shows_in_the_frame_and_the_nodes(small):
    frame = ph.read(small[1])
    color = frame.passes["color"]
    color[5, 7, :3] = [3.0, 2.0, 1.0]
    assert list(frame.passes["color"][5, 7, :3]) == [3.0, 2.0, 1.0]
    # A node sees the written pixel: grade with gain 2 doubles it.
    out = ph.node("grade", frame, gain=[2, 2, 2])
    assert list(out.passes["color"][5, 7, :3]) == [6.0, 4.0, 2.0]
    # The written pass reaches a file.
    np.testing.assert_array_equal(ph.node("channels", frame).passes["color"], frame.passes["color"])


def test_shared_passes_are_read_only_and_writable_copies(small):
    frame = ph.read(small[1])
    assert frame.owns("depth")
    # No array of depth alive: the node's output shares the frame's image, no copy.
    out = ph.node("grade", frame, gain=[2, 2, 2])
    assert not frame.owns("depth") and not out.owns("depth")
    assert out._data_address("depth") == frame._data_address("depth")
    shared = frame.passes["depth"]
    assert not shared.flags.writeable
    with pytest.raises(ValueError):
        frame.passes["depth"][0, 0, 0] = 1.0
    # writable() gives the frame its own copy; the node's output keeps the old pixels.
    mine = frame.writable("depth")
    assert frame._data_address("depth") != out._data_address("depth")
    mine[0, 0, 0] = -5.0
    assert frame.passes["depth"][0, 0, 0] == -5.0
    assert out.passes["depth"][0, 0, 0] != -5.0
    # The color the node replaced is the node's own.
    assert out.owns("color")


def test_writable_arrays_and_their_views_never_reach_a_shared_frame(small):
    # A pass with a writable array alive is handed to a node as a copy: the array, and every
    # view of it (numpy keeps a view's own writeable flag), stay writable and change this frame
    # only. Clearing the array's flag had left d = a[..., 0] writing into the node's output.
    f = ph.read(small[1])
    a = f.passes["depth"]
    d = a[..., 0]
    flat = a.reshape(-1)
    g = ph.node("exposure", f, exposure=1)
    before = float(g.passes["depth"][0, 0, 0])
    d[0, 0] = 9.0
    flat[1] = 7.0
    assert a.flags.writeable and f.owns("depth")
    assert f.passes["depth"][0, 0, 0] == 9.0 and f.passes["depth"][0, 1, 0] == 7.0
    assert g.passes["depth"][0, 0, 0] == before
    # Written before the share, a value reaches the node.
    a[2, 2, 0] = 3.5
    assert ph.node("exposure", f, exposure=1).passes["depth"][2, 2, 0] == 3.5
    assert f.copy().passes["depth"][2, 2, 0] == 3.5
    # Once the arrays are gone the frame shares its image again.
    del a, d, flat
    h = ph.node("exposure", f, exposure=1)
    assert h._data_address("depth") == f._data_address("depth")


@pytest.mark.parametrize("dtype", [np.float16, np.float32, np.float64])
def test_frame_from_numpy(dtype, rgba):
    depth = np.linspace(1, 2, 16 * 24).reshape(16, 24).astype(dtype)
    f = ph.Frame(passes={"color": rgba.astype(dtype), "depth": depth}, number=12)
    assert (f.width, f.height, f.number) == (24, 16, 12)
    assert f.display_window == (0, 0, 24, 16) == f.data_window
    np.testing.assert_array_equal(f.passes["color"], rgba.astype(dtype).astype(np.float32))
    assert f.passes["depth"].shape == (16, 24, 1)
    assert f.channels("color") == ["R", "G", "B", "A"]
    assert f.channels("depth") == ["Z"]
    # Converted once: the frame holds its own float32 copy.
    assert f.owns("color") and f.passes["color"].ctypes.data != rgba.ctypes.data


def test_frame_from_numpy_refuses_what_is_not_a_pass(rgba):
    with pytest.raises(ValueError, match='pass "color": dtype int32 is not float16, float32 or float64'):
        ph.Frame(passes={"color": rgba.astype(np.int32)})
    with pytest.raises(ValueError, match='pass "color": expected shape'):
        ph.Frame(passes={"color": rgba[None]})
    with pytest.raises(ValueError, match='pass "depth": 8x8, but the frame\'s data window is 24x16'):
        ph.Frame(passes={"color": rgba, "depth": np.zeros((8, 8), np.float32)})
    with pytest.raises(ValueError, match='pass "n": expected a numpy array, got list'):
        ph.Frame(passes={"n": [[1.0]]})
    with pytest.raises(ValueError, match='pass "x": 65 channels'):
        ph.Frame(passes={"x": np.zeros((2, 2, 65), np.float32)})
    with pytest.raises(ValueError, match="display_window: expected"):
        ph.Frame(passes={"color": rgba}, display_window=(0, 0, 4))


def test_windows_camera_and_attributes_round_trip(tmp_path, rgba):
    w2c = np.eye(4, dtype=np.float32)
    w2c[3, 2] = 5.0  # a translation, in OpenEXR's row-vector convention
    f = ph.Frame(passes={"color": rgba}, display_window=(0, 0, 20, 12), data_window=(-2, -2, 22, 14),
                 camera={"worldToCamera": w2c, "focalLength": 35.0},
                 attributes={"studio:artist": "test", "take": 3, "gains": [0.5, 2.0], "tags": ["a", "b"]})
    path = tmp_path / "f.exr"
    ph.write(f, path, storage="float")
    g = ph.read(path)
    assert g.display_window == (0, 0, 20, 12) and g.data_window == (-2, -2, 22, 14)
    np.testing.assert_array_equal(g.passes["color"], rgba)
    np.testing.assert_array_equal(g.camera["worldToCamera"], w2c)
    assert g.camera["focalLength"] == 35.0
    assert g.attributes["studio:artist"] == "test" and g.attributes["take"] == 3
    assert g.attributes["gains"] == [0.5, 2.0] and g.attributes["tags"] == ["a", "b"]
    with pytest.raises(ValueError, match='camera: unknown key "worldToCam"'):
        f.camera = {"worldToCam": w2c}
    with pytest.raises(ValueError, match='camera "worldToNDC": expected a 4x4 matrix'):
        f.camera = {"worldToNDC": np.eye(3)}


def test_passes_mapping(rgba):
    f = ph.Frame(passes={"color": rgba})
    f.passes["mask"] = np.ones((16, 24), np.float32)
    assert "mask" in f.passes and len(f.passes) == 2 and sorted(f.passes) == ["color", "mask"]
    del f.passes["mask"]
    assert "mask" not in f.passes and f.passes.get("mask") is None
    with pytest.raises(KeyError, match='no pass "mask" in the frame \\(it has: color\\)'):
        f.passes["mask"]
    # A replaced pass keeps its channel names; arrays of the old image stay valid.
    old = f.passes["color"]
    f.passes["color"] = rgba * 2
    assert f.channels("color") == ["R", "G", "B", "A"]
    np.testing.assert_array_equal(old, rgba)
    np.testing.assert_array_equal(f.passes["color"], rgba * 2)


def test_passes_given_without_channel_names_get_a_readers_names(tmp_path, rgba):
    # A three-channel colour is R, G, B in the file (it was "0", "1", "2"), one channel is Y.
    f = ph.Frame(passes={"color": rgba[:, :, :3], "mask": rgba[:, :, 0], "beauty": rgba[:, :, :3]})
    assert f.channels("color") == ["R", "G", "B"]
    assert f.channels("mask") == ["Y"] and f.channels("beauty") == ["R", "G", "B"]
    path = tmp_path / "rgb.exr"
    ph.write(f, path, storage="float")
    g = ph.read(path)
    np.testing.assert_array_equal(g.passes["color"][:, :, :3], rgba[:, :, :3])
    assert g.channels("beauty") == ["R", "G", "B"] and g.channels("mask") == ["Y"]


def test_arrays_outlive_their_frame(small):
    color = ph.read(small[1]).passes["color"]
    reference = ph.read(small[1]).passes["color"].copy()
    np.testing.assert_array_equal(color, reference)


def test_numbered_channels_come_back_in_their_order(tmp_path):
    # EXR sorts a part's channels by name: 0, 1, 10, 11, 2, ... came back in that order.
    a = np.random.default_rng(3).random((8, 8, 12), dtype=np.float32)
    ph.write(ph.Frame(passes={"aov": a}), tmp_path / "o.exr", storage="float")
    r = ph.read(tmp_path / "o.exr")
    assert r.channels("aov") == [str(k) for k in range(12)]
    np.testing.assert_array_equal(r.passes["aov"], a)


def test_reassigned_attributes_keep_their_file_types(tmp_path):
    """A dict of attributes given back (unchanged, or one value edited) keeps each attribute's
    type where the value fits it: a time code came back as two ints and was dropped, a float
    vector of three as a v3f, and deleting one attribute meant giving the whole dict back."""
    import shutil
    import subprocess

    from conftest import cli_binary

    if not shutil.which("oiiotool"):
        pytest.skip("oiiotool is not installed")
    src = tmp_path / "typed.exr"
    subprocess.run(["oiiotool", "--create", "4x4", "3",
                    "--attrib:type=timecode", "smpte:TimeCode", "01:02:03:04",
                    "--attrib", "studio:note", "kept", "-o", str(src)], check=True)

    def info(path):
        return subprocess.run([cli_binary(), "info", str(path)], capture_output=True,
                              text=True, check=True).stdout

    frame = ph.read(src)
    frame.attributes = dict(frame.attributes)
    ph.write(frame, tmp_path / "same.exr")
    assert "smpte:TimeCode     timecode = 01:02:03:04" in info(tmp_path / "same.exr")

    attributes = dict(frame.attributes)
    del attributes["studio:note"]
    attributes["studio:floats"] = [1.0, 2.0, 3.0]
    frame.attributes = attributes
    ph.write(frame, tmp_path / "edited.exr")
    text = info(tmp_path / "edited.exr")
    assert "smpte:TimeCode     timecode = 01:02:03:04" in text
    assert not any(line.split()[:1] == ["studio:note"] for line in text.splitlines())
    assert "studio:floats      float[3] = 1, 2, 3" in text  # a floatvector, as given


def test_a_value_for_an_attribute_the_frame_holds_is_checked_as_a_new_one(tmp_path):
    """A name the frame held kept its type, and that path skipped the checks: a null cut the
    string short in the file, 1e40 became inf, 2**70 was pybind11's "Unable to cast"."""
    f = ph.Frame(passes={"color": np.zeros((2, 2, 4), np.float32)})
    f.attributes = {"owner": "x", "fx": 1.0, "i": 1, "v": [1.0, 2.0]}
    for attrs, error, message in [
        ({"owner": "a\x00b"}, ValueError, 'attribute "owner": embedded null character'),
        ({"owner": "\ud800"}, ValueError, 'attribute "owner": not valid UTF-8 text'),
        ({"fx": 1e40}, ValueError, 'attribute "fx": 1e\\+40 does not fit an EXR float'),
        ({"v": [1.0, 1e40]}, ValueError, 'attribute "v": 1e\\+40 does not fit an EXR float'),
        ({"i": 2**70}, ValueError, 'attribute "i": 1180591620717411303424 does not fit an EXR int'),
        ({"j": 2**70}, ValueError, 'attribute "j": 1180591620717411303424 does not fit an EXR int'),
        ({"j": [1.0, 2**1100]}, ValueError, 'attribute "j": .* does not fit an EXR float'),
        ({"\ud800": 1}, ValueError, "attribute '\\\\ud800': not valid UTF-8 text"),
    ]:
        with pytest.raises(error, match=message) as e:
            f.attributes = attrs
        assert "\n" not in str(e.value)
    assert f.attributes == {"owner": "x", "fx": 1.0, "i": 1, "v": [1.0, 2.0]}  # left as it was
    f.attributes = {"owner": "y", "fx": 2.5, "i": 3, "v": [3.0, 4.0]}
    ph.write(f, tmp_path / "a.exr")
    back = ph.read(tmp_path / "a.exr").attributes
    assert (back["Copyright"], back["fx"], back["i"], list(back["v"])) == ("y", 2.5, 3, [3.0, 4.0])


def test_the_camera_takes_only_values_it_can_hold():
    """1e40 became inf, a complex number its real part (with only a ComplexWarning), a matrix of
    strings was parsed, a null in origin cut it short; 2**1100 was pybind11's "Unable to cast"."""
    f = ph.Frame(passes={"color": np.zeros((2, 2, 4), np.float32)})
    eye = np.eye(4)
    for camera, error, message in [
        ({"focalLength": 1e40}, ValueError, 'camera "focalLength": 1e\\+40 does not fit a float'),
        ({"focalLength": 2**1100}, ValueError, 'camera "focalLength": 1358.*does not fit a float'),
        ({"focalLength": np.complex128(1 + 2j)}, TypeError, 'camera "focalLength": expected a number'),
        ({"worldToCamera": eye * (1 + 1j)}, TypeError,
         'camera "worldToCamera": expected a 4x4 matrix of real numbers, got complex128'),
        ({"worldToCamera": [[str(x) for x in row] for row in eye]}, TypeError,
         'camera "worldToCamera": expected a 4x4 matrix of real numbers'),
        ({"origin": "a\x00b"}, ValueError, 'camera "origin": embedded null character'),
        ({"\ud800": 1.0}, ValueError, "camera: key '\\\\ud800': not valid UTF-8 text"),
    ]:
        with pytest.raises(error, match=message) as e:
            f.camera = camera
        assert "\n" not in str(e.value) and len(str(e.value)) < 200, str(e.value)
    f.camera = {"worldToCamera": eye.astype(np.int64), "focalLength": np.float32(35), "origin": "x"}
    assert f.camera["focalLength"] == 35.0 and f.camera["origin"] == "x"
    assert (f.camera["worldToCamera"] == eye).all()


def test_names_with_a_null_or_a_lone_surrogate_are_refused():
    """A null cut the pass "a\\0b" to "a" and the channel "x\\0y" to "x" in the file; a lone
    surrogate was pybind11's "Unable to cast Python instance to C++ type"."""
    z = np.zeros((2, 2, 2), np.float32)
    f = ph.Frame(passes={"color": z})
    for call, message in [
        (lambda: ph.Frame(passes={"a\x00b": z}), "passes: pass name 'a\\\\x00b': embedded null"),
        (lambda: ph.Frame(passes={"\ud800": z}), "passes: pass name '\\\\ud800': not valid UTF-8"),
        (lambda: f.passes.__setitem__("a\x00b", z), "pass name 'a\\\\x00b': embedded null"),
        (lambda: f.set_pass("\ud800", z), "Frame.set_pass: pass name '\\\\ud800': not valid UTF-8"),
        (lambda: ph.Frame(passes={"c": z}, channels={"c": ["x\x00y", "b"]}),
         "pass \"c\": channel name 'x\\\\x00y': embedded null character"),
        (lambda: ph.Frame(passes={"c": z}, channels={"c": ["\ud800", "b"]}),
         "pass \"c\": channel name '\\\\ud800': not valid UTF-8"),
    ]:
        with pytest.raises(ValueError, match=message):
            call()
    assert list(f.passes) == ["color"]


def test_pass_names_of_the_wrong_type_and_missing_passes():
    """writable/channels/set_pass gave pybind11's several-line TypeError naming no argument;
    owns() of a missing pass was a RunError where the others are KeyErrors; channels for a pass
    not given were ignored without a word."""
    f = ph.Frame(passes={"color": np.zeros((2, 2, 4), np.float32)})
    for call, name in [(lambda: f.writable(5), "writable"), (lambda: f.channels(5), "channels"),
                       (lambda: f.owns(5), "owns"), (lambda: f.set_pass(5, np.zeros((2, 2))), "set_pass")]:
        with pytest.raises(TypeError, match=f"posthaste.Frame.{name}: pass names are str, got int 5") as e:
            call()
        assert "\n" not in str(e.value)
    for call in [lambda: f.owns("nope"), lambda: f.writable("nope"), lambda: f.channels("nope")]:
        with pytest.raises(KeyError, match='no pass "nope" in the frame'):
            call()
    assert f.owns("color")
    with pytest.raises(ValueError, match='channels: no pass "c" in passes'):
        ph.Frame(channels={"c": ["R"]})
    assert ph.Frame(channels={}).passes.keys() == []
