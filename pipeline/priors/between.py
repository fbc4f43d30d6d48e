"""What lies between an object's sides rests on that object: the part under it is hidden.

Evidence: the segmentation's objects, the completed boxes and the depth views.
Regularity: furniture carries what lies inside it (cushions on a sofa's seat between its
arms, things on a cabinet's bottom between its sides), and a view from the side or from
above sees the load's top and the sides that flank it but not the part under it.  A box
(the load) whose bottom is ``min_height`` or more above the floor with no box under it,
lying between two upright parts of another object (square to each other, beside it:
their heights overlap its own, on opposite sides of it along a horizontal axis of
theirs, each within ``side_tol`` of the fit's noise, and each covering at least
``cover_min`` of its extent along the other axis), rests
on a hidden part of that object: one box, square to the two parts, from one's inner face
to the other's, over the extent along the other axis both cover (cut back at the near
face of a box it would enter at one end), from the floor up to the lowest bottom of the
loads between them.  The gate keeps it only where it enters nothing and no view saw its
space empty.  Without it the search stands each load on the floor by a column of its
own: as many hidden volumes as loads where one part of the flanking object explains
them all.  A part of that object standing on the floor between the two sides, seen
only in part (a seat seen by a strip of its top between the cushions on it, taken down
to the floor as a panel), is that part: where it is the one box the hidden part would
enter, it grows into it, keeping what was seen of it; where its top lies more than
``side_tol`` under the loads, that top was seen and the part ends there, and the loads,
seen by their tops, reach down to it (``seen_part``).

The same sides bound what fills the space between them.  A row of upright boxes
resting (within ``side_tol``) on a part of the object whose two sides flank them, which
together fill the width between the sides' inner faces (but for ``side_tol`` at each
end), is made to fit that space: a sofa's seat cushions from arm to arm, seen only by
their front faces, go back as far as both arms reach, each face stopping at the near
face of a box in the way (the back) or of one seen above the space it would fill, up to
the sides' top (a back cushion whose lower end they hide).  One edit per row, kept only
where no view saw the added space empty.  A row that leaves a gap, or rests on a box
of another object, is left to ``deepen``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import (
    entered,
    extent_along,
    floor_height,
    free_id,
    horizontal_axes,
    merged,
    overlap_along,
    pushed,
    resting_on,
    same_axes,
    vertical_axis,
    z_range,
)
from ..model import Cuboid
from .base import Edit, Prior, principle_of


@dataclass(frozen=True)
class Params:
    min_height: float = 0.10  #: metres: a load lower above the floor than this is left alone
    #: metres of fit noise: how far a side may reach into the load's extent or start above
    #: its top, and a box under the load may reach above its bottom
    side_tol: float = 0.03
    cover_min: float = 0.5  #: least share of the load's extent along the sides that each covers
    fill: bool = True  #: rows filling the width between two sides go back as far as they reach
    #: a part of the object standing on the floor between the sides, seen in part, is the
    #: part under the loads (it grows into it)
    seen_part: bool = True


def _vertical_face(c: Cuboid, top: bool) -> tuple[int, int]:
    """``(axis, side)`` of upright box ``c``'s top (``top``) or bottom face, as
    :func:`pipeline.boxops.pushed` takes them."""
    ax = vertical_axis(c)
    return ax, int((c.rotation[2, ax] > 0) == top)


def _column(c: Cuboid, ground: float, bottom: float) -> Cuboid:
    """The space under an upright box ``c`` down to the floor (its own footprint)."""
    ax = vertical_axis(c)
    size = c.size.copy()
    size[ax] = bottom - ground
    centre = np.array([c.center[0], c.center[1], 0.5 * (ground + bottom)])
    return Cuboid(c.id, centre, c.rotation, size, c.density)


def loads(arr, ground: float, p: Params) -> list[tuple[int, float, tuple[int, ...]]]:
    """``(k, bottom, under)`` of the upright boxes ``min_height`` or more above the floor,
    ``under`` the boxes their column down to the floor enters that end below them."""
    out = []
    for k, c in enumerate(arr.cuboids):
        if vertical_axis(c) is None:
            continue
        bottom = z_range(c)[0]
        if bottom - ground < p.min_height:
            continue
        under = [j for j in entered(arr, _column(c, ground, bottom), skip=[k])
                 if z_range(arr.cuboids[j])[1] < bottom + p.side_tol]  # not one beside it
        out.append((k, bottom, tuple(int(j) for j in under)))
    return out


def _inside(arr, j: int, lo: int, hi: int, ax: int, p: Params, ground: float) -> bool:
    """Whether box ``j`` is a part of the object of ``lo`` and ``hi`` standing on the
    floor (within ``side_tol``) between their inner faces along their axis ``ax``
    (within ``side_tol``): not a board the sides hold."""
    A, B, c = arr.cuboids[lo], arr.cuboids[hi], arr.cuboids[j]
    if c.object != A.object or z_range(c)[0] > ground + p.side_tol:
        return False
    u = A.rotation[:, ax]
    c0, c1 = extent_along(c, u)
    return c0 > extent_along(A, u)[1] - p.side_tol and c1 < extent_along(B, u)[0] + p.side_tol


def _parts(arr) -> list[int]:
    """Indices of the upright boxes of ``arr`` that are parts of an object."""
    return [j for j, q in enumerate(arr.cuboids)
            if q.object is not None and vertical_axis(q) is not None]


def _across(A: Cuboid, ax: int) -> np.ndarray:
    """The unit vector of ``A``'s horizontal axis other than ``ax``."""
    return A.rotation[:, next(x for x in horizontal_axes(A) if x != ax)]


