"""A part seen only face-on has depth the sensor could not see.

Evidence: the box's extents against the first view's horizontal viewing direction, the
other parts of its object, and the depth views.  Regularity: solid parts are not
millimetre slivers; a leg, a pillar or a box behind a table top seen from the front is
fitted a few millimetres deep along the view because its depth is not in the data.  A
box whose extent along a horizontal axis within ``face_on_part_deg`` of the view is
below ``thin_fraction`` of its other horizontal extent (within ``face_on_deg`` for a
slab standing on its edge that is a box of its own or shows a face of
``big_face`` metres: a box in a pile seen obliquely, a sofa's base, a seat cushion seen
along the sofa) has its back face pushed away from the camera towards that other extent
(a square footprint), in ``steps`` increments, as far as no view saw the added space
empty and nothing is entered.  Seen at a grazing angle, such a slab's depth is hidden
behind its own face and its neighbours as much as seen face-on; where the view saw its
end and past it, the space a push adds was seen empty and the push stops there, so the
angle is left to the views (``face_on_deg`` short of a view exactly along the face).
A panel of an object of several parts (its seen sides within ``thin_fraction`` of each
other, or its seen face at least ``big_face`` wide, which no leg or post is: a
desk's or a shelf's side, a sofa's arm, a chair's back) is pushed only where the parts
joined to it (within ``joined_gap``; not one fixed to its back face) end within
``thin_fraction`` of its width behind it (a chair's back seen from the front goes back to
the seat's rear edge; a monitor's screen not to the foot under its neck): furniture is
built of thin panels, so what shows a panel's depth is the parts it is joined to
(below), not a square footprint (a desk seen from the side became a block filling the
hidden space under its top).  A part that is the only one seen of an object whose other parts the
segmentation's part map names (``object_parts``: a sofa seen from behind shows its back
alone) is such a panel too, and nothing seen says its depth: it is left as seen.  A part
goes no deeper than its object's other parts span along that axis, nor
further than they reach behind it; a flat slab of its own (thinner than
``thin_fraction`` of its width) no further than what it rests on and what rests on it
(within ``rest_gap``) reach behind it: a plank on a block seen end-on is not a square.
A neighbour seen as the slab is does not bound it: a slab as deep within a factor
``sliver_ratio`` (thinner along the view than ``thin_fraction`` of its width) and at
least ``thin_fraction`` as wide, whose depth is as unseen as the slab's; so a pile of
flat boxes seen from the front goes back box by box, while one box of the pile whose
depth the view did see bounds the slivers on it.
A board of furniture standing on its long edge (at least twice as tall as the view saw
it deep) on a post of its object (narrower along the board than ``thin_fraction`` of
its height) goes no deeper than that post reaches behind it: a chair's back rail on its
back posts, filmed from behind, is not pushed over the seat into a floating block.
Blocked within a step by a broad face (a back cushion a few degrees askew to the sofa's
back), it goes as deep as it fits, to ``resolution``.  "No view saw the added space
empty" holds for every layer a push adds (each of its ``steps``), not for the added
space on average (``layers``): a camera looking over a part's top sees the space
behind it only from some distance back, and the part ends before that layer, however
much of the space nearer its face its own shadow hides.  Every push below does the same.

The parts a part is joined to say how deep it is too: furniture is joined face to face
(a board's end against its side panel, a seat cushion's end against an arm), so where
two upright parts of one object meet side by side (vertical ranges sharing at least
``joined_share`` of the lower one, their faces within ``joined_gap``), the one whose
extent across the joint stops short of the other's on the side away from the camera by
more than ``joined_min`` is pushed back to the other's far face there, as far as no view
saw the added space empty, when the other reaches past it on the side the camera sees
by no more than ``joined_min`` or half as far as on the side away from it: then the
view ended it, while a part behind the other's middle (a monitor's neck behind its
screen) was ended by its own width.  A leg under a top or a box on a board is not
joined side by side; a rail between two legs is no wider across the joint than they
are.  A panel seen face-on across the joint's axis (a sofa's arm seen from the side,
whose end meets the back) is not pushed along it: its thickness is what the face-on
rule says, not the length of the part beside it.

Furniture repeats its boards: two flat parts of one object (upright, thinner than half
their length) of the same length (within ``twin_size_rel``) and thickness (within
``twin_thickness``: a chair's back rail standing on its edge above the seat is no twin
of it), parallel (``twin_cos``) and above one another are as deep as each other, so the
shallower one is pushed back to the deeper one's far face in the same way (a shelf's
lower boards half hidden behind its books, its top board seen edge-on at eye height).

Things come in copies: boxes resting side by side on one box, parallel (``twin_cos``),
as tall as each other and as wide across the row (within ``twin_size_rel``), are as
deep as each other, so the shallower one is pushed back to the deeper one's far face in
the same way (``copies``; a sofa's seat cushions seen past their neighbour, their back
halves hidden behind an arm or in their own shadow).

What rests on a board lies on it whole: a board whose face away from the camera stops
short by more than ``joined_min`` of the far face of a box resting on it (its bottom
above the board's middle, within ``rest_gap`` of its top), or of any part of that box's
object, is pushed back under it in the same way (a desk's top seen edge-on from its
height, the monitor on it seen reaching further back).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import (
    broad_face,
    changed_boxes,
    extent_along,
    face_normal,
    horizontal_axes,
    is_upright,
    joined_reach,
    object_depth,
    object_reach,
    overlap_along,
    overlap_face,
    push_face,
    resting_cut,
    resting_on,
    single_part,
    trimmed,
    up_axis,
    z_range,
)
from ..contacts import find_contacts
from ..evidence import slab_layers, slab_samples
from ..model import Arrangement, is_support_id
from .base import Edit, Prior, principle_of


@dataclass(frozen=True)
class Params:
    thin_fraction: float = 0.5  #: thin extent / other horizontal extent of a slab
    face_on_part_deg: float = 45.0  #: degrees between the thin axis and the view
    face_on_deg: float = 89.0  #: degrees, for a box of its own or a big face
    big_face: float = 0.2  #: metres: both sides of a big seen face
    steps: int = 4  #: increments of the push
    resolution: float = 0.002  #: metres: how finely a blocked push is found
    rest_gap: float = 0.02  #: metres between a flat slab and what it rests on or carries
    sliver_ratio: float = 2.0  #: a neighbour as deep as a slab within this factor: no bound
    joined_gap: float = 0.02  #: metres between the faces of parts joined side by side
    joined_share: float = 0.5  #: share of the lower part's height the two share
    joined_min: float = 0.03  #: metres one part must stop short of the other
    twin_size_rel: float = 0.1  #: relative agreement of two twin boards' lengths
    twin_thickness: float = 0.03  #: metres: two twin boards' heights agree within this
    twin_cos: float = 0.996  #: |cos| between twin boards' long axes (5 degrees)
    copies: bool = True  #: copies side by side on one box are as deep as each other
    layers: bool = True  #: no layer a push adds was seen empty (off: the added space as a whole)


def settle_resting(arr: Arrangement, cid: str) -> Arrangement | None:
    """``arr`` with the overlaps of box ``cid`` cleared where they are a box resting on
    another (:func:`pipeline.boxops.resting_cut`) or where ``cid`` reaches into the other
    by at most a tenth of its extent; None when another overlap remains."""
    for _ in range(4):
        pens = [(a, b) for a, b, _ in find_contacts(arr).penetrations if cid in (a, b)]
        if not pens:
            return arr
        cubs = list(arr.cuboids)
        for a, b in pens:
            if b.startswith(("ground", "wall:")):
                return None
            ia, ib = arr.index[a], arr.index[b]
            rest = resting_cut(cubs[ia], cubs[ib])
            if rest is not None:
                cubs[ia], cubs[ib] = rest
                continue
            # else the deepened box gives way where it reaches least far, if by little
            k, other = (ia, cubs[ib]) if a == cid else (ib, cubs[ia])
            face = overlap_face(cubs[k], other)
            if face is None or face[0] > 0.1 * float(cubs[k].size[face[1]]):
                return None
            cubs[k] = trimmed(cubs[k], other)
        arr = arr.with_(cuboids=tuple(cubs))
    return None


def stack_reach(arr: Arrangement, c, u: np.ndarray, p: Params) -> float:
    """How far behind ``c``'s face against ``u`` the boxes reach that ``c`` rests on or
    that rest on it (within ``p.rest_gap``), but for those seen as ``c`` is: slabs as
    deep as ``c`` within a factor ``p.sliver_ratio`` and thinner along ``u`` than
    ``p.thin_fraction`` of their width across it, at least ``p.thin_fraction`` as wide
    as ``c``, whose depth is as unseen as ``c``'s; inf when there are none."""
    below = resting_on(arr, c, p.rest_gap)
    across_u = np.cross([0.0, 0.0, 1.0], u)
    across_u /= max(float(np.linalg.norm(across_u)), 1e-12)
    near, far = extent_along(c, u)
    wide = p.thin_fraction * float(np.ptp(extent_along(c, across_u)))

    def like_c(q) -> bool:
        deep, across = float(np.ptp(extent_along(q, u))), float(np.ptp(extent_along(q, across_u)))
        return ((far - near) / p.sliver_ratio <= deep <= p.sliver_ratio * (far - near)
                and deep < p.thin_fraction * across and across >= wide)

    touching = [q for q in arr.cuboids if q.id != c.id and (
        (below is not None and q.id == below.id) or resting_on(arr, q, p.rest_gap) is c)
        and not like_c(q)]
    if not touching:
        return float("inf")
    return max(extent_along(q, u)[1] for q in touching) - near


