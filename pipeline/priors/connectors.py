"""A part that hangs above another part of its object is held by a part the sensor missed.

Evidence: the segmentation's objects, each part's observed box, and the depth views.
Regularity: an object is one rigid body; a monitor's screen hangs a few centimetres above
its foot on a neck hidden behind it.  Where a view saw into the gap between an upright
part and one of its object's parts below it (beside the lower part, over
:data:`pipeline.evidence.FREE_FRACTION_MAX` of the gap's samples seen empty, so
stretching the upper part down would fill seen space), and no other part of the object
already stands in the gap, a new part fills the columns of the gap over the lower part
that no view saw into at any height (sampled every ``step``), from the lower part's top to
the upper part's bottom.  Only gaps of at least ``min_gap`` and at most ``max_gap_rel`` of
the upper part's height are bridged; the new part is marked ``hallucinated`` and
``connector``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import is_free, same_object_groups, vertical_axis
from ..contacts import pair_tolerance
from ..evidence import FREE_FRACTION_MAX
from ..model import Cuboid
from .base import Edit, Prior, principle_of


@dataclass(frozen=True)
class Params:
    max_gap_rel: float = 0.5  #: the longest gap, in heights of the upper part
    min_gap: float = 0.02  #: metres: a narrower gap is a noisy edge that joins close
    step: float = 0.01  #: metres between samples of the gap


def _gap_grid(a: Cuboid, horiz: list[int], lo: np.ndarray, hi: np.ndarray, z0: float,
              gap: float, step: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Samples every :data:`step` (4 to 64 a side) over the footprint
    ``lo``..``hi`` (in ``a``'s frame, axes ``horiz``) and from height ``z0`` up by ``gap``:
    the two horizontal coordinates (n0, n1, nz) and the world points (n0 * n1 * nz, 3)."""
    n = [max(4, min(64, int(np.ceil((hi[k] - lo[k]) / step)))) for k in horiz]
    nz = max(4, min(16, int(np.ceil(gap / step))))
    t0 = lo[horiz[0]] + (np.arange(n[0]) + 0.5) / n[0] * (hi[horiz[0]] - lo[horiz[0]])
    t1 = lo[horiz[1]] + (np.arange(n[1]) + 0.5) / n[1] * (hi[horiz[1]] - lo[horiz[1]])
    tz = z0 + (np.arange(nz) + 0.5) / nz * gap
    g0, g1, gz = np.meshgrid(t0, t1, tz, indexing="ij")
    pts = (a.center + g0[..., None] * a.rotation[:, horiz[0]]
           + g1[..., None] * a.rotation[:, horiz[1]])
    pts[..., 2] = gz
    return g0, g1, pts.reshape(-1, 3)


def _over(g0: np.ndarray, g1: np.ndarray, horiz: list[int], lo: np.ndarray,
          hi: np.ndarray) -> np.ndarray:
    """Which samples of :func:`_gap_grid` lie inside the footprint ``lo``..``hi``."""
    return ((g0 > lo[horiz[0]]) & (g0 < hi[horiz[0]])
            & (g1 > lo[horiz[1]]) & (g1 < hi[horiz[1]]))


def _between(c: Cuboid, a: Cuboid, b: Cuboid, lo: float, hi: float, pad: float = 0.01
             ) -> bool:
    """Whether ``c`` stands in the gap from height ``lo`` to ``hi`` between ``b`` below
    and ``a`` above: it spans half the gap's height, and its footprint overlaps both
    theirs or comes within ``pad`` of them (world-aligned bounds)."""
    z = c.corners()[:, 2]
    if min(z.max(), hi) - max(z.min(), lo) < 0.5 * (hi - lo):
        return False
    cx = c.corners()[:, :2]
    for other in (a, b):
        ox = other.corners()[:, :2]
        if (np.any(cx.max(axis=0) + pad < ox.min(axis=0))
                or np.any(ox.max(axis=0) + pad < cx.min(axis=0))):
            return False
    return True


