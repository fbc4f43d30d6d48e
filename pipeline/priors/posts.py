"""A body that nothing seen can hold stands on a part the view could not see: a post.

Evidence: the boxes the search could not hold even with every candidate contact fixed
(``ctx.unheld``; the orchestrator asks only then), and the depth views.  Physics:
gravity is certain, so a body seen above the floor with no support among the boxes,
the floor and the walls rests on something hidden under it (a table's pedestal behind
what stands on it, a chair's legs lost in the depth noise, a stand cut off by the
picture's edge).  Each object with such boxes gets one post: under the centre of its
lowest upright unheld box, square, from that box's bottom down to the floor, as wide as
the gate lets it be (:data:`WIDTHS` of the box's narrower side, widest first): it may
enter no box and fill no space a view saw empty, and it is no narrower than what stands
with the box on it under gravity tilted by :data:`pipeline.priors.gate.TILT_DEG` (a
narrower one would stand only glued to the floor).  A box above another box's top rests
on that box, which is the one to hold: it gets no post.  The search then decides
whether the posts hold; when fewer boxes fall with them, the result carries them, and
otherwise none of them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import floor_height, free_id, vertical_axis, z_range
from ..model import Cuboid
from .base import Edit, Prior, principle_of
from .gate import TILT_DEG

#: Widths of a post tried, as shares of the narrower horizontal side of the box it holds.
WIDTHS = (0.5, 0.3, 0.2, 0.1)


@dataclass(frozen=True)
class Params:
    #: a box whose bottom is within this of what lies under it (metres) needs no post
    min_height: float = 0.02
    #: no post is narrower than this (metres)
    min_width: float = 0.01


def _over_a_box(arr, c: Cuboid, bottom: float) -> bool:
    """Whether another upright box's top lies under ``c``'s centre below ``bottom``
    (then ``c`` rests on that box, and it is that box that needs holding)."""
    for o in arr.cuboids:
        ax = vertical_axis(o)
        if o.id == c.id or ax is None or z_range(o)[1] > bottom + 1e-9:
            continue
        local = (np.array([c.center[0], c.center[1], o.center[2]]) - o.center) @ o.rotation
        if all(abs(local[k]) <= o.size[k] / 2 for k in range(3) if k != ax):
            return True
    return False


def apply(arr, evidence, p: Params, ctx):
    unheld = set(ctx.unheld)
    if not unheld:
        return
    ground = floor_height(arr)
    if ground is None:
        return
    # one post per object, under its lowest part with nothing but the floor below it
    lowest: dict[str, tuple[float, Cuboid, int]] = {}
    for c in arr.cuboids:
        ax = vertical_axis(c)
        if c.id not in unheld or ax is None:
            continue
        bottom = z_range(c)[0]
        key = c.object or c.id
        if key not in lowest or bottom < lowest[key][0]:
            lowest[key] = (bottom, c, ax)
    for bottom, c, ax in sorted(lowest.values(), key=lambda t: (t[0], t[1].id)):
        height = bottom - ground
        if height < p.min_height or _over_a_box(arr, c, bottom):
            continue
        narrow = float(min(c.size[k] for k in range(3) if k != ax))
        # a post narrower than this tips under the search's tilted gravity with the box
        # on it (its centre of mass no higher than the box's): it would stand only glued
        least = max(p.min_width, 2.0 * np.tan(np.radians(TILT_DEG)) * (c.center[2] - ground))
        name = free_id(arr, f"{c.id}_post")
        for share in WIDTHS:
            width = share * narrow
            if width < least:
                break
            size = np.full(3, width)
            size[ax] = height
            centre = np.array([c.center[0], c.center[1], ground + height / 2])
            post = Cuboid(name, centre, c.rotation, size, c.density, c.object, None,
                          {"hallucinated": True, "points": 0})
            v = yield Edit((post,), f"{c.id}: nothing seen holds it {height:.2f} m up; a "
                                    f"post {100 * width:.0f} cm wide under its centre")
            if v.ok:
                arr = v.arrangement
                break


PRIOR = Prior("posts", "complete", Params(), apply, principle_of(__doc__))