def post_reach(arr: Arrangement, c, axis: int, u: np.ndarray, p: Params) -> float:
    """How far behind ``c``'s face against ``u`` the post it stands on reaches, when
    ``c`` is a board standing on its long edge (at least twice as tall as it is thick
    along ``axis``) on a post of its object (a part narrower along ``c``'s length than
    ``p.thin_fraction`` of ``c``'s height: a chair's back rail on its back posts); inf
    otherwise."""
    height = float(c.size[up_axis(c)])
    if c.object is None or height < 2.0 * float(c.size[axis]):
        return float("inf")
    below = resting_on(arr, c, p.rest_gap)
    if below is None or below.object != c.object:
        return float("inf")
    along = [a for a in horizontal_axes(c) if a != axis]
    if not along:  # tilted: no length lies level
        return float("inf")
    if float(np.ptp(extent_along(below, c.rotation[:, along[0]]))) >= p.thin_fraction * height:
        return float("inf")
    return extent_along(below, u)[1] - extent_along(c, u)[0]


def across(c, axis: int) -> float:
    """The width of the face of ``c`` across its horizontal ``axis``: its largest other
    horizontal extent (0 when it has none)."""
    return max((float(c.size[a]) for a in horizontal_axes(c) if a != axis), default=0.0)


def is_panel(arr: Arrangement, c, axis: int, p: Params) -> bool:
    """Whether ``c``, thin along its horizontal ``axis``, is a panel of furniture: a part
    of an object of several parts whose face across ``axis`` is as wide as half its
    height or ``big_face``, and as tall as half its width (a desk's side, a sofa's arm,
    a chair's back; not a leg or a post)."""
    width = across(c, axis)
    height = float(c.size[up_axis(c)])
    return (not single_part(arr, c)
            and (width >= p.thin_fraction * height or width >= p.big_face)
            and height >= p.thin_fraction * width)


