"""Imagining the unseen: initial cuboids -> a stable, typed arrangement (sections 4.2-4.3).

:func:`imagine` runs, in order:

1. *overlap repair*: initial boxes fitted to noisy points may overlap slightly; each
   overlapping pair is separated by shrinking the box with fewer points along the
   separating axis (a true overlap cannot be a contact);
2. *symmetry* (:mod:`pipeline.symmetry`): wholly occluded repeated parts (the fourth leg)
   are hallucinated where the object's other parts show the pattern and the sensor saw
   nothing there;
3. *candidates* (:mod:`pipeline.extend`) with interpenetration and visibility pruning;
4. *search* (:mod:`pipeline.search`): fewest fixed contacts, then least added volume;
5. *refinement* (:mod:`pipeline.refine`) when the result still carries residual energy.

It returns the final arrangement (each cuboid keeps its ``observed`` box) and a report
dict with counts, statistics and timings per step.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .contacts import find_contacts, pair_tolerance, sat_separation
from .extend import DepthView, candidate_edges, depth_noise, prune_by_visibility
from .model import Arrangement, Cuboid, ObservedBox
from .refine import refine
from .search import search
from .symmetry import hallucinate


@dataclass(frozen=True)
class ImagineResult:
    arrangement: Arrangement
    initial: Arrangement  #: after overlap repair and symmetry, before extension
    report: dict


def repair_overlaps(arr: Arrangement, max_rounds: int = 10) -> tuple[Arrangement, int]:
    """Shrink boxes until no pair overlaps beyond the contact tolerance."""
    repaired = 0
    for _ in range(max_rounds):
        cs = find_contacts(arr)
        pen = [p for p in cs.penetrations if not p[1].startswith(("ground", "wall:"))]
        sup = [p for p in cs.penetrations if p[1].startswith(("ground", "wall:"))]
        if not pen and not sup:
            break
        cubs = list(arr.cuboids)
        idx = arr.index
        for a_id, b_id, _depth in pen:
            i, j = idx[a_id], idx[b_id]
            ci, cj = cubs[i], cubs[j]
            # shrink the box with fewer points (the less certain one)
            k, o = (i, j) if ci.extra.get("points", 0) <= cj.extra.get("points", 0) else (j, i)
            cubs[k] = _shrink_against(cubs[k], cubs[o])
            repaired += 1
        for a_id, s_id, _depth in sup:
            k = idx[a_id]
            cubs[k] = _lift_from_plane(cubs[k], arr.support(s_id))
            repaired += 1
        arr = arr.with_(cuboids=tuple(cubs))
    return arr, repaired


def _shrink_against(c: Cuboid, other: Cuboid) -> Cuboid:
    """Move the face of ``c`` that overlaps ``other`` back to just touch it."""
    tol = float(pair_tolerance(c.size[None], other.size[None])[0])
    best = None
    for ax in range(3):
        for side in (0, 1):
            u = c.rotation[:, ax] * (1 if side else -1)
            face = c.center @ u + c.size[ax] / 2
            proj = other.corners() @ u
            overlap = face - proj.min()  # how far c reaches into the other along u
            if overlap > 0 and (best is None or overlap < best[0]):
                best = (overlap, ax, side)
    if best is None:
        return c
    overlap, ax, side = best
    cut = min(overlap - 0.5 * tol, 0.9 * c.size[ax])
    if cut <= 0:
        return c
    size = c.size.copy()
    size[ax] -= cut
    u = c.rotation[:, ax] * (1 if side else -1)
    return c.with_(center=c.center - u * cut / 2, size=size)


def _lift_from_plane(c: Cuboid, sup) -> Cuboid:
    """Trim the part of ``c`` below a support plane (an upright box loses its bottom)."""
    d = sup.signed_distance(c.corners())
    depth = -d.min()
    if depth <= 0:
        return c
    cos = np.abs(c.rotation.T @ sup.normal)
    ax = int(np.argmax(cos))
    cut = min(depth / max(cos[ax], 1e-6), 0.9 * c.size[ax])
    size = c.size.copy()
    size[ax] -= cut
    u = c.rotation[:, ax] * np.sign(c.rotation[:, ax] @ sup.normal)
    return c.with_(center=c.center + u * cut / 2, size=size)


def views_from_scan(scan, arr: Arrangement) -> list[DepthView]:
    """The depth image(s) of a loaded scan in the arrangement's world frame."""
    if scan is None or getattr(scan, "depth", None) is None or scan.intrinsics is None:
        return []
    pose = arr.meta.get("camera_pose")
    if pose is None:
        return []
    return [DepthView(np.asarray(scan.depth, float), scan.intrinsics, np.asarray(pose, float))]


