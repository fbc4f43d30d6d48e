"""``unseen eval table1``: the paper's Table 1 on our synthetic benchmark.

Initial vs optimized contact-graph precision / recall / F1 (typed: a contact is right when
its pair and its type, ``touch`` or ``fixed``, are; untyped: the pair only), per scene
family and for all, from single Kinect-noised views, plus a multi-view row (3 views fused:
the paper's KinectFusion row), printed next to the paper's figures.

Scenes: ``--n`` per family (default 4; ``--quick``: 1, stack only), seeds
:func:`eval.suites._scenes.scene_seed` (1000 + 100 * --seed + i).  Next to each F1: its
95% bootstrap interval over the row's scenes, and the geometry of the matched boxes
(matched share, IoU, side error; a box matches its part only with 3D IoU >= 0.1).
Outputs under ``--out``: ``table1.md`` / ``.csv`` (the table), ``table1_physics.md`` / ``.csv`` (per row: the
fraction of results that stand in the analytic check, MuJoCo and PyBullet, and the
paper's size error, equations 5-6), ``table1_unseen.md`` / ``.csv`` (per row: the true
parts the scans saw too little of, the missed contacts at them, and the F1 a result
reaches when only those are missed), ``scenes.csv`` (one row per scene), ``table1.png``
(initial vs optimized F1 per family), ``tasks/`` (one record per scene; resumable).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

#: Families of the single-view rows (room only outside --quick).
#: Rough relative scene times per family (rooms and shelves hold many cuboids), for
#: the order parallel runs start them in (:attr:`eval.runner.Task.cost`).
COST = {"room": 4.0, "shelf": 2.5}
FAMILIES = ("stack", "table", "chair", "shelf", "desk", "sofa", "counterweight", "bridge",
            "wall_shelf")
QUICK_FAMILIES = ("stack",)
#: Families of the multi-view (KinectFusion-like) row and its number of views.
MULTIVIEW_FAMILIES = ("stack", "table", "chair", "shelf")
QUICK_MULTIVIEW_FAMILIES = ("stack",)
MULTIVIEW = 3
DEFAULT_N = 4
#: Engines every result is settled in (``table1_physics``).
ENGINES = ("mujoco", "pybullet")


def build_tasks(args: argparse.Namespace) -> list:
    """One :class:`eval.runner.Task` per (family, scene, views)."""
    from eval.runner import Task
    from eval.suites._scenes import scene_seed, scene_task

    quick = bool(getattr(args, "quick", False))
    n = args.n if getattr(args, "n", None) is not None else (1 if quick else DEFAULT_N)
    fams = QUICK_FAMILIES if quick else (*FAMILIES, "room")
    multi = QUICK_MULTIVIEW_FAMILIES if quick else MULTIVIEW_FAMILIES
    tasks = []
    for views, families in ((1, fams), (MULTIVIEW, multi)):
        for fam in families:
            for i in range(n):
                seed = scene_seed(args.seed, i)
                tasks.append(Task(f"{fam}-{seed}-v{views}", scene_task,
                                  {"family": fam, "seed": seed, "views": views,
                                   "engines": list(ENGINES)},
                                  cost=views * COST.get(fam, 1.0)))
    return tasks


def paper_rows() -> list[list]:
    """The paper's synthetic and KinectFusion rows in the layout of ``PR_F1_COLUMNS``."""
    from eval.suites._common import PAPER_TABLE1

    rows = []
    for name in ("Synthetic", "Kinfu"):
        p = PAPER_TABLE1[name]
        rows.append([f"paper: {name}", int(p["scenes"]), f"{p['init_p']:.1f} / {p['init_r']:.1f}",
                     f"{p['init_f1']:.1f}", f"{p['opt_p']:.1f} / {p['opt_r']:.1f}",
                     f"{p['opt_f1']:.1f}", "-", "-", "-", "-", "-"])
    return rows


def physics_rows(single: dict, multi: list) -> list[list]:
    """Per family (and all single views, and the fused views): fractions standing in the
    analytic check, MuJoCo and PyBullet, and the mean size error before and after."""
    groups = list(single.items()) + [("all, single view", [r for v in single.values() for r in v])]
    if multi:
        groups.append((f"all, {MULTIVIEW} views fused", multi))
    rows = []
    for name, recs in groups:
        def frac(values: list) -> str:
            return f"{sum(values)}/{len(values)}" if values else "-"
        sizes = [r["size"] for r in recs if r.get("size")]
        row = [name, len(recs), frac([bool(r.get("stable")) for r in recs])]
        row += [frac([bool(r["stands_in"][e]) for r in recs if "stands_in" in r]) for e in ENGINES]
        if sizes:
            a = sum(x["mean_init"] for x in sizes) / len(sizes)
            b = sum(x["mean_opt"] for x in sizes) / len(sizes)
            row += [f"{a:.3f} -> {b:.3f}", f"{sum(x['improvement'] for x in sizes) / len(sizes):.3f}"]
        else:
            row += ["-", "-"]
        rows.append(row)
    return rows


