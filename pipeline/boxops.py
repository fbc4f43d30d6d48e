"""The vocabulary of box edits and predicates every prior speaks.

One place for the geometry the priors of :mod:`pipeline.priors` share, so that "upright",
"a face pushed out", "a gap" or "a group" mean one thing everywhere:

* **edits**: push a face out (:func:`pushed`, :func:`push_face`), trim a face back out of
  another box (:func:`trimmed`), turn about the vertical (:func:`turned_by`,
  :func:`squared_to`), bound two boxes by one (:func:`merged`), cut a box at a plane
  (:func:`lifted_from_plane`) or at the face it rests on (:func:`resting_cut`);
* **predicates**: :func:`is_upright` (one tolerance, :data:`UPRIGHT_TOL_DEG`),
  :func:`penetrating`, :func:`same_axes`, :func:`side_by_side`, :func:`broad_face`,
  :func:`overlap_across`, :func:`face_seen`;
* **ranges and gaps**: :func:`z_range`, :func:`gap`, :func:`separations`,
  :func:`is_free`, :func:`overlap_face`, :func:`object_depth`, :func:`object_reach`;
* **groups**: :func:`same_object_groups`, :func:`fixed_components`,
  :func:`touching_group`, :func:`near`, :func:`resting_on`.

Everything here is a pure function of boxes (no views, no camera: that is
:mod:`pipeline.evidence`).  Lengths in metres, angles in degrees unless named ``_rad``.
"""

from __future__ import annotations

import numpy as np

from .contacts import find_contacts, pair_tolerance, sat_separation
from .model import Arrangement, Cuboid, ObservedBox, rotation_about_axis

#: A box is upright when one of its axes is within this many degrees of the vertical.
#: Every non-slanted box is stood exactly upright by the ``upright`` prior (tilts up to
#: 15 degrees are fitting noise), so any tolerance well below 15 degrees says the same;
#: this one admits the rounding of a few turns and nothing a person would call tilted.
UPRIGHT_TOL_DEG = 2.5
_UPRIGHT_COS = float(np.cos(np.radians(UPRIGHT_TOL_DEG)))
#: An axis at least 60 degrees from the vertical (within 30 degrees of the horizontal:
#: its vertical component at most cos 60 = 0.5) counts as horizontal.
HORIZONTAL_COS = 0.5
#: A box under another is a slab it rests on (:func:`resting_cut`) when its footprint is
#: this many times the upper box's and it is at most half as tall.
SLAB_AREA_RATIO = 4.0
#: A face at least this many square metres (the back of a sofa, a shelf's side panel) is
#: broad: like a wall, a plane fitted to many points (:func:`broad_face`).
BROAD_FACE_AREA = 0.5
#: A face is where the sensor saw it when within this many metres of its observed box's
#: face (:func:`face_seen`).
SEEN_FACE_TOL = 0.005
UP = np.array([0.0, 0.0, 1.0])


# ------------------------------------------------------------------ orientation
def is_upright(c: Cuboid, tol_deg: float = UPRIGHT_TOL_DEG) -> bool:
    """Whether one of ``c``'s axes lies within ``tol_deg`` of the vertical."""
    cos = _UPRIGHT_COS if tol_deg == UPRIGHT_TOL_DEG else float(np.cos(np.radians(tol_deg)))
    return bool(np.abs(c.rotation[2]).max() >= cos)


def vertical_axis(c: Cuboid, tol_deg: float = UPRIGHT_TOL_DEG) -> int | None:
    """The local axis of an upright box along the vertical (None when it is tilted)."""
    ax = int(np.argmax(np.abs(c.rotation[2])))
    return ax if is_upright(c, tol_deg) else None


def up_axis(c: Cuboid) -> int:
    """The local axis nearest the vertical, whatever the tilt."""
    return int(np.argmax(np.abs(c.rotation[2])))


def horizontal_axes(c: Cuboid) -> list[int]:
    """The local axes at least 60 degrees from the vertical (:data:`HORIZONTAL_COS`)."""
    return [a for a in range(3) if abs(c.rotation[2, a]) <= HORIZONTAL_COS]


def yaw_of(R: np.ndarray) -> float:
    """The yaw of an upright frame (the angle of its most horizontal axis), radians."""
    h = R[:, int(np.argmin(np.abs(R[2])))]
    return float(np.arctan2(h[1], h[0]))