def imagine(arr: Arrangement, views: list[DepthView] | None = None, *, budget: float = 10.0,
            mu: float = 0.7, threshold: float | None = None, symmetry: bool = True,
            refine_steps: int = 20, progress=None) -> ImagineResult:
    """Extend the initial cuboids of ``arr`` into a stable arrangement (module docstring)."""
    views = views or []
    timings: dict[str, float] = {}
    t = time.perf_counter()
    arr = arr.with_(contacts=(), stability=None)
    # keep the observed box of every cuboid (before any change)
    arr = arr.with_(cuboids=tuple(
        c if c.observed is not None else c.with_(observed=ObservedBox(c.center, c.size))
        for c in arr.cuboids))
    arr, repaired = repair_overlaps(arr)
    timings["repair"] = time.perf_counter() - t

    t = time.perf_counter()
    margin = 0.0
    if views:
        scale = arr.scale_length()
        margin = 0.05 * scale
    hallucinated = []
    if symmetry:
        arr, hallucinated = hallucinate(arr, views, margin)
    timings["symmetry"] = time.perf_counter() - t

    t = time.perf_counter()
    edges = candidate_edges(arr)
    n_candidates = sum(len(e.options) for e in edges)
    edges, rejected_visibility = prune_by_visibility(arr, edges, views, margin)
    timings["candidates"] = time.perf_counter() - t

    t = time.perf_counter()
    result = search(arr, edges, budget=budget, mu=mu, threshold=threshold, progress=progress)
    timings["search"] = time.perf_counter() - t

    t = time.perf_counter()
    final = result.arrangement
    refined = None
    if final.stability is not None and final.stability.energy > (threshold or 1e-5) / 100:
        refined = refine(final, mu=mu, max_steps=refine_steps)
        from .search import finalize

        fixed = [c for c in refined.arrangement.contacts if c.type == "fixed"]
        final = finalize(refined.arrangement, fixed, mu=mu, threshold=threshold)
    timings["refine"] = time.perf_counter() - t

    unstable = []
    if final.stability is not None and not final.stability.stable:
        from .stability import check_stability

        unstable = check_stability(final, mu=mu, threshold=threshold).unstable_ids
    meta = dict(final.meta)
    meta.update(stage="full")
    final = final.with_(meta=meta)
    report = {
        "cuboids": len(final.cuboids),
        "repaired_overlaps": repaired,
        "hallucinated": hallucinated,
        "candidate_edges": len(edges),
        "candidate_options": n_candidates,
        "rejected_by_visibility": rejected_visibility,
        "visibility": "depth image" if views else "skipped (no camera: a bare point cloud)",
        "search": result.stats.to_json(),
        "fixed_chosen": result.n_fixed,
        "added_volume_m3": result.added_volume,
        "refine": None if refined is None else {
            "energy_before": refined.energy_before, "energy_after": refined.energy_after,
            "steps": refined.steps, "evaluations": refined.evaluations},
        "stable": bool(final.stability.stable) if final.stability else False,
        "energy": float(final.stability.energy) if final.stability else float("nan"),
        "unstable": list(unstable),
        "timings": timings,
    }
    return ImagineResult(final, arr, report)


__all__ = ["imagine", "ImagineResult", "repair_overlaps", "views_from_scan", "depth_noise",
           "sat_separation"]
