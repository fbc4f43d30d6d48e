"""``unseen eval viewpoint``: the same scene from several viewpoints.

Each scene (``--n`` per family, default 1; families :data:`FAMILIES`, quick: stack) is
scanned from :data:`VIEWS` single viewpoints (quick: :data:`QUICK_VIEWS`) evenly spread in
azimuth around it, at :data:`ELEVATION` degrees and :data:`DISTANCE` m (moved back when the
scene would not fit the image), each with Kinect noise, and run through the pipeline on
its own.  Per view: typed F1 initial -> optimized, the ground-truth cuboids the scan saw
too little of to make a cuboid (*hidden*: :func:`eval.suites._scenes.unseen_parts`,
fewer points than an instance needs), and how many of the missed true contacts (false
negatives) touch a hidden cuboid, i.e. failures the scan gave no evidence for
except through physics.

Outputs: ``viewpoint.md`` / ``.csv`` (one row per view, with a per-scene spread summary),
``viewpoint.png`` (F1 against azimuth per scene), ``tasks/``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

FAMILIES = ("chair", "table", "shelf", "desk", "stack")
QUICK_FAMILIES = ("stack",)
VIEWS = 6
QUICK_VIEWS = 3
ELEVATION = 30.0
DISTANCE = 2.2


def viewpoint_task(rng: np.random.Generator, family: str, seed: int, azimuth: float) -> dict:
    """One scene seen from one azimuth (degrees), through the pipeline, scored."""
    from eval.metrics import score_arrangement
    from eval.suites._common import score_record
    from eval.suites._scenes import (
        make_scene,
        missed_at,
        run_dir,
        scratch,
        summary_of,
        unseen_parts,
    )

    del rng  # the view is fixed; the scan noise is a function of the scene seed
    ranges = {"azimuth": (azimuth, azimuth), "elevation": (ELEVATION, ELEVATION),
              "distance": (DISTANCE, DISTANCE)}
    with scratch() as tmp:
        made = make_scene(family, seed, tmp / "scene", view_ranges=ranges)
        gt = made.truth.arrangement
        hidden = unseen_parts(made.path / "scan", gt)
        result = run_dir(made.path)
        initial = result.initial
    s = score_arrangement(result.arrangement, gt, initial=initial)
    fn = [list(e) for e in s.optimized.false_negatives]
    rec = score_record(result.arrangement, gt, initial=initial, unseen=hidden)
    rec.update(family=family, seed=int(seed), azimuth=float(azimuth), n_gt=len(gt.cuboids),
               n_initial=len(initial.cuboids), hidden=hidden, false_negatives=fn,
               fn_hidden=missed_at(fn, hidden), n_fp=len(s.optimized.false_positives),
               **summary_of(result.arrangement, result.report))
    return rec


def run(args: argparse.Namespace) -> int:
    from eval.runner import Task
    from eval.suites._common import (
        GEOMETRY_COLUMNS,
        geometry_cells,
        geometry_note,
        pct,
        plot_series,
        run_suite_tasks,
        write_table,
    )
    from eval.suites._scenes import f1_of, failure_note, scene_seed

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    quick = bool(getattr(args, "quick", False))
    n = args.n if getattr(args, "n", None) is not None else 1
    fams = QUICK_FAMILIES if quick else FAMILIES
    views = QUICK_VIEWS if quick else VIEWS
    azimuths = [round(360.0 * k / views, 3) for k in range(views)]
    tasks = [Task(f"{fam}-{scene_seed(args.seed, i)}-az{int(a):03d}", viewpoint_task,
                  {"family": fam, "seed": scene_seed(args.seed, i), "azimuth": a})
             for fam in fams for i in range(n) for a in azimuths]
    summary = run_suite_tasks(args, tasks, "viewpoint")
    results = summary.results
    rows, series, spread = [], {}, []
    for fam in fams:
        for i in range(n):
            seed = scene_seed(args.seed, i)
            recs = [(t.kwargs["azimuth"], results[t.id]) for t in tasks
                    if t.kwargs["family"] == fam and t.kwargs["seed"] == seed and t.id in results]
            for a, r in recs:
                rows.append([fam, seed, a, r["n_gt"], len(r["hidden"]),
                             " ".join(r["hidden"]) or "-", pct(f1_of(r, "initial.typed")),
                             pct(f1_of(r, "optimized.typed")), *geometry_cells([r]),
                             len(r["false_negatives"]), r["fn_hidden"], r["n_fp"],
                             int(r["stable"])])
            if recs:
                f1s = [100 * f1_of(r) for _, r in recs]
                series[f"{fam} {seed}"] = ([a for a, _ in recs], f1s)
                fn = sum(len(r["false_negatives"]) for _, r in recs)
                fnh = sum(r["fn_hidden"] for _, r in recs)
                spread.append([fam, seed, len(recs), f"{min(f1s):.1f}", f"{np.median(f1s):.1f}",
                               f"{max(f1s):.1f}", *geometry_cells([r for _, r in recs]), fn, fnh,
                               pct(fnh / fn if fn else float("nan"))])
    from pipeline.segment import MIN_INSTANCE_POINTS

    note = (f"Single Kinect-noised views at elevation {ELEVATION:g} deg, distance {DISTANCE:g} m "
            "(farther if the scene would not fit), azimuths evenly spread.  'hidden': true "
            f"cuboids with fewer than {MIN_INSTANCE_POINTS} points in the scan (too few to "
            "make a cuboid of).  FN: true contacts the optimized graph missed "
            "(typed); 'FN at hidden': those touching a hidden cuboid.  F1: typed, percent.  "
            f"{geometry_note()}  {summary.n_ok} views ok, {summary.n_failed} failed.\n"
            + failure_note(summary))
    md = write_table(out, "viewpoint", ["family", "seed", "azimuth (deg)", "gt cuboids",
                                        "hidden", "hidden ids", "initial F1", "optimized F1",
                                        *GEOMETRY_COLUMNS, "FN", "FN at hidden", "FP",
                                        "stable"], rows,
                     title="One scene, many viewpoints", note=note)
    md += "\n" + write_table(out, "viewpoint_summary",
                             ["family", "seed", "views", "min F1", "median F1", "max F1",
                              *GEOMETRY_COLUMNS, "FN", "FN at hidden", "FN at hidden %"], spread,
                             title="Spread over viewpoints")
    plot_series(out / "viewpoint.png", series, xlabel="azimuth (degrees)",
                ylabel="optimized typed F1 (%)", title="F1 per viewpoint")
    stream = getattr(args, "stream", None) or sys.stdout
    stream.write(md)
    return 0
