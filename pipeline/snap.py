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


def _rows(arr: Arrangement, cs: ContactSet) -> np.ndarray:
    """(M, 6K) gradient of every contact's gap in the centres and extents of the cuboids."""
    K = len(arr.cuboids)
    R = arr.rotations
    J = np.zeros((cs.count, 6 * K))
    for m in range(cs.count):
        a, b, n = int(cs.a[m]), int(cs.b[m]), cs.normal[m]
        J[m, 6 * a:6 * a + 3] = n
        J[m, 6 * a + 3:6 * a + 6] = -0.5 * np.abs(R[a].T @ n)
        if b < K:
            J[m, 6 * b:6 * b + 3] = -n
            J[m, 6 * b + 3:6 * b + 6] = -0.5 * np.abs(R[b].T @ n)
    return J


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
        J = _rows(current, cs)
        target = np.where(between, -cs.gap, 0.0)
        delta = np.linalg.lstsq(J, target, rcond=None)[0].reshape(-1, 6)
        sizes = current.sizes + delta[:, 3:]
        if np.any(sizes < 0.5 * current.sizes):
            return arr, 0.0
        current = current.with_(cuboids=tuple(
            c.with_(center=c.center + delta[k, :3], size=sizes[k])
            for k, c in enumerate(current.cuboids)), stability=None)
        cs = find_contacts(current)
        if cs.penetrations or set(cs.pairs) != pairs0:
            return arr, 0.0
        between = _between_bodies(current, cs)
        if float(np.abs(cs.gap[between]).max(initial=0.0)) <= GAP_DONE:
            break
    return current, worst


__all__ = ["close_gaps"]