def quarter_turn(a: float, b: float) -> float:
    """The turn (radians, within +-45 degrees) that takes yaw ``a`` onto yaw ``b``
    modulo a quarter turn (a box's axes repeat every 90 degrees)."""
    return (b - a + np.pi / 4) % (np.pi / 2) - np.pi / 4


def turn_onto(c: Cuboid, other: Cuboid) -> float:
    """The turn about the vertical (radians, within +-45 degrees) that puts the upright
    ``c`` onto the axes of the upright ``other``."""
    ax_c = next(k for k in range(3) if abs(c.rotation[2, k]) < HORIZONTAL_COS)
    ax_o = next(k for k in range(3) if abs(other.rotation[2, k]) < HORIZONTAL_COS)
    a = np.arctan2(c.rotation[1, ax_c], c.rotation[0, ax_c])
    b = np.arctan2(other.rotation[1, ax_o], other.rotation[0, ax_o])
    return quarter_turn(a, b)


def turned_by(c: Cuboid, angle: float) -> Cuboid:
    """``c`` turned about the vertical through its centre by ``angle`` radians."""
    return c.with_(rotation=rotation_about_axis(UP, angle) @ c.rotation)


def same_axes(a: Cuboid, b: Cuboid, cos_tol: float = np.cos(np.radians(5))) -> bool:
    """True when the boxes' axes coincide up to order and sign (within 5 degrees)."""
    M = np.abs(a.rotation.T @ b.rotation)
    return bool(np.all(M.max(axis=1) > cos_tol))


# ------------------------------------------------------------------ face edits
def face_normal(c: Cuboid, axis: int, side: int) -> np.ndarray:
    """The outward unit normal of ``c``'s face on ``axis`` (``side`` 1: the + face)."""
    return c.rotation[:, axis] * (1.0 if side else -1.0)


def pushed(c: Cuboid, axis: int, side: int, length: float) -> Cuboid:
    """``c`` with its face on ``axis`` (``side`` 1: the + face) pushed out by ``length``
    (negative: pulled in), the opposite face fixed."""
    return pushed_along(c, axis, face_normal(c, axis, side), length)


def pushed_along(c: Cuboid, axis: int, u: np.ndarray, length: float) -> Cuboid:
    """``c`` with its face on ``axis`` towards the unit vector ``u`` (that axis, signed)
    pushed out by ``length``."""
    size = c.size.copy()
    size[axis] += length
    return c.with_(center=c.center + u * length / 2, size=size)


def push_face(arr: Arrangement, k: int, axis: int, u: np.ndarray, length: float
              ) -> Arrangement:
    """``arr`` with box ``k``'s face on ``axis`` towards ``u`` pushed out by ``length``."""
    cubs = list(arr.cuboids)
    cubs[k] = pushed_along(arr.cuboids[k], axis, u, length)
    return arr.with_(cuboids=tuple(cubs))


def extended(c: Cuboid, x) -> Cuboid:
    """``c`` with extension ``x`` (:class:`pipeline.extend.Extension`) applied."""
    return pushed(c, x.axis, x.side, x.length)


def overlap_face(c: Cuboid, other: Cuboid, by_share: bool = False,
                 skip: int | None = None, sideways: bool = False
                 ) -> tuple[float, int, int] | None:
    """(overlap, axis, side) of the face of ``c`` reaching least far into ``other``
    (``by_share``: whose retreat costs ``c`` the smallest share of its extent there),
    not along axis ``skip`` (``sideways``: of its upright faces only)."""
    best, least = None, None
    for ax in range(3):
        if ax == skip or (sideways and abs(c.rotation[2, ax]) > HORIZONTAL_COS):
            continue
        for side in (0, 1):
            u = face_normal(c, ax, side)
            face = c.center @ u + c.size[ax] / 2
            proj = other.corners() @ u
            overlap = face - proj.min()  # how far c reaches into the other along u
            key = overlap / max(float(c.size[ax]), 1e-12) if by_share else overlap
            if overlap > 0 and (least is None or key < least):
                best, least = (float(overlap), ax, side), key
    return best


def relative_overlap(c: Cuboid, other: Cuboid, by_share: bool = False,
                     skip: int | None = None, sideways: bool = False) -> float:
    """The share of its extent ``c`` would lose to clear ``other`` (inf when it cannot)."""
    best = overlap_face(c, other, by_share, skip, sideways)
    return float("inf") if best is None else best[0] / float(c.size[best[1]])


