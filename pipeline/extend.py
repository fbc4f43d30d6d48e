"""Candidate extensions of cuboids into the unseen (paper section 4.2, Figure 7).

A cuboid is extended by pushing *one face* outwards: the face of box ``i`` that faces
the other object (the face whose outer half-space contains it: space partition), by
the gap between that face's plane and the other object along the face normal, so
that the extended box just touches it.  For a pair (i, j) this gives the candidates of
Figure 7: unchanged, i extended to touch j, j extended to touch i, and each of those
fused (``fixed``).  Every cuboid is also offered an extension to each support (ground
and walls) that one of its faces looks at (hidden legs, bottoms and backs).  A push that
brings the two over each other but leaves them a gap of sensor noise apart
(:func:`corner_gaps`) along another face of the pushed box is offered with that face
pushed across the gap too, or with the other box's face across it: a desk top seen only
by its front edge, pushed back under the boxes fitted a few millimetres above it; a
plank pushed out over the far pier whose top the noise cut short.

Geometry is carried as per-face offsets ``(K, 3, 2)`` (axis, negative/positive face,
metres >= 0) on top of the initial boxes, so an arrangement for any combination of
choices is rebuilt with a few vectorised operations (:func:`apply_offsets`).

A candidate whose added volume lies in space the sensor saw as empty is rejected
(:func:`visible_free_fraction`): points sampled in the added slab are projected into
the depth image; a sample clearly in front of the measured depth (beyond the sensor
noise at that depth) was seen through.  Pixels with no reading, or outside the image,
say nothing.  The slab is judged in layers along the push (:func:`layers_unseen`), as
the priors judge theirs: a layer seen empty ends it, however much of the space beyond
was out of the picture or in a shadow.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .contacts import candidate_pairs, pair_tolerance, sat_separation
from .evidence import (
    FREE_FRACTION_MAX,
    DepthView,
    depth_noise,
    seen_in_front,
    slab_layers,
    slab_samples,
    visible_free_fraction,
    visible_free_mask,
)
from .model import Arrangement, Cuboid, box_corners, is_support_id

#: An extension longer than this many times the scene's median box edge is not proposed.
MAX_EXTENSION_REL = 12.0
#: A sideways extension (face normal within 30 degrees of horizontal) is at most this
#: many times the box's largest edge: hidden backs, not bridges between far objects.
SIDEWAYS_EXTENSION_REL = 1.5
#: A face looks at a support when its outward normal is within 60 degrees of facing it.
FACING_COS = 0.5
#: A push that leaves the pair at most this far apart (metres, about three deviations of
#: Kinect noise at 2 m) is offered with a second push of the face the gap faces; with
#: cameras, at most three deviations of the depth noise at the pushed box's distance from
#: the nearest one, if that is more (:func:`corner_gaps`).
CORNER_GAP = 0.02
#: ... when the gap's direction is within about 8 degrees of that face's normal.
CORNER_COS = 0.99
#: A contact is a resting one (box on box) when its normal is within about 25 degrees of
#: vertical: only then is the lower box offered to grow under an overhanging upper box.
RESTING_COS = 0.9


@dataclass(frozen=True)
class Extension:
    """Push face ``(axis, side)`` of cuboid ``box`` outwards by ``length`` metres."""

    box: int
    axis: int
    side: int  # 0: the -axis face, 1: the +axis face
    length: float

    def volume(self, sizes: np.ndarray) -> float:
        other = [k for k in range(3) if k != self.axis]
        return float(self.length * sizes[self.box, other[0]] * sizes[self.box, other[1]])


@dataclass(frozen=True)
class Option:
    """One choice for an edge: which extensions it needs and the contact type it asserts.

    ``type`` is "none" (the pair is left apart, or touches as it happens to), "touch" or
    "fixed".  ``extensions`` is empty when the pair already touches.
    """

    type: str
    extensions: tuple[Extension, ...] = ()
    volume: float = 0.0


@dataclass(frozen=True)
class Edge:
    """A pair that could touch: ``a`` a cuboid index, ``b`` a cuboid index or a support id."""

    a: int
    b: int | str
    options: tuple[Option, ...]
    same_object: bool = False
    touching: bool = False  # already touching in the initial arrangement


def apply_offsets(arr: Arrangement, offsets: np.ndarray, memo: dict | None = None
                  ) -> Arrangement:
    """The arrangement with every box's faces pushed out by ``offsets (K, 3, 2)``.

    ``memo`` (a dict kept by the caller for one base ``arr``) reuses the cuboid built
    for the same box and offsets (the search applies the same few extensions often).
    """
    if not np.any(offsets):
        return arr
    sizes = arr.sizes + offsets.sum(axis=2)
    shift = np.einsum("kij,kj->ki", arr.rotations, (offsets[:, :, 1] - offsets[:, :, 0]) / 2.0)
    centers = arr.centers + shift
    moved = np.any(offsets != 0, axis=(1, 2))
    centers = _lift_leaning(arr, centers, sizes, moved)
    cubs = list(arr.cuboids)
    for k in np.nonzero(moved)[0].tolist():
        key = (k, offsets[k].tobytes())
        c = None if memo is None else memo.get(key)
        if c is None:
            o = arr.cuboids[k]
            c = Cuboid(o.id, centers[k], o.rotation, sizes[k], o.density, o.object, o.observed,
                       o.extra)
            if memo is not None:
                memo[key] = c
        cubs[k] = c
    return arr.with_(cuboids=tuple(cubs))


def _lift_leaning(arr: Arrangement, centers: np.ndarray, sizes: np.ndarray,
                  moved: np.ndarray) -> np.ndarray:
    """``centers`` with each pushed slanted box that its pushes took into the ground
    lifted back onto it.

    Each push is measured on the fitted boxes alone.  On an upright box the pushes are
    independent; on a leaning one a push of its back to a wall lowers its foot too, and
    with the push of the foot to the floor the two go into the floor.  A leaning box
    slides up its wall instead: what would enter the floor lifts it (along the floor's
    normal, which keeps a contact with an upright wall)."""
    g = next((s for s in arr.supports if s.id == "ground"), None)
    if g is None:
        return centers
    out = centers
    for k in np.nonzero(moved)[0].tolist():
        c = arr.cuboids[k]
        if not c.extra.get("slanted"):
            continue
        low = float(((box_corners(centers[k:k + 1], c.rotation[None], sizes[k:k + 1])[0]
                      - g.point) @ g.normal).min())
        low0 = float(((c.corners() - g.point) @ g.normal).min())
        if low < 0.0 <= low0:
            out = out.copy() if out is centers else out
            out[k] = out[k] - low * g.normal
    return out


def apart(arr: Arrangement, geom: Arrangement, falls=None) -> Arrangement:
    """``geom`` (``arr`` extended group by group) with no box entering another that did
    not enter it in ``arr``.

    Groups are searched independently, each against its own boxes only, so an extension
    of one group may grow into a box, or an extension, of another.  For each such pair
    the box whose overlapping face can move back without cutting into its fitted box
    (``arr``'s) is trimmed clear of the other (:func:`pipeline.boxops.trimmed`); when
    both can, and ``falls`` (a callable: cuboids -> how many boxes fall) is given, the
    one whose trimming leaves fewer boxes falling (a desk grown down onto its pedestal
    keeps that reach; the shelf that grew up into it gives way); when neither can, both
    go back to their fitted boxes."""
    from .boxops import trimmed
    from .contacts import find_contacts

    def key(a: str, b: str) -> tuple[str, str]:
        return (a, b) if a <= b else (b, a)

    before = {key(a, b) for a, b, _ in find_contacts(arr).penetrations}
    cubs = list(geom.cuboids)
    for _ in range(2 * len(cubs)):
        cur = geom.with_(cuboids=tuple(cubs))
        new = [(a, b) for a, b, _ in find_contacts(cur).penetrations
               if b in cur.index and key(a, b) not in before]
        if not new:
            break
        a, b = new[0]
        i, j = cur.index[a], cur.index[b]
        ways = []
        for k, other in ((i, j), (j, i)):
            c = trimmed(cubs[k], cubs[other])
            fit = arr.cuboids[k]
            local = (fit.corners() - c.center) @ c.rotation
            if c is not cubs[k] and np.all(np.abs(local) <= c.size / 2 + 1e-6):
                ways.append((k, c))
                if falls is None:
                    break
        if ways:  # two only with ``falls``: the trimming that leaves fewer falling
            k, c = ways[0] if len(ways) == 1 else min(
                ways, key=lambda w: falls(tuple(w[1] if n == w[0] else x
                                                for n, x in enumerate(cubs))))
            cubs[k] = c
        else:
            cubs[i], cubs[j] = arr.cuboids[i], arr.cuboids[j]
    return geom.with_(cuboids=tuple(cubs))


def offsets_of(extensions, K: int) -> np.ndarray:
    """Per-face offsets of a set of extensions (the longest wins on a shared face)."""
    off = np.zeros((K, 3, 2))
    for e in extensions:
        off[e.box, e.axis, e.side] = max(off[e.box, e.axis, e.side], e.length)
    return off


def _face_gaps(Ca, Ra, Ha, corners_b) -> np.ndarray:
    """(P, 3, 2) distance from each face plane of box a to the nearest corner of b beyond it."""
    axes = Ra.transpose(0, 2, 1)  # (P, 3, 3): axis k of each box as a row
    proj = np.einsum("pck,pak->pac", corners_b, axes)  # (P, 3, 8)
    cproj = np.einsum("pk,pak->pa", Ca, axes)
    pos = proj.min(axis=2) - (cproj + Ha)  # + face: how far b starts beyond it
    neg = (cproj - Ha) - proj.max(axis=2)  # - face
    return np.stack([neg, pos], axis=2)


def _caps(R: np.ndarray, S: np.ndarray, axis: np.ndarray, max_ext: float) -> np.ndarray:
    """(P,) longest extension allowed along ``axis`` of each box (sideways ones are short)."""
    uz = np.abs(R[np.arange(len(axis)), 2, axis])
    sideways = uz < 0.5
    return np.where(sideways, np.minimum(max_ext, SIDEWAYS_EXTENSION_REL * S.max(axis=1)),
                    max_ext)


def _overhangs(C, R, S, corners, i, j, axis, tol, max_ext) -> dict[int, list[Extension]]:
    """Per touching pair ``p`` (box ``i[p]`` against ``j[p]``, contact normal ``axis[p]``
    from i towards j) resting one on the other: the lower box's side faces pushed out
    under the upper box's footprint where it hangs over them (a desk top whose back edge
    was not seen, a box on it hanging over the seen edge): the length is how far the
    upper box's farthest corner lies past that face's plane."""
    out: dict[int, list[Extension]] = {}
    rest = np.abs(axis[:, 2]) >= RESTING_COS
    if not rest.any():
        return out
    up = axis[:, 2] > 0  # j above i
    for p in np.nonzero(rest)[0].tolist():
        lo, hi = (int(i[p]), int(j[p])) if up[p] else (int(j[p]), int(i[p]))
        axes = R[lo].T  # rows: the lower box's axes
        proj = corners[hi] @ axes.T  # (8, 3)
        c = axes @ C[lo]
        h = S[lo] / 2
        beyond = np.stack([(c - h) - proj.min(axis=0), proj.max(axis=0) - (c + h)], axis=1)
        for ax in range(3):
            if abs(R[lo, 2, ax]) >= 0.5:  # only side faces
                continue
            cap = min(max_ext, SIDEWAYS_EXTENSION_REL * float(S[lo].max()))
            for side in (0, 1):
                length = float(beyond[ax, side])
                if tol[p] < length <= cap:
                    out.setdefault(p, []).append(Extension(lo, ax, side, length))
    return out


def corner_gaps(arr: Arrangement, eyes=()) -> np.ndarray:
    """(K,) the largest gap a push may leave and still close along a second face, per
    box: :data:`CORNER_GAP`, or three deviations of the depth noise
    (:func:`pipeline.evidence.depth_noise`) at the box's distance from the nearest
    camera centre in ``eyes`` when that is more.  A face seen at 3.5 m is placed to
    within 6 cm; a gap that small between a plank and the pier under it is noise."""
    gaps = np.full(len(arr.cuboids), CORNER_GAP)
    if len(eyes) and len(gaps):
        d = np.linalg.norm(arr.centers[:, None, :] - np.asarray(eyes, float)[None], axis=2)
        gaps = np.maximum(gaps, 3.0 * depth_noise(d.min(axis=1)))
    return gaps


def pair_edges(arr: Arrangement, max_ext: float, same_object: bool = False,
               overhang: bool = False, eyes=()) -> list[Edge]:
    """Candidate edges between cuboids (Figure 7), vectorised over all nearby pairs
    (``same_object``: only the pairs of parts of one object, each edge as without).

    With ``overhang``, a pair of different objects already resting one on the other
    (contact normal near vertical) whose upper box hangs over a side face of the lower
    one is also offered that face pushed out under it (:func:`_overhangs`), as ``touch``
    and ``fixed``: the lower box's far part may be hidden by the box on it.  ``eyes``:
    the camera centres, for the gaps a push may close along a second face
    (:func:`corner_gaps`)."""
    K = len(arr.cuboids)
    if K < 2:
        return []
    C, R, S = arr.centers, arr.rotations, arr.sizes
    H = S / 2.0
    i, j = candidate_pairs(C, R, S, np.full(K, max_ext))
    if same_object and len(i):
        objects = [c.object for c in arr.cuboids]
        keep = np.array([objects[a] is not None and objects[a] == objects[b]
                         for a, b in zip(i.tolist(), j.tolist())], bool)
        i, j = i[keep], j[keep]
    if not len(i):
        return []
    tol = pair_tolerance(S[i], S[j])
    corners = box_corners(C, R, S)
    sep, normal, _ = sat_separation(C[i], R[i], H[i], C[j], R[j], H[j], tol)
    touching = np.abs(sep) <= tol
    apart = sep > tol
    gi = _face_gaps(C[i], R[i], H[i], corners[j])  # i's faces towards j
    gj = _face_gaps(C[j], R[j], H[j], corners[i])
    edges: list[Edge] = []
    exts = []  # (pair, which, axis, side, length)
    for which, g in ((0, gi), (1, gj)):
        src_idx = i if which == 0 else j
        flat = g.reshape(len(i), 6)
        best = np.argmax(flat, axis=1)
        length = flat[np.arange(len(i)), best]
        cap = _caps(R[src_idx], S[src_idx], best // 2, max_ext)
        ok = apart & (length > -tol) & (length <= cap)
        for p in np.nonzero(ok)[0]:
            exts.append((p, which, int(best[p] // 2), int(best[p] % 2), max(float(length[p]), 0.0)))
    # verify that each extension really makes the pair touch (footprints overlap)
    by_pair: dict[int, list[tuple[Extension, ...]]] = {}
    if exts:
        P = np.array([e[0] for e in exts])
        which = np.array([e[1] for e in exts])
        src = np.where(which == 0, i[P], j[P])
        dst = np.where(which == 0, j[P], i[P])
        off = np.zeros((len(exts), 3, 2))
        off[np.arange(len(exts)), [e[2] for e in exts], [e[3] for e in exts]] = [e[4] for e in exts]
        def separation(q: np.ndarray, off_q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            """Separation (and its axis) of extension ``q``'s box, its faces pushed out by
            ``off_q``, from the box it is to touch."""
            a = src[q]
            cen = C[a] + np.einsum("pij,pj->pi", R[a], (off_q[:, :, 1] - off_q[:, :, 0]) / 2.0)
            sep, axis, _ = sat_separation(cen, R[a], (S[a] + off_q.sum(axis=2)) / 2,
                                          C[dst[q]], R[dst[q]], H[dst[q]], tol[P[q]])
            return sep, axis

        every = np.arange(len(exts))
        s2, n2 = separation(every, off)
        good = np.abs(s2) <= tol[P]
        for n, (p, _, ax, side, length) in enumerate(exts):
            if good[n]:
                by_pair.setdefault(p, []).append((Extension(int(src[n]), ax, side, length),))
        # a push that brings the footprints over each other but leaves them a gap of
        # sensor noise apart (a desk top seen by its front edge pushed back under the
        # boxes on it, their bottoms fitted a few millimetres above its top) closes that
        # gap with the face it faces: both pushes together are one option
        q = gap = np.nonzero(~good & (s2 > tol[P]) & (s2 <= corner_gaps(arr, eyes)[src]))[0]
        dots = np.einsum("qji,qj->qi", R[src[q]], n2[q])  # the gap's axis in the box's axes
        ax2 = np.argmax(np.abs(dots), axis=1)
        cos2 = dots[np.arange(len(q)), ax2]
        first = np.array([exts[n][2] for n in q.tolist()], int)
        keep = (ax2 != first) & (np.abs(cos2) >= CORNER_COS)
        q, ax2, side2 = q[keep], ax2[keep], (cos2[keep] > 0).astype(int)
        off2 = off[q].copy()
        off2[np.arange(len(q)), ax2, side2] = s2[q]
        s3, _ = separation(q, off2)
        for m, n in enumerate(q.tolist()):
            if abs(s3[m]) <= tol[P[n]]:
                p, _, ax, side, length = exts[n]
                a = int(src[n])
                by_pair.setdefault(p, []).append(
                    (Extension(a, ax, side, length),
                     Extension(a, int(ax2[m]), int(side2[m]), float(s2[n]))))
        # ... or the other box's face across it: the noise may have cut either one (a
        # pier's top fitted short under the plank pushed out over it)
        dd = np.einsum("qji,qj->qi", R[dst[gap]], -n2[gap])  # towards the pushed box
        axd = np.argmax(np.abs(dd), axis=1)
        cosd = dd[np.arange(len(gap)), axd]
        for m, n in enumerate(gap.tolist()):
            if abs(cosd[m]) < CORNER_COS:
                continue
            p, _, ax, side, length = exts[n]
            a, b = int(src[n]), int(dst[n])
            offd = np.zeros((3, 2))
            offd[axd[m], int(cosd[m] > 0)] = s2[n]
            ca = C[a] + R[a] @ ((off[n][:, 1] - off[n][:, 0]) / 2.0)
            cb = C[b] + R[b] @ ((offd[:, 1] - offd[:, 0]) / 2.0)
            sep3, _, _ = sat_separation(ca[None], R[a][None], ((S[a] + off[n].sum(1)) / 2)[None],
                                        cb[None], R[b][None], ((S[b] + offd.sum(1)) / 2)[None],
                                        tol[P[n]][None])
            if abs(sep3[0]) <= tol[P[n]]:
                by_pair.setdefault(p, []).append(
                    (Extension(a, ax, side, length),
                     Extension(b, int(axd[m]), int(cosd[m] > 0), float(s2[n]))))
    over: dict[int, list[Extension]] = {}
    if overhang and touching.any():
        objects = [c.object for c in arr.cuboids]
        t = np.array([p for p in np.nonzero(touching)[0].tolist()
                      if objects[i[p]] is None or objects[i[p]] != objects[j[p]]], int)
        if len(t):
            found = _overhangs(C, R, S, corners, i[t], j[t], normal[t], tol[t], max_ext)
            over = {int(t[q]): v for q, v in found.items()}
    for p in range(len(i)):
        a, b = int(i[p]), int(j[p])
        same = (arr.cuboids[a].object is not None
                and arr.cuboids[a].object == arr.cuboids[b].object)
        if touching[p]:
            opts = (Option("touch"), Option("fixed"))
            for e in over.get(p, ()):
                v = e.volume(S)
                opts += (Option("touch", (e,), v), Option("fixed", (e,), v))
        elif p in by_pair:
            opts = [Option("none")]
            for es in by_pair[p]:
                v = sum(e.volume(S) for e in es)
                opts += [Option("touch", es, v), Option("fixed", es, v)]
            opts = tuple(opts)
        else:
            continue
        edges.append(Edge(a, b, opts, same, bool(touching[p])))
    return edges


def support_edges(arr: Arrangement, max_ext: float) -> list[Edge]:
    """Each cuboid against each support one of its faces looks at."""
    K = len(arr.cuboids)
    edges: list[Edge] = []
    if not K:
        return edges
    corners = box_corners(arr.centers, arr.rotations, arr.sizes)
    tol = pair_tolerance(arr.sizes)
    for sup in arr.supports:
        d = (corners - sup.point) @ sup.normal  # (K, 8) heights above the plane
        dmin = d.min(axis=1)
        facing = -np.einsum("kij,i->kj", arr.rotations, sup.normal)  # (K, 3) cos of +faces
        cos = np.stack([-facing, facing], axis=2)  # (K, 3, 2): face outward . (-n)
        flat = cos.reshape(K, 6)
        best = np.argmax(flat, axis=1)
        c = flat[np.arange(K), best]
        for k in range(K):
            if abs(dmin[k]) <= tol[k]:
                edges.append(Edge(k, sup.id, (Option("touch"), Option("fixed")), False, True))
                continue
            if dmin[k] < 0 or c[k] < FACING_COS:
                continue
            length = float(dmin[k] / c[k])
            cap = _caps(arr.rotations[k:k + 1], arr.sizes[k:k + 1], np.array([best[k] // 2]),
                        max_ext)[0]
            if length > cap:
                continue
            e = Extension(k, int(best[k] // 2), int(best[k] % 2), length)
            v = e.volume(arr.sizes)
            edges.append(Edge(k, sup.id, (Option("none"), Option("touch", (e,), v),
                                          Option("fixed", (e,), v))))
    return edges


def candidate_edges(arr: Arrangement, max_ext: float | None = None, eyes=()) -> list[Edge]:
    """All candidate edges of ``arr`` (pairs and supports); ``eyes``: camera centres."""
    if max_ext is None:
        max_ext = MAX_EXTENSION_REL * arr.scale_length()
    edges, _ = prune_penetrating(arr, pair_edges(arr, max_ext, overhang=True, eyes=eyes)
                                 + support_edges(arr, max_ext))
    return edges


def prune_penetrating(arr: Arrangement, edges: list[Edge]) -> tuple[list[Edge], int]:
    """Drop options whose extension, applied alone, drives a box into another box.

    Extensions only grow boxes, so such an option can never be part of a valid
    arrangement.  Returns (edges with at least one contact option left, n rejected).
    """
    K = len(arr.cuboids)
    C, R, S = arr.centers, arr.rotations, arr.sizes
    exts = list(dict.fromkeys(x for e in edges for o in e.options for x in o.extensions))
    verdict: dict[Extension, bool] = {x: True for x in exts}
    if exts and K > 1:
        # every extended box against every other box at once: a world-aligned bounds
        # test first (boxes whose inflated bounds are apart are separated, so they pass),
        # then the separating-axis test on the remaining pairs
        box = np.array([x.box for x in exts])
        off = np.zeros((len(exts), 3, 2))
        off[np.arange(len(exts)), [x.axis for x in exts], [x.side for x in exts]] = \
            [x.length for x in exts]
        size = S[box] + off.sum(axis=2)
        cen = C[box] + np.einsum("xij,xj->xi", R[box], (off[:, :, 1] - off[:, :, 0]) / 2.0)
        tol_x = pair_tolerance(size)
        tol_k = pair_tolerance(S)
        half_x = np.einsum("xij,xj->xi", np.abs(R[box]), size / 2.0)
        half_k = np.einsum("kij,kj->ki", np.abs(R), S / 2.0)
        margin = np.maximum(tol_x[:, None], tol_k[None, :])  # (X, K)
        near = np.all(np.abs(cen[:, None, :] - C[None, :, :])
                      <= half_x[:, None, :] + half_k[None, :, :] + margin[:, :, None], axis=2)
        near[np.arange(len(exts)), box] = False
        xi, ki = np.nonzero(near)
        if len(xi):
            tol = pair_tolerance(size[xi], S[ki])
            sep, _, _ = sat_separation(cen[xi], R[box[xi]], size[xi] / 2, C[ki], R[ki],
                                       S[ki] / 2, tol)
            bad = np.unique(xi[sep < -tol])
            for q in bad.tolist():
                verdict[exts[q]] = False
    out, rejected = [], 0
    for e in edges:
        keep = [o for o in e.options if all(verdict[x] for x in o.extensions)]
        rejected += len(e.options) - len(keep)
        if any(o.type != "none" for o in keep):
            out.append(Edge(e.a, e.b, tuple(keep), e.same_object, e.touching))
    return out, rejected


#: An extension is judged in this many layers along its push (each no thinner than
#: :data:`LAYER_MIN` metres): no layer may be seen empty.
LAYERS = 4
LAYER_MIN = 0.05


def layers_unseen(arr: Arrangement, x: Extension, views: list[DepthView], margin: float
                  ) -> bool:
    """Whether no layer of the slab that extension ``x`` adds was seen empty (at most
    :data:`FREE_FRACTION_MAX` of its samples seen through): a camera looking over a
    box's edge sees the space beside it only from some distance on, and the box ends
    before that layer however much of the space nearer its face the box's own shadow
    hides (the space right under a wall shelf's lowest board, seen empty, under which
    the rest down to the floor is hidden by the board)."""
    n = int(min(LAYERS, max(1, x.length // LAYER_MIN)))
    ends = [x.length * j / n for j in range(n + 1)]
    return all(visible_free_fraction(layer, views, margin) <= FREE_FRACTION_MAX
               for layer in slab_layers(arr, x, ends))


def prune_by_visibility(arr: Arrangement, edges: list[Edge], views: list[DepthView],
                        margin: float, whole_only: frozenset[int] = frozenset(),
                        cache: dict | None = None) -> tuple[list[Edge], int]:
    """Drop options whose added volume the sensor saw through; returns (edges, n rejected).

    An added volume is seen through when more than :data:`FREE_FRACTION_MAX` of its
    samples were (:func:`visible_free_fraction`) or when the median of them was
    (:func:`seen_in_front`).  On the edges of the boxes in ``whole_only`` (indices) only
    the median test counts: the per-sample fraction also counts the mixed depths at a
    silhouette, which a slab a few centimetres thick under a box's bottom edge is mostly
    made of.  ``cache`` (extension, whole) -> verdict may be shared by calls on the same
    ``arr`` and views.
    """
    if not views:
        return edges, 0
    cache = {} if cache is None else cache
    rejected = 0
    out = []
    for e in edges:
        whole = e.a in whole_only or e.b in whole_only
        keep = []
        for o in e.options:
            ok = True
            for x in o.extensions:
                if (x, whole) not in cache:
                    pts = slab_samples(arr, x)
                    cache[x, whole] = ((whole or layers_unseen(arr, x, views, margin))
                                       and not seen_in_front(pts, views))
                ok &= cache[x, whole]
            if ok:
                keep.append(o)
            else:
                rejected += 1
        if any(o.type != "none" for o in keep):
            out.append(Edge(e.a, e.b, tuple(keep), e.same_object, e.touching))
    return out, rejected


__all__ = ["Extension", "Option", "Edge", "apart", "apply_offsets", "offsets_of", "candidate_edges",
           "pair_edges", "support_edges", "prune_penetrating", "DepthView", "prune_by_visibility",
           "visible_free_fraction", "visible_free_mask", "seen_in_front", "slab_samples", "depth_noise",
           "is_support_id"]
