"""Hallucinating wholly occluded parts by symmetry (paper section 5.1 (ii)).

A part with no points cannot be extended into existence.  Where an object shows a
repeated structure, the missing copy is added: an object with a top (its part of
largest horizontal area) and two or three legs below it (upright parts taller than
wide) whose positions in the top's frame occupy two or three of its four quadrants
gets the missing legs: each is the diagonally opposite leg turned half a turn about the
top's vertical axis (independent of the top's yaw), or, when that leg is missing too, a
leg of a neighbouring quadrant mirrored.  With both legs seen at one end, the top first
grows towards the other end up to where a depth view saw past its edge
(:func:`_grown_to_seen_edge`): a far strip lost to noise would put the copies short.  An object of just a top and one part under
one end of it (a wall shelf's board and one of its brackets, a desk's top and one side)
gets that part's mirror image under the other end.  An object whose top has a twin
(another object's top of the same size right above or below it: wall shelves hung one
above the other) with more parts under it gets the twin's parts it lacks, moved by the
offset between the two tops.  The new part
is kept only if it does not interpenetrate anything and, when a depth image exists,
the sensor did not see through its volume; it carries ``extra["hallucinated"]`` and
no observed box, and takes part in the search like any other cuboid.

A part seen only in part is completed the same way (:func:`complete_by_mirror`): where
the mirror image of a better-seen part of its object overlaps it (a desk's far side
panel seen as a strip at its front edge), it grows to cover that image, up to the top's
underside, where nothing is in the way and no view saw the space empty.
"""

from __future__ import annotations

import numpy as np

from .contacts import pair_tolerance, sat_separation
from .extend import FREE_FRACTION_MAX, DepthView, visible_free_fraction, visible_free_mask
from .model import Arrangement, Cuboid

#: A hidden connector bridges a gap of at most this fraction of the upper part's height.
CONNECTOR_MAX_GAP_REL = 0.5
#: ... and of at least this much (metres): a narrower gap is a fitted box's noisy edge,
#: which :func:`pipeline.imagine.join_parts` closes.
CONNECTOR_MIN_GAP = 0.02
#: The gap under the upper part is sampled this finely (metres) to find the columns no
#: view saw into.
CONNECTOR_STEP = 0.01

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


def _separations(arr: Arrangement, cand: Cuboid) -> tuple[np.ndarray, np.ndarray]:
    """(separation, contact tolerance) of ``cand`` from each cuboid of ``arr``."""
    n = len(arr.cuboids)
    C, R, S = arr.centers, arr.rotations, arr.sizes
    tol = pair_tolerance(np.broadcast_to(cand.size, (n, 3)), S)
    sep, _, _ = sat_separation(np.broadcast_to(cand.center, (n, 3)),
                               np.broadcast_to(cand.rotation, (n, 3, 3)),
                               np.broadcast_to(cand.size / 2, (n, 3)), C, R, S / 2, tol)
    return sep, tol


def _free(arr: Arrangement, cand: Cuboid) -> bool:
    if not arr.cuboids:
        return True
    sep, tol = _separations(arr, cand)
    return bool(np.all(sep >= -tol))


