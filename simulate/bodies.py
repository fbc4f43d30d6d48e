"""Rigid bodies of an arrangement: cuboids fused by ``fixed`` contacts, with mass properties.

An arrangement's ``fixed`` contacts fuse cuboids: a connected group of fused cuboids
is one rigid body (``welds="exact"``, the default), and a group that is fused to a
support (``ground`` / ``wall:k``) is static.  With ``welds="constraint"`` every
cuboid is its own body and each ``fixed`` contact becomes an engine constraint
(MuJoCo ``equality/weld``, PyBullet ``JOINT_FIXED``) instead.

Mass properties are computed here once, in closed form, so that both exporters, both
engines and the tests agree on them: a box of mass ``m`` and full extents ``(a, b, c)``
has the local inertia ``m / 12 * diag(b^2 + c^2, a^2 + c^2, a^2 + b^2)``; a body's
inertia about its centre of mass adds ``R I R^T`` and the parallel-axis term of every box.

This module imports nothing else from :mod:`simulate`: the exporters and the engines
depend on it, never the other way round.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.errors import InputError
from pipeline.model import Arrangement, is_support_id

WELDS = ("exact", "constraint")


@dataclass(frozen=True)
class RigidBody:
    """One rigid body of an export.

    Attributes
    ----------
    name : str
        A short ASCII name, unique in the scene (``body0``, ``body1``, ...).
    members : (n,) int
        Rows of the arrangement's cuboids that form this body.
    static : bool
        True when the group is fused to a support (it never moves).
    anchors : tuple of str
        The support ids the group is fused to (empty for a free body).
    mass : float
        kg (sum of the member boxes).
    com : (3,) float
        Centre of mass in world coordinates.
    rotation : (3, 3) float
        Orientation of the body frame in world (that of its first member cuboid).
    inertia : (3, 3) float
        Inertia tensor about ``com`` expressed in world axes, kg m^2.
    """

    name: str
    members: np.ndarray
    static: bool
    anchors: tuple[str, ...]
    mass: float
    com: np.ndarray
    rotation: np.ndarray
    inertia: np.ndarray


@dataclass(frozen=True)
class Weld:
    """A ``fixed`` contact kept as a constraint (``welds="constraint"``).

    ``a`` is a body index; ``b`` is a body index or ``None`` for the world (a support).
    """

    a: int
    b: int | None
    contact: tuple[str, str]


def check_welds(welds: str) -> str:
    if welds not in WELDS:
        raise InputError(f"welds: expected one of {', '.join(WELDS)}, got {welds!r}")
    return welds


def box_inertias(sizes: np.ndarray, masses: np.ndarray) -> np.ndarray:
    """Principal inertias of solid boxes.

    Parameters
    ----------
    sizes : (K, 3) float, full extents
    masses : (K,) float

    Returns
    -------
    (K, 3) float, the diagonal of the inertia tensor in the box's own axes.
    """
    sq = np.asarray(sizes, float) ** 2
    return np.asarray(masses, float)[:, None] / 12.0 * (sq.sum(axis=1, keepdims=True) - sq)


def _components(n: int, edges: list[tuple[int, int]]) -> np.ndarray:
    """(n,) label of the connected component of every node."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    if not edges:
        return np.arange(n)
    e = np.asarray(edges, dtype=np.int64)
    g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    return connected_components(g, directed=False)[1]