def horizontal_look(c, eye: np.ndarray) -> np.ndarray | None:
    """The unit horizontal direction from ``eye`` to ``c``'s centre (cameras often look
    down steeply); None when the eye is right above or below it."""
    look = np.asarray(c.center, float) - eye
    look[2] = 0.0
    n = np.linalg.norm(look)
    return look / n if n >= 1e-9 else None


def meets_face(c, axis: int, look: np.ndarray, deg: float) -> bool:
    """Whether the unit horizontal view ``look`` runs within ``deg`` of ``c``'s ``axis``:
    it looks at the face across ``axis``."""
    return abs(float(c.rotation[:, axis] @ look)) >= np.cos(np.radians(deg))


def seen_face_on(c, axis: int, eye: np.ndarray, deg: float) -> bool:
    """Whether the horizontal view from ``eye`` to ``c`` runs within ``deg`` of its
    ``axis``: the camera looks at the face across ``axis``."""
    look = horizontal_look(c, eye)
    return look is not None and meets_face(c, axis, look, deg)


def face_on_panel_axes(arr: Arrangement, c, eye: np.ndarray, p: Params) -> set[int]:
    """The horizontal axes of ``c`` across which it is a panel (:func:`is_panel`), thin
    along them, whose face the horizontal view from ``eye`` meets within
    ``p.face_on_part_deg``."""
    look = horizontal_look(c, eye)
    if look is None:
        return set()
    return {a for a in horizontal_axes(c)
            if c.size[a] < p.thin_fraction * across(c, a) and is_panel(arr, c, a, p)
            and meets_face(c, a, look, p.face_on_part_deg)}