def _both_cover(A: Cuboid, B: Cuboid, w: np.ndarray) -> tuple[float, float]:
    """The extent along ``w`` that both ``A`` and ``B`` cover."""
    (a0, a1), (b0, b1) = extent_along(A, w), extent_along(B, w)
    return max(a0, b0), min(a1, b1)


def flanked(arr, k: int, parts: list[int], p: Params, of_object: str | None = None):
    """``(a, b, ax)``: pairs of ``parts`` (upright parts of objects) of one object, not
    ``k``'s (``of_object``: of that one only), beside box ``k`` (their heights overlap
    its own, within ``side_tol``) on opposite sides of it along their local horizontal
    axis ``ax`` (``a`` on the low side)."""
    c = arr.cuboids[k]
    bottom, top = z_range(c)
    sides = [j for j in parts if j != k and arr.cuboids[j].object != c.object
             and (of_object is None or arr.cuboids[j].object == of_object)
             and z_range(arr.cuboids[j])[1] > bottom
             and z_range(arr.cuboids[j])[0] < top + p.side_tol]
    out = []
    for i, a in enumerate(sides):
        A = arr.cuboids[a]
        for b in sides[i + 1:]:
            B = arr.cuboids[b]
            if B.object != A.object or not same_axes(A, B):
                continue
            for ax in horizontal_axes(A):
                u, w = A.rotation[:, ax], _across(A, ax)
                l0, l1 = extent_along(c, u)
                lo, hi = sorted((a, b), key=lambda j: extent_along(arr.cuboids[j], u)[0])
                if (extent_along(arr.cuboids[lo], u)[1] > l0 + p.side_tol
                        or extent_along(arr.cuboids[hi], u)[0] < l1 - p.side_tol):
                    continue
                depth = float(np.ptp(extent_along(c, w)))
                if min(overlap_along(arr.cuboids[j], c, w) for j in (lo, hi)) \
                        >= p.cover_min * depth:
                    out.append((lo, hi, ax))
    return out


