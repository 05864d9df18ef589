"""posthaste.Graph: runs over frames as the CLI does, evaluates to frames in memory, reports
progress on the calling thread, stops on Ctrl-C, and gives the same bits from several threads."""

import json
import os
import signal
import threading

import numpy as np
import pytest

import posthaste as ph
from conftest import run_cli


def graph_dict(scene, out, size=(64, 36), gain=(1.5, 1.0, 0.5)):
    return {"frames": "1-4", "nodes": [
        {"id": "scene", "type": "render", "params": {"scene": scene, "width": size[0], "height": size[1]}},
        {"id": "grade", "type": "grade", "inputs": {"image": "scene"}, "params": {"gain": list(gain)}},
        {"id": "dof", "type": "dof", "inputs": {"image": "grade"}, "params": {"samples": 16}},
        {"id": "write", "type": "write", "inputs": {"image": "dof"},
         "params": {"path": str(out), "passes": "color,depth", "storage": "float"}}]}


def pixels(path):
    f = ph.read(path)
    return {n: f.passes[n].copy() for n in f.passes}


def assert_same_pixels(a, b):
    pa, pb = pixels(a), pixels(b)
    assert pa.keys() == pb.keys()
    for n in pa:
        np.testing.assert_array_equal(pa[n], pb[n], err_msg=n)


def test_run_writes_what_the_cli_writes_and_reports_progress(tmp_path, scene):
    g = ph.Graph.from_dict(graph_dict(scene, tmp_path / "py.####.exr"))
    assert g.frames == [1, 2, 3, 4]
    assert ("dof", "dof") in g.nodes and g.outputs(2) == [str(tmp_path / "py.0002.exr")]
    seen = []
    result = g.run(progress=lambda frame, done, total: seen.append((frame, done, total)), jobs=2)
    assert sorted(result["frames"]) == [1, 2, 3, 4]
    assert sorted(f for f, _, _ in seen) == [1, 2, 3, 4]
    assert [d for _, d, _ in seen] == [1, 2, 3, 4] and {t for _, _, t in seen} == {4}
    assert set(result["node_seconds"]) == {"scene (render)", "grade (grade)", "dof (dof)", "write (write)"}
    path = tmp_path / "cli.json"
    path.write_text(json.dumps(graph_dict(scene, tmp_path / "cli.####.exr")))
    assert run_cli("run", path, "--quiet")[0] == 0
    for n in range(1, 5):
        assert_same_pixels(tmp_path / f"py.{n:04d}.exr", tmp_path / f"cli.{n:04d}.exr")


def test_load_with_overrides_and_frames(tmp_path, scene):
    path = tmp_path / "g.json"
    path.write_text(json.dumps(graph_dict(scene, "out.####.exr")))  # relative: beside the graph
    g = ph.Graph.load(path, set={"grade.gain": [2, 2, 2]})
    assert g.run(frames=[3])["frames"] == [3]
    ph.Graph.load(path).run(frames="3", set={"write.path": str(tmp_path / "plain.####.exr")})
    doubled = ph.read(tmp_path / "out.0003.exr").passes["color"]
    plain = ph.read(tmp_path / "plain.0003.exr").passes["color"]
    assert not np.array_equal(doubled, plain)
    with pytest.raises(ph.ParameterError, match='unknown param "gian"'):
        ph.Graph.load(path, set={"grade.gian": 2})


def test_evaluate_returns_frames_without_writing(tmp_path, scene):
    g = ph.Graph.from_dict(graph_dict(scene, tmp_path / "never.####.exr"))
    out = g.evaluate(2)
    assert list(out) == ["write"] and not any(tmp_path.iterdir())
    frame = out["write"]
    assert frame.number == 2 and {"color", "depth"} <= set(frame.passes)
    both = g.evaluate(2, outputs=["scene", "dof"])
    np.testing.assert_array_equal(both["dof"].passes["color"], frame.passes["color"])
    assert not np.array_equal(both["scene"].passes["color"], frame.passes["color"])
    with pytest.raises(ph.GraphError, match='no node "nope"'):
        g.evaluate(2, outputs=["nope"])
    # One id as a str is that node (it was taken letter by letter: no node "d").
    assert list(g.evaluate(2, outputs="dof")) == ["dof"]
    with pytest.raises(TypeError, match="Graph.evaluate: outputs: expected node ids, got 5"):
        g.evaluate(2, outputs=5)