def trimmed(c: Cuboid, other: Cuboid, share: float = 1.0, by_share: bool = False,
            skip: int | None = None, sideways: bool = False) -> Cuboid:
    """``c`` with the face that overlaps ``other`` moved back by ``share`` of the overlap
    and a quarter of the contact tolerance (at most half of ``c``'s extent there)."""
    tol = float(pair_tolerance(c.size[None], other.size[None])[0])
    best = overlap_face(c, other, by_share, skip, sideways)
    if best is None:
        return c
    overlap, ax, side = best
    cut = min(share * overlap + 0.25 * tol, 0.5 * c.size[ax])
    if cut <= 0:
        return c
    return pushed(c, ax, side, -cut)


def merged(a: Cuboid, b: Cuboid) -> Cuboid:
    """The box in ``a``'s frame that bounds both ``a`` and ``b`` (``a``'s id; the points
    of both; observed as the result)."""
    local = (b.corners() - a.center) @ a.rotation
    lo = np.minimum(-a.size / 2, local.min(axis=0))
    hi = np.maximum(a.size / 2, local.max(axis=0))
    center = a.center + a.rotation @ ((lo + hi) / 2)
    extra = dict(a.extra)
    extra["points"] = int(a.extra.get("points", 0)) + int(b.extra.get("points", 0))
    obs = ObservedBox(center, hi - lo)
    return Cuboid(a.id, center, a.rotation, hi - lo, a.density, a.object, obs, extra)


def lifted_from_plane(c: Cuboid, sup) -> Cuboid:
    """``c`` without its part below a support plane (an upright box loses its bottom).

    The face pushed in is the one along the axis closest to the plane's normal; the cut
    along axis ``k`` is the depth over the axis' cosine with the normal.  Where that cut
    would take more than the box has along it (a long box askew to a wall, poking
    through with its end), the axis that loses the least share of its extent gives way
    instead: the box loses its end rather than all its thickness."""
    d = sup.signed_distance(c.corners())
    depth = -d.min()
    if depth <= 0:
        return c
    cos = np.abs(c.rotation.T @ sup.normal)
    need = depth / np.maximum(cos, 1e-6)
    ax = int(np.argmax(cos))
    if need[ax] >= 0.9 * c.size[ax]:
        share = np.where(need < 0.9 * c.size, need / c.size, np.inf)
        if np.isfinite(share).any():
            ax = int(np.argmin(share))
    cut = min(need[ax], 0.9 * c.size[ax])
    size = c.size.copy()
    size[ax] -= cut
    u = c.rotation[:, ax] * np.sign(c.rotation[:, ax] @ sup.normal)
    return c.with_(center=c.center + u * cut / 2, size=size)


def squared_to(c: Cuboid, other: Cuboid, min_deg: float) -> Cuboid:
    """``c`` turned about the vertical through its centre onto the axes of ``other``
    (both upright; the turn of at most 45 degrees that does it) when they are more than
    ``min_deg`` apart and ``c`` would clear ``other`` sideways; otherwise ``c`` (a box
    lying askew on another is cut from below, where its yaw does not matter)."""
    if c.extra.get("slanted") or not is_upright(c) or not is_upright(other):
        return c
    turn = turn_onto(c, other)
    face = overlap_face(c, other, by_share=True)
    if (abs(np.degrees(turn)) <= min_deg or face is None
            or abs(c.rotation[2, face[1]]) > HORIZONTAL_COS):  # cleared from above/below
        return c
    return turned_by(c, turn)


# ------------------------------------------------------------------ ranges and gaps
def z_range(c: Cuboid) -> tuple[float, float]:
    """(bottom, top) heights of an upright box."""
    h = float(c.size[up_axis(c)]) / 2
    return float(c.center[2]) - h, float(c.center[2]) + h


def extent_along(c: Cuboid, u: np.ndarray) -> tuple[float, float]:
    """(lowest, highest) of ``c``'s points projected on the unit vector ``u``."""
    half = 0.5 * float(np.abs(c.rotation.T @ u) @ c.size)
    m = float(c.center @ u)
    return m - half, m + half


