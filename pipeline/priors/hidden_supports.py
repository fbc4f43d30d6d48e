"""What the search stretched to the floor far below what was seen rests on a hidden support.

Evidence: each box's observed box, the contacts the search chose, the depth views.
Regularity: a sofa's seat is hidden under its cushions and behind its back; the search
can hold a cushion up only by growing it to the floor, half a metre of cushion.  A box
of a one-part object, seen over a height ``h`` and grown down to the floor by more than
``drop_rel`` ``h`` (and ``min_drop``), keeps its seen part and stands on a new box below it
(``hidden_support``, hallucinated).  New boxes side by side (gap under ``merge_gap``) with
tops at one height merge (one seat under two cushions); a new box touching parts of a
multi-part object becomes a part of it, reaching out to them across hidden space by at
most ``reach_rel`` of its width, fused to them.  A box alone, next to no such object, is
left as the search made it: one tall box whose top was all the sensor saw is as likely.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import gap, is_upright, merged, overlap_across, same_axes, up_axis, z_range
from ..contacts import find_contacts
from ..evidence import slab_samples
from ..model import Arrangement, Contact, Cuboid
from .base import Edit, Prior, principle_of


@dataclass(frozen=True)
class Params:
    drop_rel: float = 1.5  #: the drop, in seen heights of the box
    min_drop: float = 0.15  #: metres
    merge_gap: float = 0.05  #: metres between new supports that merge, and between tops
    reach_rel: float = 0.25  #: a support reaches out by this fraction of its width


def _reach_out(support: Cuboid, others: list[Cuboid], reach: float, evidence) -> Cuboid:
    """``support`` with each horizontal face pushed out to the nearest of ``others`` it
    faces (overlapping it sideways and in height) when that is at most ``reach`` away
    and no view saw the added slab empty: a seat hidden under cushions meets the arms
    and the back around it."""
    from ..extend import Extension

    out = support
    for axis in range(3):
        if abs(support.rotation[2, axis]) > 0.5:
            continue
        for side in (0, 1):
            u = out.rotation[:, axis] * (1.0 if side else -1.0)
            face = float(out.center @ u + out.size[axis] / 2)
            best = None
            for o in others:
                if overlap_across(out, o, u) and (gap := float((o.corners() @ u).min()) - face) > 0:
                    best = gap if best is None else min(best, gap)
            if best is None or best > reach:
                continue
            tmp = Arrangement((out,), ())
            x = Extension(0, axis, side, best)
            if evidence.seen_empty(slab_samples(tmp, x)):
                continue
            size = out.size.copy()
            size[axis] += best
            out = out.with_(center=out.center + u * best / 2, size=size)
    return out


def apply(arr, evidence, p: Params, ctx):
    final = arr
    if final.stability is None or not final.stability.stable:
        return
    parts: dict[str, int] = {}
    for c in final.cuboids:
        if c.object is not None:
            parts[c.object] = parts.get(c.object, 0) + 1
    grounded = {c.a for c in final.contacts if c.b == "ground"} | \
        {c.b for c in final.contacts if c.a == "ground"}
    cands = []  # (cut box, support box)
    for c in final.cuboids:
        o = c.observed
        if (o is None or c.extra.get("hallucinated") or c.id not in grounded
                or (c.object is not None and parts[c.object] > 1)):
            continue
        k = up_axis(c)
        if not is_upright(c):
            continue
        bottom, _ = z_range(c)
        seen_bottom = float(o.center[2] - o.size[k] / 2)
        drop = seen_bottom - bottom
        if drop < max(p.min_drop, p.drop_rel * float(o.size[k])):
            continue
        size = c.size.copy()
        size[k] = drop
        low = c.with_(center=np.array([*c.center[:2], bottom + drop / 2]), size=size)
        size = c.size.copy()
        size[k] -= drop
        cut = c.with_(center=np.array([*c.center[:2], seen_bottom + size[k] / 2]), size=size)
        cands.append((cut, low))
    if not cands:
        return

    def beside(i: int, j: int) -> bool:
        a, b = cands[i][1], cands[j][1]
        return (same_axes(a, b) and gap(a, b) < p.merge_gap
                and abs(z_range(a)[1] - z_range(b)[1]) < p.merge_gap)

    def grouped(members: list[int], chain: bool) -> list[list[int]]:
        """Supports side by side with tops at one height, as groups: beside any box of
        the group (``chain``: a row of three cushions) or beside its first one."""
        out: list[list[int]] = []
        for i in members:
            for g in out:
                if any(beside(i, j) for j in (g if chain else g[:1])):
                    g.append(i)
                    break
            else:
                out.append([i])
        return out

    # each group becomes one box (in its first box's frame); a row that cannot (the
    # merged box grazes an arm) is tried again as the boxes beside its first one
    groups = grouped(list(range(len(cands))), chain=True)
    objects = {c.object for c in final.cuboids if c.object is not None and parts[c.object] > 1}
    current = final
    n = -1
    while groups:
        g = groups.pop(0)
        n += 1
        low = cands[g[0]][1]
        for i in g[1:]:
            low = merged(low, cands[i][1])
        k = up_axis(low)
        top = min(z_range(cands[i][0])[0] for i in g)
        size = low.size.copy()
        size[k] = top - z_range(low)[0]
        new_id = f"hidden{n}"
        while new_id in current.index:
            new_id += "_"
        support = Cuboid(new_id, np.array([*low.center[:2], top - size[k] / 2]), low.rotation,
                         size, low.density, None, None,
                         {"hallucinated": True, "hidden_support": True, "points": 0})
        cut = {}
        for i in g:  # each box down to the common top (at most the merge gap)
            c = cands[i][0]
            grow = z_range(c)[0] - top
            sz = c.size.copy()
            sz[up_axis(c)] += grow
            cut[c.id] = c.with_(center=c.center - np.array([0, 0, grow / 2]), size=sz)
        # a part of the multi-part object it touches most (the sofa around its seat),
        # reaching out to that object's parts across hidden space
        around = [c for c in current.cuboids if c.object in objects and c.id not in cut]
        reach = p.reach_rel * float(max(support.size[a] for a in range(3)
                                             if abs(support.rotation[2, a]) <= 0.5))
        support = _reach_out(support, around, reach, evidence)
        near = {}
        for c in current.cuboids:
            if c.object in objects and c.id not in cut and gap(support, c) < 0.02:
                near[c.object] = near.get(c.object, 0) + 1
        if near:
            support = support.with_(object=max(sorted(near), key=lambda x: near[x]))
        elif len(g) > 1:  # under several boxes at one height: their own support
            support = support.with_(object=new_id)
        else:  # one box alone: as likely one tall box whose top was all that was seen
            continue
        trial = current.with_(cuboids=tuple(cut.get(c.id, c) for c in current.cuboids)
                              + (support,), stability=None)
        cs = find_contacts(trial)
        fixed = [c for c in current.contacts if c.type == "fixed"]
        touching = cs.lookup()
        fixed += [Contact(new_id, c.id, "fixed") for c in trial.cuboids
                  if c.object == support.object and c.id != new_id
                  and tuple(sorted((new_id, c.id))) in touching]
        v = yield Edit((*cut.values(), support),
                       f"{', '.join(sorted(cut))} stretched to the floor far below what was "
                       f"seen: rest on a hidden support", fixed=tuple(fixed))
        if v.ok:
            current = v.arrangement
        elif len(g) > 1 and len(parts_of := grouped(g, chain=False)) > 1:
            groups[:0] = parts_of


PRIOR = Prior("hidden_supports", "settle", Params(), apply, principle_of(__doc__))
