"""Hallucinating wholly occluded parts by symmetry (paper section 5.1 (ii)).

A part with no points cannot be extended into existence.  Where an object shows a
repeated structure, the missing copy is added: an object with a top (its part of
largest horizontal area) and two or three legs below it (upright parts taller than
wide) whose positions in the top's frame occupy two or three of its four quadrants
gets the missing legs: each is the diagonally opposite leg turned half a turn about the
top's vertical axis (independent of the top's yaw), or, when that leg is missing too, a
leg of a neighbouring quadrant mirrored.  An object of just a top and one part under
one end of it (a wall shelf's board and one of its brackets, a desk's top and one side)
gets that part's mirror image under the other end.  An object whose top has a twin
(another object's top of the same size right above or below it: wall shelves hung one
above the other) with more parts under it gets the twin's parts it lacks, moved by the
offset between the two tops.  The new part
is kept only if it does not interpenetrate anything and, when a depth image exists,
the sensor did not see through its volume; it carries ``extra["hallucinated"]`` and
no observed box, and takes part in the search like any other cuboid.
"""

from __future__ import annotations

import numpy as np

from .contacts import pair_tolerance, sat_separation
from .extend import FREE_FRACTION_MAX, DepthView, visible_free_fraction
from .model import Arrangement, Cuboid

#: A leg is at most this fraction of its top's narrower horizontal side wide (a shelf's
#: side panel, as deep as its boards, is not a leg to be copied to the other corners).
LEG_MAX_WIDTH = 0.5


def _upright_extent(c: Cuboid) -> tuple[float, float]:
    """(height, largest horizontal extent) of a box, from its axes' z components."""
    zc = np.abs(c.rotation[2, :])
    ax = int(np.argmax(zc))
    other = [k for k in range(3) if k != ax]
    return float(c.size[ax]), float(max(c.size[other]))


def _box_samples(c: Cuboid, n: int = 5) -> np.ndarray:
    t = ((np.arange(n) + 0.5) / n) * 2 - 1
    g = np.stack(np.meshgrid(t, t, t, indexing="ij"), axis=-1).reshape(-1, 3) * (c.size / 2 * 0.85)
    return c.center + g @ c.rotation.T


def _free(arr: Arrangement, cand: Cuboid) -> bool:
    others = [c for c in arr.cuboids]
    if not others:
        return True
    n = len(others)
    C = np.stack([c.center for c in others])
    R = np.stack([c.rotation for c in others])
    S = np.stack([c.size for c in others])
    tol = pair_tolerance(np.broadcast_to(cand.size, (n, 3)), S)
    sep, _, _ = sat_separation(np.broadcast_to(cand.center, (n, 3)),
                               np.broadcast_to(cand.rotation, (n, 3, 3)),
                               np.broadcast_to(cand.size / 2, (n, 3)), C, R, S / 2, tol)
    return bool(np.all(sep >= -tol))


def _mirror_support(top: Cuboid, part: Cuboid, obj: str, n: int) -> Cuboid | None:
    """The mirror image of ``part`` across the plane through ``top``'s centre across its
    longer horizontal axis, when ``part`` stands under ``top`` (its top within a tenth of
    the top's length of the top's bottom, its centre inside the top's footprint) towards
    one end (off the centre by over a quarter of the top's length): the second bracket
    of a wall shelf's board, the second side of a desk."""
    zc = np.abs(top.rotation[2, :])
    up = int(np.argmax(zc))
    horiz = [k for k in range(3) if k != up]
    long_ax = max(horiz, key=lambda k: float(top.size[k]))
    length = float(top.size[long_ax])
    p = top.rotation.T @ (part.center - top.center)
    h_part, _ = _upright_extent(part)
    top_bottom = float(top.center[2] - top.size[up] / 2)
    part_top = float(part.center[2] + h_part / 2)
    inside = all(abs(p[k]) <= top.size[k] / 2 for k in horiz)
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


