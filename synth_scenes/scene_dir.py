"""Write a scene directory: validated ground truth (``scene.json``) and its scan (``scan/``).

Layout (DESIGN.md)::

    DIR/scene.json             ground truth arrangement (all cuboids, true sizes, typed
                               contacts, each cuboid's ``object``; ``meta`` records the
                               family, seed, options, attempts, verdicts and scan settings)
    DIR/scan/color.png         8-bit RGB          DIR/scan/depth.png    16-bit mm
    DIR/scan/instance.png      16-bit, id k = cuboids[k-1] of scene.json, 0 = supports/none
    DIR/scan/intrinsics.json   DIR/scan/camera_pose.json (4x4 camera-to-world)
    DIR/scan/points.ply        world points with per-point instance ids
    DIR/scan/view<k>/...       per-view files when views > 1 (points.ply above is fused)

Everything is a function of (family, options, seed, scan settings): the same call gives
byte-identical files.  The scene and the scan draw from independent generators
(:func:`synth_scenes.truth.scene_rngs`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from pipeline.arrangement_io import write_arrangement
from pipeline.errors import InputError

from .truth import TRUTH_ENGINES, GroundTruth, sample_scene, scene_rngs

NOISE_CHOICES = ("kinect", "none")
RENDERERS = ("mujoco", "pybullet")


@dataclass(frozen=True)
class SceneDir:
    """What :func:`make_scene_dir` wrote."""

    path: Path
    truth: GroundTruth
    n_points: int
    views: int


def make_scene_dir(family: str, out: str | os.PathLike, seed: int = 0, *, views: int = 1,
                   noise: str = "kinect", renderer: str = "mujoco",
                   engines: tuple[str, ...] = TRUTH_ENGINES, view_ranges: dict | None = None,
                   intrinsics=None, max_attempts: int | None = None,
                   write_invalid: bool = False, **options) -> SceneDir:
    """Sample a valid scene of ``family`` from ``seed``, scan it, write the directory.

    Parameters
    ----------
    family : str
        A registry name (``stack``, ``table``, ..., ``room``).
    out : path
        The scene directory (created; existing files are replaced atomically).
    seed : int
    views : int
        Number of camera views (``scan/view<k>/`` when > 1).
    noise : {"kinect", "none"}
    renderer : {"mujoco", "pybullet"}
    engines : tuple of str
        Engines a scene must stand in to be kept (analytic statics always).
    view_ranges, intrinsics
        Passed to :func:`simulate.scan.scan_arrangement`.
    write_invalid : bool
        Write the last sample even when no valid scene was found (its ``meta.status``
        says ``gave_up``); by default nothing is written then.
    **options
        Family options (``n_boxes``, ``n_objects``, ...).

    Returns
    -------
    SceneDir
        ``truth.status == "gave_up"`` when no valid scene was found.
    """
    if views < 1:
        raise InputError(f"--views: must be at least 1, got {views}")
    if noise not in NOISE_CHOICES:
        raise InputError(f"--noise: must be one of {', '.join(NOISE_CHOICES)}, got {noise!r}")
    if renderer not in RENDERERS:
        raise InputError(f"--renderer: must be one of {', '.join(RENDERERS)}, got {renderer!r}")
    scene_rng, scan_rng = scene_rngs(seed)
    kw = {} if max_attempts is None else {"max_attempts": max_attempts}
    gt = sample_scene(family, scene_rng, seed=seed, engines=tuple(engines), **kw, **options)
    out = Path(out)
    if gt.status != "ok" and not write_invalid:
        return SceneDir(out, gt, 0, views)
    from simulate.scan import scan_arrangement, write_scan

    arr = gt.arrangement
    arr = arr.with_(meta={**arr.meta, "generator": "unseen synth",
                          "scan": {"views": views, "noise": noise, "renderer": renderer,
                                   "view_ranges": view_ranges}})
    scan = scan_arrangement(arr, scan_rng, views=views, noise=noise, intrinsics=intrinsics,
                            renderer=renderer, view_ranges=view_ranges)
    out.mkdir(parents=True, exist_ok=True)
    _remove_stale_views(out / "scan", views)
    write_scan(scan, out / "scan")
    write_arrangement(arr, out / "scene.json")
    gt = GroundTruth(arr, gt.family, gt.options, gt.attempts, gt.validation, gt.status,
                     gt.seconds, gt.rejected)
    return SceneDir(out, gt, int(len(scan.points)), views)


#: the per-view files of a scan folder (``simulate.scan.write_scan``)
VIEW_FILES = ("color.png", "depth.png", "instance.png", "intrinsics.json", "camera_pose.json",
              "points.ply")


def _remove_stale_views(scan_dir: Path, views: int) -> None:
    """Delete view files an earlier run with another ``--views`` left in ``scan_dir``.

    Only the names :func:`simulate.scan.write_scan` writes are touched: ``view<k>/`` for
    ``k >= views`` (all of them when ``views == 1``), and the top-level per-view images
    when ``views > 1`` (the top-level ``points.ply`` is rewritten either way).
    """
    import re

    if not scan_dir.is_dir():
        return
    for sub in scan_dir.iterdir():
        m = re.fullmatch(r"view(\d+)", sub.name)
        if m and sub.is_dir() and (views == 1 or int(m.group(1)) >= views):
            for name in VIEW_FILES:
                (sub / name).unlink(missing_ok=True)
            if not any(sub.iterdir()):          # foreign files: leave the folder
                sub.rmdir()
    if views > 1:
        for name in VIEW_FILES[:-1]:
            (scan_dir / name).unlink(missing_ok=True)