def _mirror_support(top: Cuboid, part: Cuboid, obj: str, n: int) -> Cuboid | None:
    """The mirror image of ``part`` across the plane through ``top``'s centre across its
    longer horizontal axis, when ``part`` stands under ``top`` (its top within a tenth of
    the top's length of the top's bottom, its centre inside the top's footprint or past
    its edge by at most its own half extent there, up to :data:`MIRROR_SLACK`) towards
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
    # over the top's footprint: a side panel flush with the top's end has its centre
    # just outside a top whose end strip the sensor lost
    reach = np.abs(top.rotation.T @ part.rotation) @ part.size / 2
    inside = all(abs(p[k]) <= top.size[k] / 2 + min(float(reach[k]), MIRROR_SLACK)
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


def _upright_axis(c: Cuboid) -> int | None:
    """The axis of ``c`` along the vertical, or None when it is tilted (over 2.5 deg)."""
    k = int(np.argmax(np.abs(c.rotation[2])))
    return k if abs(c.rotation[2, k]) > np.cos(np.radians(2.5)) else None


def _gap_grid(a: Cuboid, horiz: list[int], lo: np.ndarray, hi: np.ndarray, z0: float,
              gap: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Samples every :data:`CONNECTOR_STEP` (4 to 64 a side) over the footprint
    ``lo``..``hi`` (in ``a``'s frame, axes ``horiz``) and from height ``z0`` up by ``gap``:
    the two horizontal coordinates (n0, n1, nz) and the world points (n0 * n1 * nz, 3)."""
    n = [max(4, min(64, int(np.ceil((hi[k] - lo[k]) / CONNECTOR_STEP)))) for k in horiz]
    nz = max(4, min(16, int(np.ceil(gap / CONNECTOR_STEP))))
    t0 = lo[horiz[0]] + (np.arange(n[0]) + 0.5) / n[0] * (hi[horiz[0]] - lo[horiz[0]])
    t1 = lo[horiz[1]] + (np.arange(n[1]) + 0.5) / n[1] * (hi[horiz[1]] - lo[horiz[1]])
    tz = z0 + (np.arange(nz) + 0.5) / nz * gap
    g0, g1, gz = np.meshgrid(t0, t1, tz, indexing="ij")
    pts = (a.center + g0[..., None] * a.rotation[:, horiz[0]]
           + g1[..., None] * a.rotation[:, horiz[1]])
    pts[..., 2] = gz
    return g0, g1, pts.reshape(-1, 3)


def _over(g0: np.ndarray, g1: np.ndarray, horiz: list[int], lo: np.ndarray,
          hi: np.ndarray) -> np.ndarray:
    """Which samples of :func:`_gap_grid` lie inside the footprint ``lo``..``hi``."""
    return ((g0 > lo[horiz[0]]) & (g0 < hi[horiz[0]])
            & (g1 > lo[horiz[1]]) & (g1 < hi[horiz[1]]))


def _between(c: Cuboid, a: Cuboid, b: Cuboid, lo: float, hi: float, pad: float = 0.01
             ) -> bool:
    """Whether ``c`` stands in the gap from height ``lo`` to ``hi`` between ``b`` below
    and ``a`` above: it spans half the gap's height, and its footprint overlaps both
    theirs or comes within ``pad`` of them (world-aligned bounds)."""
    z = c.corners()[:, 2]
    if min(z.max(), hi) - max(z.min(), lo) < 0.5 * (hi - lo):
        return False
    cx = c.corners()[:, :2]
    for other in (a, b):
        ox = other.corners()[:, :2]
        if (np.any(cx.max(axis=0) + pad < ox.min(axis=0))
                or np.any(ox.max(axis=0) + pad < cx.min(axis=0))):
            return False
    return True