def overlap_along(a: Cuboid, b: Cuboid, u: np.ndarray) -> float:
    """How far the extents of ``a`` and ``b`` along the unit vector ``u`` overlap
    (metres; negative: the gap between them)."""
    (a0, a1), (b0, b1) = extent_along(a, u), extent_along(b, u)
    return min(a1, b1) - max(a0, b0)


def upright_extent(c: Cuboid) -> tuple[float, float]:
    """(height, largest horizontal extent) of a box, from its axes' z components."""
    ax = up_axis(c)
    other = [k for k in range(3) if k != ax]
    return float(c.size[ax]), float(max(c.size[other]))


def gap(a: Cuboid, b: Cuboid) -> float:
    """Separation of two boxes (negative: they overlap), by the separating-axis test."""
    sep, _, _ = sat_separation(a.center[None], a.rotation[None], a.size[None] / 2,
                               b.center[None], b.rotation[None], b.size[None] / 2, np.zeros(1))
    return float(sep[0])


def penetrating(a: Cuboid, b: Cuboid) -> bool:
    """Whether two boxes overlap by more than their contact tolerance."""
    tol = pair_tolerance(a.size[None], b.size[None])
    sep, _, _ = sat_separation(a.center[None], a.rotation[None], a.size[None] / 2,
                               b.center[None], b.rotation[None], b.size[None] / 2, tol)
    return bool(sep[0] < -tol[0])


def separations(arr: Arrangement, cand: Cuboid) -> tuple[np.ndarray, np.ndarray]:
    """(separation, contact tolerance) of ``cand`` from each cuboid of ``arr``."""
    n = len(arr.cuboids)
    C, R, S = arr.centers, arr.rotations, arr.sizes
    tol = pair_tolerance(np.broadcast_to(cand.size, (n, 3)), S)
    sep, _, _ = sat_separation(np.broadcast_to(cand.center, (n, 3)),
                               np.broadcast_to(cand.rotation, (n, 3, 3)),
                               np.broadcast_to(cand.size / 2, (n, 3)), C, R, S / 2, tol)
    return sep, tol


def entered(arr: Arrangement, cand: Cuboid, skip=()) -> np.ndarray:
    """Indices of the cuboids of ``arr`` that ``cand`` enters (beyond contact tolerance),
    but those at the indices ``skip``."""
    if not arr.cuboids:
        return np.zeros(0, int)
    sep, tol = separations(arr, cand)
    hit = sep < -tol
    hit[list(skip)] = False
    return np.nonzero(hit)[0]


def is_free(arr: Arrangement, cand: Cuboid, skip=()) -> bool:
    """Whether ``cand`` enters none of the cuboids of ``arr`` (beyond contact tolerance)
    but those at the indices ``skip``."""
    return not len(entered(arr, cand, skip))


def flat_axes_xy(R: np.ndarray) -> np.ndarray:
    """(K, 2, 2) unit xy directions of the two local axes nearest horizontal of each of
    the rotations ``R`` (K, 3, 3), in the order of the axes."""
    up_axis = np.argmax(np.abs(R[:, 2, :]), axis=1)
    cols = np.array([[a for a in range(3) if a != u] for u in up_axis])  # (K, 2)
    ax = np.take_along_axis(R[:, :2, :], cols[:, None, :], axis=2)  # (K, 2 xy, 2 axes)
    ax = np.transpose(ax, (0, 2, 1))  # (K, 2 axes, 2 xy)
    n = np.linalg.norm(ax, axis=2, keepdims=True)
    return ax / np.maximum(n, 1e-12)


def footprints(C: np.ndarray, R: np.ndarray, S: np.ndarray) -> np.ndarray:
    """(K, 4, 2) corners of the footprints on the ground of the boxes with centres ``C``,
    rotations ``R`` and sizes ``S``, in order around each."""
    up_axis = np.argmax(np.abs(R[:, 2, :]), axis=1)
    cols = np.array([[a for a in range(3) if a != u] for u in up_axis])
    half = np.take_along_axis(S, cols, axis=1) / 2  # (K, 2)
    signs = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)  # (4, 2)
    off = np.einsum("cs,ks,ksd->kcd", signs, half, flat_axes_xy(R))
    return C[:, None, :2] + off


def box_samples(c: Cuboid, n: int = 5) -> np.ndarray:
    """``n``^3 points filling the inner 85 % of ``c`` on a regular grid."""
    t = ((np.arange(n) + 0.5) / n) * 2 - 1
    g = np.stack(np.meshgrid(t, t, t, indexing="ij"), axis=-1).reshape(-1, 3) * (c.size / 2 * 0.85)
    return c.center + g @ c.rotation.T