def apply(arr, evidence, p: Params, ctx):
    if not evidence:
        return

    by_object: dict[str, list[int]] = {}
    for k, c in enumerate(arr.cuboids):
        if c.object is not None:
            by_object.setdefault(c.object, []).append(k)
    if not any(len(m) > 1 for m in by_object.values()):
        return
    groups = same_object_groups(arr)
    added: list[Cuboid] = []
    for i, a in enumerate(arr.cuboids):
        ka = vertical_axis(a)
        if a.object is None or ka is None or a.extra.get("hallucinated"):
            continue
        a_lo = float(a.center[2] - a.size[ka] / 2)
        horiz = [k for k in range(3) if k != ka]
        for j in by_object[a.object]:
            b = arr.cuboids[j]
            if j == i or groups[i] == groups[j] or (kb := vertical_axis(b)) is None:
                continue
            b_hi = float(b.center[2] + b.size[kb] / 2)
            gap = a_lo - b_hi
            tol = float(pair_tolerance(a.size[None], b.size[None])[0])
            if not max(tol, p.min_gap) < gap <= p.max_gap_rel * a.size[ka]:
                continue
            if any(_between(arr.cuboids[m], a, b, b_hi, a_lo) for m in by_object[a.object]
                   if m not in (i, j)):
                continue  # a part of theirs already stands in the gap (the neck, seen)
            # a stretched down to b would fill the gap under its seen face: beside b (over
            # b the gap is too close to b's top for the sensor to tell) was it seen empty?
            o = a.observed
            if o is None:
                continue
            local = (b.corners() - a.center) @ a.rotation  # b's corners in a's frame
            blo, bhi = local.min(axis=0), local.max(axis=0)
            oc = a.rotation.T @ (np.asarray(o.center, float) - a.center)
            osz = np.asarray(o.size, float)
            g0, g1, pts = _gap_grid(a, horiz, oc - osz / 2, oc + osz / 2, b_hi, gap, p.step)
            beside = ~_over(g0, g1, horiz, blo, bhi).reshape(-1)
            if not beside.any() or evidence.free_mask(pts[beside]).mean() \
                    <= FREE_FRACTION_MAX:
                continue  # nothing seen in the gap: a join may close it
            # the columns over b that no view saw into, at any height
            lo, hi = -a.size / 2, a.size / 2
            g0, g1, pts = _gap_grid(a, horiz, lo, hi, b_hi, gap, p.step)
            n = g0.shape[:2]
            seen = evidence.free_mask(pts).reshape(g0.shape)
            hidden = _over(g0, g1, horiz, blo, bhi)[..., 0] & ~seen.any(axis=2)
            if not hidden.any():
                continue
            r0, r1 = np.nonzero(hidden)
            d0, d1 = a.size[horiz[0]] / n[0], a.size[horiz[1]] / n[1]
            lo0, hi0 = lo[horiz[0]] + r0.min() * d0, lo[horiz[0]] + (r0.max() + 1) * d0
            lo1, hi1 = lo[horiz[1]] + r1.min() * d1, lo[horiz[1]] + (r1.max() + 1) * d1
            size = np.zeros(3)
            size[horiz[0]], size[horiz[1]], size[ka] = hi0 - lo0, hi1 - lo1, gap
            center = (a.center + (lo0 + hi0) / 2 * a.rotation[:, horiz[0]]
                      + (lo1 + hi1) / 2 * a.rotation[:, horiz[1]])
            center[2] = b_hi + gap / 2
            new = Cuboid(f"j{len(added)}_{a.object}", center, a.rotation.copy(), size,
                         a.density, a.object, None,
                         {"hallucinated": True, "connector": True, "points": 0})
            if not is_free(arr.with_(cuboids=arr.cuboids + tuple(added)), new):
                continue
            v = yield Edit((new,), f"{a.id} hangs {100 * gap:.0f} cm above {b.id} with the gap "
                                   f"seen beside it: a hidden part holds it")
            if v.ok:
                added.append(new)
                groups = {k: (groups[i] if w == groups[j] else w) for k, w in groups.items()}


PRIOR = Prior("connectors", "complete", Params(), apply, principle_of(__doc__))
