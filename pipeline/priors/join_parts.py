"""Parts of one object meet: a short gap between two of its parts is noise, not a gap.

Evidence: the segmentation's objects and the depth views.  Regularity: an object is one
connected rigid body, and a shelf's board whose end was not seen stops a few
centimetres short of its side panel.  Two parts of one object that a short extension
(:func:`pipeline.search.short_join`) or two short ones across a corner
(:func:`corner_joins`: a desk's panel just past the end of its top) bring together are
joined, smallest added volume first, trimming the noisy edge of another object's box in
the way by at most ``trim_abs`` or ``trim_rel`` of its extent (never ``trim_max_share``
of it).  Two parts already held together through their object's other parts are not
joined through space a view saw empty, nor along a third part touching both.

Hidden ends.  With views, a part under another of its object whose upper end no view
saw (:func:`hidden_joins`: a table's leg under its overhanging top, seen from above)
reaches up to it however far, the upper part growing over it where its end was hidden
too if it is a top (not a panel or a post standing up: a chair's back keeps the
thickness the view measured).  Furniture stands on the floor and its parts hold each
other up, so no stability need makes their hidden lower ends reach it: a part taller
than wide, not standing on
a part of its object, of an object another part of which stands within ``near_floor``
of the floor (the floor's plane takes a few centimetres of every object's points with
it), whose bottom is more than ``floor_gap`` above the floor, reaches down to it
(:func:`floor_reaches`: a desk's side panel, a sofa's back behind its seat).  So does a
flat part (``flat``) unless two parts of its object hold it at opposite ends, within
``hold_gap`` (:func:`held_between`: a shelf's board between its side panels): furniture
carries a board from below or between two sides, so a flat part held at one end only,
with nothing of its object under it, is the top of a solid whose sides no view saw (a
sofa's arm seen only by the far end of its top, over its back).  Both only
through space no view saw empty and where nothing is entered.  What the sensor saw
outranks a guess: a part stands on another only where what the sensor saw of that part
lies under it, and a box whose guessed extent is in the way of the reach down gives way
to it, cut back to the part's face, as long as the cut leaves all it was seen to fill,
but for the noisy edge of a box of another object, as in a join (:func:`_give_way`: a
sofa's back seen above its back cushions, whose seat and cushions an earlier guess had
pushed back under it, a seat cushion's fitted top reaching a few millimetres under it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import (
    UP,
    as_seen,
    changed_boxes,
    extended,
    extent_along,
    face_normal,
    floor_height,
    horizontal_axes,
    is_upright,
    near,
    overlap_across,
    overlap_along,
    overlap_face,
    pushed,
    same_object_groups,
    up_axis,
    upright_extent,
    z_range,
)
from ..contacts import candidate_pairs, find_contacts, pair_tolerance, sat_separation
from ..evidence import FREE_FRACTION_MAX, slab_samples
from ..model import Arrangement, Cuboid, box_corners
from .base import Edit, Prior, principle_of


@dataclass(frozen=True)
class Params:
    max_rounds: int = 64  #: passes over the pairs
    trim_abs: float = 0.02  #: metres another object's box may give way ...
    trim_rel: float = 0.1  #: ... or this fraction of its extent, whichever is larger ...
    trim_max_share: float = 0.5  #: ... but never more than this share of it
    floor_gap: float = 0.02  #: metres: a part further above the floor may reach down ...
    near_floor: float = 0.06  #: ... when another part of its object is this near it
    flat: bool = True  #: flat parts reach down too, unless held at both ends ...
    hold_gap: float = 0.03  #: ... by parts within this many metres of them


def _seen_through(arr: Arrangement, extensions, evidence) -> bool:
    """Whether a view saw empty some slab the ``extensions`` would add."""
    return bool(evidence) and any(
        evidence.free_fraction(slab_samples(arr, x)) > FREE_FRACTION_MAX for x in extensions)


def apply(arr, evidence, p: Params, ctx):
    from ..extend import MAX_EXTENSION_REL, apply_offsets, offsets_of, pair_edges
    from ..search import along_link, short_join, touching_links


    if not any(c.object is not None for c in arr.cuboids):
        return
    views = evidence.views
    max_ext = MAX_EXTENSION_REL * arr.scale_length()
    for _ in range(p.max_rounds):
        K = len(arr.cuboids)
        trials = []
        held = same_object_groups(arr) if views else {}
        reached = set()  # pairs that touch or that one extension joins
        edges = [e for e in pair_edges(arr, max_ext, same_object=True)
                 if e.same_object and not isinstance(e.b, str)]
        links = touching_links(edges)  # parts of one object touching each other
        for e in edges:
            if e.touching or any(short_join(arr, o) for o in e.options):
                reached.add((min(e.a, e.b), max(e.a, e.b)))
            if e.touching:
                continue
            # parts already held together through their object's other parts (a screen
            # on its neck on its foot) do not grow through space the sensor saw empty,
            # nor along a part that touches them both (beside the neck onto the foot)
            both = held and held.get(e.a) == held.get(e.b)
            trials += [(o.volume, e.a, e.b, o) for o in e.options
                       if o.extensions and short_join(arr, o)
                       and not (both and (_seen_through(arr, o.extensions, evidence)
                                          or along_link(arr, o.extensions, links,
                                                        e.a, e.b)))]
        for a, b, o in hidden_joins(arr, max_ext, reached) if views else ():
            if not _seen_through(arr, o.extensions, evidence):
                trials.append((o.volume, a, b, o))
        for a, b, o in corner_joins(arr, max_ext, reached):
            if not (held and held.get(a) == held.get(b)
                    and _seen_through(arr, o.extensions, evidence)):
                trials.append((o.volume, a, b, o))
        touched: set[int] = set()  # boxes changed this round: their trials wait
        for _vol, a, b, o in sorted(trials, key=lambda t: (t[0], t[1], t[2])):
            grown = {x.box for x in o.extensions}
            if touched & ({a, b} | grown):
                continue
            geom = apply_offsets(arr, offsets_of(list(o.extensions), K))
            cubs = list(geom.cuboids)
            near_ = near(geom, grown)  # only boxes near the grown ones can be entered
            ok = True
            for pp, q, _depth in _penetrations(geom, near_):
                kp, kq = geom.index.get(pp), geom.index.get(q)
                if kp is None or kq is None or (kp in grown and kq in grown):
                    ok = False  # into a support, or two grown boxes into each other
                    break
                if kp not in grown and kq not in grown:
                    continue  # an overlap the join did not make
                k, other = (kq, kp) if kp in grown else (kp, kq)
                r = cubs[k]
                if r.object is not None and r.object == cubs[other].object:
                    ok = False
                    break
                cut = _cut_back(r, cubs[other])
                if cut is None:
                    continue
                depth, axis, _side, cubs[k] = cut
                if not _trim_allowed(depth, float(r.size[axis]), p):
                    ok = False  # (2 cm of a 12 mm book would leave a negative size)
                    break
            if not ok:
                continue
            trial = arr.with_(cuboids=tuple(cubs))
            changed = {n for n, (c, before) in enumerate(zip(cubs, arr.cuboids))
                       if c is not before}
            names = {cubs[n].id for n in changed}
            if any(pp in names or q in names for pp, q, _ in _penetrations(trial, near_)):
                continue
            v = yield Edit(tuple(cubs[n] for n in sorted(changed)),
                           f"{arr.cuboids[a].id} and {arr.cuboids[b].id}, parts of one object, "
                           f"meet by a short extension")
            if not v.ok:
                continue
            arr = v.arrangement
            touched |= changed | {a, b}
        if not touched:
            break
    if views:
        yield from _down_to_floor(arr, evidence, p)


def _end(c, ax: int, top: bool) -> int:
    """The side (0: -ax, 1: +ax) of box ``c``'s upright axis ``ax`` at its top or bottom."""
    return int((float(c.rotation[2, ax]) > 0) == top)