def test_ctrl_c_stops_between_frames(tmp_path, scene):
    d = graph_dict(scene, tmp_path / "c.####.exr", size=(480, 270))
    d["frames"] = "1-48"
    g = ph.Graph.from_dict(d)
    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        g.run(jobs=1)
    timer.join()
    written = sorted(tmp_path.glob("c.*.exr"))
    assert 0 < len(written) < 48
    for path in written:  # every file written is whole
        assert ph.read(path).passes["color"].shape == (270, 480, 4)


def test_an_error_in_the_progress_callable_stops_the_run(tmp_path, scene):
    d = graph_dict(scene, tmp_path / "p.####.exr")
    d["frames"] = "1-12"

    def progress(frame, done, total):
        raise RuntimeError(f"stop at {done}")

    with pytest.raises(RuntimeError, match="stop at 1"):
        ph.Graph.from_dict(d).run(progress=progress, jobs=1)
    assert len(list(tmp_path.glob("p.*.exr"))) < 12


def test_a_failing_frame_is_a_run_error(tmp_path, scene):
    d = {"nodes": [
        {"id": "read", "type": "read", "params": {"path": str(tmp_path / "in.####.exr")}},
        {"id": "write", "type": "write", "inputs": {"image": "read"}, "params": {"path": str(tmp_path / "o.####.exr")}}]}
    ph.write(ph.node("render", scene=scene, width=16, height=16, frame=1), tmp_path / "in.0001.exr")
    (tmp_path / "in.0002.exr").write_text("broken")
    g = ph.Graph.from_dict(d)
    with pytest.raises(ph.RunError, match="in.0002.exr") as e:
        g.run(frames="1-2", jobs=1)
    assert e.value.exit_code == 1
    assert g.run(frames="1-2", jobs=1, skip_bad_frames=True)["frames"] == [1]


def test_two_threads_give_the_bits_of_one_at_a_time(tmp_path, scene):
    graphs = [ph.Graph.from_dict(graph_dict(scene, tmp_path / f"t{i}.####.exr", size=(160, 90), gain=g))
              for i, g in enumerate([(1.5, 1.0, 0.5), (0.5, 1.0, 2.0)])]
    for g in graphs:
        g.run(jobs=2)
    for i in range(2):
        for n in range(1, 5):
            os.rename(tmp_path / f"t{i}.{n:04d}.exr", tmp_path / f"seq{i}.{n:04d}.exr")
    errors = []

    def run(g):
        try:
            g.run(jobs=2)
        except Exception as e:  # noqa: BLE001 (reported below)
            errors.append(e)

    threads = [threading.Thread(target=run, args=(g,)) for g in graphs]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    for i in range(2):
        for n in range(1, 5):
            assert_same_pixels(tmp_path / f"t{i}.{n:04d}.exr", tmp_path / f"seq{i}.{n:04d}.exr")