def hidden_connectors(arr: Arrangement, views: list[DepthView], margin: float = 0.0
                      ) -> tuple[Arrangement, list[str]]:
    """Add the hidden part that holds one part of an object above another.

    A monitor's screen hangs a few centimetres above its foot on a neck hidden behind
    it.  The two parts do not touch, and nothing else of their object holds them
    together; stretching the screen down to the foot would fill space the sensor saw
    empty under the screen's lower edge.  Where a view saw into the gap between an
    upright part and one of its object's parts below it (over
    :data:`pipeline.extend.FREE_FRACTION_MAX` of samples filling the gap over both
    footprints seen empty), a new part fills the columns of the gap that no view saw into
    at any height (sampled every :data:`CONNECTOR_STEP` metres), from the lower part's top
    to the upper part's bottom: where the neck is, and what it hides.  Only gaps of at
    least :data:`CONNECTOR_MIN_GAP` and at most :data:`CONNECTOR_MAX_GAP_REL` of the upper
    part's height are bridged, and only where no other part of the object already
    stands in the gap over both (:func:`_between`: the neck, seen, but apart from the
    screen after a noisy fit); the new part carries ``extra["hallucinated"]`` and ``extra["connector"]`` and is kept only if
    it does not interpenetrate anything.  Returns (arrangement, new ids).
    """
    if not views:
        return arr, []
    from .imagine import _same_object_groups  # (imagine imports this module)

    by_object: dict[str, list[int]] = {}
    for k, c in enumerate(arr.cuboids):
        if c.object is not None:
            by_object.setdefault(c.object, []).append(k)
    if not any(len(m) > 1 for m in by_object.values()):
        return arr, []
    groups = _same_object_groups(arr)
    added: list[Cuboid] = []
    for i, a in enumerate(arr.cuboids):
        ka = _upright_axis(a)
        if a.object is None or ka is None or a.extra.get("hallucinated"):
            continue
        a_lo = float(a.center[2] - a.size[ka] / 2)
        horiz = [k for k in range(3) if k != ka]
        for j in by_object[a.object]:
            b = arr.cuboids[j]
            if j == i or groups[i] == groups[j] or (kb := _upright_axis(b)) is None:
                continue
            b_hi = float(b.center[2] + b.size[kb] / 2)
            gap = a_lo - b_hi
            tol = float(pair_tolerance(a.size[None], b.size[None])[0])
            if not max(tol, CONNECTOR_MIN_GAP) < gap <= CONNECTOR_MAX_GAP_REL * a.size[ka]:
                continue
            if any(_between(arr.cuboids[m], a, b, b_hi, a_lo) for m in by_object[a.object]
                   if m not in (i, j)):
                continue  # a part of theirs already stands in the gap (the neck, seen)
            # a stretched down to b would fill the gap under its seen face: beside b (over
            # b the gap is too close to b's top for the sensor to tell) was it seen empty?
            o = a.observed
            if o is None:
                continue
            local = (b.corners() - a.center) @ a.rotation  # b's corners in a's frame
            blo, bhi = local.min(axis=0), local.max(axis=0)
            oc = a.rotation.T @ (np.asarray(o.center, float) - a.center)
            osz = np.asarray(o.size, float)
            g0, g1, pts = _gap_grid(a, horiz, oc - osz / 2, oc + osz / 2, b_hi, gap)
            beside = ~_over(g0, g1, horiz, blo, bhi).reshape(-1)
            if not beside.any() or visible_free_mask(pts[beside], views, margin).mean() \
                    <= FREE_FRACTION_MAX:
                continue  # nothing seen in the gap: a join may close it
            # the columns over b that no view saw into, at any height
            lo, hi = -a.size / 2, a.size / 2
            g0, g1, pts = _gap_grid(a, horiz, lo, hi, b_hi, gap)
            n = g0.shape[:2]
            seen = visible_free_mask(pts, views, margin).reshape(g0.shape)
            hidden = _over(g0, g1, horiz, blo, bhi)[..., 0] & ~seen.any(axis=2)
            if not hidden.any():
                continue
            r0, r1 = np.nonzero(hidden)
            d0, d1 = a.size[horiz[0]] / n[0], a.size[horiz[1]] / n[1]
            lo0, hi0 = lo[horiz[0]] + r0.min() * d0, lo[horiz[0]] + (r0.max() + 1) * d0
            lo1, hi1 = lo[horiz[1]] + r1.min() * d1, lo[horiz[1]] + (r1.max() + 1) * d1
            size = np.zeros(3)
            size[horiz[0]], size[horiz[1]], size[ka] = hi0 - lo0, hi1 - lo1, gap
            center = (a.center + (lo0 + hi0) / 2 * a.rotation[:, horiz[0]]
                      + (lo1 + hi1) / 2 * a.rotation[:, horiz[1]])
            center[2] = b_hi + gap / 2
            new = Cuboid(f"j{len(added)}_{a.object}", center, a.rotation.copy(), size,
                         a.density, a.object, None,
                         {"hallucinated": True, "connector": True, "points": 0})
            if not _free(arr.with_(cuboids=arr.cuboids + tuple(added)), new):
                continue
            added.append(new)
            groups = {k: (groups[i] if v == groups[j] else v) for k, v in groups.items()}
    if not added:
        return arr, []
    return arr.with_(cuboids=arr.cuboids + tuple(added)), [c.id for c in added]


#: A top whose hidden legs are copied is grown towards them in steps of this much
#: (metres) ...
EDGE_STEP = 0.01
#: ... by at most this fraction of its extent there.
EDGE_MAX_REL = 0.5
#: ... and where no step is, a top whose strip just past that end lies behind another
#: object (from the first view) for at least this fraction of it may go on unseen.
EDGE_HIDDEN_MIN = 0.25
#: (what :func:`_grown_to_seen_edge` returns then)
UNBOUNDED = object()


