"""Benchmark section: synthetic scenes per second (sample, validate, settle, scan, write).

One scene = what ``unseen synth`` does: sample the family, check contacts and analytic
statics, settle in MuJoCo (rejecting and redrawing what moves), scan one Kinect view
with noise, and write the scene directory.  Workloads: 10-box stacks (target from the
issue: at least 2 scenes per second) and ~50-cuboid rooms; the full run adds a row per
family.
"""

from __future__ import annotations

import os
import tempfile
import time

import numpy as np

from . import BenchTable

TITLE = "Synthetic scenes"


def _workload(family: str, seeds: range, **options) -> list:
    from synth_scenes.scene_dir import make_scene_dir

    with tempfile.TemporaryDirectory() as tmp:
        make_scene_dir(family, os.path.join(tmp, "warmup"), seed=10_000, **options)
        sample, total, cpu, cuboids, attempts = [], [], [], [], []
        for seed in seeds:
            t0, c0 = time.perf_counter(), time.process_time()
            res = make_scene_dir(family, os.path.join(tmp, str(seed)), seed=seed, **options)
            total.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
            sample.append(res.truth.seconds)
            cuboids.append(len(res.truth.arrangement.cuboids))
            attempts.append(res.truth.attempts)
    n = len(total)
    return [n, float(np.mean(cuboids)), float(np.mean(attempts)), float(np.mean(sample)),
            float(np.mean(total) - np.mean(sample)), float(np.mean(total)),
            float(np.mean(cpu)), n / float(np.sum(total))]


def run(quick: bool = False) -> list[BenchTable]:
    os.environ.setdefault("MUJOCO_GL", "egl")
    from synth_scenes.registry import family_names

    n = 3 if quick else 10
    rows = [["stack, 10 boxes", *_workload("stack", range(n), n_boxes=10)],
            ["room, ~50 cuboids", *_workload("room", range(max(2, n // 3)), min_cuboids=48,
                                              max_cuboids=52)]]
    if not quick:
        for fam in family_names():
            rows.append([fam, *_workload(fam, range(3))])
    return [BenchTable(
        title="Synthetic scenes: sample + validate + MuJoCo settle + 1-view scan + write",
        columns=["workload", "scenes", "cuboids (mean)", "attempts (mean)",
                 "s/scene sample+validate+settle", "s/scene scan+write", "s/scene total",
                 "CPU s/scene", "scenes/s"],
        rows=rows,
        note="One process, Kinect noise, 640x480, MuJoCo renderer (shared GL context); "
             "seeds 0..n-1 after one warm-up scene.  Target (issue 4): >= 2 scenes/s for "
             "10-box single-view scenes.  CPU s/scene (all threads of the process) is "
             "the load-independent figure on a shared machine.",
    )]
