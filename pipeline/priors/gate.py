"""The one gate every proposed edit passes: :func:`accept`.

An edit (:class:`pipeline.priors.base.Edit`) is rejected, with the reason, when

0. **it collapses a box**: a box it changes or adds is thinner than :data:`MIN_SIDE`
   along some axis (and was not before): no fit or clearing may leave a box without
   volume (in every stage);
1. **it enters another box**: a box it changes or adds overlaps another box, a wall or
   the floor by more than their contact tolerance, and deeper than before the edit
   (overlaps a fitted box already had may stay: removing them is the ``overlaps``
   prior's job; a box merged into another counts with the overlaps of both);
2. **it puts volume where a depth view saw empty space**: more than
   :data:`pipeline.evidence.FREE_FRACTION_MAX` of the samples of the volume it adds to
   a box (each pushed face's slab; for a turned box, the part outside the old box; a
   new box whole) lie clearly in front of the depth (:mod:`pipeline.evidence`, one
   noise model for every prior);
3. **after the search** (stage ``settle``) **a box falls that stood**: the arrangement with the edit, its
   contacts listed from the geometry (``fixed`` where the edit says), fails the analytic
   check with gravity tilted by :data:`TILT_DEG` (the margin the search demands: no
   knife-edge explanations) for a box that stood before the edit.

Rules 1 and 2 judge what is added beyond the fit, from the ``complete`` stage on.  The
``prepare`` stage corrects the fit itself (a box stood upright, turned to hold more of
its points, two overlapping fits cleared): its boxes may still overlap, clearing those
overlaps is that stage's last prior, and its priors judge each correction by the
observed points it is fitted to.  Before the search there is no contact graph to judge (rule 3); the
search itself then demands stability with gravity tilted by
:data:`pipeline.search.ROBUST_TILT_DEG`.
"""

from __future__ import annotations

import numpy as np

from ..boxops import box_samples, near
from ..contacts import find_contacts
from ..errors import InputError
from ..evidence import FREE_FRACTION_MAX, Evidence
from ..model import Arrangement, Cuboid
from .base import Context, Edit, Verdict

#: An overlap counts as deeper than before when it grew by more than this (metres):
#: the separating-axis depth of an unchanged pair moves by rounding when a box is
#: rebuilt from its pushed faces.
ENTER_TOL = 1e-6
#: No edit may leave a box thinner than this (metres) along any axis (rule 0).
MIN_SIDE = 1e-3
#: Samples per axis of the volume an edit adds.
SAMPLES = 5
#: Gravity is tilted by this many degrees (towards +-x and +-y) in rule 3: the search's
#: margin (:data:`pipeline.search.ROBUST_TILT_DEG`).
TILT_DEG = 2.0


def apply_edit(arr: Arrangement, edit: Edit) -> Arrangement:
    """``arr`` with the edit's boxes in place (same id) or appended (new id), and its
    removed boxes taken away; contacts and verdict left for the caller."""
    new = {c.id: c for c in edit.boxes}
    gone = set(edit.removed)
    cubs = [new.pop(c.id, c) for c in arr.cuboids if c.id not in gone]
    cubs += [c for c in edit.boxes if c.id in new]
    return arr.with_(cuboids=tuple(cubs))


def _pen_depths(arr: Arrangement, ids: set[str]) -> dict[tuple[str, str], float]:
    """Overlap depth of every overlapping pair with one of ``ids`` among the boxes near
    them (keys sorted)."""
    ks = {arr.index[i] for i in ids if i in arr.index}
    if not ks:
        return {}
    local = near(arr, ks)
    sub = arr.with_(cuboids=tuple(arr.cuboids[n] for n in local), contacts=(), stability=None)
    return {tuple(sorted((p, q))): float(d) for p, q, d in find_contacts(sub).penetrations
            if p in ids or q in ids}


def entered(arr: Arrangement, trial: Arrangement, edit: Edit) -> str | None:
    """The first pair the edit makes overlap deeper (``"a into b"``), or None."""
    changed = set(edit.ids)
    after = _pen_depths(trial, changed)
    if not after:
        return None
    before = _pen_depths(arr, changed | set(edit.removed))
    gone = set(edit.removed)
    for (p, q), d in sorted(after.items()):
        was = before.get((p, q), 0.0)
        if gone:  # a merged box carries the overlaps of what it swallowed
            for g in gone:
                for a, b in ((g, q), (p, g)):
                    was = max(was, before.get(tuple(sorted((a, b))), 0.0))
        if d > was + ENTER_TOL:
            return f"{p} into {q} by {1000 * d:.1f} mm"
    return None