def under_between(arr, lo: int, hi: int, ax: int, members: list[int], ground: float,
                  top: float, p: Params = Params()) -> Cuboid | None:
    """The box between parts ``lo`` and ``hi`` (along their axis ``ax``) under the loads
    ``members``, from the floor to ``top``, cut back along the other horizontal axis at
    the near face of a box it would enter at one end; None when it would enter one over
    the loads' middle.  Where the one box it enters is a part of that object standing on
    the floor between the two, no higher than ``top`` (with ``seen_part``), that part
    grown to hold the box instead, up to its own top where that lies more than
    ``side_tol`` under ``top`` (None when it holds it already)."""
    A, B = arr.cuboids[lo], arr.cuboids[hi]
    aw = next(x for x in horizontal_axes(A) if x != ax)
    az = vertical_axis(A)
    u, w = A.rotation[:, ax], A.rotation[:, aw]
    u0, u1 = extent_along(A, u)[1], extent_along(B, u)[0]
    w0, w1 = _both_cover(A, B, w)
    mid = float(np.mean([arr.cuboids[m].center @ w for m in members]))
    ids = {arr.cuboids[m].id for m in members}
    name = free_id(arr, f"{A.object}_under")
    for _ in range(4):
        if u1 - u0 <= 0 or w1 - w0 <= 0 or not w0 < mid < w1:
            return None
        size = np.zeros(3)
        size[ax], size[aw], size[az] = u1 - u0, w1 - w0, top - ground
        centre = 0.5 * (u0 + u1) * u + 0.5 * (w0 + w1) * w
        centre = centre + 0.5 * (ground + top) * np.array([0.0, 0.0, 1.0])
        box = Cuboid(name, centre, A.rotation, size, A.density, A.object, None,
                     {"hallucinated": True, "points": 0})
        hit = [j for j in entered(arr, box) if arr.cuboids[j].id not in ids]
        if p.seen_part and len(hit) == 1:
            part = arr.cuboids[hit[0]]
            ptop = z_range(part)[1]
            if (_inside(arr, hit[0], lo, hi, ax, p, ground) and same_axes(part, A)
                    and ptop < top + p.side_tol):  # that part, seen in part, is the one
                below = ptop < top - p.side_tol
                if below:  # its top was seen: it ends there (the loads reach down to it)
                    box = pushed(box, *_vertical_face(box, True), ptop - top)
                grown = merged(part, box).with_(observed=part.observed)
                if not below and np.allclose(grown.size, part.size, atol=1e-6):
                    return None  # it fills that space and carries the loads already
                return grown
        if not hit:
            return box
        for j in hit:
            e0, e1 = extent_along(arr.cuboids[j], w)
            if e0 >= mid:
                w1 = min(w1, e0)
            elif e1 <= mid:
                w0 = max(w0, e1)
            else:
                return None
    return None


def groups_of(arr, ground: float, p: Params) -> dict[tuple[int, int, int], list]:
    """``(lo, hi, ax)`` -> the ``(k, bottom)`` of the loads (:func:`loads`) that the pair
    of parts ``lo`` and ``hi`` flanks along their axis ``ax`` (:func:`flanked`), with
    nothing under them or (with ``seen_part``) only parts of that object standing on the
    floor between the two."""
    parts = _parts(arr)
    groups: dict[tuple[int, int, int], list] = {}
    for k, bottom, under in loads(arr, ground, p):
        for key in flanked(arr, k, parts, p):
            # nothing under it, or only a part of that object standing on the floor
            # between its sides, seen in part (a seat's top between the cushions on it)
            if not under or (p.seen_part and all(_inside(arr, j, *key, p, ground)
                                                 for j in under)):
                groups.setdefault(key, []).append((k, bottom))
    return groups


def rows_filling(arr, p: Params) -> dict[tuple[int, int, int], list[int]]:
    """``(lo, hi, ax)`` -> the upright boxes resting (within ``side_tol``) on a part of
    the object whose upright parts ``lo`` and ``hi`` flank them along their axis ``ax``
    (:func:`flanked`), where together they fill the width between the two parts' inner
    faces but for ``side_tol`` at each end."""
    parts = _parts(arr)
    groups: dict[tuple[int, int, int], list[int]] = {}
    for k in parts:
        c = arr.cuboids[k]
        under = resting_on(arr, c, p.side_tol)
        if under is None or under.object is None or under.object == c.object:
            continue
        for key in flanked(arr, k, parts, p, of_object=under.object):
            groups.setdefault(key, []).append(k)
    out = {}
    for (lo, hi, ax), ks in groups.items():
        u = arr.cuboids[lo].rotation[:, ax]
        u0, u1 = extent_along(arr.cuboids[lo], u)[1], extent_along(arr.cuboids[hi], u)[0]
        spans = sorted(tuple(np.clip(extent_along(arr.cuboids[k], u), u0, u1)) for k in ks)
        covered, end = 0.0, u0
        for a, b in spans:  # the length of the union of the rows' spans
            covered += max(0.0, b - max(a, end))
            end = max(end, b)
        if covered >= (u1 - u0) - 2 * p.side_tol:
            out[(lo, hi, ax)] = ks
    return out


