"""A body that nothing seen can hold reaches, through space no view saw, over what carries it.

Evidence: the boxes the search could not hold even with every candidate contact fixed
(``ctx.unheld``; the orchestrator asks only then, before ``posts``), the boxes under
them and the depth views.  Physics: a rigid body resting on a support stands when its
centre of mass, with everything resting on it, lies over the region where it touches
the support (with gravity tilted by :data:`pipeline.priors.gate.TILT_DEG`, the margin
the search demands).  A plank or a board seen end-on shows only its near end; its
length runs away from the camera, hidden behind that end.  Each horizontal face of an
unheld upright box that faces away from the first view's camera (beyond one facing it,
the view saw) is pushed out, in steps of ``step``, while some box beyond it has its
top within ``rest_gap`` of the body's bottom; the first length at which the body and all
that rests on it (stacked boxes whose bottoms lie within ``rest_gap`` of a top under
them) stands on those boxes in this closed-form check is proposed, the shortest over the
faces (least added volume, as the search prefers).  The gate rejects a push into space a
view saw empty or into another box, and then longer ones are not tried.  A plank on a
block with a weight at its seen end reaches back past the block as far as it must to
balance the weight (a counterweighted cantilever); a body that already stands over the
boxes under it is left to the search.  Bodies are taken lowest first, so what rests on
a body is judged on the body as it reached.  The search then decides whether the reach holds;
when fewer boxes fall with it the result carries it, and otherwise not.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import (
    face_normal,
    footprints,
    overlap_along,
    pushed,
    vertical_axis,
    z_range,
)
from ..model import Arrangement, Cuboid
from .base import Edit, Prior, principle_of
from .gate import TILT_DEG


@dataclass(frozen=True)
class Params:
    #: a box whose top lies within this of a body's bottom can carry it (metres)
    rest_gap: float = 0.04
    #: the push grows by this much per step (metres)
    step: float = 0.02
    #: no push is longer than this many times the scene's median box edge (the search's
    #: own limit on an extension, :data:`pipeline.extend.MAX_EXTENSION_REL`)
    max_rel: float = 12.0


def _footprint(c: Cuboid) -> np.ndarray:
    """(4, 2) float32: the corners of an upright box's footprint, in order (for OpenCV)."""
    return footprints(c.center[None], c.rotation[None], c.size[None])[0].astype(np.float32)


def _contact_region(c: Cuboid, supports: list[Cuboid]) -> np.ndarray | None:
    """The convex hull (k, 1, 2) of where ``c``'s footprint meets the ``supports``' tops."""
    import cv2

    pts = []
    for s in supports:
        area, poly = cv2.intersectConvexConvex(_footprint(c), _footprint(s))
        if area > 1e-8 and poly is not None:
            pts.append(poly.reshape(-1, 2))
    if not pts:
        return None
    return cv2.convexHull(np.concatenate(pts).astype(np.float32))


def _riders(arr: Arrangement, c: Cuboid, gap: float, skip: set[str]) -> list[Cuboid]:
    """Every upright box resting on ``c`` or, in turn, on one that does."""
    out, todo, seen = [], [c], {c.id} | skip
    while todo:
        base = todo.pop()
        top = z_range(base)[1]
        for o in arr.cuboids:
            if o.id in seen or vertical_axis(o) is None:
                continue
            if abs(z_range(o)[0] - top) <= gap and _overlaps(base, o):
                seen.add(o.id)
                out.append(o)
                todo.append(o)
    return out


def _overlaps(a: Cuboid, b: Cuboid) -> bool:
    """Whether two upright boxes' footprints overlap."""
    import cv2

    area, _ = cv2.intersectConvexConvex(_footprint(a), _footprint(b))
    return area > 1e-8


def stands_on(body: Cuboid, riders: list[Cuboid], supports: list[Cuboid]) -> bool:
    """Whether ``body`` with ``riders`` on it stands on ``supports`` (those whose tops its
    footprint does not meet count for nothing): the centre of mass
    of all of them lies inside the region where the body touches the supports' tops, at
    least its height above that region times tan(:data:`TILT_DEG`) from its edge."""
    import cv2

    region = _contact_region(body, supports)
    if region is None:
        return False
    bodies = [body, *riders]
    m = np.array([b.density * float(np.prod(b.size)) for b in bodies])
    com = (m[:, None] * np.array([b.center for b in bodies])).sum(0) / m.sum()
    inside = cv2.pointPolygonTest(region, (float(com[0]), float(com[1])), True)
    margin = (com[2] - z_range(body)[0]) * np.tan(np.radians(TILT_DEG))
    return inside >= margin


def apply(arr, evidence, p: Params, ctx):
    unheld = set(ctx.unheld)
    if not unheld or not arr.cuboids:
        return
    limit = p.max_rel * float(np.median([s for c in arr.cuboids for s in c.size]))
    steps = int(limit / p.step)
    eye = evidence.eye
    # carriers first: what rests on a body is judged once the body has reached
    order = sorted((c for c in arr.cuboids if c.id in unheld and vertical_axis(c) is not None),
                   key=lambda c: (z_range(c)[0], c.id))
    for c0 in order:
        c = arr.cuboid(c0.id)
        ax = vertical_axis(c)
        bottom = z_range(c)[0]
        carriers = [o for o in arr.cuboids if o.id != c.id and vertical_axis(o) is not None
                    and abs(z_range(o)[1] - bottom) <= p.rest_gap]
        if not carriers:
            continue
        riders = _riders(arr, c, p.rest_gap, {o.id for o in carriers})
        if stands_on(c, riders, carriers):
            continue  # it stands over what is under it: the search's to join
        best = None
        for axis in (k for k in range(3) if k != ax):
            for side in (0, 1):
                u = face_normal(c, axis, side)
                if eye is not None and (c.center - eye)[:2] @ u[:2] <= 0:
                    continue  # a face towards the camera: the view saw what is beyond it
                across = c.rotation[:, 3 - ax - axis]
                longest = pushed(c, axis, side, limit)
                # a carrier beyond this face, across from the body
                ahead = [o for o in carriers if overlap_along(c, o, across) > 0
                         and overlap_along(longest, o, u) > 0
                         and (o.center - c.center) @ u > 0]
                if not ahead:
                    continue
                for k in range(1, steps + 1):
                    if best is not None and k * p.step >= best[0]:
                        break
                    trial = pushed(c, axis, side, k * p.step)
                    if stands_on(trial, riders, carriers):
                        best = (k * p.step, trial)
                        break
        if best is None:
            continue
        length, trial = best
        v = yield Edit((trial,), f"{c.id}: nothing seen holds it; it reaches {100 * length:.0f} "
                                 f"cm further, through space no view saw, to stand on what "
                                 f"is under it")
        if v.ok:
            arr = v.arrangement


PRIOR = Prior("reach", "complete", Params(), apply, principle_of(__doc__))