def away_from(c, axis: int, eye: np.ndarray) -> np.ndarray:
    """Box ``c``'s ``axis`` turned away from the camera at ``eye``."""
    u = c.rotation[:, axis]
    return u if float(u @ (c.center - eye)) >= 0 else -u


def reach_past(c, q, u: np.ndarray, p: Params) -> float | None:
    """How far box ``q`` reaches past box ``c``'s face towards ``u`` when the two overlap
    along ``u`` and it reaches more than ``p.joined_min`` further; None otherwise."""
    c0, c1 = extent_along(c, u)
    q0, q1 = extent_along(q, u)
    return q1 - c1 if q0 <= c1 and q1 >= c0 and q1 - c1 > p.joined_min else None


def joined_pushes(arr: Arrangement, eye: np.ndarray, p: Params):
    """``(k, axis, u, length)``: box ``k``'s face on ``axis`` towards ``u`` (away from the
    camera at ``eye``) would reach the far face of a part of its object joined to it side
    by side (see the module docstring) when pushed out by ``length``; longest first."""
    out = []
    for k, c in enumerate(arr.cuboids):
        if c.object is None or c.extra.get("hallucinated") or not is_upright(c):
            continue
        cz0, cz1 = z_range(c)
        face_on = face_on_panel_axes(arr, c, eye, p)
        for q in arr.cuboids:
            if q is c or q.object != c.object or not is_upright(q):
                continue
            qz0, qz1 = z_range(q)
            if min(cz1, qz1) - max(cz0, qz0) < p.joined_share * min(cz1 - cz0, qz1 - qz0):
                continue
            normal, across = horizontal_axes(c)
            for n, a in ((normal, across), (across, normal)):
                # faces meet along the joint's normal n ...
                c0, c1 = extent_along(c, c.rotation[:, n])
                q0, q1 = extent_along(q, c.rotation[:, n])
                if max(q0 - c1, c0 - q1) > p.joined_gap or min(c1, q1) - max(c0, q0) > p.joined_gap:
                    continue
                # ... and q reaches further across it, away from the eye, much further
                # than on the side the camera sees (a part behind the other's middle, as
                # a monitor's neck behind its screen, is not cut short by the view)
                if a in face_on:
                    continue  # a panel seen face-on: its thickness is the face-on rule's
                u = away_from(c, a, eye)
                length = reach_past(c, q, u, p)
                if length is None:
                    continue
                near = extent_along(c, u)[0] - extent_along(q, u)[0]  # q past c, seen side
                if near <= max(p.joined_min, 0.5 * length):
                    out.append((k, a, u, length))
    return sorted(out, key=lambda t: -t[3])


