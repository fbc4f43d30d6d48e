"""Image edits in the original view: move or remove an object of a stable arrangement.

Section 6 (iii) of the paper: the colour image of a single-view scan is edited with the
structure the method recovered (ground, walls, the stable cuboid arrangement).

1. **Plan** (:func:`plan_edit`).  An object moves with everything it *carries*: the
   objects resting on it (a contact whose normal, pointing from the lower object into
   the upper one, is within 45 degrees of up), transitively, and those ``fixed`` to it.
   An object merely *leaning* on it (a side contact) is not carried: it stays, and the
   stability check decides whether it still stands.  A ``fixed`` contact of a moved
   object with the ground (or a wall it slides along) stays fixed: whatever hidden cause
   the search glued it for travels with the object.  The move is a translation along the
   floor.  It is refused, with a one-line reason, when the moved group would enter
   another box or a wall beyond the contact tolerance, when nothing is under it at its
   new place, when a carried object also rests on something that stays, or when any
   body that stood before no longer stands (analytic statics,
   :func:`pipeline.stability.check_stability`).  A removed object takes what it carries
   with it, under the same checks.
2. **Background** (:func:`edit_image`).  The pixels whose back-projected depth point lies
   inside one of the moving or removed cuboids grown by ``margin``, plus the pixels of
   their silhouette without a depth reading, dilated by a few pixels, are deleted.  The
   hole is filled surface by surface: each hole pixel is assigned the surface its ray
   now meets in the remaining arrangement (the ground, a wall, another cuboid), and is
   filled by pull-push interpolation (Gortler et al. 1996) from the known pixels that
   see the same surface; what is left (no surface behind, or no pixels of it) is filled
   by OpenCV's Telea inpainting (``fill="telea"`` or ``"ns"``, Navier-Stokes, use OpenCV
   alone for the whole hole).
3. **Foreground.**  The moved cuboids are ray cast from the original camera (numpy, with
   ``supersample``^2 rays per pixel for anti-aliased edges), depth-tested against the
   background's depth (measured where kept, the remaining arrangement's in the hole).
   A visible point takes the colour of the same point of the object in the original
   image when the camera saw it there (its old position projects onto a pixel whose
   depth agrees); otherwise the mean colour of that face, or of the object, shaded.
4. **Shadow.**  Light from above: parallel rays along ``light`` (default straight down,
   ``(0, 0, -1)``).  Every background point whose ray towards the light meets a moved
   cuboid is darkened by ``shadow_strength``, with an edge softened over
   ``shadow_soft`` metres.
5. **Composite**: background, shadow, then the foreground by its coverage.

Frames: the arrangement's world (z up) maps onto the input's camera frame by
``meta.camera_pose`` after the input's scale (``p_world = T @ (input_scale * p_input)``);
pixels are OpenCV's (:mod:`pipeline.camera`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pipeline.camera import Intrinsics, project
from pipeline.errors import InputError
from pipeline.model import Arrangement, Contact, Cuboid, is_support_id

#: Cosine of the largest angle from up of a contact normal that makes one object rest on
#: another (45 degrees): a box on a table top carries, a box against its side does not.
CARRY_MIN_NZ = float(np.cos(np.radians(45.0)))
#: Pixels cast per chunk in the ray caster (memory: chunk x boxes x 3 floats, several times).
RAY_CHUNK = 1 << 15
#: Known pixels of a surface needed before the hole is filled from them alone.
MIN_SURFACE_PIXELS = 20


@dataclass(frozen=True)
class EditParams:
    """How the image is edited (lengths in metres, angles as vectors).

    Attributes
    ----------
    margin : float
        Depth points within this distance of a moving or removed cuboid are deleted
        (the cuboids are estimates and the depth is noisy).
    dilate_px : int
        The deleted region is dilated by this many pixels (colour bleeds over edges).
    fill : {"surface", "telea", "ns"}
        ``surface``: per-surface pull-push, Telea for the rest; ``telea`` / ``ns``:
        OpenCV's inpainting (``cv2.INPAINT_TELEA`` / ``cv2.INPAINT_NS``) for the whole hole.
    inpaint_radius : float
        Pixels, OpenCV's inpainting neighbourhood.
    texture : bool
        With ``fill="surface"``: copy texture from a shifted part of the same surface
        (:func:`shift_fill`) over the smooth fill.
    shadow : bool
    light : (3,) float
        Direction the light travels (down), world frame.
    shadow_strength : float
        Share of the light a shadowed point loses, in [0, 1].
    shadow_soft : float
        Width of the shadow's soft edge, metres (Gaussian sigma at the shadow's depth).
    occlusion_tol : float
        The moved object is hidden where the background is nearer by more than this.
    seen_tol : float
        A pixel shows a cuboid's face when its depth is within this (plus 2 % of the
        depth) of the face.
    supersample : int
        Rays per pixel side for the foreground.
    """

    margin: float = 0.03
    dilate_px: int = 3
    fill: str = "surface"
    inpaint_radius: float = 5.0
    texture: bool = True
    shadow: bool = True
    light: tuple[float, float, float] = (0.0, 0.0, -1.0)
    shadow_strength: float = 0.45
    shadow_soft: float = 0.03
    occlusion_tol: float = 0.02
    seen_tol: float = 0.03
    supersample: int = 2

    def __post_init__(self) -> None:
        if self.fill not in FILLS:
            raise InputError(f"--fill: must be one of {', '.join(FILLS)}, got {self.fill!r}")
        if not (np.isfinite(self.margin) and 0 <= self.margin <= 1):
            raise InputError(f"--margin: must be in [0, 1] m, got {self.margin}")
        light = np.asarray(self.light, float)
        if light.shape != (3,) or not np.all(np.isfinite(light)) or light[2] >= -1e-3:
            raise InputError(f"light: must point down (negative z), got {self.light}")


FILLS = ("surface", "telea", "ns")


# ------------------------------------------------------------------------------ planning
@dataclass(frozen=True)
class Operation:
    """One edit: ``move`` an object by (dx, dy) metres along the floor, or ``remove`` it."""

    kind: str
    object: str
    dx: float = 0.0
    dy: float = 0.0

    def describe(self) -> str:
        if self.kind == "remove":
            return f"remove {self.object}"
        return f"move {self.object} by ({self.dx:+.3f}, {self.dy:+.3f}) m"


@dataclass(frozen=True)
class GroupEdit:
    """What one operation did: the object, what it carried, the cuboids and the offset."""

    operation: Operation
    objects: tuple[str, ...]  #: the object first, then what it carries
    cuboids: tuple[str, ...]
    offset: np.ndarray  #: (3,) metres (zero for a removal)


@dataclass(frozen=True)
class EditPlan:
    """The outcome of :func:`plan_edit`: the edited arrangement, or why it was refused.

    ``moved`` maps each moved cuboid id to its (3,) offset; ``removed`` lists removed ids.
    ``refusal`` is None when every operation is legal; ``checks`` lists what was checked.
    """

    before: Arrangement
    after: Arrangement
    groups: tuple[GroupEdit, ...]
    refusal: str | None = None
    checks: tuple[str, ...] = ()
    moved: dict = field(default_factory=dict)
    removed: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        return self.refusal is None

    @property
    def gone(self) -> tuple[str, ...]:
        """Cuboid ids whose old pixels are deleted (moved or removed)."""
        return tuple(self.moved) + tuple(self.removed)


def object_of(c: Cuboid) -> str:
    """The object a cuboid belongs to (its own id when it names none)."""
    return c.object if c.object else c.id


def object_names(arr: Arrangement) -> list[str]:
    """Object names in the order of their first cuboid."""
    return list(dict.fromkeys(object_of(c) for c in arr.cuboids))


def support_graph(arr: Arrangement, contacts=None, min_nz: float = CARRY_MIN_NZ
                  ) -> tuple[dict[str, set[str]], dict[str, set[str]]]:
    """Who rests on whom, and who is fixed to whom, between objects.

    Parameters
    ----------
    arr : Arrangement
    contacts : ContactSet, optional
        Its contacts (found from the geometry when omitted).
    min_nz : float
        An object rests on another when a contact normal from the other into it has
        ``n_z >= min_nz``.

    Returns
    -------
    under : {object: set of objects or support ids it rests on}
    fixed : {object: set of objects or support ids it is ``fixed`` to}
    """
    from pipeline.contacts import find_contacts

    cs = find_contacts(arr) if contacts is None else contacts
    K = len(arr.cuboids)
    obj = [object_of(c) for c in arr.cuboids]
    node = obj + list(cs.names[K:])
    under: dict[str, set[str]] = {o: set() for o in obj}
    fixed: dict[str, set[str]] = {o: set() for o in obj}
    nz = cs.normal[:, 2] if cs.count else np.zeros(0)
    for m, (a, b) in enumerate(zip(cs.a.tolist(), cs.b.tolist())):
        if node[a] == node[b]:
            continue
        if nz[m] >= min_nz:           # the normal points from b into a: a rests on b
            under[node[a]].add(node[b])
        elif nz[m] <= -min_nz and b < K:
            under[node[b]].add(node[a])
    idx = arr.index
    for c in arr.contacts:
        if c.type != "fixed":
            continue
        na = obj[idx[c.a]] if c.a in idx else c.a
        nb = obj[idx[c.b]] if c.b in idx else c.b
        if na != nb:
            for x, y in ((na, nb), (nb, na)):
                if x in fixed:
                    fixed[x].add(y)
    return under, fixed


def carried_set(arr: Arrangement, name: str, contacts=None) -> tuple[list[str], str | None]:
    """The object ``name`` and everything it carries, transitively.

    Carried: an object resting on a carried one (:func:`support_graph`), or ``fixed`` to
    one (a fused contact makes one rigid body).  Glue to the ground or a wall does not
    carry (it stays only while the object still touches that support).

    Returns
    -------
    objects : list of str
        ``name`` first, then the carried objects in order of discovery.
    conflict : str or None
        Why the group cannot move alone: a carried object that also rests on something
        that stays.
    """
    under, fixed = support_graph(arr, contacts)
    group, todo = [name], [name]
    while todo:
        cur = todo.pop(0)
        for o in under:
            if o in group:
                continue
            if cur in under[o] or cur in fixed[o]:
                group.append(o)
                todo.append(o)
    members = set(group)
    for o in group[1:]:
        others = sorted(x for x in under[o] if x not in members)
        if others:
            return group, (f"{o} rests on {', '.join(sorted(under[o] & members))} and on "
                           f"{', '.join(others)}: it cannot go with {name} alone")
    return group, None


def _kept_contacts(arr: Arrangement, ids: set[str], moved: set[str],
                   touching: set | None = None) -> tuple[Contact, ...]:
    """The listed ``fixed`` contacts that survive: both ends kept, and both moved or both
    staying; a moved cuboid's glue to the ground or a wall survives when the pair still
    touches after the move (``touching``: sorted id pairs that do).  Touch contacts are
    found again from the geometry."""
    out = []
    for c in arr.contacts:
        if c.type != "fixed":
            continue
        ends = [x for x in (c.a, c.b) if not is_support_id(x)]
        if any(x not in ids for x in ends):
            continue
        if (c.a in moved) == (c.b in moved) or (
                touching is not None and len(ends) == 1 and c.key in touching):
            out.append(c)
    return tuple(out)


def _with_touches(arr: Arrangement) -> Arrangement:
    """``arr`` with its listed contacts: the fixed ones kept, every touching pair as touch."""
    from pipeline.contacts import find_contacts

    cs = find_contacts(arr)
    fixed = {c.key for c in arr.contacts}
    touches = [Contact(a, b, "touch") for a, b in cs.pairs
               if ((a, b) if a <= b else (b, a)) not in fixed]
    return arr.with_(contacts=tuple(arr.contacts) + tuple(touches))


def _cm(x: float) -> str:
    return f"{100 * x:.1f} cm"


def plan_edit(arr: Arrangement, operations: list[Operation] | tuple[Operation, ...],
              mu: float | None = None, contacts=None, stability=None) -> EditPlan:
    """Apply ``operations`` in order to ``arr`` if each is legal (see the module docstring).

    Parameters
    ----------
    arr : Arrangement
        The scan's result (world frame z up, supports ``ground`` / ``wall:k``).
    operations : sequence of Operation
    mu : float, optional
        Friction for the stability check (default ``arr.meta["mu"]`` or 0.7).
    contacts, stability : optional
        ``find_contacts(arr)`` and ``check_stability(arr, mu)`` when the caller has them
        (many plans on one arrangement).

    Returns
    -------
    EditPlan
        ``refusal`` says, in one line, why the first illegal operation is refused.
    """
    from pipeline.contacts import find_contacts
    from pipeline.stability import check_stability

    mu = float(arr.meta.get("mu", 0.7)) if mu is None else float(mu)
    cur = arr
    groups: list[GroupEdit] = []
    checks: list[str] = []
    offsets: dict[str, np.ndarray] = {}
    removed: list[str] = []
    first = {c.id: c for c in arr.cuboids}
    cs = find_contacts(cur) if contacts is None else contacts
    stab = check_stability(cur, mu=mu, contacts=cs) if stability is None else stability

    def refuse(msg: str) -> EditPlan:
        return EditPlan(arr, cur, tuple(groups), msg, tuple(checks), offsets, tuple(removed))

    for op in operations:
        names = object_names(cur)
        if op.object not in names:
            gone = f" ({op.object} was removed or moved with another object)" \
                if op.object in object_names(arr) else ""
            return refuse(f"unknown object {op.object!r}{gone}; objects: {', '.join(names)}")
        group, conflict = carried_set(cur, op.object, cs)
        if conflict:
            return refuse(f"cannot {op.describe()}: {conflict}")
        members = set(group)
        ids = [c.id for c in cur.cuboids if object_of(c) in members]
        idset = set(ids)
        carried = f" with {', '.join(group[1:])}" if len(group) > 1 else ""
        if op.kind == "remove":
            offset = np.zeros(3)
            keep = [c for c in cur.cuboids if c.id not in idset]
            after = cur.with_(cuboids=tuple(keep),
                              contacts=_kept_contacts(cur, {c.id for c in keep}, set()))
        elif op.kind == "move":
            offset = np.array([op.dx, op.dy, 0.0], float)
            if not np.all(np.isfinite(offset)) or np.abs(offset).max() > 1e3:
                return refuse(f"cannot {op.describe()}: the offset must be finite metres")
            new = [c.with_(center=c.center + offset) if c.id in idset else c
                   for c in cur.cuboids]
            after = cur.with_(cuboids=tuple(new),
                              contacts=_kept_contacts(cur, set(cur.ids), idset))
        else:
            raise ValueError(f"operation kind must be 'move' or 'remove', got {op.kind!r}")
        cs_after = find_contacts(after)
        if op.kind == "move":  # glue to the floor (or a wall it slides along) goes with it
            after = after.with_(contacts=_kept_contacts(cur, set(cur.ids), idset,
                                                        set(cs_after.lookup())))
        obj_of = {c.id: object_of(c) for c in cur.cuboids}
        if op.kind == "move":
            before_pen = {(a, b) if a <= b else (b, a) for a, b, _ in cs.penetrations}
            new_pen = [(a, b, d) for a, b, d in cs_after.penetrations
                       if ((a in idset) != (b in idset))
                       and ((a, b) if a <= b else (b, a)) not in before_pen]
            if new_pen:
                a, b, d = max(new_pen, key=lambda p: p[2])
                mover, other = (a, b) if a in idset else (b, a)
                what = obj_of.get(other, other)
                return refuse(f"cannot {op.describe()}: {obj_of[mover]} would enter {what} "
                              f"by {_cm(d)}")
            checks.append(f"{op.describe()}: enters nothing")
            # something outside the group must hold it up at its new place
            under_after, _ = support_graph(after, cs_after)
            holders = set().union(*(under_after[o] for o in group)) - members
            if not holders:
                low = min(float(after.cuboid(i).corners()[:, 2].min()) for i in ids)
                floor = next((float(s.point[2]) for s in after.supports if s.id == "ground"),
                             None)
                hang = f" (its bottom would hang {_cm(low - floor)} above the floor)" \
                    if floor is not None else ""
                return refuse(f"cannot {op.describe()}: nothing under {op.object} at its new "
                              f"place{hang}")
            checks.append(f"{op.describe()}: rests on {', '.join(sorted(holders))}")
        stab_after = check_stability(after, mu=mu, contacts=cs_after)
        was = {b.id: b.stable for b in stab.bodies}
        falls = [b.id for b in stab_after.bodies if not b.stable and was.get(b.id, False)]
        if falls:
            fo = list(dict.fromkeys(obj_of.get(i, i) for i in falls))
            moving = [o for o in fo if o in members]
            if moving:
                return refuse(f"cannot {op.describe()}: {', '.join(moving)} would not stand "
                              "at its new place")
            return refuse(f"cannot {op.describe()}: {', '.join(fo)} would no longer stand "
                          f"once {op.object}{carried} {'is gone' if op.kind == 'remove' else 'moves'}")
        checks.append(f"{op.describe()}: every body that stood still stands")
        groups.append(GroupEdit(op, tuple(group), tuple(ids), offset))
        if op.kind == "remove":
            removed.extend(ids)  # deleted where they first were, moved before or not
            for i in ids:
                offsets.pop(i, None)
        else:
            for i in ids:
                offsets[i] = after.cuboid(i).center - first[i].center
        cur, cs, stab = after, cs_after, stab_after
    cur = _with_touches(cur)
    return EditPlan(arr, cur, tuple(groups), None, tuple(checks), offsets, tuple(removed))


# ------------------------------------------------------------------------------ the view
@dataclass(frozen=True)
class View:
    """The original camera view of a scan, metric, in the arrangement's world.

    Attributes
    ----------
    image : (H, W, 3) uint8 RGB
    depth : (H, W) float, metres along the optical axis, 0 = no reading
    intrinsics : Intrinsics
    T_world_cam : (4, 4) float, camera (metres) to the arrangement's world
    """

    image: np.ndarray
    depth: np.ndarray
    intrinsics: Intrinsics
    T_world_cam: np.ndarray


def view_of(scan, arr: Arrangement, where: str = "SCAN") -> View:
    """The :class:`View` of a loaded scan (:func:`pipeline.run.load`) and its result.

    Raises :class:`InputError` (one line) when the scan has no colour image, depth or
    intrinsics, the result has no ``meta.camera_pose``, or their sizes disagree.
    """
    if getattr(scan, "views", ()):
        raise InputError(f"{where}: a multi-view scan; edits are made in one RGB-D frame "
                         "(give one view's folder, e.g. scan/view0, and its own run)")
    if scan.image is None or scan.depth is None or scan.intrinsics is None:
        raise InputError(f"{where}: no colour image with depth and intrinsics; edits are "
                         "made in the original colour image of an RGB-D frame")
    pose = arr.meta.get("camera_pose")
    try:
        T = np.asarray(pose, float)
    except (TypeError, ValueError):
        T = np.zeros(0)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise InputError("RESULT: its arrangement has no meta.camera_pose (a 4x4 camera-to-"
                         "world matrix); use the arrangement.json that 'unseen run' wrote")
    if arr.meta.get("input_frame", "camera") != "camera":
        raise InputError("RESULT: it was made from a point cloud without a camera; edits need "
                         "the run of an RGB-D frame")
    intr = scan.intrinsics
    H, W = scan.depth.shape
    if scan.image.shape[:2] != (H, W) or (intr.width, intr.height) != (W, H):
        raise InputError(f"{where}: colour, depth and intrinsics disagree in size")
    mi = arr.meta.get("intrinsics")
    if isinstance(mi, dict) and (mi.get("width"), mi.get("height")) != (W, H):
        raise InputError(f"RESULT: it was made from a {mi.get('width')}x{mi.get('height')} "
                         f"frame but {where} is {W}x{H}; give the scan the result came from")
    s = float(arr.meta.get("input_scale", 1.0))
    depth = np.where(np.isfinite(scan.depth) & (scan.depth > 0), scan.depth * s, 0.0)
    return View(np.ascontiguousarray(scan.image[:, :, :3]).astype(np.uint8), depth, intr, T)


# --------------------------------------------------------------------------- ray casting
def pixel_rays(view: View, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World rays through pixel coordinates ``u, v (n,)``.

    Returns
    -------
    origin : (3,) float, the camera centre
    dirs : (n, 3) float, scaled so that the ray parameter is the camera-frame depth z
    """
    i = view.intrinsics
    d = np.stack([(np.asarray(u, float) - i.cx) / i.fx, (np.asarray(v, float) - i.cy) / i.fy,
                  np.ones(np.shape(u))], axis=-1)
    R = view.T_world_cam[:3, :3]
    return view.T_world_cam[:3, 3].copy(), d @ R.T