def _grown_to_seen_edge(arr: Arrangement, top: Cuboid, axis: int, side: int,
                        views: list[DepthView], margin: float):
    """``top`` grown along ``axis`` towards ``side`` up to where a view saw the space
    beyond it empty (the far edge of a table whose far strip the sensor lost to noise or
    to what stands on it), or None: when the first step is already seen empty, when the
    growth would enter another box, or when no step within :data:`EDGE_MAX_REL` of its
    extent is (nothing says where the edge is).  In that last case :data:`UNBOUNDED`
    when another object hides at least :data:`EDGE_HIDDEN_MIN` of the strip just past
    the edge from the first view (the top may go on behind it, as a chair's seat
    behind the boxes in front of it)."""
    if not views:
        return None
    u = top.rotation[:, axis] * (1.0 if side else -1.0)
    steps = int(EDGE_MAX_REL * float(top.size[axis]) / EDGE_STEP)
    others = arr.with_(cuboids=tuple(c for c in arr.cuboids if c.id != top.id))
    for j in range(steps + 1):
        base = j * EDGE_STEP
        size = top.size.copy()
        size[axis] = EDGE_STEP
        # the slab of the next step, beyond what is grown so far
        face = top.center + u * (float(top.size[axis]) / 2 + base + EDGE_STEP / 2)
        slab = top.with_(center=face, size=size)
        if visible_free_fraction(_box_samples(slab), views, margin) > 0.0:
            if j == 0:
                return None
            size = top.size.copy()
            size[axis] += base
            grown = top.with_(center=top.center + u * base / 2, size=size)
            return grown if _free(others, grown) else None
    # nothing seen past the edge: a top hidden there by another object may go on (its
    # legs copied about its centre would come short); one hidden by its own parts not
    size = top.size.copy()
    size[axis] = EDGE_STEP
    slab = top.with_(center=top.center + u * (float(top.size[axis]) / 2 + EDGE_STEP / 2),
                     size=size)
    from .imagine import in_shadow

    eye = np.asarray(views[0].T_world_cam, float)[:3, 3]
    pts = _box_samples(slab)
    hidden = np.zeros(len(pts), bool)
    for c in others.cuboids:
        if c.object != top.object:
            hidden |= in_shadow(pts, eye, c)
    return UNBOUNDED if hidden.mean() >= EDGE_HIDDEN_MIN else None


def hallucinate(arr: Arrangement, views: list[DepthView], margin: float = 0.0
                ) -> tuple[Arrangement, list[str]]:
    """Add mirrored legs where two or three are seen, and the mirror image of a top's one
    support under one end; returns (arrangement, new ids).  No legs are copied about a
    top whose far end may go on behind another object (:func:`_grown_to_seen_edge`):
    where they would stand is not known."""
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
        unbounded = False
        if len(legs) == 2 and up == 2:
            # both legs seen at one end: the top's other end may be short of the truth
            # (its far strip lost), and legs copied about its centre would come short by
            # as much; it first grows to where the sensor saw past its edge
            for a in (0, 1):
                if quads[0][a] == quads[1][a]:
                    grown = _grown_to_seen_edge(arr.with_(cuboids=arr.cuboids + tuple(added)),
                                                top, a, int(quads[0][a] < 0), views, margin)
                    if grown is UNBOUNDED:
                        unbounded = True
                    elif grown is not None:
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


#: :func:`complete_by_mirror`: a part is completed by its twin's mirror image when their
#: axes agree within this many degrees ...
MIRROR_AXES_DEG = 5.0
#: ... and the part grows by at least this much (metres) somewhere.
MIRROR_MIN_GROWTH = 0.02
#: ... and the image lies at most this far (metres) off the part along one axis.
MIRROR_SLACK = 0.02