def board_axes(c) -> tuple[int, int] | None:
    """(long axis, depth axis) of an upright box flatter than half its length (a board,
    a top); None for any other box."""
    if not is_upright(c):
        return None
    h = horizontal_axes(c)
    if len(h) != 2:
        return None
    long, depth = sorted(h, key=lambda a: -float(c.size[a]))
    if float(c.size[up_axis(c)]) >= 0.5 * float(c.size[long]):
        return None
    return long, depth


def alike(a: float, b: float, rel: float) -> bool:
    """Whether two extents agree within ``rel`` of the larger one."""
    return abs(a - b) <= rel * max(a, b)


def twin_pushes(arr: Arrangement, eye: np.ndarray, p: Params):
    """``(k, axis, u, length)``: board ``k``'s face on its depth ``axis`` towards ``u``
    (away from the camera at ``eye``) would reach the far face of a twin board of its
    object (see the module docstring) when pushed out by ``length``; longest first."""
    out = []
    boards = [(k, c, board_axes(c)) for k, c in enumerate(arr.cuboids)
              if c.object is not None and not c.extra.get("hallucinated")]
    boards = [(k, c, ax) for k, c, ax in boards if ax is not None]
    for k, c, (long, depth) in boards:
        for _, q, (qlong, _) in boards:
            if q is c or q.object != c.object:
                continue
            lc, lq = float(c.size[long]), float(q.size[qlong])
            if abs(float(c.size[up_axis(c)]) - float(q.size[up_axis(q)])) > p.twin_thickness:
                continue  # not as thick: a rail on its edge is no twin of a seat
            if (not alike(lc, lq, p.twin_size_rel)
                    or abs(float(c.rotation[:, long] @ q.rotation[:, qlong])) < p.twin_cos):
                continue
            if overlap_along(c, q, c.rotation[:, long]) < 0.5 * min(lc, lq):
                continue  # not above one another
            u = away_from(c, depth, eye)
            length = reach_past(c, q, u, p)
            if length is not None:
                out.append((k, depth, u, length))
    return sorted(out, key=lambda t: -t[3])


def supports_of(arr: Arrangement, gap: float) -> dict[str, str]:
    """Box id -> the id of the box it rests on (:func:`pipeline.boxops.resting_on`
    within ``gap``), for the boxes resting on one."""
    out = {}
    for q in arr.cuboids:
        s = resting_on(arr, q, gap)
        if s is not None:
            out[q.id] = s.id
    return out


def copy_pushes(arr: Arrangement, eye: np.ndarray, p: Params):
    """``(k, axis, u, length)``: box ``k``'s face on a horizontal ``axis`` towards ``u``
    (away from the camera at ``eye``) would reach the far face of a copy of it (see the
    module docstring: resting on the same box, parallel, as tall and as wide across
    ``axis`` within ``p.twin_size_rel``, side by side) when pushed out by ``length``;
    longest first."""
    out = []
    rest = supports_of(arr, p.rest_gap)
    boxes = [(k, c) for k, c in enumerate(arr.cuboids)
             if c.id in rest and not c.extra.get("hallucinated") and is_upright(c)]
    for k, c in boxes:
        hc = float(c.size[up_axis(c)])
        for _, q in boxes:
            if q is c or rest[q.id] != rest[c.id]:
                continue
            hq = float(q.size[up_axis(q)])
            if not alike(hc, hq, p.twin_size_rel):
                continue
            for a in horizontal_axes(c):
                ua = c.rotation[:, a]
                qa = int(np.argmax(np.abs(q.rotation.T @ ua)))
                if abs(float(q.rotation[:, qa] @ ua)) < p.twin_cos:
                    continue
                wc, wq = float(c.size[a]), float(q.size[qa])
                if (not alike(wc, wq, p.twin_size_rel)
                        or overlap_along(c, q, ua) > 0.5 * min(wc, wq)):
                    continue  # not as wide, or one in front of the other
                d = next(x for x in horizontal_axes(c) if x != a)
                u = away_from(c, d, eye)
                length = reach_past(c, q, u, p)
                if length is not None:
                    out.append((k, d, u, length))
    return sorted(out, key=lambda t: -t[3])