def unseen_rows(single: dict, multi: list) -> list[list]:
    """Per family (and all single views, and the fused views): ground-truth parts the scan
    saw too little of to make a cuboid, the true contacts missed, those of them at such
    parts, and the F1 a result would reach with only those missed (every contact between
    seen parts right): the part of the gap the scan gave no evidence for."""
    from eval.suites._common import seen_bound

    groups = list(single.items()) + [("all, single view", [r for v in single.values() for r in v])]
    if multi:
        groups.append((f"all, {MULTIVIEW} views fused", multi))
    rows = []
    for name, recs in groups:
        recs = [r for r in recs if "unseen" in r]
        if not recs:
            continue
        n_gt = sum(int(r["optimized"]["typed"]["n_gt"]) for r in recs)
        tp = sum(int(r["optimized"]["typed"]["tp"]) for r in recs)
        n_pred = sum(int(r["optimized"]["typed"]["n_pred"]) for r in recs)
        fn_unseen = sum(int(r["fn_unseen"]) for r in recs)
        f1 = 2 * tp / (n_pred + n_gt) if n_pred + n_gt else float("nan")
        bound = seen_bound(recs)
        rows.append([name, len(recs), sum(int(r["n_gt"]) for r in recs),
                     sum(len(r["unseen"]) for r in recs), n_gt, n_gt - tp, fn_unseen,
                     f"{100 * f1:.1f}", f"{100 * bound:.1f}"])
    return rows


def run(args: argparse.Namespace) -> int:
    """Run the scenes and write Table 1 under ``args.out``."""
    from eval.suites._common import (
        BOOTSTRAP_RESAMPLES,
        GEOMETRY_COLUMNS,
        PR_F1_COLUMNS,
        aggregate_prf,
        geometry_cells,
        geometry_note,
        pct,
        plot_bars,
        pr_f1_rows,
        run_suite_tasks,
        write_table,
    )
    from eval.suites._scenes import f1_of, failure_note

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tasks = build_tasks(args)
    summary = run_suite_tasks(args, tasks, "table1")
    results = summary.results
    single = {}
    multi = []
    for t in tasks:
        rec = results.get(t.id)
        if rec is None:
            continue
        if t.kwargs["views"] == 1:
            single.setdefault(t.kwargs["family"], []).append(rec)
        else:
            multi.append(rec)
    rows = pr_f1_rows(single, total="all, single view")
    if multi:
        rows += pr_f1_rows({f"all, {MULTIVIEW} views fused": multi}, total=None)
    rows += paper_rows()
    note = (f"Typed contact-graph P / R / F1 in percent, micro-averaged over the edges of a "
            f"row's scenes (seeds from {tasks[0].kwargs['seed'] if tasks else '-'}; single "
            f"Kinect-noised view unless said).  F1 95% interval: percentile bootstrap "
            f"over the row's scenes ({BOOTSTRAP_RESAMPLES} resamples, fixed seed).  Untyped F1 "
            f"and the geometry are the optimized result's.  {geometry_note()}  "
            f"{summary.n_ok} scenes ok, {summary.n_failed} failed.\n"
            + failure_note(summary))
    md = write_table(out, "table1", PR_F1_COLUMNS, rows,
                     title="Table 1: contact graph, initial vs optimized", note=note)
    write_table(out, "table1_physics", ["scenes", "#scenes", "stable (analytic)",
                                        "stands in MuJoCo", "stands in PyBullet",
                                        "side error initial -> optimized",
                                        "eq. 6 improvement"],
                physics_rows(single, multi), title="Table 1: do the results stand, sizes",
                note="Fractions of results.  Side error: relative error of every side of "
                     "the matched boxes, weighted by its true length, mean over scenes.  "
                     "Eq. 6 improvement: the paper's size measure, the same weighted mean of "
                     "the signed decrease over the sides that changed by more than 5 % "
                     "(> 0: optimization brought sizes closer to the truth).\n")
    from pipeline.segment import MIN_INSTANCE_POINTS

    write_table(out, "table1_unseen", ["scenes", "#scenes", "true cuboids", "unseen parts",
                                       "true contacts", "missed", "missed at unseen parts",
                                       "optimized F1", "F1 if only those were missed"],
                unseen_rows(single, multi), title="Table 1: what the scans did not see",
                note=f"Unseen part: a true cuboid with fewer than {MIN_INSTANCE_POINTS} points "
                     "in the scan (the least the pipeline makes a cuboid of).  Missed: true "
                     "contacts (typed) not in the optimized graph; those touching an unseen "
                     "part can only come back through physics or symmetry.  The last column "
                     "is the typed F1 of a result that gets every other contact right and "
                     "adds none: the most the rest of the pipeline can reach on these scans."
                     "\n")
    scene_rows = [[t.id, t.kwargs["family"], t.kwargs["seed"], t.kwargs["views"],
                   results[t.id]["n_gt"], results[t.id]["n_initial"], results[t.id]["n_final"],
                   pct(f1_of(results[t.id], "initial.typed")),
                   pct(f1_of(results[t.id], "optimized.typed")),
                   pct(f1_of(results[t.id], "optimized.untyped")),
                   *geometry_cells([results[t.id]]),
                   results[t.id]["n_fixed"], int(results[t.id]["stable"])]
                  for t in tasks if t.id in results]
    write_table(out, "scenes", ["task", "family", "seed", "views", "gt cuboids",
                                "initial cuboids", "final cuboids", "initial F1",
                                "optimized F1", "untyped F1", *GEOMETRY_COLUMNS, "fixed",
                                "stable"], scene_rows)
    bars = {}
    for fam, recs in single.items():
        bars[fam] = {"initial": 100 * aggregate_prf(recs, "initial.typed")["f1"],
                     "optimized": 100 * aggregate_prf(recs, "optimized.typed")["f1"]}
    if multi:
        bars[f"{MULTIVIEW} views"] = {
            "initial": 100 * aggregate_prf(multi, "initial.typed")["f1"],
            "optimized": 100 * aggregate_prf(multi, "optimized.typed")["f1"]}
    plot_bars(out / "table1.png", bars, ylabel="typed contact F1 (%)",
              title="Initial vs optimized contact graph", ylim=(0, 105))
    stream = getattr(args, "stream", None) or sys.stdout
    stream.write(md)
    return 0
