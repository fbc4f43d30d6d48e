"""A board or panel runs across its object: its hidden end reaches as far as the object.

Evidence: the segmentation's objects and the depth views.  Regularity: furniture is built
of boards and panels that run from one side of the object to the other (a sofa's back
from arm to arm, a shelf's board between its sides, a desk's side panel under the whole
depth of its top).  A single view sees such a part only up to where something in front
hid it, so its fit stops short of the object.  An upright board or panel (its thinnest
extent at most its next one over ``panel_ratio``; a leg or a block is none; nor is a part
most of whose object's parts standing over the same heights, ``copy_share`` of both, are
posts: furniture repeats its legs, and a leg fitted as the sliver of one face is a leg)
whose end along a horizontal axis other than its thickness stops more than
``min_reach`` short of how far the other parts of its object reach in that direction
grows to that reach, or
up to the near face of one of those parts on the way (it meets that part: a board stops
at its side panel), whichever is furthest without entering a part of its object or
sliding in under one it was not under (a side panel stands on the floor, not on the
bottom board), through space no view saw empty
(:data:`pipeline.evidence.FREE_FRACTION_MAX`) and at least ``hidden_min`` of it hidden
from every view (something nearer in front of it, or no reading there).  A part whose
end a view saw keeps it: the space beyond it seen empty, or seen at all (a monitor's
foot lying on a desk, the desk top in plain view beside it: a slab two centimetres above
a seen surface is never "seen empty", the depth noise is wider).  The gate rejects a
growth into another object.  It runs after ``join_parts``: a leg seen only at its foot
is a flat stub, and no board, until it is reached up to its seat.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import (
    UP,
    extent_along,
    face_normal,
    horizontal_axes,
    is_upright,
    overlap_along,
    pushed,
    separations,
    upright_extent,
    z_range,
)
from ..evidence import FREE_FRACTION_MAX, slab_samples
from ..extend import Extension
from .base import Edit, Prior, principle_of


@dataclass(frozen=True)
class Params:
    panel_ratio: float = 3.0  #: a board's thickness is at most its next extent over this
    min_reach: float = 0.03  #: metres the object must reach past the part's end
    #: least share of the growth's samples that no view could see (something nearer in
    #: front of them, or no reading)
    hidden_min: float = 0.5
    #: share of both heights two parts of one object stand over to be copies of each other
    copy_share: float = 0.8


def _board(c, p: Params) -> bool:
    """Whether box ``c`` is a board or panel: its thinnest extent at most its next one over
    ``panel_ratio``."""
    ext = np.sort(c.size)
    return bool(ext[0] <= ext[1] / p.panel_ratio)


def _among_posts(c, mates, p: Params) -> bool:
    """Whether most of the upright parts of ``c``'s object that stand over the same heights
    as ``c`` (each sharing ``copy_share`` of both heights) are posts, not boards: ``c`` is
    one of its object's legs, seen by a sliver of one face."""
    height = upright_extent(c)[0]
    posts = boards = 0
    for q in mates:
        if not is_upright(q) or (overlap_along(c, q, UP)
                                 < p.copy_share * max(height, upright_extent(q)[0])):
            continue
        if _board(q, p):
            boards += 1
        else:
            posts += 1
    return posts > boards


def reaches(arr, k: int, p: Params) -> list[tuple[int, int, float]]:
    """``(axis, side, length)`` growths of part ``k`` across its object: along each of its
    horizontal axes but its thickness, to its object's reach or to the near face of a part
    of its object on the way; ``[]`` when the part is no board or panel or its object
    reaches no further."""
    c = arr.cuboids[k]
    if c.object is None or not is_upright(c):
        return []
    mates = [j for j, q in enumerate(arr.cuboids) if j != k and q.object == c.object]
    if not mates:
        return []
    if not _board(c, p) or _among_posts(c, [arr.cuboids[j] for j in mates], p):
        return []
    thin = int(np.argmin(c.size))
    sub = arr.with_(cuboids=tuple(arr.cuboids[j] for j in mates))
    out = []
    for ax, side in [(a, s) for a in horizontal_axes(c) if a != thin for s in (0, 1)]:
        u = face_normal(c, ax, side)
        w = c.rotation[:, next(a for a in horizontal_axes(c) if a != ax)]
        face = float(c.center @ u + c.size[ax] / 2)
        ends = [(float(q_lo) - face, float(q_hi) - face)
                for q_lo, q_hi in (extent_along(q, u) for q in sub.cuboids)]
        reach = max(far for _near, far in ends)
        # as far as its object reaches, or up to the near face of a part of it on the way
        for length in sorted({reach, *(near for near, _far in ends if near < reach)},
                             reverse=True):
            if length <= p.min_reach:
                break
            grown = pushed(c, ax, side, length)
            sep, tol = separations(sub, grown)
            if np.any(sep < -tol):
                continue  # into a part of its object
            # nor in under one it was not under before (it would carry it)
            top = z_range(grown)[1]
            if any(z_range(q)[0] >= top - t and overlap_along(c, q, u) <= t
                   and overlap_along(grown, q, u) > t and overlap_along(grown, q, w) > t
                   for q, t in zip(sub.cuboids, tol)):
                continue
            out.append((ax, side, length))
            break
    return out


def apply(arr, evidence, p: Params, ctx):
    order = sorted((c.object, k) for k, c in enumerate(arr.cuboids)
                   if c.object is not None and not c.extra.get("hallucinated"))
    for _obj, k in order:
        for ax, side, length in reaches(arr, k, p):
            x = Extension(k, ax, side, length)
            free, hidden = evidence.free_and_hidden(slab_samples(arr, x))
            if free > FREE_FRACTION_MAX:
                continue  # a view saw the part's end: the space beyond it is empty
            if hidden < p.hidden_min:
                continue  # nothing hid the space beyond its end: the view saw it end
            c = arr.cuboids[k]  # as the accepted growths left it: both ends' growths add up
            v = yield Edit((pushed(c, ax, side, length),),
                           f"{c.id}, a board or panel of {c.object}, runs "
                           f"{1000 * length:.0f} mm further to where its object reaches, "
                           f"through space no view saw")
            if v.ok:
                arr = v.arrangement


PRIOR = Prior("span", "complete", Params(), apply, principle_of(__doc__))
