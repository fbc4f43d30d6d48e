"""Glue between two different objects is the last resort: drop it where the boxes can be
completed so that the group stands without it.

Evidence: the depth views and the search's contacts.  Regularity: separate pieces of
furniture are not glued; the search judges boxes as fitted, and a box seen only in part
puts a centre of mass off (a box half hidden under another looks too short to carry
it), so the search pays with a glue joint the scene does not have.  For each ``fixed``
contact between different objects, in order, the joint becomes a ``touch`` and, smallest
added volume first, one face of either box grows into space no view saw empty: an upright
face by ``growth_fractions`` of its extent or of its widest one, or to the other box's
centre or far side; the lower end, along the box's own axis (a leaning box too), until
its lowest point meets the floor or the top of a box under that end, by no more than
the largest growth of its largest extent (a cushion leaning on a sofa's back, seen only
above the seat cushions in front of it: gravity says it rests on the seat; a board on
a wall is no pillar down to the floor).  The first variant under which the group stands
with gravity tilted by :data:`pipeline.search.ROBUST_TILT_DEG` is kept.  The joints are
taken in passes until one drops none (a joint dropped may be what held another up; a
joint is tried again only where a drop reached its group).  Joints within one object are
what holds it together and stay.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from .. import workclock
from ..boxops import UP, extent_along, face_normal, floor_height, horizontal_axes, touching_group
from ..contacts import find_contacts
from ..errors import InputError
from ..evidence import slab_samples
from ..model import Arrangement
from .base import Edit, Prior, principle_of


@dataclass(frozen=True)
class Params:
    growth_fractions: tuple = (0.25, 0.5, 1.0)  #: face growths, in extents of the box


def _down_to_what_is_under(arr: Arrangement, c, axis: int, u: np.ndarray) -> set[float]:
    """Lengths by which box ``c``'s lower end (its face ``u`` along ``axis``, the one
    nearest down) grows until its lowest point reaches the floor or the top of a box of
    ``arr`` under the middle of that end, as it would stand there."""
    low = extent_along(c, UP)[0]
    slope = -float(u[2])  # metres down per metre along u
    out = set()
    floor = floor_height(arr)
    if floor is not None and low - floor > 1e-4:
        out.add(round((low - floor) / slope, 6))
    for o in arr.cuboids:
        if o.id == c.id:
            continue
        top = extent_along(o, UP)[1]
        if top >= low - 1e-4:
            continue
        length = (low - top) / slope
        end = c.center + u * (c.size[axis] / 2 + length)  # the middle of the grown end
        if all(abs(float((end - o.center) @ o.rotation[:, a])) <= o.size[a] / 2
               for a in horizontal_axes(o)):
            out.add(round(length, 6))
    return out


def _growths(arr: Arrangement, ids: list[str], evidence, p: Params,
             with_contacts: bool = False, contacts=None) -> Iterator:
    """Variants of ``arr`` with one face of one of the two boxes ``ids`` pushed out, into
    space no view saw empty and without interpenetration, smallest added volume first.
    The lower end grows down to what is under it (:func:`_down_to_what_is_under`).  An
    upright face is pushed by ``p.growth_fractions`` of the box's extent
    and, when it faces the other box, until it reaches that box's centre or its far
    side (the paper's extension length, horizontally: under a box that overhangs), and
    by the same fractions of the box's widest horizontal extent (a part seen edge-on,
    such as a pillar seen only from the front, has almost no depth).  ``with_contacts``:
    yield ``(arrangement, its contacts)``; ``contacts`` (those of ``arr``) lets them be
    updated for the one grown box instead of found anew."""
    from ..contacts import update_contacts_of_one
    from ..extend import Extension

    out = []
    boxes = [arr.cuboids[arr.index[i]] for i in ids if i in arr.index]
    for c in boxes:
        k = arr.index[c.id]
        other = [o for o in boxes if o.id != c.id]
        for axis in range(3):
            for side in (0, 1):
                u = face_normal(c, axis, side)
                if abs(c.rotation[2, axis]) > 0.5:  # the vertical axis: the lower end
                    if u[2] > 0:
                        continue
                    # no longer than a face may grow: a board is no pillar
                    most = max(p.growth_fractions) * float(c.size.max())
                    lengths = {x for x in _down_to_what_is_under(arr, c, axis, u)
                               if x <= most}
                else:
                    face = float(c.center @ u + c.size[axis] / 2)
                    # fractions of this extent, and of the widest horizontal one (a slab
                    # seen edge-on, a pillar seen from the front, has almost no depth)
                    widest = max(float(c.size[a]) for a in horizontal_axes(c))
                    lengths = {round(f * e, 6) for f in p.growth_fractions
                               for e in (float(c.size[axis]), widest)}
                    for o in other:
                        lengths |= {round(float(o.center @ u) - face, 6),
                                    round(float((o.corners() @ u).max()) - face, 6)}
                for length in sorted(x for x in lengths if x > 1e-4):
                    x = Extension(k, axis, side, length)
                    if evidence.seen_empty(slab_samples(arr, x)):
                        break  # a longer push would cross the same seen-empty space
                    size = c.size.copy()
                    size[axis] += length
                    cubs = list(arr.cuboids)
                    cubs[k] = c.with_(center=c.center + u * length / 2, size=size)
                    out.append((x.volume(arr.sizes), len(out), c.id,
                                arr.with_(cuboids=tuple(cubs)).inherit_views(arr)))
    out.sort(key=lambda t: t[:2])
    found: dict[int, object] = {}  # id of a variant -> its contacts
    for _v, _n, cid, g in out:  # lazily: the caller stops at the first that stands
        if contacts is None:
            cs = find_contacts(g)
        else:
            if id(g) not in found:  # all variants of this box at once (one batch)
                mine = [t[3] for t in out if t[2] == cid]
                found.update(zip(map(id, mine), update_contacts_of_one(
                    mine, arr, contacts, arr.index[cid])))
            cs = found[id(g)]
        if not any(cid in (a, b) for a, b, _ in cs.penetrations):
            yield (g, cs) if with_contacts else g


def apply(arr, evidence, p: Params, ctx):
    from dataclasses import replace

    from ..search import ROBUST_TILT_DEG
    from ..stability import check_stability

    final, mu, threshold, deadline = arr, ctx.mu, ctx.threshold, ctx.deadline
    objects = {c.id: c.object for c in final.cuboids}
    # component solutions shared by every check below (digest-keyed: exact reuse)
    cache: dict = {}

    def stands(arr: Arrangement, cs=None) -> bool:
        try:
            return check_stability(arr, mu=mu, threshold=threshold, tilt_deg=ROBUST_TILT_DEG, contacts=cs,
                                   solve_cache=cache, verdict_only=True).stable
        except InputError:  # a fixed pair pulled apart
            return False

    final_cs = None  # contacts of the current geometry (type changes keep them)
    joints = [c.key for c in final.contacts if c.type == "fixed" and c.a in objects
              and not (c.b in objects and objects[c.a] is not None
                       and objects[c.a] == objects[c.b])]
    # passes until one drops nothing: a joint dropped may free another.  A joint is tried
    # again only when a drop after its try reached its group (the dropped joint's group,
    # and what its grown boxes touch after the drop): otherwise its try comes out the same
    drops: list[set] = []
    pending = joints
    while pending and workclock.now() <= deadline:
        left = []  # (joint, its group, drops before its try)
        for key in pending:
            i = next((j for j, x in enumerate(final.contacts)
                      if x.key == key and x.type == "fixed"), None)
            if i is None:
                continue
            if workclock.now() > deadline:
                break
            c = final.contacts[i]
            contacts = tuple(replace(x, type="touch") if j == i else x
                             for j, x in enumerate(final.contacts))
            trial = final.with_(contacts=contacts, stability=None)
            if final_cs is None:
                final_cs = find_contacts(trial)
            group = touching_group(trial, c.a, final_cs)
            sub = trial.with_(cuboids=tuple(x for x in trial.cuboids if x.id in group),
                              contacts=tuple(x for x in contacts if x.a in group
                                             and (x.b in group or x.b not in objects)))
            sub_cs = find_contacts(sub)
            # the search may have kept a spare joint
            found = sub if stands(sub, sub_cs) else None
            if found is None:
                found = next((g for g, cs in _growths(sub, [c.a, c.b], evidence, p,
                                                       with_contacts=True, contacts=sub_cs)
                              if stands(g, cs)), None)
            if found is None:
                left.append((key, set(group), len(drops)))
                continue
            moved = {x.id: x for x in found.cuboids if x is not sub.cuboids[sub.index[x.id]]}
            v = yield Edit(tuple(moved.values()),
                           f"glue {c.a}|{c.b} between two objects dropped: the group stands "
                           f"without it", fixed=tuple(x for x in contacts if x.type == "fixed"))
            if v.ok:
                final = v.arrangement
                final_cs = find_contacts(final)
                # its group, and what the grown boxes touch now
                near = {q for pair in final_cs.pairs if set(pair) & set(moved) for q in pair}
                drops.append(set(group) | near)
            else:
                left.append((key, set(group), len(drops)))
        pending = [key for key, group, n in left if any(group & d for d in drops[n:])]

PRIOR = Prior("relax_glue", "settle", Params(), apply, principle_of(__doc__))