def upright_parts(arr: Arrangement) -> dict[str, list]:
    """Object -> ``(index, box)`` of each of its upright parts."""
    parts: dict[str, list] = {}
    for k, c in enumerate(arr.cuboids):
        if c.object is not None and is_upright(c):
            parts.setdefault(c.object, []).append((k, c))
    return parts


def held_between(c: Cuboid, mates, tol: float) -> bool:
    """Whether two of the boxes ``mates`` hold box ``c`` at opposite ends of one of its
    horizontal axes: each level with it and beside it across that axis (within ``tol``
    metres), one reaching from the middle of ``c`` to its end or beyond, the other the
    same at the other end (a shelf's board between its side panels)."""
    hz = horizontal_axes(c)
    for a in hz:
        u = c.rotation[:, a]
        lo, hi = extent_along(c, u)
        mid = (lo + hi) / 2
        across = [c.rotation[:, b] for b in hz if b != a]
        plus = minus = False
        for q in mates:
            if (overlap_along(c, q, UP) < -tol
                    or any(overlap_along(c, q, v) < -tol for v in across)):
                continue  # not level with it, or not beside it
            qlo, qhi = extent_along(q, u)
            plus |= qlo >= mid and qlo <= hi + tol and qhi >= hi - tol
            minus |= qhi <= mid and qhi >= lo - tol and qlo <= lo + tol
        if plus and minus:
            return True
    return False