def complete_by_mirror(arr: Arrangement, views: list[DepthView], margin: float = 0.0
                       ) -> tuple[Arrangement, list[str]]:
    """Grow a part seen in part to the mirror image of its twin.

    The two sides of a desk, the two brackets of a board: an object's part under one
    end of its top whose mirror image across the top's centre (:func:`_mirror_support`)
    of another of its parts, as the sensor saw that part (its observed box), overlaps
    it, with axes parallel (within :data:`MIRROR_AXES_DEG`), is the same part seen from
    another side: the one seen with fewer points grows to the bounding box of itself and
    that image, where the image reaches past it by at least :data:`MIRROR_MIN_GROWTH` (a
    desk's far side, seen as a 13 cm strip at its front edge, becomes as deep as its
    near side), never above the top's underside, and never wider across than the twin
    by more than twice :data:`MIRROR_SLACK` (a twin seen face-on as a thinner sliver
    counts as twice that thick).  The growth is kept where it enters no other box
    (overlaps the part already had may stay) and no view saw its space empty.  Returns
    the arrangement and the ids grown.
    """
    by_object: dict[str, list[int]] = {}
    for k, c in enumerate(arr.cuboids):
        if c.object is not None and not c.extra.get("hallucinated"):
            by_object.setdefault(c.object, []).append(k)
    cubs = list(arr.cuboids)
    grown: list[str] = []
    cos = np.cos(np.radians(MIRROR_AXES_DEG))
    for obj, members in sorted(by_object.items()):
        if len(members) < 3:
            continue
        top = _top_of([cubs[k] for k in members])
        top_bottom = float(top.center[2] - np.abs(top.rotation[2]) @ top.size / 2)
        for k in members:
            part = cubs[k]
            if part is top:
                continue
            for j in members:
                twin = cubs[j]
                if j == k or twin is top or (twin.extra.get("points", 0)
                                             <= part.extra.get("points", 0)):
                    continue
                # the twin as the sensor saw it (a deepening's guess is no evidence)
                seen = twin if twin.observed is None else twin.with_(
                    center=np.asarray(twin.observed.center, float),
                    size=np.asarray(twin.observed.size, float))
                image = _mirror_support(top, seen, obj, 0)
                if image is None or np.min(np.max(np.abs(part.rotation.T @ image.rotation),
                                                  axis=0)) < cos:
                    continue
                # both boxes in the part's frame
                own = part.rotation.T @ part.center
                corners = image.corners() @ part.rotation
                lo = np.minimum(own - part.size / 2, corners.min(axis=0))
                hi = np.maximum(own + part.size / 2, corners.max(axis=0))
                # up to the underside of the top, not into it (a strip whose noisy top
                # reaches into the top would carry that overlap along)
                up = int(np.argmax(np.abs(part.rotation[2])))
                if part.rotation[2, up] > 0:
                    hi[up] = min(hi[up], top_bottom)
                else:
                    lo[up] = max(lo[up], -top_bottom)
                overlap = np.minimum(own + part.size / 2, corners.max(axis=0)) - \
                    np.maximum(own - part.size / 2, corners.min(axis=0))
                growth = (hi - lo) - part.size
                # the same part: overlapping along two axes, and along the third at most
                # MIRROR_SLACK apart (a thin panel's mirror image lands a few mm off)
                if (np.sum(overlap > 0) < 2 or np.any(overlap <= -MIRROR_SLACK)
                        or growth.max() < MIRROR_MIN_GROWTH):
                    continue
                # ... and no bigger than its twin (with the slack) once grown: a leg's
                # foot and the image of another leg 30 cm off are two legs, not one
                twin_size = np.abs(part.rotation.T @ seen.rotation) @ seen.size
                horiz = np.abs(part.rotation[2]) < 0.5
                # (a twin seen face-on as a sliver is at least twice the slack thick: its
                # depth is not in the data, and the part's own fit may be wider)
                twin_size = np.maximum(twin_size, 2 * MIRROR_SLACK)
                if np.any(((hi - lo) > twin_size + 2 * MIRROR_SLACK) & horiz):
                    continue
                new = part.with_(center=part.rotation @ ((lo + hi) / 2), size=hi - lo)
                rest = arr.with_(cuboids=tuple(c for n, c in enumerate(cubs) if n != k))
                before, tol = _separations(rest, part)
                after, _ = _separations(rest, new)
                if np.any((after < -tol) & (after < before - 1e-9)):
                    continue  # the growth enters another box (overlaps it had may stay)
                if views and visible_free_fraction(_box_samples(new), views,
                                                   margin) > FREE_FRACTION_MAX:
                    continue
                cubs[k] = new
                grown.append(part.id)
                break
    if not grown:
        return arr, []
    return arr.with_(cuboids=tuple(cubs)), grown


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
    tops = {obj: _top_of(members) for obj, members in by_object.items()}
    for obj, members in sorted(by_object.items()):
        top = tops[obj]
        for other, theirs in sorted(by_object.items()):
            if other == obj or len(theirs) <= len(members):
                continue
            twin_top = tops[other]
            if not _twins(top, twin_top):
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
