"""The one library entry point: a scan in, a result out (``run_scan``).

    from pipeline.run import RunConfig, run_scan
    result = run_scan("scenes/table0", RunConfig(seed=0))
    result.arrangement          # the stable arrangement (pipeline.model.Arrangement)
    result.report.edits         # which prior changed which box, and why

The command line (``unseen run``) and every evaluation suite call :func:`run_scan`.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .evidence import Evidence
from .imagine import ImagineReport, imagine
from .model import Arrangement
from .priors import ImagineConfig


@dataclass(frozen=True)
class LoadOptions:
    """How to read a scan (every field as ``unseen run``'s flag of the same name)."""

    color: str | None = None
    depth: str | None = None
    intrinsics: str | None = None
    depth_format: str = "auto"
    depth_scale: float | None = None
    up: str | None = None
    max_depth: float | None = None
    instance: str | None = None
    scribbles: str | None = None
    floor_height: float | None = None
    pose: str | None = None
    scale: float | None = None  #: metres per input unit (None: found from the extent)


@dataclass(frozen=True)
class RunConfig:
    """Everything :func:`run_scan` needs besides the scan.

    Attributes
    ----------
    seed : int
        Seeds RANSAC; the same scan and seed give the same result.
    segmentation : {"auto", "parts", "instance", "cluster"}
    cell : float or None
        Voxel size as a fraction of the scene diameter (None: the default).
    edges : bool
        Refine boxes to Canny edges of the colour image.
    stage : {"full", "initial"}
        ``initial``: section 4.1 only.
    imagine : ImagineConfig
        Budget, friction, threshold, priors on or off.
    load : LoadOptions
        How a scan given as a path is read.
    """

    seed: int = 0
    segmentation: str = "auto"
    cell: float | None = None
    edges: bool = True
    stage: str = "full"
    imagine: ImagineConfig = field(default_factory=ImagineConfig)
    load: LoadOptions = field(default_factory=LoadOptions)


@dataclass(frozen=True)
class Result:
    """What :func:`run_scan` returns.

    ``initial`` holds the initial cuboids (section 4.1), ``arrangement`` the final one
    (the initial one for ``stage="initial"``), ``initial_report`` the first step's
    counts, timings, labels and world points, ``report`` the :class:`ImagineReport`
    (None for ``stage="initial"``), ``evidence`` the scan's depth views."""

    scan: Any
    initial: Arrangement
    arrangement: Arrangement
    initial_report: dict
    report: ImagineReport | None
    evidence: Evidence
    prepared: Arrangement | None = None  #: after the priors, before the search


def load(source, options: LoadOptions | None = None):
    """Read a scan (scene directory, RGB-D folder, depth file or point cloud)."""
    from .scan_io import load_scan

    o = options or LoadOptions()
    return load_scan(os.fspath(source), color=o.color, depth=o.depth,
                     intrinsics=o.intrinsics, depth_format=o.depth_format,
                     depth_scale=o.depth_scale, up=o.up, max_depth=o.max_depth,
                     instance=o.instance, scribbles=o.scribbles,
                     floor_height=o.floor_height, pose=o.pose)


def initial(scan, config: RunConfig | None = None, progress=None) -> tuple[Arrangement, dict]:
    """Section 4.1 on a loaded scan: (initial arrangement, report)."""
    from .fit import CELL_REL
    from .initial import initial_cuboids

    config = config or RunConfig()
    rng = np.random.default_rng(config.seed)
    return initial_cuboids(scan, rng=rng, cell_rel=config.cell or CELL_REL,
                           edges=config.edges, segmentation=config.segmentation,
                           progress=progress)


def source_relative(source: str, input_path: str) -> str:
    """Where the scan came from, relative to INPUT (not to the working folder): the same
    input moved elsewhere gives the same bytes."""
    src, inp = os.path.abspath(source), os.path.abspath(input_path)
    if os.path.isdir(inp) and (src == inp or src.startswith(inp + os.sep)):
        rel = os.path.relpath(src, inp)
        return os.path.basename(inp) + ("" if rel == "." else "/" + rel.replace(os.sep, "/"))
    return os.path.basename(src)


def run_scan(scan, config: RunConfig | None = None, progress=None,
             search_progress=None) -> Result:
    """Run the pipeline on ``scan`` (a loaded scan, or a path read with ``config.load``).

    The scan is first brought to metres (:func:`pipeline.units.to_metres`: a bare cloud
    whose extent no indoor scene has is rescaled, with a note; ``config.load.scale`` says
    it exactly).  ``meta`` records the input's scale, the friction coefficient and where
    the scan came from, relative to the input.  ``progress(name)`` hears each step of
    section 4.1; ``search_progress(done, total)`` each group the search finishes."""
    from .units import to_metres

    config = config or RunConfig()
    t0 = time.perf_counter()
    path = None
    if isinstance(scan, (str, os.PathLike)):
        path = os.fspath(scan)
        scan = load(scan, config.load)
    scan, scale, note = to_metres(scan, config.load.scale)
    t_load = time.perf_counter() - t0
    arr, rep = initial(scan, config, progress)
    meta = dict(arr.meta)
    if path is not None and "source" in meta:
        meta["source"] = source_relative(str(meta["source"]), path)
    meta["input_scale"] = scale
    meta["mu"] = float(config.imagine.mu)
    arr = arr.with_(meta=meta)
    if note:
        rep["notes"] = [note, *rep.get("notes", [])]
    rep["timings"] = {"load": t_load, **rep["timings"]}
    rep["timings"]["total"] = float(sum(v for k, v in rep["timings"].items() if k != "total"))
    evidence = Evidence.from_scan(scan, rep.get("pose"))
    if config.stage == "initial":
        return Result(scan, arr, arr, rep, None, evidence)
    res = imagine(arr, evidence, config.imagine, progress=search_progress)
    return Result(scan, arr, res.arrangement, rep, res.report, evidence, res.initial)


__all__ = ["run_scan", "RunConfig", "LoadOptions", "Result", "load", "initial"]
