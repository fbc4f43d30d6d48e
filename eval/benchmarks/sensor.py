"""Benchmark section: the virtual depth sensor (render speed per backend at 640x480).

Frames per second of a reused renderer (RGB + depth + instance ids), the Kinect noise
model, a whole one-view scan (GL context, render, noise, fusion) and writing it.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np

from . import BenchTable, median_time

TITLE = "Virtual depth sensor"


def _scene(n: int = 10):
    """``n`` boxes in two layers on the ground (a 10-box synthetic scene)."""
    from pipeline.model import Arrangement, box, ground

    rng = np.random.default_rng(0)
    cubs = []
    for k in range(n):
        layer, slot = divmod(k, 6)
        x, y = (slot % 3) * 0.45 - 0.45, (slot // 3) * 0.45 - 0.2
        s = rng.uniform(0.2, 0.35, 3)
        z = layer * 0.4 + s[2] / 2
        cubs.append(box(f"b{k}", (x, y, z), s, yaw=float(rng.uniform(-0.3, 0.3))))
    return Arrangement(tuple(cubs), (ground(),))


def run(quick: bool = False) -> list[BenchTable]:
    os.environ.setdefault("MUJOCO_GL", "egl")
    from pipeline.camera import Intrinsics, look_at
    from simulate.noise import apply_noise
    from simulate.render_mujoco import MujocoRenderer
    from simulate.render_pybullet import PybulletRenderer
    from simulate.scan import scan_arrangement, write_scan

    arr = _scene()
    intr = Intrinsics.kinect_v1()
    T = look_at([1.8, -1.6, 1.4], [0.0, 0.0, 0.3])
    reps = 3 if quick else 10
    rows = []
    depth = None
    for name, make in (("mujoco", lambda: MujocoRenderer(arr, intr.width, intr.height)),
                       ("pybullet", lambda: PybulletRenderer(arr))):
        with make() as r:
            t = median_time(lambda r=r: r.render(intr, T), repeats=reps)
            if depth is None:
                depth = r.render(intr, T)[1]
        rows.append([f"render ({name}, reused context)", t * 1e3, 1.0 / t])
    t = median_time(lambda: apply_noise(depth, intr, np.random.default_rng(0)), repeats=reps)
    rows.append(["Kinect noise model (all terms)", t * 1e3, 1.0 / t])
    t = median_time(lambda: scan_arrangement(arr, np.random.default_rng(0), views=1),
                    repeats=max(2, reps // 3))
    rows.append(["scan_arrangement, 1 view (context + render + noise + fuse)", t * 1e3, 1.0 / t])
    scan = scan_arrangement(arr, np.random.default_rng(0), views=1)
    with tempfile.TemporaryDirectory() as tmp:
        t = median_time(lambda: write_scan(scan, tmp), repeats=max(2, reps // 3))
    rows.append(["write_scan, 1 view (3 PNG + PLY + JSON)", t * 1e3, 1.0 / t])
    return [BenchTable(
        title="Virtual sensor, 640x480, 10-box scene",
        columns=["step", "ms (median)", "per second"],
        rows=rows,
        note=f"Median of {reps} runs; MuJoCo offscreen via MUJOCO_GL="
             f"{os.environ.get('MUJOCO_GL')}, PyBullet TinyRenderer in DIRECT mode.",
    )]