def floor_reaches(arr: Arrangement, gap: float, near_floor: float, flat: bool = True,
                  hold_gap: float = 0.03):
    """Extensions down to a level floor of the upright parts, taller than wide (with
    ``flat``, also flat ones no two parts of their object hold at opposite ends within
    ``hold_gap``, :func:`held_between`), whose bottom lies more than ``gap`` above it, of
    objects another part of which stands within ``near_floor`` of it, where no part of
    their object was seen under them; lowest first."""
    from ..extend import Extension

    floor = floor_height(arr)
    if floor is None:
        return []
    out = []
    for parts in upright_parts(arr).values():
        for k, c in parts:
            mates = [q for j, q in parts if j != k]
            is_flat = float(c.size[up_axis(c)]) < min(float(c.size[a])
                                                     for a in horizontal_axes(c))
            if (not mates
                    or not any(z_range(q)[0] - floor <= near_floor for q in mates)
                    or (is_flat and (not flat or held_between(c, mates, hold_gap)))):
                continue
            bottom = z_range(c)[0]
            if any(z_range(q)[1] <= bottom + gap and overlap_across(c, as_seen(q), UP)
                   for q in mates):
                continue  # it stands on a part of its object (a chair's back on its seat)
            drop = bottom - floor
            if drop > gap:
                ax = up_axis(c)
                out.append((drop, k, Extension(k, ax, _end(c, ax, top=False), drop)))
    return [(k, x) for _, k, x in sorted(out, key=lambda t: (t[0], t[1]))]


def _penetrations(arr: Arrangement, idx) -> list:
    """The penetrations among the boxes ``idx`` of ``arr`` (and the supports)."""
    return find_contacts(arr.with_(cuboids=tuple(arr.cuboids[n] for n in idx))).penetrations


def _cut_back(r: Cuboid, into: Cuboid, sideways: bool = False):
    """``(depth, axis, side, box)``: box ``r`` with its face (``axis``, ``side``) that
    reaches least far into the box ``into`` (``sideways``: of its upright faces) moved
    back by that ``depth``; None when no face of it does."""
    face = overlap_face(r, into, sideways=sideways)
    if face is None:
        return None
    depth, axis, side = face
    return depth, axis, side, pushed(r, axis, side, -depth)


def _trim_allowed(depth: float, extent: float, p: Params) -> bool:
    """Whether a cut ``depth`` metres deep into a box ``extent`` metres long there stays
    within its noisy edge: ``trim_abs`` or ``trim_rel`` of the extent, whichever is
    larger, never ``trim_max_share`` of it."""
    return depth <= min(max(p.trim_abs, p.trim_rel * extent), p.trim_max_share * extent)


