"""Faces that touch are fitted a few millimetres apart: where no view saw the gap, close it.

Evidence: the depth views and each box's observed faces.  Regularity: two books in a
row, a cushion and the back of its sofa, fitted to noisy points, end up a few
millimetres apart, and the search leaves them apart because they stand either way.
Where the slab between two boxes (at most ``gap`` long; up to ``level_gap`` when the box
is raised to the underside of one that rests on a neighbour standing on the same level,
within ``level_tol``) lies in space no view saw empty (at most ``free_fraction`` of its
samples), one box's face is pushed to the other: the pair's candidate extension, or,
between two seen faces facing each other within ``face_deg``, the box's own face; a face
just off a wall, by up to ``wall_gap_rel`` times ``gap``.  Shortest first; parts of one
object that meet so are fused; parts already one rigid body, a box under a part another
object's part holds, and hallucinated boxes (no noise to undo) are left as they are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import broad_face, changed_boxes, face_normal, face_seen, fixed_components
from ..contacts import find_contacts, pair_tolerance, sat_separation
from ..evidence import FREE_FRACTION_MAX, slab_samples
from ..model import Arrangement, Contact, Cuboid, box_corners, is_support_id
from .base import Edit, Prior, principle_of


@dataclass(frozen=True)
class Params:
    gap: float = 0.02  #: metres: about three deviations of Kinect noise at 2 m
    wall_gap_rel: float = 1.5  #: towards a wall or a broad face, this many times ``gap``
    level_gap: float = 0.04  #: metres, for a box raised under one resting on its level
    level_tol: float = 0.015  #: metres between the two levels
    graze_depth: float = 0.001  #: metres a box a degree askew may graze a neighbour
    face_deg: float = 5.0  #: degrees between two faces that face each other
    free_fraction: float = FREE_FRACTION_MAX / 2  #: share of the gap's samples seen empty


def _levelled(arr: Arrangement, touching, x, other: int, level_tol: float) -> bool:
    """Whether extension ``x`` raises the top of its box to the underside of box
    ``other``, which rests on a neighbour standing on the same level as the box
    (``level_tol``): the gap between them is then a difference of fitted heights."""
    c = arr.cuboids[x.box]
    if c.rotation[2, x.axis] * (1.0 if x.side else -1.0) < 0.9:
        return False
    z = box_corners(arr.centers, arr.rotations, arr.sizes)[..., 2]
    bottom, top = z.min(axis=1), z.max(axis=1)
    if bottom[other] < top[x.box]:
        return False
    lower, upper = arr.cuboids[x.box].id, arr.cuboids[other].id
    index = {cid: k for k, cid in enumerate(arr.ids)}
    for p, q in touching:
        s = q if p == upper else p if q == upper else None
        if s is None or s == lower or is_support_id(s):
            continue
        k = index[s]
        if (abs(bottom[k] - bottom[x.box]) <= level_tol
                and abs(top[k] - bottom[other]) <= level_tol):
            return True
    return False


def under_a_held_part(arr: Arrangement, a: str, b: str, x, rigid: dict[str, int]) -> bool:
    """Whether closing the vertical gap of extension ``x`` between ``a`` and ``b`` would
    put the top of one box against the underside of a part of another object that is
    fused to other parts of its own object (a book's top against the board above it:
    the board is held by its shelf, and the book under it touches it only by chance;
    a bridge's deck glued to another deck still rests on its pillars)."""
    c = arr.cuboids[x.box]
    if abs(c.rotation[2, x.axis]) < 0.9:
        return False  # a sideways push
    lower, upper = sorted((a, b), key=lambda i: float(arr.cuboid(i).center[2]))
    if arr.cuboid(lower).object == arr.cuboid(upper).object:
        return False
    obj = arr.cuboid(upper).object
    return obj is not None and sum(1 for i, v in rigid.items() if v == rigid[upper]
                                   and arr.cuboid(i).object == obj) > 1


def _facing_push(arr: Arrangement, k: int, other: Cuboid, max_len: float, p: Params,
                 steps: int = 32, broad_len: float | None = None):
    """The shortest push of one face of box ``k`` that makes it just touch ``other`` (an
    :class:`pipeline.extend.Extension`), or None when no push of at most ``max_len``
    does.  Only faces that face one of ``other``'s faces the sensor saw are pushed
    (:func:`pipeline.boxops.face_seen`, ``p.face_deg``; the pushed face may be a guess, a
    deepened cushion's rear face).  Towards a broad face of ``other``
    (:func:`pipeline.boxops.broad_face`) the push may be ``broad_len`` long.  A cushion a few degrees off its sofa's
    back in yaw: the back's corners reach past the cushion's rear face plane, so the
    candidate edges offer only to push the back (its whole face, into the arms beside
    it).  The length is found on a grid of ``steps`` and refined on a second one
    (``max_len / steps**2``), all faces in one separating-axis call each."""
    from ..extend import Extension

    c = arr.cuboids[k]
    faces = []
    for axis in range(3):
        for side in (0, 1):
            u = face_normal(c, axis, side)
            if (float(u @ (other.center - c.center)) > 0.0
                    and np.max(np.abs(other.rotation.T @ u)) >= np.cos(np.radians(p.face_deg))
                    and face_seen(other, -u)):
                faces.append((axis, side, u))
    if not faces:
        return None
    reach = np.array([broad_len if broad_len is not None and broad_face(other, -u)
                      else max_len for _, _, u in faces])
    tol = float(pair_tolerance(c.size[None], other.size[None])[0])

    def first_touch(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Per face, the smallest grid length in [lo, hi] at which the boxes meet (inf)."""
        t = np.linspace(0.0, 1.0, steps + 1)[1:]
        L = lo[:, None] + (hi - lo)[:, None] * t[None, :]  # (F, steps)
        U = np.array([u for _, _, u in faces])
        ax = np.array([a for a, _, _ in faces])
        n = L.size
        size = np.repeat(c.size[None], n, axis=0)
        size[np.arange(n), np.repeat(ax, steps)] += L.ravel()
        center = c.center + np.repeat(U, steps, axis=0) * L.ravel()[:, None] / 2
        sep, _, _ = sat_separation(center, np.repeat(c.rotation[None], n, axis=0), size / 2,
                                   np.repeat(other.center[None], n, axis=0),
                                   np.repeat(other.rotation[None], n, axis=0),
                                   np.repeat(other.size[None] / 2, n, axis=0),
                                   np.full(n, tol))
        meet = sep.reshape(L.shape) <= 0.0
        return np.where(meet.any(axis=1), L[np.arange(len(L)), np.argmax(meet, axis=1)], np.inf)

    zero = np.zeros(len(faces))
    coarse = first_touch(zero, reach)
    ok = np.isfinite(coarse)
    if not ok.any():
        return None
    step = reach / steps
    fine = first_touch(np.where(ok, np.maximum(coarse - step, 0.0), 0.0),
                       np.where(ok, coarse, step))
    fine = np.where(ok, np.minimum(fine, coarse), np.inf)
    f = int(np.argmin(fine))
    axis, side, _ = faces[f]
    return Extension(k, axis, side, float(fine[f]))


def apply(arr, evidence, p: Params, ctx):
    from ..extend import pair_edges, support_edges
    from ..snap import close_pair

    final, gap = arr, p.gap
    if not evidence or final.stability is None or not final.stability.stable:
        return
    touching = find_contacts(final).lookup()
    opts = []
    level_gap = max(gap, p.level_gap)
    for e in pair_edges(final, level_gap):
        a, b = final.cuboids[e.a].id, final.cuboids[e.b].id
        if tuple(sorted((a, b))) in touching:
            continue
        ca, cb = final.cuboids[e.a], final.cuboids[e.b]
        pushes = {}
        for o in e.options:
            if o.type != "touch" or len(o.extensions) != 1:
                continue
            x = o.extensions[0]
            if x.length <= gap or (x.length <= level_gap and _levelled(
                    final, touching, x, e.b if x.box == e.a else e.a, p.level_tol)):
                pushes[(x.box, x.axis, x.side)] = x
        # each box's own face towards the other, where the candidates offer none
        # (between faces the sensor saw: not against a face a deepening guessed)
        for k, other in ((e.a, cb), (e.b, ca)):
            if any(key[0] == k for key in pushes):
                continue
            x = _facing_push(final, k, other, gap, p, broad_len=p.wall_gap_rel * gap)
            if x is not None:
                pushes[(x.box, x.axis, x.side)] = x
        opts += [(x.length, a, b, x) for x in pushes.values()]
    # ... and a box's face to a wall it stands just off (the wall behind a book on a
    # wall shelf is hidden by the book itself)
    wall_gap = p.wall_gap_rel * gap
    for e in support_edges(final, wall_gap):
        a = final.cuboids[e.a].id
        if not str(e.b).startswith("wall:") or tuple(sorted((a, e.b))) in touching:
            continue
        for o in e.options:
            if (o.type == "touch" and len(o.extensions) == 1
                    and o.extensions[0].length <= wall_gap):
                opts.append((o.extensions[0].length, a, e.b, o.extensions[0]))
    grown: set[tuple[str, int, int]] = set()
    rigid = fixed_components(list(final.ids), final.contacts)
    for _length, a, b, x in sorted(opts, key=lambda t: (*t[:3], t[3].box, t[3].axis,
                                                            t[3].side)):
        cid = final.cuboids[x.box].id
        if (cid, x.axis, x.side) in grown or tuple(sorted((a, b))) in touching:
            continue
        if final.cuboids[x.box].extra.get("hallucinated"):
            continue  # a copy of a seen part, not a fit to noisy points: no noise to undo
        oa = final.cuboid(a).object
        ob = None if is_support_id(b) else final.cuboid(b).object
        if oa is not None and oa == ob and rigid[a] == rigid[b]:
            continue  # parts already one rigid body: a joint between them adds nothing
        if ob is not None and under_a_held_part(final, a, b, x, rigid):
            continue
        if evidence.free_fraction(slab_samples(final, x)) > p.free_fraction:
            continue
        c = final.cuboids[x.box]
        u = c.rotation[:, x.axis] * (1.0 if x.side else -1.0)
        size = c.size.copy()
        size[x.axis] += x.length
        cubs = list(final.cuboids)
        cubs[x.box] = c.with_(center=c.center + u * x.length / 2, size=size)
        trial = final.with_(cuboids=tuple(cubs), stability=None)
        cs = find_contacts(trial)
        mine = [(pp, q, d) for pp, q, d in cs.penetrations if cid in (pp, q)]
        grazing = all(d <= p.graze_depth and tuple(sorted((pp, q))) in touching
                      for pp, q, d in mine)
        if mine and (abs(u[2]) > 0.9 or grazing) and not is_support_id(b):
            # the face carries (or rests on) a second box: level the boxes that touch;
            # a box a degree or two askew grazes a neighbour it touches as it moves
            trial = close_pair(final, final.index[b if cid == a else a], x.box, u,
                               x.length, x.length)
            if trial is None:
                continue
            cs = find_contacts(trial)
        if tuple(sorted((a, b))) not in cs.lookup():
            continue
        fixed = [c for c in final.contacts if c.type == "fixed"]
        if oa is not None and oa == ob:  # parts of one object are fused where they meet
            fixed.append(Contact(a, b, "fixed"))
        v = yield Edit(changed_boxes(trial, final),
                       f"{a} and {b} {1000 * x.length:.0f} mm apart where no view saw the gap: "
                       f"closed", fixed=tuple(fixed))
        if v.ok:
            final, touching = v.arrangement, cs.lookup()
            rigid = fixed_components(list(final.ids), final.contacts)
            grown.add((cid, x.axis, x.side))


PRIOR = Prior("close_gaps", "settle", Params(), apply, principle_of(__doc__))