def carried_pushes(arr: Arrangement, eye: np.ndarray, p: Params):
    """``(k, axis, u, length)``: board ``k``'s face on a horizontal ``axis`` towards ``u``
    (away from the camera at ``eye``) would reach the far face of what rests on it (a box
    whose bottom lies above the board's middle, within ``p.rest_gap`` of its top, and
    every part of that box's object when it is another object than the board's) when
    pushed out by ``length``; longest first."""
    out = []
    support = supports_of(arr, p.rest_gap)  # found once for every board
    for k, c in enumerate(arr.cuboids):
        if c.extra.get("hallucinated") or board_axes(c) is None:
            continue
        middle = float(c.center[2])  # on it, not beside it on what it stands on
        on = [q for q in arr.cuboids if support.get(q.id) == c.id and z_range(q)[0] > middle]
        objects = {q.object for q in on if q.object is not None and q.object != c.object}
        ids = {q.id for q in on}
        carried = on + [q for q in arr.cuboids if q.object in objects and q.id not in ids]
        for axis in horizontal_axes(c):
            u = away_from(c, axis, eye)
            far = extent_along(c, u)[1]
            length = max((extent_along(q, u)[1] - far for q in carried), default=0.0)
            if length > p.joined_min:
                out.append((k, axis, u, length))
    return sorted(out, key=lambda t: -t[3])


def apply(arr, evidence, p: Params, ctx):
    if not evidence:
        return
    arr = yield from _face_on(arr, evidence, p)
    arr = yield from pushed_back(arr, evidence, p, joined_pushes(arr, evidence.eye, p),
                                 "joined side by side to a deeper part of its object")
    arr = yield from pushed_back(arr, evidence, p, twin_pushes(arr, evidence.eye, p),
                                 "as deep as a twin board of its object")
    if p.copies:
        arr = yield from pushed_back(arr, evidence, p, copy_pushes(arr, evidence.eye, p),
                                     "as deep as a copy of it beside it")
    yield from pushed_back(arr, evidence, p, carried_pushes(arr, evidence.eye, p),
                           "under all of what rests on it")


def pushed_back(arr, evidence, p, pushes, why: str):
    """Each box of ``pushes`` (see :func:`joined_pushes`) pushed back as far as it goes
    in ``p.steps`` (any parameters with ``steps``: tried longest first; no view saw the
    added space empty, nothing entered)."""
    from ..extend import Extension

    done: set[int] = set()
    for k, axis, u, full in pushes:
        if k in done:
            continue
        c = arr.cuboids[k]
        side = 1 if float(c.rotation[:, axis] @ u) > 0 else 0
        ends = [full * j / p.steps for j in range(p.steps + 1)]
        exts = [Extension(k, axis, side, e) for e in ends]
        reach = p.steps
        if p.layers:  # as far as the first layer a view saw empty
            reach = next((j for j, layer in enumerate(slab_layers(arr, exts[-1], ends))
                          if evidence.seen_empty(layer)), p.steps)
        for j in range(reach, 0, -1):
            length = ends[j]
            if not p.layers and evidence.seen_empty(slab_samples(arr, exts[j])):
                continue  # the added space as a whole seen empty
            trial = settle_resting(push_face(arr, k, axis, u, length), c.id)
            if trial is None:
                continue
            v = yield Edit(changed_boxes(trial, arr), f"{why}: pushed back "
                                                      f"{1000 * length:.0f} mm")
            if v.ok:
                arr = v.arrangement
                done.add(k)
                break
    return arr