def _give_way(geom: Arrangement, k: int, p: Params) -> Arrangement | None:
    """``geom`` with the boxes that box ``k`` enters cut back to its face where only
    their imagined extent is in the way, or, for a box of another object, only the noisy
    edge of what the sensor saw of it (:func:`_trim_allowed`, as for a box in the way of
    a join), or None when a cut would reach deeper into what the sensor saw of one, or
    into the floor or a wall.  What the sensor saw of a part of ``k``'s own object under
    it is no noise: ``k`` stands on that part."""
    c = geom.cuboids[k]
    cubs = list(geom.cuboids)
    for a, b, _ in _penetrations(geom, near(geom, {k})):
        if c.id not in (a, b):
            continue
        j = geom.index.get(b if a == c.id else a)
        if j is None:
            return None  # into the floor or a wall
        q = cubs[j]
        cut = _cut_back(q, c, sideways=True)
        if cut is None:
            return None
        _depth, axis, side, cubs[j] = cut
        u = face_normal(q, axis, side)
        lo, hi = extent_along(as_seen(q), u)
        into_seen = hi - extent_along(cubs[j], u)[1]
        if into_seen > 1e-6 and ((c.object is not None and q.object == c.object)
                                 or not _trim_allowed(into_seen, hi - lo, p)):
            return None  # the cut reaches into what the sensor saw of it
    return geom.with_(cuboids=tuple(cubs))


def _down_to_floor(arr: Arrangement, evidence, p: Params):
    """Each of :func:`floor_reaches` proposed where no view saw the space empty and the
    grown part enters nothing once the guessed extents in its way gave way."""
    from ..extend import apply_offsets, offsets_of

    for k, x in floor_reaches(arr, p.floor_gap, p.near_floor, p.flat, p.hold_gap):
        if _seen_through(arr, [x], evidence):
            continue
        geom = apply_offsets(arr, offsets_of([x], len(arr.cuboids)))
        cid = arr.cuboids[k].id
        geom = _give_way(geom, k, p)
        if geom is None:
            continue
        if any(cid in (a, b) for a, b, _ in _penetrations(geom, near(geom, {k}))):
            continue
        v = yield Edit(changed_boxes(geom, arr),
                       f"{cid}, a part of {arr.cuboids[k].object}, reaches the floor "
                       f"{1000 * x.length:.0f} mm down through space no view saw")
        if v.ok:
            arr = v.arrangement


def hidden_joins(arr: Arrangement, max_ext: float, skip: set[tuple[int, int]]):
    """Joins of a part up to the part of its object above it: ``(a, b, option)``.

    An upright part below another upright part of its object reaches up to it (a table's
    leg whose upper end the overhanging top, or something in front, hid; its fit stops
    where the view lost it), the upper part first growing along one of its horizontal
    axes over the lower one's footprint where that sticks out (the top's end was hidden
    too).  Only a top grows so (a board, seen edge-on or not: longer than it is tall):
    an upper part at least as tall as it is long (a chair's back, a post) is a panel or
    a post standing up, whose thickness the view measured, and a leg beside it does not
    make it a block.  Each extension up to ``max_ext``: the caller, given views, keeps
    only joins through space none of them saw empty.  Pairs in ``skip`` (touching, or
    joined by one short extension) are not tried.
    """
    from ..extend import Extension, Option

    out = []
    for parts in upright_parts(arr).values():
        corners = {k: c.corners() for k, c in parts}
        # a top (longer than it is tall) may grow over what holds it up; a panel or a post
        # standing up may not
        top = {}
        for k, c in parts:
            height, longest = upright_extent(c)
            top[k] = height < longest
        for a, lo in parts:
            lz1 = z_range(lo)[1]
            for b, hi in parts:
                if b == a or (min(a, b), max(a, b)) in skip:
                    continue
                hz0 = z_range(hi)[0]
                tol = float(pair_tolerance(lo.size, hi.size))
                if hz0 - lz1 <= tol:
                    continue
                # where lo's footprint sticks out of hi's (along hi's horizontal axes)
                d = (corners[a] - hi.center) @ hi.rotation
                grow = []
                for k in horizontal_axes(hi):
                    half = float(hi.size[k]) / 2
                    for side, over in ((1, d[:, k].max() - half), (0, -d[:, k].min() - half)):
                        if over > tol:
                            grow.append(Extension(b, k, side, float(over)))
                ax = up_axis(lo)
                x = Extension(a, ax, _end(lo, ax, top=True), hz0 - lz1)
                if (grow and not top[b]) or len(grow) > 1 or any(
                        e.length > max_ext for e in (*grow, x)):
                    continue
                ext = (*grow, x)
                out.append((a, b, Option("fixed", ext, sum(e.volume(arr.sizes) for e in ext))))
    return out


