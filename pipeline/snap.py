r"""Closing contact gaps: the faces the stability check counts as touching are made to touch.

:func:`pipeline.contacts.find_contacts` calls two boxes touching when their separation
lies within a tolerance (:data:`pipeline.constants.CONTACT_REL_TOL` of the smaller box's
smallest edge: 2.9 mm for a 14 cm pillar), and the statics then treats them as exactly
touching.  A physics engine does not: a box floating 0.3 mm above the floor drops onto
it, a box reaching 2.8 mm into the floor is pushed out.  Measured on the Table 1
benchmark (``bridge-1001``): a pillar 2.8 mm into the floor was pushed up by both
engines, tilting the fused deck it carries by 0.2 degrees about its other pillar, and a
box on the far end of the deck rose 3.7 mm, beyond the engines' 2 % threshold; on
``bridge-1000`` the drop of a 3 cm pillar onto the floor was enough to set it spinning
in PyBullet.  The arrangement the pipeline returns should be the one the statics judged,
so :func:`close_gaps` moves faces by these sub-tolerance amounts until every contact
between two different rigid bodies has zero gap.

For a contact with unit normal :math:`n` (from ``b`` into ``a``) the gap is linear in
the centres and extents of the two boxes (``a`` a cuboid, ``b`` a cuboid or a support
plane through :math:`p`),

.. math::  g = n\cdot(c_a - c_b) - \tfrac12\sum_k |n\cdot r_{a,k}|\, s_{a,k}
                                  - \tfrac12\sum_k |n\cdot r_{b,k}|\, s_{b,k},

(the same rows :mod:`pipeline.refine` keeps at zero).  The smallest change
:math:`\delta` of all centres and extents (least squares, minimum norm) with
:math:`J\delta = -g` on the contacts between different rigid bodies and
:math:`J\delta = 0` on the contacts inside one (a fused group is one body in the
engines, its internal gaps are kept as they are) is applied; two rounds absorb the
rare contact whose separating axis changes.  The result is kept only when it has the
same touching pairs, no interpenetration and no box shrunk below half its extent;
otherwise the input is returned unchanged.
"""

from __future__ import annotations

import numpy as np

from .contacts import ContactSet, find_contacts
from .model import Arrangement

#: Rounds of linearised closing.
ROUNDS = 3
#: A gap at most this many metres is closed (float noise of the geometry).
GAP_DONE = 1e-9


def _rows(arr: Arrangement, a: np.ndarray, b: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(M, 6K) gradient of the gaps of the contacts ``a[m]``-``b[m]`` (normal from ``b``
    into ``a``; ``b >= K`` a support plane) in the centres and extents of the cuboids."""
    K = len(arr.cuboids)
    R = arr.rotations
    J = np.zeros((len(a), 6 * K))
    for m in range(len(a)):
        i, j, n = int(a[m]), int(b[m]), normal[m]
        J[m, 6 * i:6 * i + 3] = n
        J[m, 6 * i + 3:6 * i + 6] = -0.5 * np.abs(R[i].T @ n)
        if j < K:
            J[m, 6 * j:6 * j + 3] = -n
            J[m, 6 * j + 3:6 * j + 6] = -0.5 * np.abs(R[j].T @ n)
    return J


def _moved(arr: Arrangement, delta: np.ndarray) -> Arrangement | None:
    """``arr`` with centres and extents changed by ``delta (K, 6)`` (None when a box
    would shrink below half an extent)."""
    sizes = arr.sizes + delta[:, 3:]
    if np.any(sizes < 0.5 * arr.sizes):
        return None
    return arr.with_(cuboids=tuple(c.with_(center=c.center + delta[k, :3], size=sizes[k])
                                   for k, c in enumerate(arr.cuboids)), stability=None)


def _between_bodies(arr: Arrangement, cs: ContactSet) -> np.ndarray:
    """(M,) bool: the contact joins two different rigid bodies (not both anchored)."""
    from .stability import build_bodies, fixed_node_pairs

    bodies = build_bodies(arr, fixed_node_pairs(arr, cs))
    ga, gb = bodies.of_node[cs.a], bodies.of_node[cs.b]
    return (ga != gb) & ~(bodies.anchored[ga] & bodies.anchored[gb])


def close_gaps(arr: Arrangement) -> tuple[Arrangement, float]:
    """Make every contact between two different rigid bodies of ``arr`` exact.

    Returns the arrangement (``arr`` itself when nothing needed closing or the closed
    geometry would change which boxes touch) and the largest gap closed, metres.
    """
    if not arr.cuboids:
        return arr, 0.0
    cs0 = find_contacts(arr)
    if not cs0.count:
        return arr, 0.0
    between = _between_bodies(arr, cs0)
    if not np.any(between):
        return arr, 0.0
    worst = float(np.abs(cs0.gap[between]).max())
    if worst <= GAP_DONE:
        return arr, 0.0
    pairs0 = set(cs0.pairs)
    current, cs = arr, cs0
    for _ in range(ROUNDS):
        J = _rows(current, cs.a, cs.b, cs.normal)
        target = np.where(between, -cs.gap, 0.0)
        delta = np.linalg.lstsq(J, target, rcond=None)[0].reshape(-1, 6)
        moved = _moved(current, delta)
        if moved is None:
            return arr, 0.0
        current = moved
        cs = find_contacts(current)
        if cs.penetrations or set(cs.pairs) != pairs0:
            return arr, 0.0
        between = _between_bodies(current, cs)
        if float(np.abs(cs.gap[between]).max(initial=0.0)) <= GAP_DONE:
            break
    return current, worst


def close_pair(arr: Arrangement, a: int, b: int, normal: np.ndarray, gap: float,
               max_move: float) -> Arrangement | None:
    """Close the gap ``gap`` between cuboids ``a`` and ``b`` (``normal`` from ``b`` into
    ``a``) by the smallest change of all centres and extents that keeps every contact
    of ``arr`` as it is (gap unchanged; the same least squares as :func:`close_gaps`).

    Where one face cannot simply be pushed (a box's top raised to the box above would
    reach into a second box it already carries), the change spreads over the boxes
    that touch: the tops of a row of boxes meet at one level.  Returns None when the
    result changes which other pairs touch, interpenetrates, moves a centre or a face
    by more than ``max_move`` or shrinks a box below half an extent.
    """
    cs = find_contacts(arr)
    n = np.asarray(normal, float)[None]
    J = np.vstack([_rows(arr, cs.a, cs.b, cs.normal), _rows(arr, [a], [b], n)])
    target = np.r_[np.zeros(cs.count), -float(gap)]
    delta = np.linalg.lstsq(J, target, rcond=None)[0].reshape(-1, 6)
    if np.abs(delta[:, :3]).max() + np.abs(delta[:, 3:]).max() / 2 > max_move:
        return None
    moved = _moved(arr, delta)
    if moved is None:
        return None
    after = find_contacts(moved)
    want = set(cs.lookup()) | {tuple(sorted((arr.cuboids[a].id, arr.cuboids[b].id)))}
    if after.penetrations or set(after.lookup()) != want:
        return None
    return moved


__all__ = ["close_gaps", "close_pair"]
