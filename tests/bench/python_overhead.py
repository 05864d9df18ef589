#!/usr/bin/env python3
"""What a node costs from Python against the same node in the CLI, at 1920x1080.

For each node, in alternating rounds, two fresh processes: the CLI's (`posthaste run` over 16
frames of one read -> node -> write graph; its summary's ms/frame, the engine's per-node clock)
and Python's (the same file read once, then 16 posthaste.node() calls timed from Python: the
call, its validation and the result's wrapping included). Each process pays its own warm-up
over its 16 frames. Prints the medians over rounds of the means per frame, and their ratio.

    PYTHONPATH=build/python python3 tests/bench/python_overhead.py build/posthaste [ROUNDS]
"""

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import posthaste as ph

SOURCE = Path(__file__).resolve().parents[2]
NODES = [("grade", {"gain": [1.2, 1.0, 0.8], "saturation": 0.9}),
         ("bloom", {"intensity": 0.2}),
         ("ao", {}),
         ("dof", {"fstop": 2.0}),
         ("motion_blur", {})]


def cli_node_ms(binary, graph, node_id):
    out = subprocess.run([binary, "run", str(graph), "--frames", "1-16", "--jobs", "1"],
                         capture_output=True, text=True, check=True).stdout
    for line in out.splitlines():
        words = line.split()
        if words and words[0] == node_id:
            return float(words[-1])
    raise RuntimeError(f"no line for {node_id} in:\n{out}")


def python_node_ms(path, node_type, params):
    """Mean ms of 16 posthaste.node() calls in a fresh Python process."""
    code = ("import json, sys, time, posthaste as ph\n"
            "f = ph.read(sys.argv[1]); t, p = sys.argv[2], json.loads(sys.argv[3])\n"
            "total = 0.0\n"
            "for _ in range(16):\n"
            "    t0 = time.perf_counter(); out = ph.node(t, f, **p)\n"
            "    total += time.perf_counter() - t0; del out\n"
            "print(total / 16 * 1e3)\n")
    out = subprocess.run([sys.executable, "-c", code, str(path), node_type, json.dumps(params)],
                         capture_output=True, text=True, check=True).stdout
    return float(out)


def main():
    binary = sys.argv[1]
    rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 7
    work = Path(tempfile.mkdtemp(prefix="ph_pybench_"))
    frame = ph.node("render", scene=str(SOURCE / "samples/scenes/minecrappy.json"), width=1920,
                    height=1080, frame=40)
    ph.write(frame, work / "in.0001.exr")
    for n in range(2, 17):
        os.link(work / "in.0001.exr", work / f"in.{n:04d}.exr")
    print(f"{'node':<12} {'CLI ms':>8} {'Python ms':>10} {'ratio':>7}   (medians of {rounds} rounds)")
    for node_type, params in NODES:
        graph = work / f"{node_type}.json"
        graph.write_text(json.dumps({"nodes": [
            {"id": "read", "type": "read", "params": {"path": str(work / "in.####.exr")}},
            {"id": node_type, "type": node_type, "inputs": {"image": "read"}, "params": params},
            {"id": "write", "type": "write", "inputs": {"image": node_type},
             "params": {"path": str(work / "out.####.exr"), "passes": "color"}}]}))
        cli, py = [], []
        for _ in range(rounds):
            cli.append(cli_node_ms(binary, graph, node_type))
            py.append(python_node_ms(work / "in.0001.exr", node_type, params))
        c, p = statistics.median(cli), statistics.median(py)
        print(f"{node_type:<12} {c:8.2f} {p:10.2f} {p / c:7.3f}", flush=True)


if __name__ == "__main__":
    main()