def added_samples(old: Cuboid | None, new: Cuboid, n: int = SAMPLES) -> list[np.ndarray]:
    """Samples of the volume ``new`` adds to ``old``: one set per pushed face (its slab,
    kept off the borders as the candidates' slabs are), the part of a turned box outside
    the old one, or the whole of a new box."""
    if old is None:
        return [box_samples(new, n)]
    if not np.allclose(old.rotation, new.rotation, atol=1e-12):
        pts = box_samples(new, n + 2)
        local = (pts - old.center) @ old.rotation
        out = np.any(np.abs(local) > old.size / 2 + 1e-9, axis=1)
        return [pts[out]] if out.any() else []
    R = new.rotation
    o = R.T @ old.center
    c = R.T @ new.center
    o_lo, o_hi = o - old.size / 2, o + old.size / 2
    n_lo, n_hi = c - new.size / 2, c + new.size / 2
    ts = (np.arange(n) + 0.5) / n
    out = []
    for axis in range(3):
        for lo, hi in ((o_hi[axis], n_hi[axis]), (n_lo[axis], o_lo[axis])):
            if hi - lo <= 1e-6:
                continue
            grids = []
            for k in range(3):
                if k == axis:
                    grids.append(lo + (hi - lo) * (0.1 + 0.8 * ts))
                else:
                    grids.append(c[k] + (ts * 2 - 1) * new.size[k] / 2 * 0.85)
            g = np.stack(np.meshgrid(*grids, indexing="ij"), axis=-1).reshape(-1, 3)
            out.append(g @ R.T)
    return out


def seen_empty(arr: Arrangement, edit: Edit, evidence: Evidence) -> str | None:
    """The first box whose added volume a view saw empty (``"b3: 40 % seen empty"``)."""
    if not evidence:
        return None
    for c in edit.boxes:
        old = arr.cuboids[arr.index[c.id]] if c.id in arr.index else None
        for pts in added_samples(old, c):
            frac = evidence.free_fraction(pts)
            if frac > FREE_FRACTION_MAX:
                return f"{c.id}: {100 * frac:.0f} % of its added volume seen empty"
    return None


def accept(arr: Arrangement, edit: Edit, evidence: Evidence, ctx: Context | None = None,
           stage: str = "complete") -> Verdict:
    """Judge ``edit`` against ``arr`` (module docstring) in ``stage``; returns the
    :class:`Verdict`."""
    ctx = ctx or Context()
    trial = apply_edit(arr, edit)
    why = collapsed(arr, edit)
    if why is not None:
        return Verdict(False, arr, why)
    if stage != "prepare":
        why = entered(arr, trial, edit) or seen_empty(arr, edit, evidence)
    if why is not None:
        return Verdict(False, arr, why)
    if stage in ("prepare", "complete"):
        return Verdict(True, trial)
    from ..search import finalize

    fixed = edit.fixed if edit.fixed is not None else tuple(
        c for c in arr.contacts if c.type == "fixed")
    try:
        cand = finalize(trial.with_(stability=None), list(fixed), mu=ctx.mu,
                        threshold=ctx.threshold)
    except InputError:
        return Verdict(False, arr, "a fixed pair no longer touches")
    falls = _falling(cand, ctx) - _falling(arr, ctx)
    if falls:
        return Verdict(False, arr, f"{', '.join(sorted(falls))} would fall "
                                   f"(gravity tilted {TILT_DEG:g} deg)")
    return Verdict(True, cand)


def collapsed(arr: Arrangement, edit: Edit) -> str | None:
    """Rule 0: why ``edit`` collapses a box (thinner than :data:`MIN_SIDE`), or None."""
    for c in edit.boxes:
        thin = float(np.min(c.size))
        if thin >= MIN_SIDE:
            continue
        old = arr.cuboids[arr.index[c.id]] if c.id in arr.index else None
        if old is None or float(np.min(old.size)) >= MIN_SIDE:
            return f"{c.id} would be {1000 * thin:.2g} mm thin (a box keeps a volume)"
    return None


def _falling(arr: Arrangement, ctx: Context) -> set[str]:
    """Ids of the boxes of ``arr`` that fail the analytic check with gravity tilted by
    :data:`TILT_DEG` (remembered per arrangement in ``ctx.memo``)."""
    from ..stability import check_stability

    key = id(arr)
    hit = ctx.memo.get(key)
    if hit is not None and hit[0] is arr:
        return hit[1]
    cache = ctx.memo.setdefault("solves", {})
    if len(cache) > 512:
        cache.clear()
    try:
        res = check_stability(arr, mu=ctx.mu, threshold=ctx.threshold, tilt_deg=TILT_DEG,
                              solve_cache=cache)
        out = set() if res.stable else set(res.unstable_ids) or set(arr.ids)
    except InputError:  # a listed fixed pair apart: nothing stands as listed
        out = set(arr.ids)
    if len(ctx.memo) > 64:
        solves = ctx.memo.pop("solves")
        ctx.memo.clear()
        ctx.memo["solves"] = solves
    ctx.memo[key] = (arr, out)
    return out