def test_nodes_from_two_threads_give_the_bits_of_one_at_a_time(small):
    frame = ph.read(small[1])
    alone = [ph.node("dof", frame, fstop=f, samples=32).passes["color"].copy() for f in (1.4, 4.0)]
    results = [None, None]

    def run(i, f):
        results[i] = ph.node("dof", frame, fstop=f, samples=32).passes["color"].copy()

    threads = [threading.Thread(target=run, args=(i, f)) for i, f in enumerate((1.4, 4.0))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for a, b in zip(alone, results):
        np.testing.assert_array_equal(a, b)


def test_run_argument_errors(tmp_path, scene):
    g = ph.Graph.from_dict(graph_dict(scene, tmp_path / "x.####.exr"))
    with pytest.raises(ph.GraphError, match="frames") as e:
        g.run(frames="3-x")
    assert e.value.exit_code == 2
    with pytest.raises(ph.GraphError, match="empty list"):
        g.run(frames=[])
    with pytest.raises(ph.GraphError, match="max-memory"):
        g.run(max_memory="lots")
    with pytest.raises(ph.GraphError, match='from_dict:/nodes: expected a non-empty array of nodes'):
        ph.Graph.from_dict({"nodes": 3})
    assert not any(tmp_path.iterdir())


def test_an_absurd_size_is_refused_before_any_allocation(scene):
    code, line = run_cli("render", scene, "--size", "16384x16384", "-o", "/tmp/never.####.exr",
                         "--frames", "1")
    with pytest.raises(ph.Error) as e:
        ph.node("render", scene=scene, width=16384, height=16384, frame=1)
    assert code == e.value.exit_code != 0


def test_run_and_evaluate_arguments_are_checked_on_one_line(scene, tmp_path):
    """bytes ran as frame numbers (b"\\x01\\x02": frames 1 and 2); a wrong type was pybind11's
    several-line TypeError naming no argument; set="a=1" and set=[1] were dict()'s own
    message; a null in a set value cut "20\\0garbage" to 20."""
    g = ph.Graph.from_dict(graph_dict(scene, str(tmp_path / "o.####.exr"), size=(8, 8)))
    for call, error, message in [
        (lambda: g.run(frames=b"\x01\x02"), TypeError, "Graph.run: frames: expected frame numbers"),
        (lambda: g.run(frames=bytearray(b"\x01")), TypeError, "Graph.run: frames: expected frame numbers"),
        (lambda: g.run(frames=memoryview(b"\x01")), TypeError, "Graph.run: frames: expected frame numbers"),
        (lambda: g.run(frames="1\ud800"), ValueError, "Graph.run: frames: not valid UTF-8"),
        (lambda: g.run(jobs="2"), TypeError, "Graph.run: jobs: expected an int \\(32 bits\\), got str '2'"),
        (lambda: g.run(jobs=2**40), TypeError, "Graph.run: jobs: expected an int"),
        (lambda: g.run(threads=1.5), TypeError, "Graph.run: threads: expected an int"),
        (lambda: g.run(skip_existing="yes"), TypeError, "Graph.run: skip_existing: expected a bool"),
        (lambda: g.run(max_memory=5), TypeError, "Graph.run: max_memory: expected a str"),
        (lambda: g.evaluate("1"), TypeError, "Graph.evaluate: frame: expected an int \\(32 bits\\), got str"),
        (lambda: g.evaluate(2**40), TypeError, "Graph.evaluate: frame: expected an int"),
        (lambda: g.run(set="scene.width=3"), TypeError, 'set: expected a dict {"node.param": value}, got str'),
        (lambda: g.run(set=[1]), TypeError, 'set: expected a dict {"node.param": value}, got list'),
        (lambda: g.run(set={"scene.width": "20\x00garbage"}), ValueError,
         "set scene.width: embedded null character"),
        (lambda: g.run(set={"\ud800": 1}), ValueError, "set: key '\\\\ud800': not valid UTF-8"),
        (lambda: g.run(set={"scene.scene": "\ud800"}), ValueError, "set scene.scene: not valid UTF-8"),
        (lambda: ph.Graph.from_dict(graph_dict(scene, "x.exr"), set={"scene.width": "20\x00x"}),
         ValueError, "set scene.width: embedded null character"),
        (lambda: ph.Graph.from_dict({"nodes": [], "\ud800": 1}), ValueError,
         "Graph.from_dict: key '\\\\ud800': not valid UTF-8"),
        (lambda: g.evaluate(1, outputs="wr\x00ite"), ValueError,
         "Graph.evaluate: outputs: embedded null character"),
        (lambda: g.evaluate(1, outputs=["\ud800"]), ValueError, "Graph.evaluate: outputs: not valid UTF-8"),
        (lambda: g.evaluate(1, outputs=[1]), TypeError, "Graph.evaluate: outputs: expected node ids, got int 1"),
        (lambda: ph.Graph.from_dict({"nodes": []}, base_dir="/tmp\x00/x"), ValueError,
         "Graph.from_dict: base_dir: embedded null character"),
    ]:
        with pytest.raises(error, match=message) as e:
            call()
        assert "\n" not in str(e.value), str(e.value)
    assert not list(tmp_path.iterdir())  # nothing ran
    assert g.run(frames=[1], jobs=np.int64(1), skip_existing=np.bool_(False))["frames"] == [1]
    assert list(g.evaluate(np.int32(2))) == ["write"]
    assert g.run(frames=(2,), set={"scene.width": "8"}, max_memory="")["frames"] == [2]


def test_a_path_whose_fspath_gives_bytes_is_decoded(scene, tmp_path):
    """os.PathLike.__fspath__ may return bytes: the path was the text "b'/...'"."""
    class BytesPath:
        def __init__(self, p):
            self.p = p

        def __fspath__(self):
            return os.fsencode(self.p)

    f = ph.Frame(passes={"color": np.ones((2, 2, 4), np.float32)})
    out = tmp_path / "bytes.exr"
    ph.write(f, BytesPath(str(out)))
    assert out.exists()
    assert ph.read(BytesPath(str(out))).passes["color"].shape == (2, 2, 4)
    with pytest.raises(ValueError, match="embedded null character"):
        ph.write(f, BytesPath(str(out) + "\x00x"))