def filled(arr, lo: int, hi: int, ax: int, k: int) -> Cuboid | None:
    """Box ``k`` grown along the horizontal axis of parts ``lo`` and ``hi`` other than
    ``ax`` over the extent both cover, each face stopping at the near face of a box it
    would enter, or that enters the space above it up to the lower side's top (what
    stands there stands in that space: a back cushion).  A box beside it that it enters
    already (the fit's noise) is not in the way; any other box that the growth enters
    over ``k``'s middle stops it.  None when it grows nowhere."""
    A, B = arr.cuboids[lo], arr.cuboids[hi]
    w = _across(A, ax)
    w0, w1 = _both_cover(A, B, w)
    c = arr.cuboids[k]
    axis = int(np.argmax(np.abs(c.rotation.T @ w)))
    sign = 1.0 if float(c.rotation[:, axis] @ w) > 0 else -1.0
    l0, l1 = extent_along(c, w)
    mid = 0.5 * (l0 + l1)
    already = {int(j) for j in entered(arr, c, skip=[k])}  # the fit's noise
    rise = min(z_range(A)[1], z_range(B)[1]) - z_range(c)[1]  # up to the sides' top
    for target, side in ((w0, -1.0), (w1, 1.0)):
        length = side * (target - (l1 if side > 0 else l0))
        if length <= 1e-3:
            continue
        grown = pushed(c, axis, int(side * sign > 0), length)
        if rise > 0:  # what is seen above the space stands in it (a back cushion)
            grown = pushed(grown, *_vertical_face(c, True), rise)
        for j in entered(arr, grown, skip=[k]):
            e0, e1 = extent_along(arr.cuboids[j], w)
            if side > 0 and e0 >= mid:
                length = min(length, e0 - l1)
            elif side < 0 and e1 <= mid:
                length = min(length, l0 - e1)
            elif j not in already:
                length = 0.0
        if length > 1e-3:
            c = pushed(c, axis, int(side * sign > 0), length)
    return None if c is arr.cuboids[k] else c


def apply(arr, evidence, p: Params, ctx):
    ground = floor_height(arr)
    if ground is None:
        return
    done: set[str] = set()
    groups = groups_of(arr, ground, p)
    while True:
        todo = sorted(((key, ms) for key, ms in groups.items()
                       if arr.cuboids[key[0]].object not in done),
                      key=lambda t: (-len(t[1]), arr.cuboids[t[0][0]].id, arr.cuboids[t[0][1]].id))
        if not todo:
            break
        (lo, hi, ax), ms = todo[0]
        obj = arr.cuboids[lo].object
        done.add(obj)  # one hidden part per object
        top = min(b for _k, b in ms)
        box = under_between(arr, lo, hi, ax, [k for k, _b in ms], ground, top, p)
        if box is None:
            continue
        names = ", ".join(sorted(arr.cuboids[k].id for k, _b in ms))
        part = arr.cuboid(box.id) if box.id in arr.index else None  # a part seen in part
        carrier = f"a hidden part of {obj} carries them"
        lowered: tuple = ()
        if part is not None:
            carrier = f"{box.id}, a part of {obj} seen in part, grows under them from side to side"
            ptop = z_range(box)[1]
            if ptop < top - p.side_tol:  # it ends at its seen top: the loads reach down to it
                lowered = tuple(pushed(arr.cuboids[k], *_vertical_face(arr.cuboids[k], False),
                                       b - ptop) for k, b in ms)
                carrier += f" up to its top, {ptop - ground:.2f} m, and they reach down to it"
        v = yield Edit((box, *lowered), f"{names} between {arr.cuboids[lo].id} and "
                               f"{arr.cuboids[hi].id} of {obj}, {top - ground:.2f} m above "
                               f"the floor with nothing else under them: {carrier}")
        if v.ok:
            arr = v.arrangement
            groups = groups_of(arr, ground, p)  # the new part may hold loads of others
    if p.fill:
        yield from _fill(arr, p)


def _fill(arr, p: Params):
    """Rows that fill the width between two sides of the object carrying them grow to the
    depth both sides cover (:func:`rows_filling`, :func:`filled`); one edit per row."""
    for (lo, hi, ax), ks in sorted(rows_filling(arr, p).items(),
                                   key=lambda t: (arr.cuboids[t[0][0]].id,
                                                  arr.cuboids[t[0][1]].id)):
        grown = [g for g in (filled(arr, lo, hi, ax, k) for k in ks) if g is not None]
        if not grown:
            continue
        names = ", ".join(sorted(g.id for g in grown))
        v = yield Edit(tuple(grown), f"{names} fill the width between {arr.cuboids[lo].id} "
                                     f"and {arr.cuboids[hi].id} of "
                                     f"{arr.cuboids[lo].object}: as deep as both cover")
        if v.ok:
            arr = v.arrangement


PRIOR = Prior("between", "complete", Params(), apply, principle_of(__doc__))
