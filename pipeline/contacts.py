"""Contact geometry: which boxes touch, and over which interface polygon.

For every pair of oriented boxes, and every box against every support plane, decide
whether they touch within a tolerance relative to the boxes' size, and if so return
the interface polygon (1 vertex for a corner contact, 2 for an edge, up to 8 for two
overlapping faces at any relative yaw), its normal and tangent frame.  Pairs that
overlap by more than the tolerance are reported as interpenetrating (not contacts).

Method
------
*Broad phase*: axis-aligned bounds inflated by the tolerance, all pairs tested at
once with numpy broadcasting (no Python loop over pairs).

*Narrow phase*: the separating axis theorem over the 15 candidate axes (3 face
normals of each box and the 9 edge cross products), vectorised over all candidate
pairs.  ``s = max_L (|d.L| - r_A(L) - r_B(L))`` is the signed separation (negative:
overlap depth along the best axis).  ``|s| <= tol`` means touching; face axes are
preferred over edge axes when both are within tolerance, so a face resting on a face
is reported as a face contact.

*Interface*: along the contact normal ``n`` the touching feature of each box is the
set of its corners within ``tol`` of its extreme (1, 2 or 4 corners).  Both features
are projected on the plane orthogonal to ``n`` and intersected with shapely
(vectorised over all pairs); when float noise makes a touching pair miss (a corner on
an edge), the feature of A is grown by ``tol`` and the result collapsed to its centre.
Interface vertices lie on the plane midway between the two features.

*Incremental*: a pair's contact depends only on its two boxes, so
:func:`update_contacts` derives the contacts of an arrangement from those of another
that differs in a few boxes, recomputing only the pairs with a changed box; the
result equals :func:`find_contacts` (same canonical order).

Conventions: a contact is stored with ``a`` always a cuboid and ``b`` a cuboid or a
support; the ``normal`` points from ``b`` into ``a`` (the direction in which ``b``
pushes ``a``).  Node indices: cuboids are ``0..K-1``, supports ``K..K+S-1``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import workclock
from .constants import CONTACT_ABS_TOL, CONTACT_REL_TOL
from .model import CORNER_SIGNS, Arrangement, box_corners


@dataclass(frozen=True)
class ContactSet:
    """All contacts of an arrangement, struct-of-arrays.

    Attributes
    ----------
    names : tuple of str
        Node names: the cuboid ids followed by the support ids.
    n_cuboids : int
    a, b : (M,) int
        Node indices of each contact (``a`` a cuboid, ``b`` a cuboid or support, a < b
        when both are cuboids).
    normal : (M, 3) float
        Unit normal pointing from ``b`` into ``a``.
    tangent_u, tangent_v : (M, 3) float
        Tangent frame, ``(u, v, normal)`` right-handed.
    vertices : (V, 3) float
        Interface polygon vertices of all contacts, concatenated.
    vertex_contact : (V,) int
        The contact each vertex belongs to (sorted ascending).
    gap : (M,) float
        Signed separation at the contact (negative: slight overlap within tolerance).
    penetrations : tuple of (str, str, float)
        Pairs overlapping by more than the tolerance, with the depth in metres.
    """

    names: tuple[str, ...]
    n_cuboids: int
    a: np.ndarray
    b: np.ndarray
    normal: np.ndarray
    tangent_u: np.ndarray
    tangent_v: np.ndarray
    vertices: np.ndarray
    vertex_contact: np.ndarray
    gap: np.ndarray
    penetrations: tuple[tuple[str, str, float], ...]

    @property
    def count(self) -> int:
        """Number of contacts."""
        return int(len(self.a))

    @property
    def n_vertices(self) -> np.ndarray:
        """(M,) int, interface vertices per contact (1 corner, 2 edge, >= 3 face)."""
        return np.bincount(self.vertex_contact, minlength=self.count)

    @property
    def pairs(self) -> list[tuple[str, str]]:
        """The touching pairs as (name_a, name_b)."""
        return [(self.names[i], self.names[j]) for i, j in zip(self.a.tolist(), self.b.tolist())]

    def polygon(self, m: int) -> np.ndarray:
        """(k, 3) vertices of contact ``m``."""
        return self.vertices[self.vertex_contact == m]

    def lookup(self) -> dict[tuple[str, str], int]:
        """Unordered name pair (sorted) -> contact index (built once; do not modify)."""
        out = self.__dict__.get("_lookup")
        if out is None:
            out = {}
            for m, (x, y) in enumerate(self.pairs):
                out[(x, y) if x <= y else (y, x)] = m
            self.__dict__["_lookup"] = out
        return out


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross`` over the last axis (length 3), same arithmetic, less overhead."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def tangent_frame(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Right-handed unit tangents ``(u, v)`` orthogonal to unit ``normal (M, 3)``."""
    n = np.asarray(normal, dtype=float).reshape(-1, 3)
    helper = np.where(np.abs(n[:, [0]]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    u = cross(helper, n)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = cross(n, u)
    return u, v


def pair_tolerance(sizes_a: np.ndarray, sizes_b: np.ndarray | None = None,
                   rel: float = CONTACT_REL_TOL) -> np.ndarray:
    """(P,) contact tolerance: ``rel`` x the smallest edge of the two boxes, floored."""
    smallest = np.min(sizes_a, axis=-1)
    if sizes_b is not None:
        smallest = np.minimum(smallest, np.min(sizes_b, axis=-1))
    return np.maximum(rel * smallest, CONTACT_ABS_TOL)


def candidate_pairs(centers: np.ndarray, rotations: np.ndarray, sizes: np.ndarray,
                    margin: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Broad phase: index pairs ``(i < j)`` whose inflated world-aligned bounds overlap.

    ``margin`` is a scalar or a (K,) per-box inflation.
    """
    K = len(centers)
    if K < 2:
        return np.zeros(0, int), np.zeros(0, int)
    ext = np.einsum("kij,kj->ki", np.abs(rotations), sizes / 2.0)
    ext = ext + np.broadcast_to(np.asarray(margin, float), (K,))[:, None]
    lo, hi = centers - ext, centers + ext
    i, j = np.triu_indices(K, k=1)
    if K <= 3000:
        overlap = np.all((lo[i] <= hi[j]) & (lo[j] <= hi[i]), axis=1)
        return i[overlap], j[overlap]
    # very large scenes: sweep along x in blocks to bound memory
    order = np.argsort(lo[:, 0])
    out_i, out_j = [], []
    for start in range(0, K, 1024):
        rows = order[start:start + 1024]
        cand = (lo[None, :, :] <= hi[rows, None, :]) & (lo[rows, None, :] <= hi[None, :, :])
        r, c = np.nonzero(np.all(cand, axis=2))
        keep = rows[r] < c
        out_i.append(rows[r][keep])
        out_j.append(c[keep])
    return np.concatenate(out_i), np.concatenate(out_j)


def changed_pairs(centers: np.ndarray, rotations: np.ndarray, sizes: np.ndarray,
                  margin: np.ndarray, changed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pairs of :func:`candidate_pairs` that have a ``changed (K,)`` box, in the same
    order (by ``i``, then ``j``), testing only the changed boxes against all."""
    K = len(centers)
    ch = np.nonzero(changed)[0]
    if K < 2 or not len(ch):
        return np.zeros(0, int), np.zeros(0, int)
    ext = np.einsum("kij,kj->ki", np.abs(rotations), sizes / 2.0)
    ext = ext + np.broadcast_to(np.asarray(margin, float), (K,))[:, None]
    lo, hi = centers - ext, centers + ext
    a, b = np.nonzero(np.all((lo[ch, None] <= hi[None]) & (lo[None] <= hi[ch, None]), axis=2))
    a = ch[a]
    keep = a != b
    a, b = a[keep], b[keep]
    codes = np.unique(np.minimum(a, b) * K + np.maximum(a, b))
    return codes // K, codes % K


def sat_separation(ca: np.ndarray, Ra: np.ndarray, ha: np.ndarray, cb: np.ndarray,
                   Rb: np.ndarray, hb: np.ndarray, tol: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Separating-axis test for P box pairs.

    Parameters
    ----------
    ca, cb : (P, 3) centres; Ra, Rb : (P, 3, 3) rotations; ha, hb : (P, 3) half extents
    tol : (P,) contact tolerance

    Returns
    -------
    sep : (P,) float
        Signed separation along the chosen axis (negative: overlap).
    axis : (P, 3) float
        The chosen unit axis, oriented from A towards B.
    is_face : (P,) bool
        True when the axis is a face normal of A or B.
    """
    P = len(ca)
    face_axes = np.concatenate([Ra.transpose(0, 2, 1), Rb.transpose(0, 2, 1)], axis=1)  # (P,6,3)
    edge = cross(Ra.transpose(0, 2, 1)[:, :, None, :], Rb.transpose(0, 2, 1)[:, None, :, :])
    edge = edge.reshape(P, 9, 3)
    norms = np.linalg.norm(edge, axis=2)
    valid_cross = norms > 1e-6
    edge = edge / np.where(valid_cross, norms, 1.0)[:, :, None]
    axes = np.concatenate([face_axes, edge], axis=1)  # (P, 15, 3)
    d = cb - ca
    proj_d = np.einsum("pk,pak->pa", d, axes)
    ra = np.einsum("pj,paj->pa", ha, np.abs(np.einsum("pkj,pak->paj", Ra, axes)))
    rb = np.einsum("pj,paj->pa", hb, np.abs(np.einsum("pkj,pak->paj", Rb, axes)))
    s = np.abs(proj_d) - ra - rb  # (P, 15)
    s[:, 6:][~valid_cross] = -np.inf
    best_face = np.argmax(s[:, :6], axis=1)
    s_face = s[np.arange(P), best_face]
    best_all = np.argmax(s, axis=1)
    s_all = s[np.arange(P), best_all]
    # prefer a face axis whenever it is within half a tolerance of the best axis
    use_face = s_face >= s_all - 0.5 * tol
    choice = np.where(use_face, best_face, best_all)
    sep = s[np.arange(P), choice]
    axis = axes[np.arange(P), choice]
    sign = np.sign(proj_d[np.arange(P), choice])
    sign[sign == 0] = 1.0
    return sep, axis * sign[:, None], use_face


def _features(corners: np.ndarray, direction: np.ndarray, tol: np.ndarray, extreme: str
              ) -> np.ndarray:
    """(P, 8) bool mask of the corners within ``tol`` of the extreme along ``direction``."""
    h = np.einsum("pck,pk->pc", corners, direction)
    if extreme == "max":
        return h >= h.max(axis=1, keepdims=True) - tol[:, None]
    return h <= h.min(axis=1, keepdims=True) + tol[:, None]


def _clean(geoms: np.ndarray) -> np.ndarray:
    """Drop repeated vertices; a sliver that collapses doing so becomes its centroid."""
    import shapely

    try:
        return shapely.normalize(shapely.remove_repeated_points(geoms, tolerance=1e-12))
    except shapely.errors.GEOSException:
        out = np.empty(len(geoms), dtype=object)
        for k, g in enumerate(geoms):
            try:
                out[k] = shapely.normalize(shapely.remove_repeated_points(g, tolerance=1e-12))
            except shapely.errors.GEOSException:  # a polygon thinner than float noise
                out[k] = shapely.centroid(g)
        return out


def _interfaces(corners_a: np.ndarray, mask_a: np.ndarray, corners_b: np.ndarray | None,
                mask_b: np.ndarray | None, normal: np.ndarray, tol: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Intersect the projected features of P touching pairs.

    ``normal`` (P, 3) points from B into A.  With ``corners_b`` None, B is a plane (the
    interface is A's feature itself).  Returns (vertices (V,3), vertex_pair (V,), u, v, ok (P,)).
    """
    import shapely

    P = len(normal)
    u, v = tangent_frame(normal)
    frame = np.stack([u, v], axis=1)  # (P, 2, 3)

    def hulls(corners: np.ndarray, mask: np.ndarray):
        pi, ci = np.nonzero(mask)
        pts2 = np.einsum("pk,pjk->pj", corners[pi, ci], frame[pi])
        mp = shapely.multipoints(pts2, indices=pi)
        geoms = np.empty(P, dtype=object)
        geoms[np.unique(pi)] = mp
        return shapely.convex_hull(geoms)

    ga = hulls(corners_a, mask_a)
    ha_n = np.einsum("pck,pk->pc", corners_a, normal)
    level_a = np.where(mask_a, ha_n, np.inf).min(axis=1)  # A's touching side (towards B = -n)
    if corners_b is None:
        inter = ga
        level = level_a
    else:
        gb = hulls(corners_b, mask_b)
        hb_n = np.einsum("pck,pk->pc", corners_b, normal)
        level_b = np.where(mask_b, hb_n, -np.inf).max(axis=1)
        level = 0.5 * (level_a + level_b)
        inter = shapely.intersection(ga, gb)
        empty = shapely.is_empty(inter)
        if np.any(empty):
            grown = shapely.buffer(ga[empty], tol[empty], join_style="mitre", cap_style="square")
            fix = shapely.intersection(grown, gb[empty])
            fix = np.where(shapely.is_empty(fix), fix, shapely.centroid(fix))
            inter[empty] = fix
        # a sliver from float noise (segment much shorter than the tolerance) is one point
        short = (shapely.get_type_id(inter) == 1) & (shapely.length(inter) < tol)
        if np.any(short):
            inter[short] = shapely.centroid(inter[short])
    inter = _clean(inter)
    coords, idx = shapely.get_coordinates(inter, return_index=True)
    # polygons repeat their first vertex at the end: drop it
    types = shapely.get_type_id(inter)
    if len(idx):
        last = np.r_[idx[1:] != idx[:-1], True]
        first = np.r_[True, idx[1:] != idx[:-1]]
        closing = last & (types[idx] == 3) & ~first
        coords, idx = coords[~closing], idx[~closing]
    ok = np.bincount(idx, minlength=P) > 0
    verts = (coords[:, [0]] * u[idx] + coords[:, [1]] * v[idx] + level[idx, None] * normal[idx])
    return verts, idx, u, v, ok


def find_contacts(arr: Arrangement, rel_tol: float = CONTACT_REL_TOL) -> ContactSet:
    """All contacts of ``arr``: cuboid-cuboid and cuboid-support.

    Parameters
    ----------
    arr : Arrangement
    rel_tol : float
        Tolerance as a fraction of the smallest edge of the two boxes involved.

    Returns
    -------
    ContactSet
    """
    workclock.charge_contacts(len(arr.cuboids))
    names = arr.ids + arr.support_ids
    parts, penetrations = _contact_parts(arr, rel_tol, None)
    return _assemble(names, len(arr.cuboids), parts, tuple(penetrations))


def _contact_parts(arr: Arrangement, rel_tol: float, changed: np.ndarray | None):
    """Contact parts (see :func:`_assemble`) and penetrations of ``arr``.

    With ``changed`` (K,) bool, only pairs with at least one changed cuboid (and changed
    cuboids against the supports) are evaluated.
    """
    K = len(arr.cuboids)
    names = arr.ids + arr.support_ids
    C, R, S = arr.centers, arr.rotations, arr.sizes
    H = S / 2.0
    corners = arr.corners
    box_tol = np.maximum(rel_tol * (S.min(axis=1) if K else np.zeros(0)), CONTACT_ABS_TOL)

    parts = []  # (a, b, normal, verts, vidx, u, v, gap, ok)
    penetrations: list[tuple[str, str, float]] = []

    # ---- cuboid / cuboid
    if changed is None:
        i, j = candidate_pairs(C, R, S, box_tol)
    else:
        i, j = changed_pairs(C, R, S, box_tol, changed)
    if len(i):
        tol = np.minimum(box_tol[i], box_tol[j])
        sep, axis, _ = sat_separation(C[i], R[i], H[i], C[j], R[j], H[j], tol)
        touch = np.abs(sep) <= tol
        for p in np.nonzero(sep < -tol)[0]:
            penetrations.append((names[i[p]], names[j[p]], float(-sep[p])))
        i, j, axis, tol, sep = i[touch], j[touch], axis[touch], tol[touch], sep[touch]
        if len(i):
            normal = -axis  # axis points from a(=i) to b(=j); the normal points from b into a
            mask_a = _features(corners[i], normal, tol, "min")  # a's corners nearest b
            mask_b = _features(corners[j], normal, tol, "max")
            verts, vidx, u, v, ok = _interfaces(corners[i], mask_a, corners[j], mask_b, normal, tol)
            parts.append((i, j, normal, verts, vidx, u, v, sep, ok))

    # ---- cuboid / support
    # (all supports in one batch: rows by support, then by cuboid, as listed)
    rows = np.arange(K) if changed is None else np.nonzero(changed)[0]
    sup_parts = []  # (ks, support node, normal, flat corners, mask, gap)
    for s_idx, sup in enumerate(arr.supports):
        if not len(rows):
            break
        d = (corners[rows] - sup.point) @ sup.normal  # (k, 8)
        dmin = d.min(axis=1)
        tol_r = box_tol[rows]
        for q in np.nonzero(dmin < -tol_r)[0]:
            penetrations.append((names[rows[q]], sup.id, float(-dmin[q])))
        qs = np.nonzero(np.abs(dmin) <= tol_r)[0]
        if len(qs):
            ks = rows[qs]
            normal = np.broadcast_to(sup.normal, (len(ks), 3)).copy()
            mask = d[qs] <= dmin[qs, None] + tol_r[qs, None]
            # put the feature on the plane: drop each corner along -n by its height
            flat = corners[ks] - d[qs][:, :, None] * normal[:, None, :]
            sup_parts.append((ks, np.full(len(ks), K + s_idx), normal, flat, mask, dmin[qs]))
    if sup_parts:
        ks, bs, normal, flat, mask, gap = (np.concatenate(x) for x in zip(*sup_parts))
        verts, vidx, u, v, ok = _interfaces(flat, mask, None, None, normal, box_tol[ks])
        parts.append((ks, bs, normal, verts, vidx, u, v, gap, ok))
    return parts, penetrations


def changed_cuboids(arr: Arrangement, base: Arrangement) -> np.ndarray:
    """(K,) bool: cuboids whose centre, rotation or size differ (exactly) from ``base``."""
    return (np.any(arr.centers != base.centers, axis=1)
            | np.any(arr.sizes != base.sizes, axis=1)
            | np.any(arr.rotations != base.rotations, axis=(1, 2)))


def update_contacts(arr: Arrangement, base: Arrangement, base_contacts: ContactSet,
                    rel_tol: float = CONTACT_REL_TOL) -> ContactSet:
    """Contacts of ``arr`` from those of ``base``, which differs in some cuboids' geometry.

    ``arr`` and ``base`` must have the same cuboid ids and supports.  Contacts (and
    penetrations) between two unchanged nodes are carried over from ``base_contacts``;
    every pair with a changed cuboid is recomputed exactly as :func:`find_contacts`
    does, and the result is put in the same canonical order (cuboid pairs by ``(a, b)``,
    then supports in order, each by ``a``), so it equals ``find_contacts(arr)``.  A pair
    depends only on its two boxes, which is what makes this exact.
    """
    workclock.charge_contacts(len(arr.cuboids))
    K = len(arr.cuboids)
    names = arr.ids + arr.support_ids
    if base.ids != arr.ids or base.support_ids != arr.support_ids or base_contacts.names != names:
        raise ValueError("update_contacts: base arrangement has other cuboids or supports")
    changed = changed_cuboids(arr, base)
    if not changed.any():
        return base_contacts
    if changed.sum() * 2 > K:
        return find_contacts(arr, rel_tol)
    parts, pens = _contact_parts(arr, rel_tol, changed)
    return _merge_carried(names, K, len(arr.supports), changed, parts, pens, base_contacts)


def _merge_carried(names, K, n_supports, changed, parts, pens, base_contacts,
                   carried=None) -> ContactSet:
    """The contacts recomputed for the ``changed`` cuboids (``parts``, ``pens``) merged
    with those of ``base_contacts`` between unchanged nodes, in canonical order
    (``carried``: :func:`_carried` of the same inputs, when several merges share it)."""
    part, kept_pens, index = _carried(names, n_supports, changed, base_contacts) \
        if carried is None else carried
    if part is not None:
        parts.append(part)
    pens = pens + kept_pens
    out = _assemble(names, K, parts, ())
    # canonical order: cuboid pairs first by (a, b), then each support in order by a
    group = np.where(out.b < K, -1, out.b)
    order = np.lexsort((out.b, out.a, group))
    inv = np.empty_like(order)
    inv[order] = np.arange(len(order))
    vnew = inv[out.vertex_contact]
    vorder = np.argsort(vnew, kind="stable")
    pen_key = [(-1 if index[y] < K else index[y], index[x], index[y]) for x, y, _ in pens]
    pens = [pens[q] for q in sorted(range(len(pens)), key=pen_key.__getitem__)]
    return ContactSet(names, K, out.a[order], out.b[order], out.normal[order],
                      out.tangent_u[order], out.tangent_v[order], out.vertices[vorder],
                      vnew[vorder], out.gap[order], tuple(pens))


def _carried(names, n_supports, changed, base_contacts):
    """(part, penetrations, node index) of the contacts of ``base_contacts`` between
    nodes that did not change (see :func:`_merge_carried`)."""
    bc = base_contacts
    node_changed = np.r_[changed, np.zeros(n_supports, bool)]
    keep = ~(node_changed[bc.a] | node_changed[bc.b]) if bc.count else np.zeros(0, bool)
    kept = np.nonzero(keep)[0]
    part = None
    if len(kept):
        vsel = keep[bc.vertex_contact]
        remap = -np.ones(bc.count, int)
        remap[kept] = np.arange(len(kept))
        part = (bc.a[kept], bc.b[kept], bc.normal[kept], bc.vertices[vsel],
                remap[bc.vertex_contact[vsel]], bc.tangent_u[kept], bc.tangent_v[kept],
                bc.gap[kept], np.ones(len(kept), bool))
    index = {n: k for k, n in enumerate(names)}
    pens = [p for p in bc.penetrations
            if not (node_changed[index[p[0]]] or node_changed[index[p[1]]])]
    return part, pens, index


def update_contacts_of_one(variants: list[Arrangement], base: Arrangement,
                           base_contacts: ContactSet, k: int,
                           rel_tol: float = CONTACT_REL_TOL) -> list[ContactSet]:
    """``[update_contacts(v, base, base_contacts) for v in variants]`` for variants that
    differ from ``base`` in cuboid ``k`` alone (refinement's finite differences), with the
    pairs of all variants computed in one batch: the same per-pair arithmetic, so the
    same contact sets.  A variant that differs elsewhere too is updated on its own."""
    workclock.charge_contacts(len(base.cuboids) * len(variants))
    K = len(base.cuboids)
    names = base.ids + base.support_ids
    out: list = [None] * len(variants)
    batch = []
    for n, v in enumerate(variants):
        if v.ids != base.ids or v.support_ids != base.support_ids or K < 2:
            out[n] = update_contacts(v, base, base_contacts, rel_tol)
            continue
        ch = changed_cuboids(v, base)
        if not (ch[k] and ch.sum() == 1):
            out[n] = update_contacts(v, base, base_contacts, rel_tol)
            continue
        batch.append(n)
    if not batch:
        return out
    N = len(batch)
    changed = np.zeros(K, bool)
    changed[k] = True
    C, R, S = base.centers, base.rotations, base.sizes
    Ck = np.stack([variants[n].cuboids[k].center for n in batch])
    Sk = np.stack([variants[n].cuboids[k].size for n in batch])
    Rk = np.repeat(R[k][None], N, axis=0)
    corners, corners_k = base.corners, box_corners(Ck, Rk, Sk)
    box_tol = np.maximum(rel_tol * S.min(axis=1), CONTACT_ABS_TOL)
    tol_k = np.maximum(rel_tol * Sk.min(axis=1), CONTACT_ABS_TOL)
    # broad phase of box k in each variant against the others (as candidate_pairs)
    ext = np.einsum("kij,kj->ki", np.abs(R), S / 2.0) + box_tol[:, None]
    ext_k = np.einsum("kij,kj->ki", np.abs(Rk), Sk / 2.0) + tol_k[:, None]
    lo, hi, lo_k, hi_k = C - ext, C + ext, Ck - ext_k, Ck + ext_k
    near = np.all((lo_k[:, None] <= hi[None]) & (lo[None] <= hi_k[:, None]), axis=2)
    near[:, k] = False
    vi, j = np.nonzero(near)  # by variant, then j ascending: the canonical pair order
    first = j < k  # pair (j, k): box j is a
    # per pair: a and b sides, from the base or from the variant's box k
    ca = np.where(first[:, None], C[j], Ck[vi])
    cb = np.where(first[:, None], Ck[vi], C[j])
    ra = np.where(first[:, None, None], R[j], R[k])
    rb = np.where(first[:, None, None], R[k], R[j])
    ha = np.where(first[:, None], S[j], Sk[vi]) / 2.0
    hb = np.where(first[:, None], Sk[vi], S[j]) / 2.0
    cra = np.where(first[:, None, None], corners[j], corners_k[vi])
    crb = np.where(first[:, None, None], corners_k[vi], corners[j])
    ia, ib = np.where(first, j, k), np.where(first, k, j)
    tol = np.minimum(np.where(first, box_tol[j], tol_k[vi]), np.where(first, tol_k[vi], box_tol[j]))
    pens: list[list] = [[] for _ in range(N)]
    pair_parts: list = [None] * N
    if len(j):
        sep, axis, _ = sat_separation(ca, ra, ha, cb, rb, hb, tol)
        for q in np.nonzero(sep < -tol)[0]:
            pens[vi[q]].append((names[ia[q]], names[ib[q]], float(-sep[q])))
        t = np.nonzero(np.abs(sep) <= tol)[0]
        if len(t):
            normal = -axis[t]
            mask_a = _features(cra[t], normal, tol[t], "min")
            mask_b = _features(crb[t], normal, tol[t], "max")
            verts, vidx, u, v, ok = _interfaces(cra[t], mask_a, crb[t], mask_b, normal, tol[t])
            bounds = np.searchsorted(vi[t], np.arange(N + 1))
            vbounds = np.searchsorted(vidx, bounds)
            for n in range(N):
                r0, r1 = bounds[n], bounds[n + 1]
                if r1 > r0:
                    w0, w1 = vbounds[n], vbounds[n + 1]
                    pair_parts[n] = (ia[t[r0:r1]], ib[t[r0:r1]], normal[r0:r1], verts[w0:w1],
                                     vidx[w0:w1] - r0, u[r0:r1], v[r0:r1], sep[t[r0:r1]],
                                     ok[r0:r1])
    # box k against the supports (each variant as _contact_parts does it, then one batch)
    sup_rows = []  # (variant, support node, normal, flat corners, mask, gap)
    for n in range(N):
        ck = corners_k[n:n + 1]
        for s_idx, sup in enumerate(base.supports):
            d = (ck - sup.point) @ sup.normal  # (1, 8)
            dmin = d.min(axis=1)
            if dmin[0] < -tol_k[n]:
                pens[n].append((names[k], sup.id, float(-dmin[0])))
            if abs(dmin[0]) <= tol_k[n]:
                normal = np.broadcast_to(sup.normal, (1, 3)).copy()
                mask = d <= dmin[:, None] + tol_k[n]
                flat = ck - d[:, :, None] * normal[:, None, :]
                sup_rows.append((n, K + s_idx, normal, flat, mask, dmin))
    sup_parts: list = [None] * N
    if sup_rows:
        vs = np.array([r[0] for r in sup_rows])
        normal, flat, mask, gap = (np.concatenate([r[q] for r in sup_rows]) for q in (2, 3, 4, 5))
        verts, vidx, u, v, ok = _interfaces(flat, mask, None, None, normal, tol_k[vs])
        bounds = np.searchsorted(vs, np.arange(N + 1))
        vbounds = np.searchsorted(vidx, bounds)
        for n in range(N):
            r0, r1 = bounds[n], bounds[n + 1]
            if r1 > r0:
                w0, w1 = vbounds[n], vbounds[n + 1]
                sup_parts[n] = (np.full(r1 - r0, k), np.array([r[1] for r in sup_rows[r0:r1]]),
                                normal[r0:r1], verts[w0:w1], vidx[w0:w1] - r0, u[r0:r1],
                                v[r0:r1], gap[r0:r1], ok[r0:r1])
    carried = _carried(names, len(base.supports), changed, base_contacts)  # shared by all
    for n, m in enumerate(batch):
        parts = [p for p in (pair_parts[n], sup_parts[n]) if p is not None]
        out[m] = _merge_carried(names, K, len(base.supports), changed, parts, pens[n],
                                base_contacts, carried)
    return out


def _assemble(names, K, parts, penetrations) -> ContactSet:
    a_list, b_list, n_list, u_list, v_list, g_list, vert_list, vidx_list = ([] for _ in range(8))
    offset = 0
    for a, b, normal, verts, vidx, u, v, gap, ok in parts:
        keep = np.nonzero(ok)[0]
        remap = -np.ones(len(a), int)
        remap[keep] = np.arange(len(keep)) + offset
        a_list.append(a[keep])
        b_list.append(b[keep])
        n_list.append(normal[keep])
        u_list.append(u[keep])
        v_list.append(v[keep])
        g_list.append(gap[keep])
        vert_list.append(verts)
        vidx_list.append(remap[vidx])
        offset += len(keep)
    if not a_list:
        z3 = np.zeros((0, 3))
        return ContactSet(names, K, np.zeros(0, int), np.zeros(0, int), z3, z3, z3, z3,
                          np.zeros(0, int), np.zeros(0), penetrations)
    vidx = np.concatenate(vidx_list)
    order = np.argsort(vidx, kind="stable")
    return ContactSet(
        names, K, np.concatenate(a_list).astype(int), np.concatenate(b_list).astype(int),
        np.concatenate(n_list), np.concatenate(u_list), np.concatenate(v_list),
        np.concatenate(vert_list)[order], vidx[order], np.concatenate(g_list), penetrations,
    )


__all__ = ["ContactSet", "find_contacts", "update_contacts", "update_contacts_of_one",
           "changed_cuboids", "cross", "tangent_frame", "pair_tolerance", "candidate_pairs",
           "sat_separation", "CORNER_SIGNS"]