def cast_boxes(origin: np.ndarray, dirs: np.ndarray, centers: np.ndarray,
               rotations: np.ndarray, sizes: np.ndarray, grow: float = 0.0
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First hit of rays with oriented boxes (slab test, vectorised over rays and boxes).

    Parameters
    ----------
    origin : (3,) float, or (n, 3) one per ray
    dirs : (n, 3) float
    centers, rotations, sizes : (K, 3), (K, 3, 3), (K, 3) the boxes (full sizes)
    grow : float
        Added to every half size (metres).

    Returns
    -------
    t : (n,) float, ray parameter of the entry point (inf: no hit; rays starting inside a
        box do not hit it)
    box : (n,) int, the box hit (-1: none)
    face : (n,) int, ``2 * axis + (1 if the face is on the + side)``, -1 for none
    """
    dirs = np.asarray(dirs, float)
    n, K = len(dirs), len(centers)
    t_out = np.full(n, np.inf)
    box = np.full(n, -1, np.int64)
    face = np.full(n, -1, np.int64)
    if n == 0 or K == 0:
        return t_out, box, face
    half = np.asarray(sizes, float) / 2 + grow
    R = np.asarray(rotations, float)
    orig = np.asarray(origin, float)
    per_ray = orig.ndim == 2
    for s in range(0, n, RAY_CHUNK):
        d = np.einsum("kji,nj->nki", R, dirs[s:s + RAY_CHUNK])  # local directions (m, K, 3)
        if per_ray:
            o = np.einsum("kji,nkj->nki", R, orig[s:s + RAY_CHUNK, None, :] - centers[None])
        else:
            o = np.einsum("kji,kj->ki", R, orig[None] - centers)[None]  # (1, K, 3)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / d
            t1 = (-half[None] - o) * inv
            t2 = (half[None] - o) * inv
        t1 = np.where(np.isnan(t1), -np.inf, t1)
        t2 = np.where(np.isnan(t2), np.inf, t2)
        lo, hi = np.minimum(t1, t2), np.maximum(t1, t2)
        tn, tf = lo.max(axis=2), hi.min(axis=2)
        hit = (tn <= tf) & (tn > 0)
        tn = np.where(hit, tn, np.inf)
        k = np.argmin(tn, axis=1)
        rows = np.arange(len(k))
        tk = tn[rows, k]
        ok = np.isfinite(tk)
        axis = np.argmax(lo[rows, k], axis=1)
        plus = d[rows, k, axis] < 0  # entering through the + face when moving towards -
        sl = slice(s, s + len(k))
        t_out[sl] = tk
        box[sl] = np.where(ok, k, -1)
        face[sl] = np.where(ok, 2 * axis + plus, -1)
    return t_out, box, face


def cast_supports(origin: np.ndarray, dirs: np.ndarray, arr: Arrangement
                  ) -> tuple[np.ndarray, np.ndarray]:
    """First hit of rays with the support planes of ``arr`` (from their free side).

    Returns ``t (n,)`` (inf: none) and ``support (n,)`` (index into ``arr.supports``, -1).
    """
    n = len(dirs)
    t = np.full(n, np.inf)
    which = np.full(n, -1, np.int64)
    for s, sup in enumerate(arr.supports):
        dn = dirs @ sup.normal
        with np.errstate(divide="ignore", invalid="ignore"):
            ts = ((sup.point - origin) @ sup.normal) / dn
        ok = (dn < 0) & (ts > 0) & (ts < t)
        t = np.where(ok, ts, t)
        which = np.where(ok, s, which)
    return t, which


def _boxes(cubs: list[Cuboid]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if not cubs:
        return np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros((0, 3))
    return (np.stack([c.center for c in cubs]), np.stack([c.rotation for c in cubs]),
            np.stack([c.size for c in cubs]))


def inside_boxes(points: np.ndarray, cubs: list[Cuboid], grow: float = 0.0) -> np.ndarray:
    """(n,) bool: whether each point lies in one of ``cubs`` grown by ``grow`` metres."""
    C, R, S = _boxes(cubs)
    out = np.zeros(len(points), bool)
    for k in range(len(cubs)):  # a handful of boxes; vectorised over points
        local = (points - C[k]) @ R[k]
        out |= np.all(np.abs(local) <= S[k] / 2 + grow, axis=1)
    return out


def silhouette(view: View, cubs: list[Cuboid]) -> np.ndarray:
    """(H, W) bool: the pixels whose centre ray meets one of ``cubs`` (occlusion ignored)."""
    H, W = view.depth.shape
    out = np.zeros((H, W), bool)
    if not cubs:
        return out
    v, u = np.mgrid[0:H, 0:W]
    o, d = pixel_rays(view, u.ravel(), v.ravel())
    t, _, _ = cast_boxes(o, d, *_boxes(cubs))
    return np.isfinite(t).reshape(H, W)


# ----------------------------------------------------------------------------- filling
def pull_push(image: np.ndarray, known: np.ndarray) -> np.ndarray:
    """Fill every pixel from the ``known`` ones by pull-push (Gortler et al. 1996).

    Pull: average colour and coverage down an image pyramid; push: at each finer level a
    pixel keeps its own average where its coverage is full and blends in the coarser
    estimate where it is not.  Smooth, and exact on the known pixels.

    Parameters
    ----------
    image : (H, W, 3) float
    known : (H, W) bool

    Returns
    -------
    (H, W, 3) float
    """
    import cv2

    w = known.astype(np.float32)
    num = image.astype(np.float32) * w[..., None]
    levels = [(num, w)]
    while min(levels[-1][1].shape) > 2:
        n, ww = levels[-1]
        levels.append((cv2.pyrDown(n), cv2.pyrDown(ww)))
    n, ww = levels[-1]
    est = np.where(ww[..., None] > 1e-6, n / np.maximum(ww, 1e-6)[..., None],
                   n.reshape(-1, 3).sum(0) / max(float(ww.sum()), 1e-6))
    for n, ww in reversed(levels[:-1]):
        up = cv2.pyrUp(est.astype(np.float32), dstsize=(ww.shape[1], ww.shape[0]))
        a = np.clip(ww, 0.0, 1.0)[..., None]
        est = np.where(a > 1e-6, n / np.maximum(ww, 1e-6)[..., None], 0.0) * a + up * (1 - a)
    return np.where(known[..., None], image, est)


def shift_fill(out: np.ndarray, image: np.ndarray, src: np.ndarray, tgt: np.ndarray,
               min_cover: float = 0.97, min_pixels: int = 30) -> None:
    """Give each connected part of ``tgt`` the texture of a copy of itself shifted onto
    ``src`` pixels, blended at its border (in place on ``out``).

    Per part the shift is the one with least ``|dx| + 2 |dy|`` (rows change scale under
    perspective, columns less) whose shifted part lands on ``src`` for at least
    ``min_cover`` of its pixels; the coverage of every shift comes from one FFT
    correlation.  The copy is corrected by the membrane (pull-push) interpolation of
    the colour differences along the part's border, so it meets its surroundings
    without a seam (a Poisson-like blend).  Parts with no such shift, or smaller than
    ``min_pixels``, keep what ``out`` holds (the smooth fill).

    Parameters
    ----------
    out : (H, W, 3) float, modified in place
    image : (H, W, 3) float, the colours to copy (valid on ``src``)
    src, tgt : (H, W) bool
    """
    import cv2
    from scipy.signal import fftconvolve

    H, W = src.shape
    n, comp = cv2.connectedComponents(tgt.astype(np.uint8), connectivity=8)
    srcf = src.astype(np.float64)
    for c in range(1, n):
        part = comp == c
        ys, xs = np.nonzero(part)
        if len(ys) < min_pixels:
            continue
        y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
        if y1 - y0 >= H or x1 - x0 >= W:
            continue
        t = part[y0:y1, x0:x1].astype(np.float64)
        cover = fftconvolve(srcf, t[::-1, ::-1], mode="valid") / len(ys)  # (H-h+1, W-w+1)
        p, q = np.nonzero(cover >= min_cover)
        if len(p) == 0:
            continue
        dy, dx = p - y0, q - x0
        best = np.argmin(np.abs(dx) + 2 * np.abs(dy))
        dy, dx = int(dy[best]), int(dx[best])
        ok = src[ys + dy, xs + dx]
        copy = image[ys + dy, xs + dx]
        # border: the known pixels around the part, and what the copy would put there
        ring = cv2.dilate(part.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool) \
            & ~tgt & src
        ry, rx = np.nonzero(ring)
        inside = (ry + dy >= 0) & (ry + dy < H) & (rx + dx >= 0) & (rx + dx < W)
        ry, rx = ry[inside], rx[inside]
        pad = 4
        by0, by1 = max(y0 - pad, 0), min(y1 + pad, H)
        bx0, bx1 = max(x0 - pad, 0), min(x1 + pad, W)
        resid = np.zeros((by1 - by0, bx1 - bx0, 3), np.float32)
        known = np.zeros(resid.shape[:2], bool)
        resid[ry - by0, rx - bx0] = image[ry, rx] - image[ry + dy, rx + dx]
        known[ry - by0, rx - bx0] = True
        if known.any():
            corr = pull_push(resid, known)[ys - by0, xs - bx0]
        else:
            corr = 0.0
        out[ys[ok], xs[ok]] = (copy + corr)[ok]


def fill_hole(view: View, hole: np.ndarray, remaining: Arrangement, params: EditParams,
              cast: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """The colour image with ``hole`` filled (see the module docstring, step 2).

    ``cast``: the remaining arrangement's (depth, surface label) per pixel when known
    (:func:`_cast_scene`); labels are 1 + cuboid index, -(1 + support index), 0 none.
    """
    import cv2

    img = view.image
    if not hole.any():
        return img.copy()
    flag = cv2.INPAINT_NS if params.fill == "ns" else cv2.INPAINT_TELEA
    todo = hole.copy()
    out = img.astype(np.float32)
    if params.fill == "surface":
        t_rem, lab = cast if cast is not None else _cast_scene(view, remaining)
        d = view.depth
        agree = (d > 0) & (np.abs(d - t_rem) <= params.seen_tol + 0.02 * d)
        known_lab = np.where(~hole & agree, lab, 0)
        for L in np.unique(lab[hole]):
            if L == 0:
                continue
            src = known_lab == L
            if src.sum() < MIN_SURFACE_PIXELS:
                continue
            tgt = hole & (lab == L)
            ys, xs = np.nonzero(src | tgt)
            pad = 8
            y0, y1 = max(ys.min() - pad, 0), min(ys.max() + pad + 1, img.shape[0])
            x0, x1 = max(xs.min() - pad, 0), min(xs.max() + pad + 1, img.shape[1])
            crop = pull_push(out[y0:y1, x0:x1], src[y0:y1, x0:x1])
            sub = tgt[y0:y1, x0:x1]
            out[y0:y1, x0:x1][sub] = crop[sub]
            if params.texture:
                shift_fill(out, img.astype(np.float32), src, tgt)
            todo &= ~tgt
    if todo.any():
        u8 = np.clip(np.rint(out), 0, 255).astype(np.uint8)
        out = cv2.inpaint(u8, todo.astype(np.uint8) * 255, params.inpaint_radius, flag
                          ).astype(np.float32)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def _cast_scene(view: View, arr: Arrangement) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel: depth of the first surface of ``arr`` (cuboids and supports; inf: none)
    and its label (1 + cuboid index, -(1 + support index), 0 none)."""
    H, W = view.depth.shape
    v, u = np.mgrid[0:H, 0:W]
    o, d = pixel_rays(view, u.ravel(), v.ravel())
    tb, kb, _ = cast_boxes(o, d, *_boxes(list(arr.cuboids)))
    ts, ks = cast_supports(o, d, arr)
    lab = np.where(tb <= ts, kb + 1, np.where(ks >= 0, -(ks + 1), 0))
    lab = np.where(np.isfinite(np.minimum(tb, ts)), lab, 0)
    return np.minimum(tb, ts).reshape(H, W), lab.reshape(H, W)


# ----------------------------------------------------------------------------- the edit
@dataclass(frozen=True)
class EditImages:
    """What :func:`edit_image` made.

    Attributes
    ----------
    before, after : (H, W, 3) uint8
    hole : (H, W) bool, the deleted pixels
    background : (H, W, 3) uint8, the filled background before shadow and foreground
    shadow : (H, W) float in [0, 1], the darkening applied
    alpha : (H, W) float in [0, 1], the foreground's coverage
    old_region, new_region : (H, W) bool, silhouettes of the moving or removed cuboids
        at their old places, and of the moved ones at their new places
    """

    before: np.ndarray
    after: np.ndarray
    hole: np.ndarray
    background: np.ndarray
    shadow: np.ndarray
    alpha: np.ndarray
    old_region: np.ndarray
    new_region: np.ndarray


def hole_mask(view: View, cubs: list[Cuboid], params: EditParams,
              behind: np.ndarray | None = None) -> np.ndarray:
    """(H, W) bool: the pixels to delete for ``cubs`` (step 2 of the module docstring).

    ``behind``: per pixel, the depth of what stays behind the cuboids (the remaining
    arrangement, inf where nothing); then also deleted, near the cuboids' silhouette
    (within ``dilate_px + 2`` pixels), the readings between the cuboids' front and what
    stays behind them: mixed pixels at the object's edges (a depth sensor averages the
    object and the background there), which are neither."""
    import cv2

    H, W = view.depth.shape
    if not cubs:
        return np.zeros((H, W), bool)
    d = view.depth
    v, u = np.nonzero(d > 0)
    o, dirs = pixel_rays(view, u, v)
    pts = o + dirs * d[v, u][:, None]
    mask = np.zeros((H, W), bool)
    mask[v, u] = inside_boxes(pts, cubs, params.margin)
    H_, W_ = np.mgrid[0:H, 0:W]
    o, dirs = pixel_rays(view, W_.ravel(), H_.ravel())
    front, _, _ = cast_boxes(o, dirs, *_boxes(cubs))
    front = front.reshape(H, W)
    mask |= np.isfinite(front) & ~(d > 0)
    if behind is not None:
        k = 2 * (params.dilate_px + 2) + 1
        near_front = cv2.erode(np.where(np.isfinite(front), front, 1e9).astype(np.float32),
                               np.ones((k, k), np.uint8)).astype(float)
        tol = params.seen_tol + 0.02 * d
        mask |= (d > 0) & (near_front < 1e8) & (d >= near_front - params.margin) \
            & (d < behind - tol)
    if params.dilate_px > 0:
        k = 2 * params.dilate_px + 1
        mask = cv2.dilate(mask.astype(np.uint8), np.ones((k, k), np.uint8)).astype(bool)
    return mask


def _face_colours(view: View, cubs: list[Cuboid], params: EditParams
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Mean colour of each face of ``cubs`` where the image shows it: ``(K, 6, 3)`` float
    (NaN where unseen) and the mean colour of each cuboid's object ``(K, 3)`` (NaN)."""
    H, W = view.depth.shape
    K = len(cubs)
    v, u = np.mgrid[0:H, 0:W]
    o, d = pixel_rays(view, u.ravel(), v.ravel())
    t, k, f = cast_boxes(o, d, *_boxes(cubs))
    z = view.depth.ravel()
    seen = (k >= 0) & (z > 0) & (np.abs(z - t) <= params.seen_tol + 0.02 * z)
    col = view.image.reshape(-1, 3).astype(float)
    ids = (k * 6 + f)[seen]
    cnt = np.bincount(ids, minlength=6 * K).astype(float)
    sums = np.stack([np.bincount(ids, col[seen, c], minlength=6 * K) for c in range(3)], 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        face = (sums / cnt[:, None]).reshape(K, 6, 3)
    objs = [object_of(c) for c in cubs]
    obj_mean = np.full((K, 3), np.nan)
    cnt_k, sums_k = cnt.reshape(K, 6).sum(1), sums.reshape(K, 6, 3).sum(1)
    for name in set(objs):
        rows = [i for i, o_ in enumerate(objs) if o_ == name]
        n = cnt_k[rows].sum()
        if n > 0:
            obj_mean[rows] = sums_k[rows].sum(0) / n
    return face, obj_mean


def bilinear(image: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Colours of ``image (H, W, 3)`` at sub-pixel ``u, v (n,)`` (clamped at the border),
    bilinear: ``(n, 3)`` float."""
    H, W = image.shape[:2]
    u = np.clip(u, 0, W - 1)
    v = np.clip(v, 0, H - 1)
    x0 = np.minimum(np.floor(u).astype(int), W - 2) if W > 1 else np.zeros(len(u), int)
    y0 = np.minimum(np.floor(v).astype(int), H - 2) if H > 1 else np.zeros(len(v), int)
    x1, y1 = np.minimum(x0 + 1, W - 1), np.minimum(y0 + 1, H - 1)
    a, b = (u - x0)[:, None], (v - y0)[:, None]
    im = image.astype(float)
    return ((im[y0, x0] * (1 - a) + im[y0, x1] * a) * (1 - b)
            + (im[y1, x0] * (1 - a) + im[y1, x1] * a) * b)


@dataclass(frozen=True)
class PlacedModel:
    """A retrieved model on an object (``unseen retrieve``): world vertices at the
    object's place in the scan, faces, and an RGB colour (None: the object's mean colour
    in the image)."""

    vertices: np.ndarray  #: (n, 3) float, world
    faces: np.ndarray  #: (m, 3) int
    rgb: tuple | None = None


def read_retrieved(folder, arr: Arrangement) -> dict:
    """Object name -> :class:`PlacedModel` from an ``unseen retrieve`` output folder
    (``retrieval.json``: per object its ``model`` file, under the ``models`` folder it
    names, and the 4x4 ``transform`` from the file's coordinates to world).  Objects the
    arrangement does not have are skipped; a missing file is an :class:`InputError`."""
    from pathlib import Path

    import trimesh

    from pipeline.safe_read import load_json

    folder = Path(folder)
    path = folder / "retrieval.json" if folder.is_dir() else folder
    if not path.is_file():
        raise InputError(f"--retrieved {folder}: no retrieval.json (give the output folder "
                         "of 'unseen retrieve')")
    data = load_json(path, "retrieval file", limit=64 * 2**20)
    if not isinstance(data, dict) or not isinstance(data.get("objects"), list):
        raise InputError(f"{path}: not a retrieval.json (no 'objects' list)")
    names = set(object_names(arr))
    root = Path(str(data.get("models", "")))
    out = {}
    for k, o in enumerate(data["objects"]):
        if not isinstance(o, dict) or o.get("object") not in names:
            continue
        where = f"{path}: objects[{k}]"
        try:
            T = np.asarray(o["transform"], float)
            rel = Path(str(o["model"]))
        except (KeyError, TypeError, ValueError):
            raise InputError(f"{where}: needs 'model' and a 4x4 'transform'") from None
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise InputError(f"{where}.transform: must be a 4x4 matrix of numbers")
        cands = [rel] if rel.is_absolute() else [root / rel, folder / root / rel, folder / rel]
        file = next((c for c in cands if c.is_file()), None)
        if file is None:
            raise InputError(f"{where}.model: {rel} not found (looked in {root} and {folder})")
        try:
            mesh = trimesh.load(file, force="mesh", process=False)
        except Exception as exc:  # noqa: BLE001 - any reader failure is bad input
            raise InputError(f"{file}: cannot read the model ({exc.__class__.__name__})") from None
        V = np.asarray(mesh.vertices, float) @ T[:3, :3].T + T[:3, 3]
        out[o["object"]] = PlacedModel(V, np.asarray(mesh.faces, np.int64))
    return out


def _object_rgb(view: View, cubs: list[Cuboid], params: EditParams) -> tuple:
    """The mean colour (uint8 RGB) of the pixels showing ``cubs`` (grey when none)."""
    _, obj = _face_colours(view, cubs, params)
    m = obj[np.isfinite(obj[:, 0])]
    return tuple(int(x) for x in np.clip(np.rint(m[0]), 0, 255)) if len(m) else (128, 128, 128)


def _shade(normals: np.ndarray, light: np.ndarray) -> np.ndarray:
    """Lambert shading with ambient, for faces no pixel showed: (n,) in [0.55, 1]."""
    return 0.55 + 0.45 * np.clip(normals @ (-light), 0.0, 1.0)


def edit_image(view: View, plan: EditPlan, params: EditParams | None = None,
               progress=None, meshes: dict | None = None) -> EditImages:
    """Edit the view's colour image as ``plan`` says (module docstring, steps 2-5).

    ``meshes``: object name -> :class:`PlacedModel` (its retrieved model at its old
    place); a moved object that has one is drawn as that model (the cuboids still delete
    its pixels and cast its shadow).  ``progress(step)`` hears the name of each step.
    """
    import cv2

    params = params or EditParams()
    step = progress or (lambda name: None)
    H, W = view.depth.shape
    before = plan.before
    gone = [before.cuboid(i) for i in plan.gone]
    placed = [plan.after.cuboid(i) for i in plan.moved]
    offsets = np.array([plan.moved[i] for i in plan.moved]).reshape(-1, 3)
    remaining = plan.after.with_(cuboids=tuple(c for c in plan.after.cuboids
                                               if c.id not in plan.moved))
    light = np.asarray(params.light, float)
    light = light / np.linalg.norm(light)

    step("mask")
    t_rem, lab = _cast_scene(view, remaining)
    hole = hole_mask(view, gone, params, behind=t_rem)
    old_region = silhouette(view, gone)
    new_region = silhouette(view, placed)

    step("fill")
    background = fill_hole(view, hole, remaining, params, cast=(t_rem, lab))
    d = view.depth
    bg_depth = np.where(~hole & (d > 0), d, t_rem)  # what the background's pixels see

    # world point of every background pixel
    v, u = np.mgrid[0:H, 0:W]
    o, dirs = pixel_rays(view, u.ravel(), v.ravel())
    with np.errstate(invalid="ignore"):
        pts = o + dirs * bg_depth.reshape(-1, 1)

    shadow = np.zeros((H, W))
    if params.shadow and placed:
        step("shadow")
        C, R, S = _boxes(placed)
        corners = np.concatenate([c.corners() for c in placed])
        top = corners[:, 2].max()
        lo, hi = corners[:, :2].min(0), corners[:, :2].max(0)
        fin = np.all(np.isfinite(pts), axis=1)
        with np.errstate(invalid="ignore"):
            reach = np.where(fin, np.maximum(top - pts[:, 2], 0.0), 0.0) \
                * np.linalg.norm(light[:2]) / max(-light[2], 1e-6)
            near = fin & (pts[:, 2] < top) & np.all(
                (pts[:, :2] >= lo - reach[:, None] - params.shadow_soft * 3)
                & (pts[:, :2] <= hi + reach[:, None] + params.shadow_soft * 3), axis=1)
        idx = np.nonzero(near)[0]
        if len(idx):
            start = pts[idx] + 1e-3 * np.array([0.0, 0.0, 1.0])
            t, _, _ = cast_boxes(start, np.broadcast_to(-light, (len(idx), 3)), C, R, S)
            hard = np.zeros(H * W)
            hard[idx[np.isfinite(t)]] = 1.0
            hard = hard.reshape(H, W)
            if hard.any():
                zs = bg_depth.ravel()[idx[np.isfinite(t)]]
                z = float(np.median(zs[np.isfinite(zs)])) if np.isfinite(zs).any() else 2.0
                sigma = max(0.5, view.intrinsics.fx * params.shadow_soft / max(z, 0.1))
                shadow = cv2.GaussianBlur(hard.astype(np.float32), (0, 0), sigma).astype(float)
                shadow = np.clip(shadow, 0.0, 1.0) * params.shadow_strength
    shaded = background.astype(float) * (1.0 - shadow[..., None])

    alpha = np.zeros((H, W))
    fg = np.zeros((H, W, 3))
    if placed:
        step("render")
        meshes = meshes or {}
        drawn = [object_of(c) in meshes for c in placed]
        items = []
        for name in dict.fromkeys(object_of(c) for c in placed if object_of(c) in meshes):
            j = next(k for k, c in enumerate(placed) if object_of(c) == name)
            pm = meshes[name]
            rgb = pm.rgb if pm.rgb is not None else _object_rgb(
                view, [before.cuboid(c.id) for c in placed if object_of(c) == name], params)
            items.append((pm.vertices + offsets[j], pm.faces, offsets[j], rgb))
        boxes = [c for c, m in zip(placed, drawn) if not m]
        offs = offsets[[not m for m in drawn]].reshape(-1, 3)
        alpha, fg = _render_moved(view, boxes, offs, bg_depth, params, light, items)
    after = shaded * (1 - alpha[..., None]) + fg * alpha[..., None]
    after = np.clip(np.rint(after), 0, 255).astype(np.uint8)
    return EditImages(view.image.copy(), after, hole, background, shadow, alpha,
                      old_region, new_region)


def _texture(view: View, X: np.ndarray, offsets: np.ndarray, params: EditParams
             ) -> tuple[np.ndarray, np.ndarray]:
    """Colour of world points ``X (n, 3)`` of moved objects taken where the camera saw the
    same points before the move (``X - offsets``): ``(n, 3)`` float and ``(n,)`` bool, True
    where the old point projects into the image onto a pixel whose depth agrees with it."""
    H, W = view.depth.shape
    p0 = (X - offsets - view.T_world_cam[:3, 3]) @ view.T_world_cam[:3, :3]
    uv0, z0 = project(p0, view.intrinsics)
    uv0 = np.nan_to_num(uv0, nan=-1.0, posinf=-1.0, neginf=-1.0)
    inside = (z0 > 0) & (uv0[:, 0] >= 0) & (uv0[:, 0] <= W - 1) & (uv0[:, 1] >= 0) \
        & (uv0[:, 1] <= H - 1)
    iu = np.clip(np.rint(uv0[:, 0]).astype(int), 0, W - 1)
    iv = np.clip(np.rint(uv0[:, 1]).astype(int), 0, H - 1)
    dz = view.depth[iv, iu]
    seen = inside & (dz > 0) & (np.abs(dz - z0) <= params.seen_tol + 0.02 * np.abs(z0))
    return bilinear(view.image, uv0[:, 0], uv0[:, 1]), seen


def _render_moved(view: View, placed: list[Cuboid], offsets: np.ndarray,
                  bg_depth: np.ndarray, params: EditParams, light: np.ndarray,
                  meshes: list | tuple = ()) -> tuple[np.ndarray, np.ndarray]:
    """Coverage (H, W) and colour (H, W, 3) of the moved objects at their new places.

    ``placed``: the moved cuboids drawn as boxes, ``offsets (K, 3)`` theirs; ``meshes``:
    ``(vertices (n, 3) at the new place, faces (m, 3), offset (3,), rgb (3,))`` per object
    drawn as its retrieved model (:func:`pipeline.raster.rasterize`, at the same
    supersampling)."""
    H, W = bg_depth.shape
    alpha = np.zeros((H, W))
    colour = np.zeros((H, W, 3))
    pts = [c.corners() for c in placed] + [np.asarray(m[0], float) for m in meshes]
    if not pts:
        return alpha, colour
    pts = np.concatenate(pts)
    pc = (pts - view.T_world_cam[:3, 3]) @ view.T_world_cam[:3, :3]
    if np.all(pc[:, 2] > 1e-3):
        uv, _ = project(pc, view.intrinsics)
        x0, y0 = np.floor(uv.min(0)).astype(int) - 1
        x1, y1 = np.ceil(uv.max(0)).astype(int) + 2
        x0, x1, y0, y1 = max(x0, 0), min(x1, W), max(y0, 0), min(y1, H)
    else:
        x0, x1, y0, y1 = 0, W, 0, H
    if x1 <= x0 or y1 <= y0:
        return alpha, colour
    s = max(int(params.supersample), 1)
    h, w = (y1 - y0) * s, (x1 - x0) * s
    vv, uu = np.mgrid[0:h, 0:w]
    u = x0 + (uu.ravel() + 0.5) / s - 0.5
    v = y0 + (vv.ravel() + 0.5) / s - 0.5
    o, d = pixel_rays(view, u, v)
    C, R, S = _boxes(placed)
    t_box, k, f = cast_boxes(o, d, C, R, S)
    # retrieved models: rasterised into the same sub-pixel grid
    n = len(u)
    t_mesh, mesh_id, mesh_col = np.full(n, np.inf), np.full(n, -1), np.zeros((n, 3))
    i = view.intrinsics
    sub = Intrinsics(w, h, i.fx * s, i.fy * s, s * (i.cx - x0 + 0.5) - 0.5,
                     s * (i.cy - y0 + 0.5) - 0.5)
    for m, (V, F, _, rgb) in enumerate(meshes):
        from pipeline.raster import rasterize  # only with retrieved models

        img, dep = rasterize(V, F, np.tile(np.asarray(rgb, np.uint8), (len(F), 1)), sub,
                             view.T_world_cam, light=-light)
        dep = dep.ravel()
        closer = dep < t_mesh
        t_mesh[closer], mesh_id[closer] = dep[closer], m
        mesh_col[closer] = img.reshape(-1, 3)[closer]
    use_mesh = t_mesh < t_box
    t = np.minimum(t_box, t_mesh)
    pu = np.clip(np.rint(u).astype(int), 0, W - 1)
    pv = np.clip(np.rint(v).astype(int), 0, H - 1)
    behind = bg_depth[pv, pu]
    vis = np.isfinite(t) & ~(behind < t - params.occlusion_tol)
    idx = np.nonzero(vis)[0]
    col = np.zeros((n, 3))
    if len(idx):
        mesh_off = np.array([m[2] for m in meshes], float).reshape(-1, 3)
        off = np.zeros((len(idx), 3))
        on_mesh = use_mesh[idx]
        off[on_mesh] = mesh_off[mesh_id[idx][on_mesh]]
        off[~on_mesh] = offsets[k[idx][~on_mesh]]
        X = o + d[idx] * t[idx, None]
        tex, seen = _texture(view, X, off, params)
        fallback = mesh_col[idx].astype(float)
        bi = np.nonzero(~on_mesh)[0]
        if len(bi):  # a box: the face's mean colour where seen, else the object's, shaded
            kk, ff = k[idx][bi], f[idx][bi]
            old = [c.with_(center=c.center - of) for c, of in zip(placed, offsets)]
            face_col, obj_col = _face_colours(view, old, params)
            fc = face_col[kk, ff]
            axis, plus = ff // 2, ff % 2
            normals = R[kk, :, axis] * np.where(plus, 1.0, -1.0)[:, None]
            seen_faces = np.isfinite(face_col[..., 0])
            base = np.where(np.isfinite(obj_col[kk]), obj_col[kk], 128.0)
            mean_shade = np.array([
                _shade(np.array([R[j][:, a] * (1.0 if p else -1.0)
                                 for a in range(3) for p in (0, 1)])[seen_faces[j]],
                       light).mean()
                if seen_faces[j].any() else 1.0 for j in range(len(placed))])
            shaded = base * (_shade(normals, light) / mean_shade[kk])[:, None]
            fallback[bi] = np.where(np.isfinite(fc), fc, shaded)
        col[idx] = np.where(seen[:, None], tex, fallback)
    cov = vis.reshape(h, w).astype(float)
    acc = (col * vis[:, None]).reshape(h, w, 3)
    cov = cov.reshape(y1 - y0, s, x1 - x0, s).mean(axis=(1, 3))
    acc = acc.reshape(y1 - y0, s, x1 - x0, s, 3).mean(axis=(1, 3))
    alpha[y0:y1, x0:x1] = cov
    with np.errstate(invalid="ignore", divide="ignore"):
        colour[y0:y1, x0:x1] = np.where(cov[..., None] > 0, acc / cov[..., None], 0.0)
    return alpha, colour


# ------------------------------------------------------------------------------ metrics
def psnr(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Peak signal-to-noise ratio (dB, peak 255) of two uint8 images over ``mask`` pixels
    (all when None); inf when they are equal there, NaN when the mask is empty."""
    diff = a.astype(float) - b.astype(float)
    if mask is not None:
        diff = diff[mask]
    if diff.size == 0:
        return float("nan")
    mse = float(np.mean(diff ** 2))
    return float("inf") if mse == 0 else float(10 * np.log10(255.0 ** 2 / mse))


def ssim_map(a: np.ndarray, b: np.ndarray, sigma: float = 1.5) -> np.ndarray:
    """Per-pixel SSIM (Wang et al. 2004) of two uint8 images, Gaussian window of
    ``sigma`` pixels (``cv2.GaussianBlur``), K1 = 0.01, K2 = 0.03, L = 255, averaged over
    the colour channels.  Returns (H, W) float."""
    import cv2

    c1, c2 = (0.01 * 255) ** 2, (0.03 * 255) ** 2
    x, y = a.astype(np.float64), b.astype(np.float64)

    def blur(z):
        return cv2.GaussianBlur(z, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)

    mx, my = blur(x), blur(y)
    sxx, syy, sxy = blur(x * x) - mx * mx, blur(y * y) - my * my, blur(x * y) - mx * my
    s = ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx * mx + my * my + c1) * (sxx + syy + c2))
    return s.mean(axis=2) if s.ndim == 3 else s


def ssim(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Mean :func:`ssim_map` over ``mask`` (all pixels when None; NaN when empty)."""
    m = ssim_map(a, b)
    vals = m[mask] if mask is not None else m.ravel()
    return float(vals.mean()) if vals.size else float("nan")


def side_by_side(images: list[np.ndarray], labels: list[str] | None = None,
                 width: int | None = None) -> np.ndarray:
    """Images in a row (each scaled to ``width`` pixels wide when given), with labels."""
    import cv2

    out = []
    for k, im in enumerate(images):
        if width is not None and im.shape[1] != width:
            h = int(round(im.shape[0] * width / im.shape[1]))
            im = cv2.resize(im, (width, h), interpolation=cv2.INTER_AREA)
        im = np.ascontiguousarray(im.copy())
        if labels:
            cv2.putText(im, labels[k], (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 3,
                        cv2.LINE_AA)
            cv2.putText(im, labels[k], (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5,
                        (255, 255, 255), 1, cv2.LINE_AA)
        out.append(im)
        if k < len(images) - 1:
            out.append(np.full((im.shape[0], 4, 3), 255, np.uint8))
    return np.concatenate(out, axis=1)


__all__ = ["EditParams", "Operation", "EditPlan", "GroupEdit", "View", "EditImages",
           "PlacedModel", "read_retrieved", "plan_edit", "carried_set", "support_graph", "object_names", "view_of",
           "edit_image", "hole_mask", "fill_hole", "pull_push", "cast_boxes",
           "cast_supports", "silhouette", "psnr", "ssim", "ssim_map", "side_by_side"]