def corner_joins(arr: Arrangement, max_ext: float, skip: set[tuple[int, int]]):
    """Joins of two parts of one object apart across a corner: ``(a, b, option)``.

    A part that sits just beyond the end of another and a little off its face (a desk's
    side panel 2 mm past the end of a top shrunk by noise and 6 cm below it; a chair's
    back just behind the seat's rear edge and just above it) meets it by no single
    extension: one box's face reaches past the other's far side (the top over the whole
    panel), then the other's face reaches it (the panel up to the top).  Both must be
    short (:data:`pipeline.search.SHORT_JOIN` of the box's extent) and the two must then
    touch.  Smallest added volume first, except that a part hanging above the other's
    end grows down past it first where that takes its bottom near the floor (within
    :data:`pipeline.search.SHORT_JOIN` of its height: a shelf's side panel, fitted down
    to the top of the bottom board in front of it, reaches past the board and the board
    meets its face, rather than the board sliding in under the panel and the panel
    standing on it, out of the floor's reach), and last where it would end hanging
    beside the other far above the floor (a chair's back rests on its seat).  Pairs in
    ``skip`` (touching, or joined by one extension) are not tried.
    """
    from ..extend import Extension, Option
    from ..search import SHORT_JOIN

    K = len(arr.cuboids)
    if K < 2:
        return []
    C, R, S = arr.centers, arr.rotations, arr.sizes
    ii, jj = candidate_pairs(C, R, S, max_ext)
    corners = box_corners(C, R, S)
    floor = floor_height(arr)
    out = []
    for i, j in zip(ii.tolist(), jj.tolist()):
        ci, cj = arr.cuboids[i], arr.cuboids[j]
        if ci.object is None or ci.object != cj.object or (i, j) in skip:
            continue
        tol = float(pair_tolerance(S[i], S[j]))
        best, best_key = None, None
        for a, b in ((i, j), (j, i)):
            for axis in range(3):
                u = R[a][:, axis]
                for side in (0, 1):
                    sgn = 1.0 if side else -1.0
                    face = sgn * (C[a] @ u) + S[a, axis] / 2
                    proj = sgn * (corners[b] @ u) - face
                    near, far = float(proj.min()), float(proj.max())
                    if near < -tol or far <= tol or far > SHORT_JOIN * S[a, axis]:
                        continue
                    x1 = Extension(a, axis, side, far)
                    grown = extended(arr.cuboids[a], x1)
                    # the other box reaches the grown one through the face nearest it
                    for axis2 in range(3):
                        v = R[b][:, axis2]
                        for side2 in (0, 1):
                            sgn2 = 1.0 if side2 else -1.0
                            face2 = sgn2 * (C[b] @ v) + S[b, axis2] / 2
                            gap = float((sgn2 * (grown.corners() @ v) - face2).min())
                            if gap <= tol or gap > SHORT_JOIN * S[b, axis2]:
                                continue
                            x2 = Extension(b, axis2, side2, gap)
                            other = extended(arr.cuboids[b], x2)
                            sep, _, _ = sat_separation(
                                grown.center[None], grown.rotation[None], grown.size[None] / 2,
                                other.center[None], other.rotation[None], other.size[None] / 2,
                                np.array([tol]))
                            if abs(float(sep[0])) > tol:
                                continue
                            vol = x1.volume(S) + x2.volume(S)
                            # a part hanging over the other's end grows down past it
                            # (its bottom there is where the other hid it) rather than
                            # the other sliding in under it, when that takes it down
                            # near the floor (a shelf's side panel past its bottom
                            # board); one that would end hanging beside the other, far
                            # above the floor (a chair's back beside its seat), rests
                            # on it instead
                            down = 1
                            if sgn * u[2] < -0.9 and z_range(
                                    arr.cuboids[a])[0] >= z_range(arr.cuboids[b])[1] - tol:
                                low = z_range(grown)[0]
                                down = 0 if floor is not None and low - floor <= \
                                    SHORT_JOIN * (z_range(grown)[1] - low) else 2
                            if best is None or (down, vol) < best_key:
                                best, best_key = Option("fixed", (x1, x2), vol), (down, vol)
        if best is not None:
            out.append((i, j, best))
    return out


PRIOR = Prior("join_parts", "complete", Params(), apply, principle_of(__doc__))