def rigid_bodies(arr: Arrangement, welds: str = "exact") -> tuple[list[RigidBody], list[Weld]]:
    """Group the cuboids into rigid bodies.

    Parameters
    ----------
    arr : Arrangement
    welds : {"exact", "constraint"}
        ``exact``: fused groups are one body (static when fused to a support).
        ``constraint``: one body per cuboid, and a :class:`Weld` per ``fixed`` contact.

    Returns
    -------
    bodies : list of RigidBody, ordered by their first member
    welds : list of Weld (empty for ``exact``)

    Raises
    ------
    InputError
        A contact names an unknown cuboid or support.
    """
    from pipeline.arrangement_io import check_name

    check_welds(welds)
    for k, c in enumerate(arr.cuboids):  # every exported geom and link is named by its id
        check_name(c.id, f"cuboids[{k}].id")
    K = len(arr.cuboids)
    sup_ids = list(arr.support_ids)
    node = {**arr.index, **{s: K + j for j, s in enumerate(sup_ids)}}
    edges: list[tuple[int, int]] = []
    for i, c in enumerate(arr.contacts):
        for end in (c.a, c.b):
            if end not in node:
                kind = "support" if is_support_id(end) else "cuboid"
                raise InputError(f"contacts[{i}]: unknown {kind} {end!r}")
        if c.type == "fixed":
            edges.append((node[c.a], node[c.b]))
    n = K + len(sup_ids)
    if welds == "exact":
        label = _components(n, edges)
    else:
        label = np.arange(n)
    masses = np.asarray(arr.masses)
    sizes, centers, rots = arr.sizes, arr.centers, arr.rotations
    local_I = box_inertias(sizes, masses) if K else np.zeros((0, 3))
    # world-frame inertia of every box about its own centre: R diag(I) R^T
    I_world = np.einsum("kij,kj,klj->kil", rots, local_I, rots) if K else np.zeros((0, 3, 3))

    bodies: list[RigidBody] = []
    body_of = np.full(K, -1, dtype=np.int64)
    for lab in dict.fromkeys(label[:K].tolist()):  # first-member order, deterministic
        members = np.flatnonzero(label[:K] == lab)
        anchors = tuple(sup_ids[j] for j in range(len(sup_ids)) if label[K + j] == lab)
        m = masses[members]
        M = float(m.sum())
        com = (m[:, None] * centers[members]).sum(axis=0) / M
        d = centers[members] - com
        parallel = m[:, None, None] * ((d * d).sum(axis=1)[:, None, None] * np.eye(3)
                                       - d[:, :, None] * d[:, None, :])
        inertia = (I_world[members] + parallel).sum(axis=0)
        inertia = 0.5 * (inertia + inertia.T)
        body_of[members] = len(bodies)
        bodies.append(RigidBody(f"body{len(bodies)}", members, bool(anchors), anchors, M, com,
                                rots[members[0]], inertia))
    weld_list: list[Weld] = []
    if welds == "constraint":
        for c in arr.contacts:
            if c.type != "fixed":
                continue
            a_sup, b_sup = c.a not in arr.index, c.b not in arr.index
            if a_sup and b_sup:
                continue
            if a_sup:
                weld_list.append(Weld(int(body_of[arr.index[c.b]]), None, c.key))
            elif b_sup:
                weld_list.append(Weld(int(body_of[arr.index[c.a]]), None, c.key))
            else:
                weld_list.append(Weld(int(body_of[arr.index[c.a]]),
                                      int(body_of[arr.index[c.b]]), c.key))
        # a box welded to a support is simply static: no constraint needed, and a weld to
        # the world would only add softness.
        static_bodies = {w.a for w in weld_list if w.b is None}
        bodies = [b if i not in static_bodies else
                  RigidBody(b.name, b.members, True,
                            tuple(s for w in weld_list if w.a == i and w.b is None
                                  for s in w.contact if is_support_id(s)),
                            b.mass, b.com, b.rotation, b.inertia)
                  for i, b in enumerate(bodies)]
        weld_list = [w for w in weld_list if w.b is not None]
    return bodies, weld_list


def scene_extent(arr: Arrangement) -> float:
    """Largest distance of a box corner from the origin of the scene, at least 1 m."""
    if not arr.cuboids:
        return 1.0
    from pipeline.model import box_corners

    corners = box_corners(arr.centers, arr.rotations, arr.sizes)
    return float(max(1.0, np.abs(corners).max()))