def overlap_across(a: Cuboid, b: Cuboid, u: np.ndarray) -> bool:
    """Whether ``b`` overlaps ``a`` in every direction of ``a``'s axes but ``u``'s."""
    ca, cb = a.corners(), b.corners()
    for ax in range(3):
        w = a.rotation[:, ax]
        if abs(float(w @ u)) > 0.5:
            continue
        pa, pb = ca @ w, cb @ w
        if pb.max() <= pa.min() or pb.min() >= pa.max():
            return False
    return True


def broad_face(c: Cuboid, u: np.ndarray) -> bool:
    """Whether the face of ``c`` whose outward normal is nearest ``u`` is at least
    :data:`BROAD_FACE_AREA` square metres."""
    axis = int(np.argmax(np.abs(c.rotation.T @ u)))
    return float(np.prod(np.delete(c.size, axis))) >= BROAD_FACE_AREA


def as_seen(c: Cuboid) -> Cuboid:
    """Box ``c`` as the sensor saw it: its observed box (``c`` itself when unknown)."""
    o = c.observed
    return c if o is None else c.with_(center=o.center, size=o.size)


def face_seen(c: Cuboid, u: np.ndarray) -> bool:
    """Whether the face of ``c`` whose outward normal is nearest the unit vector ``u`` is
    where the sensor saw it (its observed box's face, within :data:`SEEN_FACE_TOL`)."""
    o = c.observed
    if o is None:
        return False
    cos = c.rotation.T @ u
    axis = int(np.argmax(np.abs(cos)))
    w = c.rotation[:, axis] * np.sign(cos[axis])
    face = float(c.center @ w) + float(c.size[axis]) / 2
    seen = float(np.asarray(o.center) @ w) + float(np.asarray(o.size)[axis]) / 2
    return face - seen <= SEEN_FACE_TOL


def side_by_side(a: Cuboid, b: Cuboid) -> bool:
    """Whether two upright boxes stand side by side: each at least as tall as its narrower
    horizontal side (no slab), their bottoms level within a quarter of the lower box's
    height (two books on one board, neither on the other)."""
    for c in (a, b):
        ax = vertical_axis(c)
        if ax is None or c.size[ax] < np.delete(c.size, ax).min():
            return False
    (lo_a, hi_a), (lo_b, hi_b) = z_range(a), z_range(b)
    return abs(lo_a - lo_b) <= 0.25 * min(hi_a - lo_a, hi_b - lo_b)


def points_of(c: Cuboid) -> float:
    """The points a box was fitted to (1 when unknown: every box counts alike)."""
    return max(float(c.extra.get("points", 1)), 1.0)


def same_part(a: Cuboid, b: Cuboid) -> bool:
    """False when the segmentation gave the two boxes different part ids."""
    ia, ib = a.extra.get("instance"), b.extra.get("instance")
    return ia is None or ib is None or ia == ib


# ------------------------------------------------------------------ objects and groups
#: :func:`same_column`: footprints within this fraction, tops within this fraction of
#: the taller box's height (and at least SAME_TOP_ABS metres).
SAME_FOOTPRINT_REL = 0.1
SAME_TOP_REL = 0.05
SAME_TOP_ABS = 0.02


def observed_footprint(c: Cuboid) -> np.ndarray:
    """Sorted horizontal extents of an upright box as the sensor saw it (its observed box
    when it has one: extensions and deepening guess at what was not seen)."""
    size = c.observed.size if c.observed is not None else c.size
    return np.sort(np.delete(np.asarray(size, float), up_axis(c)))


def same_column(me: Cuboid, other: Cuboid) -> bool:
    """Whether two upright parts are the same column seen differently: one footprint
    (within :data:`SAME_FOOTPRINT_REL`) and one top height (within :data:`SAME_TOP_REL`
    of the taller part's height).  A sofa's far arm, seen only over its top
    15 cm behind the cushions, is its near arm's twin that the sensor saw whole."""
    if any(abs(c.rotation[2, up_axis(c)]) < 0.99 for c in (me, other)):
        return False
    fa, fb = observed_footprint(me), observed_footprint(other)
    if not np.allclose(fa, fb, rtol=SAME_FOOTPRINT_REL):
        return False
    (_, top_a), (_, top_b) = extent_along(me, UP), extent_along(other, UP)
    tall = max(float(np.abs(c.rotation[2]) @ c.size) for c in (me, other))
    return abs(top_a - top_b) <= max(SAME_TOP_ABS, SAME_TOP_REL * tall)