def _face_on(arr, evidence, p: Params):
    from ..extend import Extension

    eye = evidence.eye
    for k in range(len(arr.cuboids)):
        c = arr.cuboids[k]
        look = horizontal_look(c, eye)
        if look is None:
            continue
        horizontal = horizontal_axes(c)
        height = float(c.size[up_axis(c)])
        for axis in horizontal:
            along = float(c.rotation[:, axis] @ look)
            width = across(c, axis)
            if c.size[axis] >= p.thin_fraction * width:
                continue
            side = 1 if along > 0 else 0  # the face away from the camera
            u = face_normal(c, axis, side)
            panel = is_panel(arr, c, axis, p)
            # a panel's depth is what the parts joined to it say (a chair's back goes back
            # to the seat it stands on; a monitor's screen not to the foot under its neck)
            reach = ((joined_reach(arr, c, u, p.joined_gap) if panel else object_reach(arr, c, u))
                     + float(c.size[axis]) / 2)
            if panel and reach > p.thin_fraction * width:
                break  # a panel of furniture: its depth is what its joints say
            if single_part(arr, c) and c.extra.get("object_parts", 1) > 1:
                break  # the one seen panel of furniture whose other parts no view shows
            if abs(along) < np.cos(np.radians(p.face_on_part_deg)):
                # seen obliquely: only a box of its own or a big face, and only a slab
                # standing on its edge (not a keyboard seen from above)
                big = np.delete(c.size, axis).min() >= p.big_face
                if (abs(along) < np.cos(np.radians(p.face_on_deg))
                        or not (big or single_part(arr, c))
                        or c.size[axis] >= p.thin_fraction * height):
                    continue
            target = min(width, object_depth(arr, c, axis), reach)
            if height < p.thin_fraction * width and single_part(arr, c):
                target = min(target, stack_reach(arr, c, u, p))
            target = min(target, post_reach(arr, c, axis, u, p))
            full = target - float(c.size[axis])
            if full <= 1e-4:
                break

            def deeper(length: float, base=arr, k=k, cid=c.id, axis=axis, u=u
                       ) -> Arrangement | None:
                return settle_resting(push_face(base, k, axis, u, length), cid)

            best, done = None, 0.0
            for j in range(1, p.steps + 1):
                length = full * j / p.steps

                start = full * (j - 1) / p.steps if p.layers else 0.0  # its new layer
                if evidence.seen_empty(slab_samples(arr, Extension(k, axis, side, length),
                                                    start=start)):
                    break
                trial = deeper(length)
                if trial is None:
                    # blocked within this step by a broad face: as deep as it goes (a
                    # wall, the floor or a small box in the way say nothing of the depth)
                    pens = find_contacts(push_face(arr, k, axis, u, length)).penetrations
                    into = [q if pp == c.id else pp for pp, q, _ in pens if c.id in (pp, q)]
                    if any(is_support_id(q) or not broad_face(arr.cuboid(q), -u)
                           for q in into):
                        break
                    lo, hi = done, length
                    while hi - lo > p.resolution:
                        mid = 0.5 * (lo + hi)
                        trial = deeper(mid)
                        if trial is None:
                            hi = mid
                        else:
                            lo, best = mid, trial
                    break
                best, done = trial, length
            if best is not None:
                changed = tuple(b for b, old in zip(best.cuboids, arr.cuboids, strict=True)
                                if b is not old)
                v = yield Edit(changed, f"seen face-on, {1000 * float(c.size[axis]):.0f} mm "
                                        f"deep: pushed back from the camera")
                if v.ok:
                    arr = v.arrangement
            break
    return arr


PRIOR = Prior("deepen", "complete", Params(), apply, principle_of(__doc__))
