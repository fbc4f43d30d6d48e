"""A body that nothing seen can hold stands on a part the view could not see: a post.

Evidence: the boxes the search could not hold even with every candidate contact fixed
(``ctx.unheld``; the orchestrator asks only then), and the depth views.  Physics:
gravity is certain, so a body seen above the floor with no support among the boxes,
the floor and the walls rests on something hidden under it (a table's pedestal behind
what stands on it, a chair's legs lost in the depth noise, a stand cut off by the
picture's edge).  Each such upright box gets one post of its own object: under its
centre, square, from its bottom down to the highest top of a box below that centre or
to the floor, as wide as the gate lets it be (:data:`WIDTHS` of the box's narrower
side, widest first): it may enter no box and fill no space a view saw empty.  The
search then decides whether the post holds the box; a post that does not is a part
the result does not need and is never proposed again.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import vertical_axis
from ..model import Cuboid
from .base import Edit, Prior, principle_of

#: Widths of a post tried, as shares of the narrower horizontal side of the box it holds.
WIDTHS = (0.5, 0.3, 0.2, 0.1)


@dataclass(frozen=True)
class Params:
    #: a box whose bottom is within this of what lies under it (metres) needs no post
    min_height: float = 0.02
    #: no post is narrower than this (metres)
    min_width: float = 0.01


def _below(arr, c: Cuboid, xy: np.ndarray, bottom: float) -> float:
    """Height of the highest top under point ``xy`` below ``bottom``: another upright
    box's top (its footprint holding ``xy``), else the ground's."""
    best = next((float(s.point[2]) for s in arr.supports if s.id == "ground"), 0.0)
    for o in arr.cuboids:
        if o.id == c.id:
            continue
        ax = vertical_axis(o)
        if ax is None:
            continue
        top = float(o.center[2] + o.size[ax] / 2)
        if top > bottom + 1e-9 or top <= best:
            continue
        local = (np.array([xy[0], xy[1], o.center[2]]) - o.center) @ o.rotation
        horiz = [k for k in range(3) if k != ax]
        if all(abs(local[k]) <= o.size[k] / 2 for k in horiz):
            best = top
    return best


def apply(arr, evidence, p: Params, ctx):
    unheld = set(ctx.unheld)
    if not unheld:
        return
    for c in list(arr.cuboids):
        if c.id not in unheld:
            continue
        ax = vertical_axis(c)
        if ax is None:
            continue
        bottom = float(c.center[2] - c.size[ax] / 2)
        floor = _below(arr, c, c.center[:2], bottom)
        height = bottom - floor
        if height < p.min_height:
            continue
        narrow = float(min(c.size[k] for k in range(3) if k != ax))
        for share in WIDTHS:
            width = share * narrow
            if width < p.min_width:
                break
            size = np.full(3, width)
            size[ax] = height
            centre = np.array([c.center[0], c.center[1], floor + height / 2])
            post = Cuboid(f"{c.id}_post", centre, c.rotation, size, c.density, c.object,
                          None, {"hallucinated": True, "points": 0})
            v = yield Edit((post,), f"{c.id}: nothing seen holds it {bottom:.2f} m up; a "
                                    f"post {100 * width:.0f} cm wide under its centre")
            if v.ok:
                arr = v.arrangement
                break


PRIOR = Prior("posts", "complete", Params(), apply, principle_of(__doc__))