def hallucinate(arr: Arrangement, views: list[DepthView], margin: float = 0.0
                ) -> tuple[Arrangement, list[str]]:
    """Add mirrored legs where two or three are seen, and the mirror image of a top's one
    support under one end; returns (arrangement, new ids)."""
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
        up = int(np.argmax(np.abs(top.rotation[2, :])))
        top_narrow = float(min(top.size[k] for k in range(3) if k != up))
        legs = []
        for c in cubs:
            if c is top:
                continue
            h, w = _upright_extent(c)
            if h > 1.5 * w and w <= LEG_MAX_WIDTH * top_narrow and c.center[2] < top.center[2]:
                legs.append(c)
        if len(members) == 2:  # a top and one part under it: its mirror image
            new = _mirror_support(top, next(c for c in cubs if c is not top), obj, len(added))
            if new is not None and _free(arr.with_(cuboids=arr.cuboids + tuple(added)), new) \
                    and not (views and visible_free_fraction(_box_samples(new), views, margin)
                             > FREE_FRACTION_MAX):
                added.append(new)
            continue
        if not 2 <= len(legs) <= 3:
            continue
        local = np.stack([top.rotation.T @ (leg.center - top.center) for leg in legs])
        quads = [(int(np.sign(x)), int(np.sign(y))) for x, y in local[:, :2]]
        if len(set(quads)) != len(quads) or any(0 in q for q in quads):
            continue
        for missing in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
            if missing in quads:
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
            p = local[src].copy()
            p[list(flips)] = -p[list(flips)]
            leg = legs[src]
            new = Cuboid(f"h{len(added)}_{obj}", top.center + top.rotation @ p, leg.rotation,
                         leg.size, leg.density, obj, None, {"hallucinated": True, "points": 0})
            if not _free(arr.with_(cuboids=arr.cuboids + tuple(added)), new):
                continue
            if views and visible_free_fraction(_box_samples(new), views, margin) > FREE_FRACTION_MAX:
                continue
            added.append(new)
    added += _twin_parts(arr, added, views, margin)
    if not added:
        return arr, []
    return arr.with_(cuboids=arr.cuboids + tuple(added)), [c.id for c in added]


def _top_of(cubs: list[Cuboid]) -> Cuboid:
    """The part of largest horizontal area."""
    def area(c: Cuboid) -> float:
        up = int(np.argmax(np.abs(c.rotation[2, :])))
        return float(np.prod(np.delete(c.size, up)))
    return max(cubs, key=area)


def _under(top: Cuboid, part: Cuboid) -> bool:
    """Whether ``part`` stands under ``top``: its top within a tenth of the top's length
    of the top's bottom and its centre inside the top's footprint."""
    up = int(np.argmax(np.abs(top.rotation[2, :])))
    horiz = [k for k in range(3) if k != up]
    p = top.rotation.T @ (part.center - top.center)
    h_part, _ = _upright_extent(part)
    top_bottom = float(top.center[2] - top.size[up] / 2)
    return (all(abs(p[k]) <= top.size[k] / 2 for k in horiz)
            and abs(part.center[2] + h_part / 2 - top_bottom) <= 0.1 * float(max(top.size)))


def _twins(a: Cuboid, b: Cuboid) -> bool:
    """Whether two upright tops are the same board one above the other: horizontal sides
    equal within :data:`TWIN_SIZE_REL`, long sides parallel within 10 degrees, centres
    within a tenth of the long side of the same vertical."""
    out = []
    for c in (a, b):
        up = int(np.argmax(np.abs(c.rotation[2, :])))
        if abs(c.rotation[2, up]) < 0.99:
            return False
        horiz = sorted((k for k in range(3) if k != up), key=lambda k: float(c.size[k]))
        out.append((c.size[horiz], c.rotation[:, horiz[1]]))
    (sa, la), (sb, lb) = out
    length = float(max(sa[1], sb[1]))
    return (bool(np.all(np.abs(sa - sb) <= TWIN_SIZE_REL * np.maximum(sa, sb)))
            and abs(float(la @ lb)) >= np.cos(np.radians(10.0))
            and float(np.linalg.norm((a.center - b.center)[:2])) <= 0.1 * length
            and abs(float(a.center[2] - b.center[2])) > 0.0)


#: Two boards are twins when their horizontal sides agree within this fraction.
TWIN_SIZE_REL = 0.1


def _twin_parts(arr: Arrangement, added: list[Cuboid], views: list[DepthView],
                margin: float) -> list[Cuboid]:
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
    for obj, members in sorted(by_object.items()):
        top = _top_of(members)
        for other, theirs in sorted(by_object.items()):
            twin_top = _top_of(theirs)
            if other == obj or len(theirs) <= len(members) or not _twins(top, twin_top):
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
                if not _free(arr.with_(cuboids=arr.cuboids + tuple(added) + tuple(new)), copy):
                    continue
                if views and visible_free_fraction(_box_samples(copy), views,
                                                   margin) > FREE_FRACTION_MAX:
                    continue
                new.append(copy)
            break
    return new
