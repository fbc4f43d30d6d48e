"""Weight goes down: what rests on furniture is carried from below, not by a wall or the floor.

Evidence: the statics of the searched arrangement (which contacts carry load), the walls,
and the depth views.  Regularity: a lamp, a plant or a monitor standing on a night stand,
a dresser or a desk is carried by that furniture; where the search left such a load
pressing on the wall behind it (its footprint reaching past the supporter's face towards
the wall, so that it stands only by leaning there), the supporter's side towards the wall
was cut short by the view: a box of furniture seldom stops where the sensor stopped
seeing it.  When a rigid body (a box and the parts ``fixed`` to it) carries load at a
wall and rests on a box below it, and the sensor saw the load reach past that box's
upright face turned towards the wall (within ``axis_deg``) by ``min_push`` or more, the
face is pushed out under as much of the load as the sensor saw (the rest of the load
is the search's guess), no further than the wall, as far as no view saw the added space
empty and nothing is entered.  The search preferred the lean because it added less volume; the lean it
leaves is the less likely account of a load that the sensor saw resting on furniture.
Loads on the floor and objects leaning on a wall from the floor (a board, a mattress)
are left alone.

The floor is no better a prop than the wall (``propped``).  A body resting at one level
does not also stand on the floor: where the search propped a load that rests on a box
below it by a part of the load reaching down to the floor through space the sensor never
saw (the part seen nowhere lower than ``rest_gap`` under the top it rests on: a lamp's
shade, seen above a night stand, stretched down behind the stand), the column is the
cheaper account in added volume only.  The supporter's upright face that the part's
seen footprint reaches past is pushed out under it (as far as that, short of any box in
the way, and ``min_push`` at least), and the part is cut back to where it was seen (no
lower than the supporter's top), in one edit that the gate keeps only where nothing is
entered, no view saw the added space empty and every box still stands.  A part seen
down near the floor (a leg), or glued to it, is never such a column.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import (
    as_seen,
    entered,
    extent_along,
    fixed_components,
    horizontal_axes,
    is_upright,
    overlap_along,
    pushed,
    up_axis,
    z_range,
)
from ..errors import InputError
from ..stability import load_carrying
from .base import Edit, Prior, principle_of


@dataclass(frozen=True)
class Params:
    #: Largest angle (degrees) between a supporter's face normal and the direction to the wall.
    axis_deg: float = 30.0
    #: Shortest push worth making (metres).
    min_push: float = 0.01
    #: A contact whose normal is within this angle (degrees) of vertical carries from below.
    below_deg: float = 30.0
    #: A part of a load seen nowhere lower than this under the top the load rests on
    #: reaches the floor only through unseen space (metres; ``propped``).
    rest_gap: float = 0.04


def _loads(arr, ctx, p: Params):
    """(body members, wall id, supporter ids) of each rigid body that carries load at a
    wall while it rests on a box, in a stable order; and (body members, column members,
    supporter ids) of each that carries load at the floor through parts seen nowhere
    near it (``propped``)."""
    try:
        cs, res, carries = load_carrying(arr, mu=ctx.mu, threshold=ctx.threshold)
    except InputError:
        return [], []
    if not res.stable:
        return [], []
    ids = set(arr.ids)
    body = fixed_components(list(arr.ids), arr.contacts)
    members: dict[int, list[str]] = {}
    for m, k in body.items():
        members.setdefault(k, []).append(m)
    cos_below = np.cos(np.radians(p.below_deg))
    at_wall: dict[int, set[str]] = {}
    at_floor: dict[int, set[str]] = {}
    below: dict[int, set[str]] = {}
    glued = {c.key for c in arr.contacts if c.type == "fixed"}
    for i, (a, b) in enumerate(cs.pairs):
        if b.startswith("wall:") and a in ids and carries[i]:
            at_wall.setdefault(body[a], set()).add(b)
        if b == "ground" and a in ids and carries[i] and tuple(sorted((a, b))) not in glued:
            at_floor.setdefault(body[a], set()).add(a)
        if a in ids and b in ids and body[a] != body[b]:
            n = cs.normal[i]  # from b into a
            if abs(float(n[2])) >= cos_below:
                upper, lower = (a, b) if n[2] > 0 else (b, a)
                below.setdefault(body[upper], set()).add(lower)
    out = []
    for k in sorted(at_wall):
        if k in below:
            for w in sorted(at_wall[k]):
                out.append((sorted(members[k]), w, sorted(below[k])))
    propped = []
    for k in sorted(at_floor):
        if k not in below:
            continue
        sups = sorted(below[k])
        level = min(z_range(arr.cuboids[arr.index[s]])[1] for s in sups)
        cols = sorted(m for m in at_floor[k]
                      if z_range(as_seen(arr.cuboids[arr.index[m]]))[0] >= level - p.rest_gap)
        if cols and len(cols) == len(at_floor[k]):
            propped.append((sorted(members[k]), cols, sups))
    return out, propped


def _push(arr, load_ids, wall, sup, p: Params):
    """The supporter ``sup`` pushed towards ``wall`` under as much of the load (the boxes
    ``load_ids``) as the sensor saw, no further than the wall; None when that is less
    than ``p.min_push`` or ``sup`` has no upright face turned towards the wall."""
    d = -wall.normal.copy()
    d[2] = 0.0
    if np.linalg.norm(d) < 1e-6 or not is_upright(sup):
        return None
    d /= np.linalg.norm(d)
    best = None
    for ax in horizontal_axes(sup):
        c = float(sup.rotation[:, ax] @ d)
        if abs(c) >= np.cos(np.radians(p.axis_deg)):
            best = (ax, 1 if c > 0 else 0, np.sign(c) * sup.rotation[:, ax])
    if best is None:
        return None
    ax, side, u = best
    face = float(sup.center @ u) + float(sup.size[ax]) / 2
    loads = [arr.cuboids[arr.index[m]] for m in load_ids]
    seen = [as_seen(c) for c in loads]
    want = max(float(np.max(c.corners() @ u)) for c in seen) - face
    # the pushed face's corners stay in front of the wall
    corners = sup.corners()
    on_face = corners[(corners - sup.center) @ u > 0]
    into = float(-(u @ wall.normal))
    if into > 1e-6:
        want = min(want, float(np.min(wall.signed_distance(on_face))) / into)
    if want < p.min_push:
        return None
    return pushed(sup, ax, side, want)


def _under(arr, cols, sup, p: Params):
    """The supporter ``sup`` pushed out under the column parts ``cols`` as the sensor saw
    them, and each column cut back to its seen bottom (no lower than ``sup``'s top); None
    when no upright face of ``sup`` has them past it by ``p.min_push`` and beside it."""
    if not is_upright(sup):
        return None
    seen = [as_seen(arr.cuboids[arr.index[m]]) for m in cols]
    best = None
    hs = horizontal_axes(sup)
    for ax in hs:
        across = sup.rotation[:, hs[1] if ax == hs[0] else hs[0]]
        beside = all(overlap_along(c, sup, across) > 0 for c in seen)
        for side in (0, 1):
            u = sup.rotation[:, ax] * (1.0 if side else -1.0)
            face = float(sup.center @ u) + float(sup.size[ax]) / 2
            want = max(extent_along(c, u)[1] for c in seen) - face
            if want >= p.min_push and beside and (best is None or want > best[2]):
                best = (ax, side, want)
    if best is None:
        return None
    ax, side, want = best
    skip = [arr.index[sup.id], *(arr.index[m] for m in cols)]
    before = set(entered(arr, sup, skip).tolist())

    def fits(length: float) -> bool:
        """Whether the push enters no box it did not already overlap."""
        return set(entered(arr, pushed(sup, ax, side, length), skip).tolist()) <= before

    if not fits(want):
        lo, hi = 0.0, want  # the longest push that enters nothing new (a bisection)
        for _ in range(12):
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if fits(mid) else (lo, mid)
        want = lo
    if want < p.min_push:
        return None
    top = z_range(sup)[1]
    cut = []
    for m in cols:
        c = arr.cuboids[arr.index[m]]
        bottom, head = z_range(c)
        new_bottom = max(z_range(as_seen(c))[0], top)
        if new_bottom >= head:
            return None
        up = up_axis(c)
        down = 0 if c.rotation[2, up] > 0 else 1  # the face looking down
        cut.append(pushed(c, up, down, -(new_bottom - bottom)))
    return (pushed(sup, ax, side, want), *cut)


def _proposals(final, walls, leaning, propped, tried, p: Params):
    """The next edit to propose (boxes, reason) from the bodies found, or None."""
    for load_ids, cols, sups in propped:
        for s in sups:
            key = (*load_ids, s, "ground")
            if key in tried or s in load_ids:
                continue
            tried.add(key)
            old = final.cuboids[final.index[s]]
            boxes = _under(final, cols, old, p)
            if boxes is not None:
                grow = float(np.max(boxes[0].size - old.size))
                return boxes, (f"{', '.join(load_ids)} propped on the floor by "
                               f"{', '.join(cols)}, seen only above {s}: {s} pushed "
                               f"{1000 * grow:.0f} mm under it, the column cut to what was seen")
    for load_ids, w, sups in leaning:
        for s in sups:
            key = (*load_ids, s, w)
            if key in tried or s in load_ids:
                continue
            tried.add(key)
            old = final.cuboids[final.index[s]]
            new = _push(final, load_ids, walls[w], old, p)
            if new is not None:
                grow = float(np.max(new.size - old.size))
                return (new,), (f"{', '.join(load_ids)} leant on {w} while resting on {s}: "
                                f"{s} pushed {1000 * grow:.0f} mm under it towards {w}")
    return None


def apply(arr, evidence, p: Params, ctx):
    final = arr
    walls = {s.id: s for s in arr.supports if s.id.startswith("wall:")}
    tried: set[tuple[str, ...]] = set()
    leaning, propped = _loads(final, ctx, p)  # again only when an edit is accepted
    while True:
        proposal = _proposals(final, walls, leaning, propped, tried, p)
        if proposal is None:
            return
        v = yield Edit(*proposal)
        if v.ok:
            final = v.arrangement
            leaning, propped = _loads(final, ctx, p)


PRIOR = Prior("from_below", "settle", Params(), apply, principle_of(__doc__))
