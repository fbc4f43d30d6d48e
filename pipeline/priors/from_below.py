"""Weight goes down: what rests on furniture is carried from below, not by a wall's friction.

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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import as_seen, fixed_components, horizontal_axes, is_upright, pushed
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


def _leaning(arr, ctx, p: Params):
    """(body members, wall id, supporter ids) of each rigid body that carries load at a
    wall while it rests on a box, in a stable order."""
    try:
        cs, res, carries = load_carrying(arr, mu=ctx.mu, threshold=ctx.threshold)
    except InputError:
        return []
    if not res.stable:
        return []
    ids = set(arr.ids)
    body = fixed_components(list(arr.ids), arr.contacts)
    members: dict[int, list[str]] = {}
    for m, k in body.items():
        members.setdefault(k, []).append(m)
    cos_below = np.cos(np.radians(p.below_deg))
    at_wall: dict[int, set[str]] = {}
    below: dict[int, set[str]] = {}
    for i, (a, b) in enumerate(cs.pairs):
        if b.startswith("wall:") and a in ids and carries[i]:
            at_wall.setdefault(body[a], set()).add(b)
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
    return out


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


def apply(arr, evidence, p: Params, ctx):
    final = arr
    walls = {s.id: s for s in arr.supports if s.id.startswith("wall:")}
    if not walls:
        return
    tried: set[tuple[str, ...]] = set()
    leaning = _leaning(final, ctx, p)  # again only when an edit changes the arrangement
    while True:
        proposal = None
        for load_ids, w, sups in leaning:
            for s in sups:
                key = (*load_ids, s, w)
                if key in tried or s in load_ids:
                    continue
                tried.add(key)
                new = _push(final, load_ids, walls[w], final.cuboids[final.index[s]], p)
                if new is not None:
                    proposal = (load_ids, w, s, new)
                    break
            if proposal is not None:
                break
        if proposal is None:
            return
        load_ids, w, s, new = proposal
        old = final.cuboids[final.index[s]]
        grow = float(np.max(new.size - old.size))
        v = yield Edit((new,), f"{', '.join(load_ids)} leant on {w} while resting on {s}: "
                               f"{s} pushed {1000 * grow:.0f} mm under it towards {w}")
        if v.ok:
            final = v.arrangement
            leaning = _leaning(final, ctx, p)


PRIOR = Prior("from_below", "settle", Params(), apply, principle_of(__doc__))