def single_part(arr: Arrangement, c: Cuboid) -> bool:
    """Whether ``c`` is the only part of its object (or has no object)."""
    return c.object is None or not any(o.object == c.object and o.id != c.id
                                       for o in arr.cuboids)


def object_depth(arr: Arrangement, c: Cuboid, axis: int) -> float:
    """How far the other parts of ``c``'s object span along ``c``'s ``axis`` together
    (inf when it has none): how deep the object shows itself to be there."""
    if c.object is None:
        return float("inf")
    u = c.rotation[:, axis]
    proj = [o.corners() @ u for o in arr.cuboids if o.object == c.object and o.id != c.id]
    if not proj:
        return float("inf")
    proj = np.concatenate(proj)
    return float(proj.max() - proj.min())


def object_reach(arr: Arrangement, c: Cuboid, u: np.ndarray) -> float:
    """How far the other parts of ``c``'s object reach beyond ``c``'s centre along the
    unit vector ``u`` (inf when it has none)."""
    if c.object is None:
        return float("inf")
    proj = [o.corners() @ u for o in arr.cuboids if o.object == c.object and o.id != c.id]
    if not proj:
        return float("inf")
    return float(np.concatenate(proj).max() - c.center @ u)


def joined_reach(arr: Arrangement, c: Cuboid, u: np.ndarray, gap_max: float) -> float:
    """How far the other parts of ``c``'s object joined to it (within ``gap_max``) reach
    beyond ``c``'s centre along the unit vector ``u`` (-inf when none does), leaving out a
    part fixed to ``c``'s face towards ``u`` (beyond it, overlapping it across that face,
    as a monitor's neck behind its screen): it shows what is behind ``c``, not its depth."""
    back = extent_along(c, u)[1]
    across = [c.rotation[:, a] for a in range(3) if abs(float(c.rotation[:, a] @ u)) < 0.5]
    reach = -np.inf
    for o in arr.cuboids:
        if o.object != c.object or o.id == c.id or gap(c, o) > gap_max:
            continue
        along = o.corners() @ u
        if float(along.min()) >= back - gap_max and all(
                overlap_along(c, o, w) > gap_max for w in across):
            continue  # on c's face towards u
        reach = max(reach, float(along.max()))
    return reach - float(c.center @ u)


