"""The close-up's motion blur at shutter 1 against its bound (docs/ACCURACY.md, "Against
Cycles"): the limit of a blur along the motion pass (many nearest-pixel taps per pixel, jittered
start), the node at its defaults, and Blender's Vector Blur, each as RMSE against Cycles' truth.

Run from the repository root after building the Python module (not part of CI: about a minute):
    PYTHONPATH=build/python python3 tests/cycles/motion_blur_bound.py [--taps 256]
"""

import argparse

import numpy as np

import posthaste as ph

SET = "samples/cycles/"


def color(path):
    return np.asarray(ph.read(path).passes["color"], dtype=np.float64)[..., :3]


def along_motion(sharp, motion, taps, rng):
    """The sharp frame averaged along each pixel's motion over the shutter (shutter 1: the path
    runs from -motion / 2 to +motion / 2), with `taps` nearest-pixel samples a pixel."""
    h, w, _ = sharp.shape
    ys, xs = np.mgrid[0:h, 0:w]
    start = rng.random((h, w))
    out = np.zeros_like(sharp)
    for i in range(taps):
        t = -1.0 + (i + start) * 2.0 / taps
        px = np.clip(np.floor(xs + 0.5 + t * motion[..., 0] * 0.5).astype(int), 0, w - 1)
        py = np.clip(np.floor(ys + 0.5 + t * motion[..., 1] * 0.5).astype(int), 0, h - 1)
        out += sharp[py, px]
    return out / taps


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--taps", type=int, default=256)
    args = parser.parse_args()
    frame = ph.read(SET + "closeup.passes.exr")
    truth = color(SET + "closeup.mb_s100.exr")
    sharp = np.asarray(frame.passes["color"], dtype=np.float64)[..., :3]
    motion = np.asarray(frame.passes["motion"], dtype=np.float64)[..., :2]

    def rmse(a):
        return float(np.sqrt(np.mean((a - truth) ** 2)))

    blender = rmse(color(SET + "closeup.blender_vblur_s100.exr"))
    node = np.asarray(ph.node("motion_blur", frame, shutter=1.0).passes["color"])[..., :3]
    limit = along_motion(sharp, motion, args.taps, np.random.default_rng(1))
    print(f"Vector Blur   {blender:.5f}")
    print(f"node          {rmse(node):.5f}  ({rmse(node) / blender:.3f}x)")
    print(f"limit, {args.taps} taps {rmse(limit):.5f}  ({rmse(limit) / blender:.3f}x)")
    print(f"doing nothing {rmse(sharp):.5f}")


if __name__ == "__main__":
    main()
