"""``unseen eval completion``: does a good scan of one object complete a partial scan of another?

Section 6 (i) of the paper, measured.  Per pair, two scenes of one family from different
seeds (so different proportions, :data:`synth_scenes.objects.WIDE`): the **partial** one
scanned from one view, the **template** from :data:`TEMPLATE_VIEWS` views (a nearly
complete scan).  Both go through :func:`pipeline.run.run_scan`; then
:func:`pipeline.complete.complete` completes the partial scan's object (the one with the
most points) from the template's with each transfer: ``auto`` (the default, reported
as "completed"), ``parts`` and ``rigid`` (the paper's).  Judged against the **partial scene's** truth:

* the true surface: points every :data:`SPACING` metres on the faces of the object's
  true boxes, without those inside another box of the scene or on the floor (faces
  hidden by contact);
* **coverage**: the share of true-surface samples within :data:`TAU` of the cloud;
* **accuracy**: mean distance from the cloud's points to the true boxes' surfaces;
  **completeness**: mean distance from the true-surface samples to the cloud;
  **chamfer**: their mean;
* **matching accuracy**: the share of matched part pairs (both with a scan instance id)
  whose true parts have the same place in their objects: centres, in the object's own
  frame scaled to its bounding box, within :data:`ROLE_TOL` of each other, up to a half
  turn of the whole object (a table matched back to front is right).

Pairs: ``--n`` per family (default 4, quick 1) of :data:`FAMILIES` (quick: chair).
Outputs: ``completion.md`` / ``.csv`` (per family and overall), ``completion.png``
(coverage bars), ``pairs.csv`` (every pair), ``pictures/<family>-<seed>.png``, ``tasks/``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

FAMILIES = ("table", "chair", "desk", "sofa", "shelf")
QUICK_FAMILIES = ("chair",)
#: Views of the template scan (the issue's "complete scan of an object"; at 8 views the
#: template scans covered 0.896 of their own true surface on seeds 1500-1504, at 16
#: 0.928; what the sensor drops at grazing angles, table-top undersides, stays missing) ...
TEMPLATE_VIEWS = 16
#: ... from eye heights down to 10 cm above the floor (under table tops and seats).
TEMPLATE_RANGES = {"height": (0.1, 1.9)}
#: Template seed = partial seed + this.
TEMPLATE_OFFSET = 500
#: A true-surface sample is covered when a cloud point lies within this distance (m) ...
TAU = 0.02
#: ... also reported at this looser distance (m).
TAU_LOOSE = 0.03
#: Spacing of the true-surface samples (m).
SPACING = 0.01
#: Samples within this distance inside another box (or of the floor) are hidden (m).
CONTACT_TOL = 0.004
#: Matched parts have the same role when their normalised centres are this close.
ROLE_TOL = 0.2


# ------------------------------------------------------------------------- truth
def surface_samples(arr, name: str, spacing: float = SPACING,
                    floor: float = 0.0) -> np.ndarray:
    """(m, 3) points on the faces of object ``name``'s boxes in ``arr``, on a grid of
    about ``spacing``, without those inside another box of ``arr`` or on the floor."""
    from pipeline.complete import parts_of

    own = [k for k, c in enumerate(arr.cuboids) if c.object == name]
    if not own:
        raise ValueError(f"no object {name!r} in the truth")
    out = []
    for k in own:
        c = arr.cuboids[k]
        h = c.size / 2
        for ax in range(3):
            u, v = [a for a in range(3) if a != ax]
            nu = max(2, int(np.ceil(c.size[u] / spacing)) + 1)
            nv = max(2, int(np.ceil(c.size[v] / spacing)) + 1)
            gu, gv = np.meshgrid(np.linspace(-h[u], h[u], nu), np.linspace(-h[v], h[v], nv))
            for sign in (-1.0, 1.0):
                loc = np.zeros((gu.size, 3))
                loc[:, u], loc[:, v], loc[:, ax] = gu.ravel(), gv.ravel(), sign * h[ax]
                pts = c.center + loc @ c.rotation.T
                others = [o for i, o in enumerate(arr.cuboids) if i != k]
                keep = pts[:, 2] > floor + CONTACT_TOL
                if others:
                    P = parts_of(others)
                    local = np.einsum("kji,nkj->nki", P.rotations,
                                      pts[:, None, :] - P.centers[None])
                    inside = np.all(np.abs(local) < P.sizes[None] / 2 + CONTACT_TOL, axis=2)
                    keep &= ~inside.any(1)
                out.append(pts[keep])
    pts = np.concatenate(out) if out else np.zeros((0, 3))
    # edges are shared by two faces: one sample per spacing/4 cube
    keys = np.round(pts / (spacing / 4)).astype(np.int64)
    _, first = np.unique(keys, axis=0, return_index=True)
    return pts[np.sort(first)]


def cloud_figures(cloud: np.ndarray, samples: np.ndarray, truth_parts,
                  tau: float = TAU) -> dict:
    """Coverage (share of samples within ``tau`` of the cloud), accuracy, completeness
    and chamfer (metres) of a cloud against the true surface."""
    from scipy.spatial import cKDTree

    from pipeline.complete import surface_distance

    if not len(cloud):
        return {"coverage": 0.0, "coverage_loose": 0.0, "accuracy": float("nan"), "completeness": float("nan"),
                "chamfer": float("nan"), "points": 0}
    d, _ = cKDTree(cloud).query(samples)
    acc = float(surface_distance(cloud, truth_parts).mean())
    comp = float(d.mean())
    return {"coverage": float((d <= tau).mean()),
            "coverage_loose": float((d <= TAU_LOOSE).mean()), "accuracy": acc,
            "completeness": comp, "chamfer": (acc + comp) / 2, "points": int(len(cloud))}


def normalised_roles(arr, name: str) -> dict[int, np.ndarray]:
    """Instance id (``k + 1`` for cuboid ``k``) -> the part's centre in its object's own
    frame (yaw of the object's first part), scaled to the object's bounding box."""
    from pipeline.model import box_corners

    ks = [k for k, c in enumerate(arr.cuboids) if c.object == name]
    R0 = arr.cuboids[ks[0]].rotation
    yaw = float(np.arctan2(R0[1, 0], R0[0, 0]))
    c_, s_ = np.cos(yaw), np.sin(yaw)
    Rz = np.array([[c_, -s_, 0.0], [s_, c_, 0.0], [0.0, 0.0, 1.0]])
    cubs = [arr.cuboids[k] for k in ks]
    corners = box_corners(np.array([c.center for c in cubs]), np.array([c.rotation for c in cubs]),
                          np.array([c.size for c in cubs])).reshape(-1, 3) @ Rz
    lo, hi = corners.min(0), corners.max(0)
    return {k + 1: ((c.center @ Rz) - (lo + hi) / 2) / np.maximum(hi - lo, 1e-6)
            for k, c in zip(ks, cubs, strict=True)}


def matching_accuracy(completion, template_arr, partial_arr, template_truth, partial_truth,
                      spectral: bool = False) -> tuple[float, int]:
    """(share of matched pairs with the same role, pairs judged); NaN when none.  Of the
    final matching, or of the spectral one with ``spectral``."""
    tr = normalised_roles(template_truth, completion.objects[0])
    pr = normalised_roles(partial_truth, completion.objects[1])
    t_inst = {c.id: c.extra.get("instance") for c in template_arr.cuboids}
    p_inst = {c.id: c.extra.get("instance") for c in partial_arr.cuboids}
    judged = [(tr[t_inst[a]], pr[p_inst[b]]) for a, b, _ in completion.matching_ids(spectral)
              if t_inst.get(a) in tr and p_inst.get(b) in pr]
    if not judged:
        return float("nan"), 0
    best = 0.0
    for flip in (np.array([1.0, 1.0, 1.0]), np.array([-1.0, -1.0, 1.0])):
        ok = [np.linalg.norm(t * flip - p) <= ROLE_TOL for t, p in judged]
        best = max(best, float(np.mean(ok)))
    return best, len(judged)


# ------------------------------------------------------------------------- one pair
def completion_task(rng: np.random.Generator, family: str, seed: int, template_seed: int,
                    template_views: int = TEMPLATE_VIEWS, pictures: str | None = None
                    ) -> dict:
    """One pair: synthesize, run both, complete (parts and rigid), measure."""
    from eval.suites._scenes import make_scene, run_dir, scratch
    from pipeline.complete import (
        CompleteConfig,
        complete,
        floor_height,
        object_points,
        parts_of,
    )

    with scratch() as tmp:
        pm = make_scene(family, seed, tmp / "partial")
        tm = make_scene(family, template_seed, tmp / "template", views=template_views,
                        view_ranges=TEMPLATE_RANGES)
        partial = run_dir(pm.path)
        template = run_dir(tm.path)
    truth, t_truth = pm.truth.arrangement, tm.truth.arrangement
    rec: dict = {"family": family, "seed": int(seed), "template_seed": int(template_seed)}
    truth_of: dict = {}
    for mode in ("auto", "parts", "rigid"):
        c = complete(partial, template, CompleteConfig(transfer=mode),
                     rng=np.random.default_rng(seed))
        name = c.objects[1]
        if not any(cb.object == name for cb in truth.cuboids):
            raise RuntimeError(f"{family} {seed}: object {name!r} is not in the truth")
        if name not in truth_of:  # the same object in every mode: its surface once
            truth_of[name] = (surface_samples(truth, name, floor=floor_height(truth)),
                              parts_of([cb for cb in truth.cuboids if cb.object == name]))
        samples, tparts = truth_of[name]
        if mode == "auto":
            rec["chosen"] = c.transfer
            rec["transfer_scores"] = c.alignment.get("transfer_scores", {})
            rec["object"] = name
            rec["template_object"] = c.objects[0]
            rec["true_parts"] = len(tparts)
            rec["partial_parts"] = len(c.partial_parts)
            rec["template_parts"] = len(c.template_parts)
            rec["samples"] = int(len(samples))
            rec["partial"] = cloud_figures(c.partial_points, samples, tparts)
            acc, judged = matching_accuracy(c, template.arrangement, partial.arrangement,
                                            t_truth, truth)
            sacc, sjudged = matching_accuracy(c, template.arrangement, partial.arrangement,
                                              t_truth, truth, spectral=True)
            rec["matching"] = {"pairs": len(c.matching.pairs), "judged": judged,
                               "accuracy": acc, "candidates": c.spectral.candidates,
                               "pruned": c.spectral.pruned,
                               "spectral_pairs": len(c.spectral.pairs),
                               "spectral_judged": sjudged, "spectral_accuracy": sacc}
            tn = c.objects[0]
            rec["template_self"] = cloud_figures(
                object_points(template.initial_report, tn),
                surface_samples(t_truth, tn, floor=floor_height(t_truth)),
                parts_of([cb for cb in t_truth.cuboids if cb.object == tn]))
            rec["icp"] = c.alignment.get("icp", {})
            rec["carved"] = c.carved
            if pictures:
                from eval.commands.complete import completion_picture

                Path(pictures).mkdir(parents=True, exist_ok=True)
                completion_picture(Path(pictures) / f"{family}-{seed}.png", c,
                                   title=f"{family} seed {seed} completed from seed "
                                         f"{template_seed} (grey: true boxes)",
                                   truth_boxes=tparts)
        rec[mode] = cloud_figures(c.points, samples, tparts)
    return rec


# ------------------------------------------------------------------------- the suite
COLUMNS = ["family", "pairs", "coverage partial", "coverage completed", "coverage parts",
           "coverage rigid",
           "coverage template (own)", ">= 90%", "partial -> completed at 3 cm", "chamfer partial (m)", "chamfer completed (m)",
           "chamfer rigid (m)", "accuracy completed (m)", "matching accuracy spectral",
           "matching accuracy aligned", "ICP fitness"]


def _row(label: str, recs: list[dict]) -> list:
    def mean(get):
        vals = [get(r) for r in recs]
        vals = [v for v in vals if v is not None and np.isfinite(v)]
        return float(np.mean(vals)) if vals else float("nan")

    def pooled(acc: str, n: str) -> float:
        judged = sum(r["matching"][n] for r in recs)
        right = sum(r["matching"][acc] * r["matching"][n] for r in recs if r["matching"][n])
        return right / judged if judged else float("nan")

    return [label, len(recs),
            mean(lambda r: r["partial"]["coverage"]), mean(lambda r: r["auto"]["coverage"]),
            mean(lambda r: r["parts"]["coverage"]), mean(lambda r: r["rigid"]["coverage"]),
            mean(lambda r: r["template_self"]["coverage"]),
            f"{sum(r['auto']['coverage'] >= 0.9 for r in recs)}/{len(recs)}",
            f"{mean(lambda r: r['partial']['coverage_loose']):.3f} -> "
            f"{mean(lambda r: r['auto']['coverage_loose']):.3f}",
            mean(lambda r: r["partial"]["chamfer"]), mean(lambda r: r["auto"]["chamfer"]),
            mean(lambda r: r["rigid"]["chamfer"]), mean(lambda r: r["auto"]["accuracy"]),
            pooled("spectral_accuracy", "spectral_judged"), pooled("accuracy", "judged"),
            mean(lambda r: r["icp"].get("fitness"))]


def run(args: argparse.Namespace) -> int:
    from eval.runner import Task
    from eval.suites._common import plot_bars, run_suite_tasks, suite_size, write_table
    from eval.suites._scenes import failure_note, scene_seed

    out, quick, n = suite_size(args, 4)
    fams = QUICK_FAMILIES if quick else FAMILIES
    tasks = []
    for fam in fams:
        for i in range(n):
            s = scene_seed(args.seed, i)
            tasks.append(Task(f"{fam}-{s}", completion_task,
                              {"family": fam, "seed": s, "template_seed": s + TEMPLATE_OFFSET,
                               "template_views": TEMPLATE_VIEWS},
                              cost=3.0 if fam in ("shelf", "desk") else 1.0,
                              where={"pictures": str(out / "pictures")}))
    summary = run_suite_tasks(args, tasks, "completion")
    results = summary.results
    groups = {fam: [results[t.id] for t in tasks
                    if t.kwargs["family"] == fam and t.id in results] for fam in fams}
    rows = [_row(f, recs) for f, recs in groups.items() if recs]
    every = [r for recs in groups.values() for r in recs]
    if every:
        rows.append(_row("all", every))
    note = (f"Coverage: share of true-surface samples (every {SPACING * 100:g} cm on the "
            f"partial object's true box faces, faces hidden by contact or the floor left "
            f"out) within {TAU * 100:g} cm of the cloud (also at {TAU_LOOSE * 100:g} cm).  Chamfer: mean of accuracy (cloud "
            "to true box surfaces) and completeness (surface samples to cloud), metres.  "
            "'completed': the partial points plus the template's as `unseen complete` "
            "gives them (--transfer auto: of the two below, the one that lies nearer the "
            "partial points and less in space the scan saw empty); 'parts': the template "
            "carried part by part into the matched partial boxes; 'rigid': moved by the "
            "rigid transform only (the paper).  '>= 90%': pairs whose completed cloud "
            f"covers at least 90%.  'template (own)': how much of its own true surface "
            f"the template scan covers (a bound on what it can give).  Partial: 1 view; "
            f"template: {TEMPLATE_VIEWS} views (eye heights "
            f"{TEMPLATE_RANGES['height'][0]:g}-{TEMPLATE_RANGES['height'][1]:g} m) of "
            f"another seed (+{TEMPLATE_OFFSET}) of the same family.  Matching accuracy: "
            f"matched pairs whose true parts hold the same place in their objects "
            f"(normalised centres within {ROLE_TOL}, up to a half turn), pooled over pairs; "
            "'spectral': the spectral matching (the alignment tries every pair of parts), 'aligned': the matching "
            "redone once aligned, which the transfer follows.  ICP fitness: share of "
            "partial points within 5 cm of the aligned template.")
    fail = failure_note(summary)
    md = write_table(out, "completion", COLUMNS, rows,
                     title="Structure-guided completion (section 6 (i))",
                     note=note + ("\n\n" + fail if fail else ""))
    pair_rows = [[r["family"], r["seed"], r["template_seed"], r["object"], r["true_parts"],
                  r["partial_parts"], r["template_parts"], r["matching"]["pairs"],
                  r["matching"]["accuracy"], r["chosen"], r["partial"]["coverage"],
                  r["auto"]["coverage"], r["parts"]["coverage"], r["rigid"]["coverage"],
                  r["template_self"]["coverage"], r["partial"]["chamfer"],
                  r["auto"]["chamfer"], r["icp"].get("fitness"), r["carved"]]
                 for r in every]
    write_table(out, "pairs", ["family", "seed", "template seed", "object", "true parts",
                               "partial boxes", "template boxes", "matched", "matching acc",
                               "transfer", "cov partial", "cov completed", "cov parts",
                               "cov rigid", "cov template own", "chamfer partial",
                               "chamfer completed", "ICP fitness", "carved"],
                pair_rows)
    plot_bars(out / "completion.png",
              {row[0]: {"partial": row[2], "completed": row[3], "parts": row[4],
                        "rigid": row[5], "template, own surface": row[6]}
               for row in rows},
              ylabel=f"coverage of the true surface (tau {TAU * 100:g} cm)",
              title="Structure-guided completion", ylim=(0.0, 1.0))
    stream = getattr(args, "stream", None) or sys.stdout
    stream.write(md)
    return 0
