"""A repeated structure completes itself: the hidden copies of seen parts are there.

Evidence: the segmentation's objects, their parts' positions under their top, and the
depth views.  Regularity: furniture is symmetric.  An object with a top (its part of
largest horizontal area) and two or three legs under it (upright parts taller than wide,
at most ``leg_max_width`` of the top's narrower side) in distinct quadrants of the top
gets the missing legs.  With three seen, the fourth completes their parallelogram (the
legs stand at the corners of a rectangle, and three of them place the fourth without the
top, whose far strip may be lost or imagined) when they make a right angle within
``corner_deg`` at the leg diagonal to it: three legs about a triangle (a three-legged
table, two at the back corners and one at the front's middle) are all there are; with
two, the diagonally opposite leg turned half a turn about the top's vertical axis
(independent of the top's yaw), or a neighbouring quadrant's leg mirrored.
With both legs seen at one end, the top first grows to where a view saw past its far
edge (in steps of ``edge_step``, by at most ``edge_max_rel``), and no legs are copied
when no view saw past it and another object hides ``edge_hidden_min`` of the strip
beyond it (the top may go on behind it).  An object of a top and one part under one
end gets that part's mirror image under the other end; an object whose top has a twin
(a board of the same size within ``twin_size_rel`` right above or below) with more parts
under it gets the twin's parts it lacks.  A copy is kept only where it enters nothing and
no view saw through it; it is marked ``hallucinated`` and has no observed box.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import box_samples, face_normal, is_free, is_upright, up_axis, upright_extent
from ..model import Arrangement, Cuboid
from .base import Edit, Prior, principle_of

#: :func:`mirror_support`: a part's centre may lie past the top's edge by this much.
MIRROR_SLACK = 0.02


@dataclass(frozen=True)
class Params:
    leg_max_width: float = 0.5  #: a leg's width / its top's narrower horizontal side
    #: degrees: three seen legs place a fourth only where they make a right angle within
    #: this (the corner of a rectangle, not a tripod's triangle)
    corner_deg: float = 15.0
    edge_step: float = 0.01  #: metres: a top grows to its seen edge in these steps ...
    edge_max_rel: float = 0.5  #: ... by at most this fraction of its extent there
    edge_hidden_min: float = 0.25  #: share of the strip past the edge another object hides
    twin_size_rel: float = 0.1  #: relative agreement of two twin boards' sides
    mirror_slack: float = MIRROR_SLACK  #: metres a mirrored part may lie past the edge


def mirror_support(top: Cuboid, part: Cuboid, obj: str, n: int, slack: float = MIRROR_SLACK
                   ) -> Cuboid | None:
    """The mirror image of ``part`` across the plane through ``top``'s centre across its
    longer horizontal axis, when ``part`` stands under ``top`` (its top within a tenth of
    the top's length of the top's bottom, its centre inside the top's footprint or past
    its edge by at most its own half extent there, up to ``slack``) towards
    one end (off the centre by over a quarter of the top's length): the second bracket
    of a wall shelf's board, the second side of a desk."""
    zc = np.abs(top.rotation[2, :])
    up = int(np.argmax(zc))
    horiz = [k for k in range(3) if k != up]
    long_ax = max(horiz, key=lambda k: float(top.size[k]))
    length = float(top.size[long_ax])
    p = top.rotation.T @ (part.center - top.center)
    h_part, _ = upright_extent(part)
    top_bottom = float(top.center[2] - top.size[up] / 2)
    part_top = float(part.center[2] + h_part / 2)
    # over the top's footprint: a side panel flush with the top's end has its centre
    # just outside a top whose end strip the sensor lost
    reach = np.abs(top.rotation.T @ part.rotation) @ part.size / 2
    inside = all(abs(p[k]) <= top.size[k] / 2 + min(float(reach[k]), slack)
                 for k in horiz)
    if not (inside and abs(part_top - top_bottom) <= 0.1 * length
            and abs(p[long_ax]) > 0.25 * length):
        return None
    p[long_ax] = -p[long_ax]
    axis = top.rotation[:, long_ax]
    reflect = np.eye(3) - 2.0 * np.outer(axis, axis)
    R = reflect @ part.rotation
    # a reflection flips handedness: turn the image's axis along the top's long axis back
    k = int(np.argmax(np.abs(R.T @ axis)))
    R[:, k] = -R[:, k]
    return Cuboid(f"h{n}_{obj}", top.center + top.rotation @ p, R, part.size.copy(),
                  part.density, obj, None, {"hallucinated": True, "points": 0})


#: (what :func:`_grown_to_seen_edge` returns when the top may go on behind another object)
UNBOUNDED = object()


def _grown_to_seen_edge(arr: Arrangement, top: Cuboid, axis: int, side: int, evidence,
                        p: Params):
    """``top`` grown along ``axis`` towards ``side`` up to where a view saw the space
    beyond it empty (the far edge of a table whose far strip the sensor lost to noise or
    to what stands on it), or None: when the first step is already seen empty, when the
    growth would enter another box, or when no step within ``p.edge_max_rel`` of its
    extent is (nothing says where the edge is).  In that last case :data:`UNBOUNDED`
    when another object hides at least ``p.edge_hidden_min`` of the strip just past
    the edge from the first view (the top may go on behind it, as a chair's seat
    behind the boxes in front of it)."""
    if not evidence:
        return None
    u = face_normal(top, axis, side)
    steps = int(p.edge_max_rel * float(top.size[axis]) / p.edge_step)
    others = arr.with_(cuboids=tuple(c for c in arr.cuboids if c.id != top.id))
    for j in range(steps + 1):
        base = j * p.edge_step
        size = top.size.copy()
        size[axis] = p.edge_step
        # the slab of the next step, beyond what is grown so far
        face = top.center + u * (float(top.size[axis]) / 2 + base + p.edge_step / 2)
        slab = top.with_(center=face, size=size)
        if evidence.free_fraction(box_samples(slab)) > 0.0:
            if j == 0:
                return None
            size = top.size.copy()
            size[axis] += base
            grown = top.with_(center=top.center + u * base / 2, size=size)
            return grown if is_free(others, grown) else None
    # nothing seen past the edge: a top hidden there by another object may go on (its
    # legs copied about its centre would come short); one hidden by its own parts not
    size = top.size.copy()
    size[axis] = p.edge_step
    slab = top.with_(center=top.center + u * (float(top.size[axis]) / 2 + p.edge_step / 2),
                     size=size)
    pts = box_samples(slab)
    hidden = np.zeros(len(pts), bool)
    for c in others.cuboids:
        if c.object != top.object:
            hidden |= evidence.in_shadow(pts, c)
    return UNBOUNDED if hidden.mean() >= p.edge_hidden_min else None


def apply(arr, evidence, p: Params, ctx):
    by_object: dict[str, list[int]] = {}
    for k, c in enumerate(arr.cuboids):
        if c.object is not None:
            by_object.setdefault(c.object, []).append(k)
    added: list[Cuboid] = []
    for obj, members in sorted(by_object.items()):
        if len(members) < 2:
            continue
        cubs = [arr.cuboids[k] for k in members]
        areas = []
        for c in cubs:
            zc = np.abs(c.rotation[2, :])
            ax = int(np.argmax(zc))
            other = [k for k in range(3) if k != ax]
            areas.append(c.size[other[0]] * c.size[other[1]])
        top = cubs[int(np.argmax(areas))]
        up = up_axis(top)
        top_narrow = float(min(top.size[k] for k in range(3) if k != up))
        legs = []
        for c in cubs:
            if c is top:
                continue
            h, w = upright_extent(c)
            if h > 1.5 * w and w <= p.leg_max_width * top_narrow and c.center[2] < top.center[2]:
                legs.append(c)
        if len(members) == 2:  # a top and one part under it: its mirror image
            new = mirror_support(top, next(c for c in cubs if c is not top), obj, len(added),
                                 p.mirror_slack)
            if new is not None and is_free(arr.with_(cuboids=arr.cuboids + tuple(added)), new) \
                    and not evidence.seen_empty(box_samples(new)):
                v = yield Edit((new,), f"{obj}: the mirror image of its one part under its top")
                if v.ok:
                    added.append(new)
            continue
        if not 2 <= len(legs) <= 3:
            continue
        local = np.stack([top.rotation.T @ (leg.center - top.center) for leg in legs])
        quads = [(int(np.sign(x)), int(np.sign(y))) for x, y in local[:, :2]]
        if len(set(quads)) != len(quads) or any(0 in q for q in quads):
            continue
        unbounded = False
        if len(legs) == 2 and up == 2:
            # both legs seen at one end: the top's other end may be short of the truth
            # (its far strip lost), and legs copied about its centre would come short by
            # as much; it first grows to where the sensor saw past its edge
            for a in (0, 1):
                if quads[0][a] == quads[1][a]:
                    grown = _grown_to_seen_edge(arr.with_(cuboids=arr.cuboids + tuple(added)),
                                                top, a, int(quads[0][a] < 0), evidence, p)
                    if grown is UNBOUNDED:
                        unbounded = True
                    elif grown is not None:
                        v = yield Edit((grown,), f"{obj}: its top grown to where a view saw "
                                                 f"past its far edge, before legs are copied")
                        if v.ok:
                            arr = arr.with_(cuboids=tuple(grown if c.id == top.id else c
                                                          for c in arr.cuboids))
                            local = local - (top.rotation.T @ (grown.center - top.center))[None]
                            top = grown
        if unbounded:
            continue
        # a quadrant where some other part of the object stands below the top (a leg
        # seen only at its foot, too short to pass for a leg) has its leg
        held = set()
        for c in cubs:
            if c is top or any(c is leg for leg in legs) or c.center[2] >= top.center[2]:
                continue
            x, y = (top.rotation.T @ (c.center - top.center))[:2]
            if abs(x) > top.size[0] / 8 and abs(y) > top.size[1] / 8:  # a corner, no rail
                held.add((int(np.sign(x)), int(np.sign(y))))
        for missing in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
            if missing in quads or missing in held:
                continue
            # the diagonal leg turned half a turn about the top's vertical axis (this
            # does not depend on the top's yaw, which noise and tilt make the least
            # certain part of its pose), else a leg of a neighbouring quadrant mirrored
            # (same y side first, then same x side)
            flips: tuple[int, ...] = (0, 1)
            src = next((n for n, q in enumerate(quads) if q == (-missing[0], -missing[1])), None)
            for flip in (0, 1):
                if src is not None:
                    break
                want = (-missing[0], missing[1]) if flip == 0 else (missing[0], -missing[1])
                src = next((n for n, q in enumerate(quads) if q == want), None)
                flips = (flip,)
            if src is None:
                continue
            if len(legs) == 3:
                # the fourth completes the parallelogram of the three seen (src is the
                # diagonal one): the seen legs place it, not the top's centre, whose far
                # edge may be imagined.  Only a right angle at src is a rectangle's
                # corner: three legs about a triangle (a tripod) are all there are
                a = local[quads.index((missing[0], -missing[1]))]
                b = local[quads.index((-missing[0], missing[1]))]
                hz = [k for k in range(3) if k != up]
                u, w = (a - local[src])[hz], (b - local[src])[hz]
                if abs(u @ w) > np.sin(np.radians(p.corner_deg)) * np.linalg.norm(u) * \
                        np.linalg.norm(w):
                    continue
                pos = a + b - local[src]
            else:
                pos = local[src].copy()
                pos[list(flips)] = -pos[list(flips)]
            leg = legs[src]
            new = Cuboid(f"h{len(added)}_{obj}", top.center + top.rotation @ pos, leg.rotation,
                         leg.size, leg.density, obj, None, {"hallucinated": True, "points": 0})
            if not is_free(arr.with_(cuboids=arr.cuboids + tuple(added)), new):
                continue
            if evidence.seen_empty(box_samples(new)):
                continue
            v = yield Edit((new,), f"{obj}: {len(legs)} legs seen, the one at corner "
                                   f"{missing} copied from the leg at {quads[src]}")
            if v.ok:
                added.append(new)
    for copy in _twin_parts(arr, added, evidence, p):
        v = yield Edit((copy,), f"{copy.object}: a part its twin board has, copied")
        if v.ok:
            added.append(copy)


def top_of(cubs: list[Cuboid]) -> Cuboid:
    """The part of largest horizontal area."""
    def area(c: Cuboid) -> float:
        up = up_axis(c)
        return float(np.prod(np.delete(c.size, up)))
    return max(cubs, key=area)


def _under(top: Cuboid, part: Cuboid) -> bool:
    """Whether ``part`` stands under ``top``: its top within a tenth of the top's length
    of the top's bottom and its centre inside the top's footprint."""
    up = up_axis(top)
    horiz = [k for k in range(3) if k != up]
    p = top.rotation.T @ (part.center - top.center)
    h_part, _ = upright_extent(part)
    top_bottom = float(top.center[2] - top.size[up] / 2)
    return (all(abs(p[k]) <= top.size[k] / 2 for k in horiz)
            and abs(part.center[2] + h_part / 2 - top_bottom) <= 0.1 * float(max(top.size)))


def _twins(a: Cuboid, b: Cuboid, TWIN_SIZE_REL: float) -> bool:
    """Whether two upright tops are the same board one above the other: horizontal sides
    equal within ``TWIN_SIZE_REL``, long sides parallel within 10 degrees, centres
    within a tenth of the long side of the same vertical."""
    out = []
    for c in (a, b):
        up = up_axis(c)
        if not is_upright(c):
            return False
        horiz = sorted((k for k in range(3) if k != up), key=lambda k: float(c.size[k]))
        out.append((c.size[horiz], c.rotation[:, horiz[1]]))
    (sa, la), (sb, lb) = out
    length = float(max(sa[1], sb[1]))
    return (bool(np.all(np.abs(sa - sb) <= TWIN_SIZE_REL * np.maximum(sa, sb)))
            and abs(float(la @ lb)) >= np.cos(np.radians(10.0))
            and float(np.linalg.norm((a.center - b.center)[:2])) <= 0.1 * length
            and abs(float(a.center[2] - b.center[2])) > 0.0)


def _twin_parts(arr: Arrangement, added: list[Cuboid], evidence, p: Params):
    """Parts under a board copied from its twin: wall shelves of one make hung one above
    the other, or a stack of equal tables, where one shows the brackets (legs) under its
    board and the other shows fewer: the other gets the missing ones, moved by the
    offset between the two boards.  A copy is kept where none of the object's own parts
    already is, nothing is in the way and no view saw through it."""
    cur = list(arr.cuboids) + list(added)
    by_object: dict[str, list[Cuboid]] = {}
    for c in cur:
        if c.object is not None:
            by_object.setdefault(c.object, []).append(c)
    new: list[Cuboid] = []
    tops = {obj: top_of(members) for obj, members in by_object.items()}
    for obj, members in sorted(by_object.items()):
        top = tops[obj]
        for other, theirs in sorted(by_object.items()):
            if other == obj or len(theirs) <= len(members):
                continue
            twin_top = tops[other]
            if not _twins(top, twin_top, p.twin_size_rel):
                continue
            shift = top.center - twin_top.center
            for part in theirs:
                if part is twin_top or not _under(twin_top, part):
                    continue
                copy = Cuboid(f"h{len(added) + len(new)}_{obj}", part.center + shift,
                              part.rotation, part.size.copy(), part.density, obj, None,
                              {"hallucinated": True, "points": 0})
                if any(np.linalg.norm(m.center - copy.center) < 0.5 * float(max(copy.size))
                       for m in members):
                    continue  # the object has that part already
                if not is_free(arr.with_(cuboids=arr.cuboids + tuple(added) + tuple(new)),
                               copy):
                    continue
                if evidence.seen_empty(box_samples(copy)):
                    continue
                new.append(copy)
            break
    return new


PRIOR = Prior("copies", "complete", Params(), apply, principle_of(__doc__))