def same_object_groups(arr: Arrangement) -> dict[int, int]:
    """Box index -> a label shared by the parts of one object that touch, directly or
    through its other parts."""
    parent = list(range(len(arr.cuboids)))

    def find(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    idx = arr.index
    for a, b in find_contacts(arr).pairs:
        ia, ib = idx.get(a), idx.get(b)
        if (ia is not None and ib is not None and arr.cuboids[ia].object is not None
                and arr.cuboids[ia].object == arr.cuboids[ib].object):
            parent[find(ia)] = find(ib)
    return {k: find(k) for k in range(len(arr.cuboids)) if arr.cuboids[k].object is not None}


def fixed_components(members: list[str], contacts) -> dict[str, int]:
    """Id -> label of its rigid body: the ``members`` joined by ``fixed`` contacts."""
    parent = {m: m for m in members}

    def find(x: str) -> str:
        while parent[x] != x:
            x = parent[x]
        return x

    for c in contacts:
        if c.type == "fixed" and c.a in parent and c.b in parent:
            parent[find(c.a)] = find(c.b)
    roots = sorted({find(m) for m in members})
    return {m: roots.index(find(m)) for m in members}


def touching_group(arr: Arrangement, start: str, cs=None) -> set[str]:
    """Ids of the cuboids connected to ``start`` through touching cuboids (supports do
    not connect: what stands on the floor apart from each other is independent);
    ``cs``: the contacts of ``arr`` when known."""
    cs = find_contacts(arr) if cs is None else cs
    nbrs: dict[str, set[str]] = {}
    for a, b in cs.pairs:
        nbrs.setdefault(a, set()).add(b)
        nbrs.setdefault(b, set()).add(a)
    cuboid_ids = set(arr.ids)
    seen, todo = {start}, [start]
    while todo:
        for n in nbrs.get(todo.pop(), ()):
            if n in cuboid_ids and n not in seen:
                seen.add(n)
                todo.append(n)
    return seen


def near(arr: Arrangement, ids: set[int], pad: float = 0.01) -> list[int]:
    """Indices of the boxes whose world bounds come within ``pad`` of those of the boxes
    ``ids`` (themselves included), in order."""
    half = np.einsum("kij,kj->ki", np.abs(arr.rotations), arr.sizes / 2.0)
    lo, hi = arr.centers - half, arr.centers + half
    mask = np.zeros(len(arr.cuboids), bool)
    for k in sorted(ids):
        mask |= np.all((lo <= hi[k] + pad) & (hi >= lo[k] - pad), axis=1)
    return np.nonzero(mask)[0].tolist()


def floor_height(arr: Arrangement) -> float | None:
    """The height of a level ground plane of ``arr`` (None when it has none)."""
    return next((float(s.point[2]) for s in arr.supports
                 if s.id == "ground" and s.normal[2] > 0.99), None)


def resting_on(arr: Arrangement, c: Cuboid, gap: float) -> Cuboid | None:
    """The upright box whose top face ``c``'s bottom lies on: within ``gap`` of its
    height, ``c``'s footprint over it or within ``gap`` of its edge (the support's far
    end may be hidden); the highest such when several, None when none."""
    bottom = c.center[2] - 0.5 * float(np.abs(c.rotation[2]) @ c.size)
    best, best_top = None, -np.inf
    for s in arr.cuboids:
        if s.id == c.id or not is_upright(s):
            continue
        top = s.center[2] + 0.5 * float(np.abs(s.rotation[2]) @ s.size)
        if abs(bottom - top) > gap or top <= best_top:
            continue
        local = (c.center - s.center) @ s.rotation
        horizontal = np.abs(s.rotation[2]) < HORIZONTAL_COS
        reach = 0.5 * np.abs(s.rotation.T @ c.rotation) @ c.size + gap  # c's footprint
        if np.all(np.abs(local[horizontal]) <= s.size[horizontal] / 2 + reach[horizontal]):
            best, best_top = s, top
    return best


def resting_cut(a: Cuboid, b: Cuboid, slabs: float | None = None
                ) -> tuple[Cuboid, Cuboid] | None:
    """Clear the overlap of a box resting on a broader one at the face they share.

    When one upright box's bottom lies in the upper three quarters of a broader upright
    box at most half as tall again and its top above it (a book whose noisy bottom
    reaches into the thick-looking board under it; not two books side by side), the
    overlap is depth noise at the interface they rest on: the upper box's bottom rises
    (by at most half of its height; beyond that the lower box's top drops by half the
    overlap and the upper's bottom rises by the other half).

    With ``slabs``, the floor's height (initial boxes, whose overlaps are fitting noise),
    the lower box may also be a slab: a footprint :data:`SLAB_AREA_RATIO` times the
    upper's, at most half as tall as the upper box and as half its own narrower side,
    that the upper box's bottom reaches down to (at most half the slab's height below
    it, and not down to the floor: a sofa's back stands beside its seat).  Returns the
    two boxes ``(a, b)`` after the cut, or None when the pair is not of that kind or
    cannot be cleared that way.
    """
    ax_a, ax_b = vertical_axis(a), vertical_axis(b)
    if ax_a is None or ax_b is None:
        return None
    za, zb = z_range(a), z_range(b)
    if za[0] + za[1] < zb[0] + zb[1]:  # a is the lower one
        r = resting_cut(b, a, slabs)
        return None if r is None else (r[1], r[0])
    (lo_u, hi_u), (lo_l, hi_l) = za, zb
    area_u = float(np.prod(np.delete(a.size, ax_a)))
    area_l = float(np.prod(np.delete(b.size, ax_b)))
    h_u, h_l = hi_u - lo_u, hi_l - lo_l
    slab = slabs is not None and (
        area_l >= SLAB_AREA_RATIO * area_u and h_l <= 0.5 * h_u
        and h_l <= 0.5 * np.delete(b.size, ax_b).min() and lo_u > slabs + 0.5 * h_l
        and lo_l - 0.5 * h_l < lo_u < hi_l < hi_l + 0.25 * h_u < hi_u)
    if not (slab or (area_l >= area_u and h_l <= 1.5 * h_u
                     and lo_l + 0.25 * h_l < lo_u < hi_l < hi_u)):
        return None
    tol = float(pair_tolerance(a.size[None], b.size[None])[0])
    cut = hi_l - lo_u + 0.25 * tol
    if cut <= 0.5 * a.size[ax_a]:  # the upper box's bottom rises
        cut_u, cut_l = cut, 0.0
    elif 0.5 * cut <= 0.5 * min(a.size[ax_a], b.size[ax_b]):  # both give way
        cut_u = cut_l = 0.5 * cut
    else:
        return None
    sa, sb = a.size.copy(), b.size.copy()
    sa[ax_a] -= cut_u
    sb[ax_b] -= cut_l
    return (a.with_(center=a.center + [0.0, 0.0, cut_u / 2], size=sa),
            b if cut_l == 0.0 else b.with_(center=b.center - [0.0, 0.0, cut_l / 2], size=sb))


def in_shadow(points: np.ndarray, eye: np.ndarray, box: Cuboid) -> np.ndarray:
    """Per point of ``points``: whether the segment from ``eye`` to it passes through
    ``box`` (the box hides the point from a camera at ``eye``)."""
    half = box.size / 2
    p0 = (np.asarray(eye, float) - box.center) @ box.rotation  # in the box's frame
    d = (np.asarray(points, float) - box.center) @ box.rotation - p0
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (-half - p0) / d
        t2 = (half - p0) / d
    lo = np.where(np.abs(d) < 1e-12, np.where(np.abs(p0) <= half, -np.inf, np.inf),
                  np.minimum(t1, t2))
    hi = np.where(np.abs(d) < 1e-12, np.where(np.abs(p0) <= half, np.inf, -np.inf),
                  np.maximum(t1, t2))
    enter = np.maximum(lo.max(axis=1), 0.0)
    leave = np.minimum(hi.min(axis=1), 1.0)
    return enter < leave


def free_id(arr: Arrangement, name: str) -> str:
    """``name``, or ``name`` with the first numeric suffix no cuboid of ``arr`` has (the
    id of a box a prior adds)."""
    taken = {c.id for c in arr.cuboids}
    return next(n for n in (name, *(f"{name}{i}" for i in range(1, len(taken) + 2)))
                if n not in taken)


def replaced(arr: Arrangement, boxes) -> Arrangement:
    """``arr`` with the cuboids of ``boxes`` (by id) in place of its own."""
    new = {c.id: c for c in boxes}
    return arr.with_(cuboids=tuple(new.get(c.id, c) for c in arr.cuboids))


def pushed_to_extension(arr: Arrangement, initial: Arrangement, x) -> Arrangement:
    """``arr`` with face (axis, side) of cuboid ``x.box`` of ``initial`` moved out to
    where extension ``x`` puts it (unchanged when the face is there or beyond already)."""
    c0 = initial.cuboids[x.box]
    k = arr.index[c0.id]
    c = arr.cuboids[k]
    u = c.rotation[:, x.axis] * (1.0 if x.side else -1.0)
    target = c0.center @ u + c0.size[x.axis] / 2 + x.length
    now = c.center @ u + c.size[x.axis] / 2
    grow = target - now
    if grow <= 0:
        return arr
    size = c.size.copy()
    size[x.axis] += grow
    cubs = list(arr.cuboids)
    cubs[k] = c.with_(center=c.center + u * grow / 2, size=size)
    return arr.with_(cuboids=tuple(cubs))


def same_box(a: Cuboid | None, b: Cuboid) -> bool:
    """Whether ``a`` and ``b`` are the same box in every field."""
    return a is b or (a is not None and a.id == b.id and np.array_equal(a.center, b.center)
                      and np.array_equal(a.size, b.size)
                      and np.array_equal(a.rotation, b.rotation) and a.density == b.density
                      and a.object == b.object and a.observed is b.observed
                      and a.extra == b.extra)


def changed_boxes(new: Arrangement, old: Arrangement) -> tuple[Cuboid, ...]:
    """The cuboids of ``new`` that differ from those of ``old`` with their id, and those
    ``old`` lacks: what an edit built from ``old`` changed or added."""
    before = {c.id: c for c in old.cuboids}
    return tuple(c for c in new.cuboids if not same_box(before.get(c.id), c))
