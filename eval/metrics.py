"""Scoring a predicted arrangement against ground truth (section 5 of the paper).

One job: say how close a predicted arrangement is to the truth.

* **Matching.**  Predicted cuboids map one-to-one to ground-truth cuboids through the
  scan's instance ids when the prediction carries them (``extra["instance"]``: the GT
  index + 1, or a GT cuboid id), restricted to the same ``object`` when the prediction's
  object names are ground-truth object names, and otherwise by exact 3D IoU of the
  oriented boxes with Hungarian assignment (:func:`scipy.optimize.linear_sum_assignment`).
  Whichever way a pair is proposed, **a match must overlap**: the two boxes need a 3D IoU
  of at least :data:`MIN_MATCH_IOU`.  A predicted box that names a part it does not
  overlap is unmatched: its contacts count as false positives and the part's as misses.
  Supports are nodes too: ``ground`` maps to ``ground``, walls map by normal and offset.
* **Contact graph.**  Precision, recall and F1 over typed edges (same pair, same type)
  and untyped edges (same pair).  The *initial* graph is every pair of initial cuboids
  (or cuboid and support) within 2 cm of each other, all labelled ``touch``
  (:func:`initial_graph`).
* **Size error.**  The paper's equations 5-6: per side ``e_i = |s_i - s_i^GT| / s_i^GT``;
  changes between the initial and optimized boxes larger than ``eps = 5 %`` are averaged,
  weighted by the true side length.
* **IoU** per matched cuboid (exact intersection of two oriented boxes).

All results are frozen dataclasses with ``to_json()``.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from pipeline.model import Arrangement, Cuboid, box_corners, is_support_id

#: A typed contact-graph edge: ``(a, b, type)`` with ``a <= b``.
Edge = tuple[str, str, str]

#: Smallest 3D IoU of any match, by instance id, object name or overlap alone.  A box
#: that names its part but lies elsewhere or has the wrong shape (a side panel fitted as
#: a 1 cm stick, IoU 0.02; a 2 cm panel deepened into a 70 cm cube, IoU 0.03; a 12 cm
#: cushion fitted as its 1 cm top skin, IoU 0.05) must not be credited with the part's
#: contacts.  Thin parts make IoU unforgiving: a board of thickness t with the right
#: extents but shifted by d across it keeps IoU (t - d) / (t + d), 0.1 at d = 0.82 t.
#: Measured on the Table 1 development views (seeds 1000-1003, pipeline at f87760e): of
#: 203 boxes of parts under 4 cm thick, 33 fall below 0.1; 31 of them have a side off by
#: more than a factor 1.6 (books seen edge-on fitted as sticks, panels, cushions), 2 have
#: the right extents but lie a thickness or more beside the part.  Intersection over the
#: smaller box would not do: a stick inside its panel scores 1.
MIN_MATCH_IOU = 0.1

#: The paper's noise threshold on a change of relative side error (equation 5).
SIZE_EPS = 0.05

#: Gap (metres) within which two initial cuboids count as touching in the initial graph:
#: about three standard deviations of Kinect depth noise at 2 m (Nguyen et al.).
INITIAL_GRAPH_GAP = 0.02

#: Support matching: largest angle between wall normals (degrees) and plane offset (m).
WALL_MAX_ANGLE_DEG = 20.0
WALL_MAX_OFFSET = 0.15

GraphSource = Literal["listed", "geometry", "union"]

# Corner k of ``box_corners`` has sign bits (x, y, z) = (k >> 2, k >> 1, k) & 1.
# The 12 edges join corners that differ in exactly one bit.
_EDGE_A, _EDGE_B = np.array(
    [(k, k | bit) for bit in (4, 2, 1) for k in range(8) if not k & bit], dtype=np.intp
).T
_PERMS = np.array(list(itertools.permutations(range(3))), dtype=np.intp)  # (6, 3)


# ============================================================================ IoU
def _nearest_rotations(R: np.ndarray) -> np.ndarray:
    """The rotations nearest ``R (M, 3, 3)`` (polar factor by SVD).

    The reader admits rotations orthonormal to ``ROTATION_TOL`` (1e-6).  The edge
    clipping below is exact only for exact rotations: a box whose rotation was off by
    1e-8 had IoU 0 with itself (each of its edges lies in two faces of the other box and
    fell just outside them).
    """
    u, _, vt = np.linalg.svd(R)
    return u @ vt
def _clip_edges(corners: np.ndarray, centers: np.ndarray, rotations: np.ndarray,
                half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Clip the 12 edges of boxes A against boxes B (Liang-Barsky, all pairs at once).

    Parameters
    ----------
    corners : (M, 8, 3) float
        Corners of the boxes A (world).
    centers, rotations, half : (M, 3), (M, 3, 3), (M, 3) float
        The boxes B: centre, local axes as columns, half extents.

    Returns
    -------
    points : (M, 24, 3) float
        The two end points of each clipped edge, in world coordinates.
    valid : (M, 24) bool
        Whether the edge meets B at all (both of its end points are then valid).
    """
    local = np.einsum("mij,mki->mkj", rotations, corners - centers[:, None, :])  # R^T (x - c)
    p0 = local[:, _EDGE_A]  # (M, 12, 3)
    d = local[:, _EDGE_B] - p0
    h = half[:, None, :] * (1.0 + 1e-12) + 1e-12
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (-h - p0) / d
        t2 = (h - p0) / d
    parallel = d == 0.0
    inside = np.abs(p0) <= h
    lo = np.where(parallel, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2))
    hi = np.where(parallel, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2))
    t_lo = np.maximum(lo.max(axis=2), 0.0)  # (M, 12)
    t_hi = np.minimum(hi.min(axis=2), 1.0)
    valid = t_lo <= t_hi
    t = np.stack([np.where(valid, t_lo, 0.0), np.where(valid, t_hi, 0.0)], axis=2)  # (M, 12, 2)
    pts_local = p0[:, :, None, :] + t[..., None] * d[:, :, None, :]  # (M, 12, 2, 3)
    pts = centers[:, None, None, :] + np.einsum("mij,mkej->mkei", rotations, pts_local)
    m = len(corners)
    return pts.reshape(m, 24, 3), np.repeat(valid, 2, axis=1)


def intersection_volumes(centers_a: np.ndarray, rotations_a: np.ndarray, sizes_a: np.ndarray,
                         centers_b: np.ndarray, rotations_b: np.ndarray,
                         sizes_b: np.ndarray) -> np.ndarray:
    """Exact volume of the intersection of paired oriented boxes.

    The intersection of two boxes is a convex polyhedron whose vertices are the
    corners of one box inside the other and the crossings of one box's edges with the
    other's faces: exactly the end points of each box's 12 edges clipped by the other
    box.  Those are computed for all pairs at once; the volume is their convex hull's.

    Parameters
    ----------
    centers_a, rotations_a, sizes_a : (M, 3), (M, 3, 3), (M, 3) float
        Boxes A (``sizes`` are full extents, rotation columns are local axes).
    centers_b, rotations_b, sizes_b : same shapes
        Boxes B, paired row by row with A.

    Returns
    -------
    volumes : (M,) float
        Intersection volumes in cubic metres (0 for boxes that only touch).
    """
    from scipy.spatial import ConvexHull, QhullError

    ca, ra, sa = (np.asarray(x, dtype=float) for x in (centers_a, rotations_a, sizes_a))
    cb, rb, sb = (np.asarray(x, dtype=float) for x in (centers_b, rotations_b, sizes_b))
    m = len(ca)
    out = np.zeros(m)
    if m == 0:
        return out
    ra, rb = _nearest_rotations(ra), _nearest_rotations(rb)
    pa, va = _clip_edges(box_corners(ca, ra, sa), cb, rb, sb / 2.0)
    pb, vb = _clip_edges(box_corners(cb, rb, sb), ca, ra, sa / 2.0)
    pts = np.concatenate([pa, pb], axis=1)  # (M, 48, 3)
    valid = np.concatenate([va, vb], axis=1)
    # Points are expressed relative to their mean and scaled, so qhull sees O(1) numbers.
    for i in np.flatnonzero(valid.sum(axis=1) >= 4):
        p = pts[i, valid[i]]
        mid = p.mean(axis=0)
        scale = float(np.abs(p - mid).max())
        if scale <= 0.0:
            continue
        try:
            out[i] = ConvexHull((p - mid) / scale).volume * scale**3
        except QhullError:  # flat or degenerate: the boxes only touch
            out[i] = 0.0
    return out


def pairwise_iou(centers_a: np.ndarray, rotations_a: np.ndarray, sizes_a: np.ndarray,
                 centers_b: np.ndarray, rotations_b: np.ndarray,
                 sizes_b: np.ndarray) -> np.ndarray:
    """3D IoU between every box of set A and every box of set B.

    Pairs whose bounding spheres are apart are 0 without computing an intersection.

    Parameters
    ----------
    centers_a, rotations_a, sizes_a : (Ka, 3), (Ka, 3, 3), (Ka, 3) float
    centers_b, rotations_b, sizes_b : (Kb, 3), (Kb, 3, 3), (Kb, 3) float

    Returns
    -------
    iou : (Ka, Kb) float in [0, 1]
    """
    ca, ra, sa = (np.asarray(x, dtype=float) for x in (centers_a, rotations_a, sizes_a))
    cb, rb, sb = (np.asarray(x, dtype=float) for x in (centers_b, rotations_b, sizes_b))
    ka, kb = len(ca), len(cb)
    iou = np.zeros((ka, kb))
    if ka == 0 or kb == 0:
        return iou
    rad_a = np.linalg.norm(sa, axis=1) / 2.0
    rad_b = np.linalg.norm(sb, axis=1) / 2.0
    dist = np.linalg.norm(ca[:, None, :] - cb[None, :, :], axis=2)
    ia, ib = np.nonzero(dist < rad_a[:, None] + rad_b[None, :])
    if len(ia) == 0:
        return iou
    inter = intersection_volumes(ca[ia], ra[ia], sa[ia], cb[ib], rb[ib], sb[ib])
    vol_a = np.prod(sa, axis=1)[ia]
    vol_b = np.prod(sb, axis=1)[ib]
    iou[ia, ib] = np.clip(inter / (vol_a + vol_b - inter), 0.0, 1.0)
    return iou


def box_iou(a: Cuboid, b: Cuboid) -> float:
    """Exact 3D IoU of two cuboids."""
    return float(pairwise_iou(a.center[None], a.rotation[None], a.size[None],
                              b.center[None], b.rotation[None], b.size[None])[0, 0])


# ============================================================================ matching
@dataclass(frozen=True)
class CuboidMatch:
    """A one-to-one map from predicted cuboids to ground-truth cuboids.

    Attributes
    ----------
    pairs : tuple of (pred_id, gt_id)
        Matched cuboids, in predicted order.
    iou : (len(pairs),) float
        IoU of each matched pair.
    how : tuple of str
        Per pair: ``"instance"`` (through the scan's instance id), ``"object"`` (by IoU
        among the cuboids of the same object) or ``"iou"``.
    unmatched_pred, unmatched_gt : tuple of str
        Ids left without a partner.
    """

    pairs: tuple[tuple[str, str], ...]
    iou: np.ndarray
    how: tuple[str, ...]
    unmatched_pred: tuple[str, ...]
    unmatched_gt: tuple[str, ...]

    @property
    def pred_to_gt(self) -> dict[str, str]:
        return dict(self.pairs)

    def to_json(self) -> dict:
        return {"pairs": [{"pred": p, "gt": g, "iou": float(v), "how": h}
                          for (p, g), v, h in zip(self.pairs, self.iou, self.how, strict=True)],
                "unmatched_pred": list(self.unmatched_pred),
                "unmatched_gt": list(self.unmatched_gt)}


def _instance_column(c: Cuboid, gt: Arrangement) -> int | None:
    """The GT row a predicted cuboid names through ``extra["instance"]``, if any."""
    inst = c.extra.get("instance")
    if isinstance(inst, bool):
        return None
    if isinstance(inst, int) and 1 <= inst <= len(gt.cuboids):
        return inst - 1
    if isinstance(inst, str) and inst in gt.index:
        return gt.index[inst]
    return None


def match_cuboids(pred: Arrangement, gt: Arrangement, *, min_iou: float = MIN_MATCH_IOU,
                  use_instances: bool = True) -> CuboidMatch:
    """Match predicted cuboids one-to-one to ground-truth cuboids.

    A predicted cuboid with an instance id (``extra["instance"]``) may only match that
    ground-truth cuboid; if several claim the same one, the one with the highest IoU
    wins.  When every predicted ``object`` name is a ground-truth object name (the
    pipeline names objects after the scan's instance mask), a cuboid may only match a
    cuboid of its object.  Everything else matches by IoU alone.  Every match, however
    proposed, needs an IoU of at least ``min_iou`` (:data:`MIN_MATCH_IOU`): a box that
    names a part it does not overlap stays unmatched.  The Hungarian assignment
    maximises total IoU.

    Returns
    -------
    CuboidMatch
    """
    from scipy.optimize import linear_sum_assignment

    kp, kg = len(pred.cuboids), len(gt.cuboids)
    iou = pairwise_iou(pred.centers, pred.rotations, pred.sizes,
                       gt.centers, gt.rotations, gt.sizes)
    allowed = iou >= min_iou
    gain = iou.copy()
    by_instance = np.zeros((kp, kg), dtype=bool)
    by_object = np.zeros(kp, dtype=bool)
    pred_objects = {c.object for c in pred.cuboids if c.object is not None}
    gt_objects = np.array([c.object for c in gt.cuboids], dtype=object)
    if pred_objects and pred_objects <= set(gt_objects.tolist()):
        for i, c in enumerate(pred.cuboids):
            if c.object is not None:
                allowed[i] = (gt_objects == c.object) & (iou[i] >= min_iou)
                by_object[i] = True
    if use_instances:
        for i, c in enumerate(pred.cuboids):
            col = _instance_column(c, gt)
            if col is not None:
                allowed[i] = False
                allowed[i, col] = iou[i, col] >= min_iou  # the named part, if it overlaps
                by_instance[i, col] = True
                gain[i, col] += 1.0  # an instance match beats any IoU match
    pairs: list[tuple[str, str]] = []
    values: list[float] = []
    how: list[str] = []
    if kp and kg:
        rows, cols = linear_sum_assignment(np.where(allowed, gain, -1.0), maximize=True)
        keep = allowed[rows, cols]
        rows, cols = rows[keep], cols[keep]
        order = np.argsort(rows)
        for r, c in zip(rows[order], cols[order], strict=True):
            pairs.append((pred.cuboids[r].id, gt.cuboids[c].id))
            values.append(float(iou[r, c]))
            how.append("instance" if by_instance[r, c] else "object" if by_object[r] else "iou")
    matched_p = {p for p, _ in pairs}
    matched_g = {g for _, g in pairs}
    return CuboidMatch(tuple(pairs), np.array(values, dtype=float), tuple(how),
                       tuple(i for i in pred.ids if i not in matched_p),
                       tuple(i for i in gt.ids if i not in matched_g))


def match_supports(pred: Arrangement, gt: Arrangement, *,
                   max_angle_deg: float = WALL_MAX_ANGLE_DEG,
                   max_offset: float = WALL_MAX_OFFSET) -> dict[str, str]:
    """Map predicted support ids to ground-truth support ids by plane.

    ``ground`` maps to ``ground``.  Walls match walls whose normals are within
    ``max_angle_deg`` and whose planes are within ``max_offset`` metres (the GT plane's
    point measured from the predicted plane), by Hungarian assignment on
    ``angle (rad) + offset (m)``.
    """
    from scipy.optimize import linear_sum_assignment

    out: dict[str, str] = {}
    if "ground" in pred.support_ids and "ground" in gt.support_ids:
        out["ground"] = "ground"
    pw = [s for s in pred.supports if s.id != "ground"]
    gw = [s for s in gt.supports if s.id != "ground"]
    if not pw or not gw:
        return out
    pn = np.array([s.normal for s in pw])
    pp = np.array([s.point for s in pw])
    gn = np.array([s.normal for s in gw])
    gp = np.array([s.point for s in gw])
    angle = np.arccos(np.clip(pn @ gn.T, -1.0, 1.0))  # (P, G)
    offset = np.abs(np.einsum("pk,pgk->pg", pn, gp[None, :, :] - pp[:, None, :]))
    ok = (angle <= math.radians(max_angle_deg)) & (offset <= max_offset)
    cost = np.where(ok, angle + offset, 1e6)
    rows, cols = linear_sum_assignment(cost)
    for r, c in zip(rows, cols, strict=True):
        if ok[r, c]:
            out[pw[r].id] = gw[c].id
    return out


# ============================================================================ graphs
def _edge(a: str, b: str, kind: str) -> Edge:
    return (a, b, kind) if a <= b else (b, a, kind)


def listed_graph(arr: Arrangement) -> frozenset[Edge]:
    """The contacts listed in the arrangement, as typed edges."""
    return frozenset(_edge(c.a, c.b, c.type) for c in arr.contacts)


def _touching_pairs(arr: Arrangement) -> list[tuple[str, str]]:
    from pipeline.contacts import find_contacts

    return [tuple(p) for p in find_contacts(arr).pairs]


def geometric_graph(arr: Arrangement) -> frozenset[Edge]:
    """Every touching pair (boxes and supports, by geometry), ``fixed`` where listed fixed."""
    fixed = arr.fixed_pairs()
    edges = set()
    for a, b in _touching_pairs(arr):
        e = _edge(a, b, "touch")
        edges.add(_edge(a, b, "fixed") if (e[0], e[1]) in fixed else e)
    return frozenset(edges)


def contact_graph(arr: Arrangement, source: GraphSource = "union") -> frozenset[Edge]:
    """The contact graph of an arrangement.

    ``listed``: the contacts in the file.  ``geometry``: the touching pairs found by
    :func:`pipeline.contacts.find_contacts`, typed by the listed ``fixed`` contacts.
    ``union``: both (a pair in both keeps the listed type).
    """
    if source == "listed":
        return listed_graph(arr)
    if source == "geometry":
        return geometric_graph(arr)
    if source != "union":
        raise ValueError(f"source: expected 'listed', 'geometry' or 'union', got {source!r}")
    listed = listed_graph(arr)
    listed_pairs = {(a, b) for a, b, _ in listed}
    return listed | frozenset(e for e in geometric_graph(arr) if (e[0], e[1]) not in listed_pairs)


def initial_graph(arr: Arrangement, gap: float = INITIAL_GRAPH_GAP) -> frozenset[Edge]:
    """The paper's initial graph: every pair among ``arr``'s cuboids (and supports) that
    touch, overlap or come within ``gap`` metres of each other, all ``touch``.

    Boxes fitted to noisy, partial points never quite touch, so the contacts of the
    initial cuboids are taken with the sensor's tolerance: every box grows by ``gap``
    (half on each side) and every support plane moves ``gap / 2`` towards the boxes.
    """
    from dataclasses import replace

    grown = arr.with_(cuboids=tuple(c.with_(size=c.size + gap) for c in arr.cuboids),
                      supports=tuple(replace(s, point=np.asarray(s.point) + 0.5 * gap *
                                             np.asarray(s.normal)) for s in arr.supports),
                      contacts=(), stability=None)
    from pipeline.contacts import find_contacts

    cs = find_contacts(grown, rel_tol=0.0)  # the gap is the tolerance
    pairs = {tuple(p) for p in cs.pairs} | {(a, b) for a, b, _ in cs.penetrations}
    return frozenset(_edge(a, b, "touch") for a, b in pairs)


def initial_arrangement(arr: Arrangement) -> Arrangement:
    """The initial cuboids of a predicted arrangement: each box as observed, before extension.

    A cuboid with an ``observed`` record is replaced by it (same rotation); a cuboid
    marked ``extra["hallucinated"]`` did not exist initially and is dropped; the others
    were not changed.  Contacts are cleared (the initial graph is all ``touch``).
    """
    cuboids = []
    for c in arr.cuboids:
        if c.extra.get("hallucinated"):
            continue
        if c.observed is not None:
            c = c.with_(center=c.observed.center, size=c.observed.size, observed=None)
        cuboids.append(c)
    return arr.with_(cuboids=tuple(cuboids), contacts=(), stability=None)


@dataclass(frozen=True)
class PRF:
    """Counts behind precision, recall and F1 (fractions in [0, 1]; the paper prints %)."""

    tp: int
    n_pred: int
    n_gt: int

    @property
    def precision(self) -> float:
        if self.n_pred:
            return self.tp / self.n_pred
        return 1.0 if self.n_gt == 0 else 0.0

    @property
    def recall(self) -> float:
        if self.n_gt:
            return self.tp / self.n_gt
        return 1.0 if self.n_pred == 0 else 0.0

    @property
    def f1(self) -> float:
        p, r = self.precision, self.recall
        return 0.0 if p + r == 0 else 2.0 * p * r / (p + r)

    def __add__(self, other: PRF) -> PRF:
        return PRF(self.tp + other.tp, self.n_pred + other.n_pred, self.n_gt + other.n_gt)

    def to_json(self) -> dict:
        return {"precision": self.precision, "recall": self.recall, "f1": self.f1,
                "tp": self.tp, "n_pred": self.n_pred, "n_gt": self.n_gt}


@dataclass(frozen=True)
class GraphScore:
    """Typed and untyped scores of one predicted graph, with the edges that were wrong.

    ``false_positives``/``false_negatives`` are typed edges in ground-truth names
    (an unmatched predicted cuboid ``b7`` appears as ``?b7``).
    """

    typed: PRF
    untyped: PRF
    false_positives: tuple[Edge, ...] = ()
    false_negatives: tuple[Edge, ...] = ()

    def to_json(self) -> dict:
        return {"typed": self.typed.to_json(), "untyped": self.untyped.to_json(),
                "false_positives": [list(e) for e in self.false_positives],
                "false_negatives": [list(e) for e in self.false_negatives]}


def compare_graphs(pred_edges: Iterable[Edge], gt_edges: Iterable[Edge],
                   mapping: Mapping[str, str]) -> GraphScore:
    """Score predicted edges against ground-truth edges.

    Parameters
    ----------
    pred_edges, gt_edges : iterables of (a, b, type)
    mapping : predicted node id -> ground-truth node id (cuboids and supports).  Nodes
        without a partner never match anything.
    """
    mapped = frozenset(_edge(mapping.get(a, "?" + a), mapping.get(b, "?" + b), t)
                       for a, b, t in pred_edges)
    gt = frozenset(_edge(a, b, t) for a, b, t in gt_edges)
    mapped_pairs = {(a, b) for a, b, _ in mapped}
    gt_pairs = {(a, b) for a, b, _ in gt}
    typed = PRF(len(mapped & gt), len(mapped), len(gt))
    untyped = PRF(len(mapped_pairs & gt_pairs), len(mapped_pairs), len(gt_pairs))
    return GraphScore(typed, untyped, tuple(sorted(mapped - gt)), tuple(sorted(gt - mapped)))


@dataclass(frozen=True)
class Valence:
    """Table 3's graph statistics: proxies, contacts and per-proxy valence.

    ``valence`` of a cuboid is its number of edges (to cuboids and to supports);
    supports are not proxies and get no valence of their own.
    """

    n_proxies: int
    n_contacts: int
    n_support_contacts: int
    max: int
    median: float
    mean: float
    min: int

    def to_json(self) -> dict:
        return {"proxies": self.n_proxies, "contacts": self.n_contacts,
                "support_contacts": self.n_support_contacts, "max_valence": self.max,
                "median_valence": self.median, "mean_valence": self.mean,
                "min_valence": self.min}


def valence_stats(edges: Iterable[Edge], cuboid_ids: Iterable[str]) -> Valence:
    """Valence statistics of a contact graph over the given cuboids (Table 3 of the paper)."""
    ids = list(cuboid_ids)
    row = {name: k for k, name in enumerate(ids)}
    pairs = {_edge(a, b, t)[:2] for a, b, t in edges}
    ends = np.array([row[n] for p in pairs for n in p if n in row], dtype=np.intp)
    deg = np.bincount(ends, minlength=len(ids))
    n_sup = sum(1 for a, b in pairs if is_support_id(a) or is_support_id(b))
    if not len(ids):
        return Valence(0, len(pairs), n_sup, 0, 0.0, 0.0, 0)
    return Valence(len(ids), len(pairs), n_sup, int(deg.max()), float(np.median(deg)),
                   float(deg.mean()), int(deg.min()))


# ============================================================================ sizes
def align_axes(pred_rotations: np.ndarray, gt_rotations: np.ndarray) -> np.ndarray:
    """Which predicted local axis corresponds to each ground-truth local axis.

    Parameters
    ----------
    pred_rotations, gt_rotations : (M, 3, 3) float

    Returns
    -------
    perm : (M, 3) int
        ``perm[m, i]`` is the predicted axis most parallel to GT axis ``i`` (the
        permutation maximising the summed ``|cos|``).
    """
    cos = np.abs(np.einsum("mki,mkj->mij", gt_rotations, pred_rotations))  # (M, 3, 3)
    scores = cos[:, np.arange(3)[None, :], _PERMS].sum(axis=2)  # (M, 6)
    return _PERMS[np.argmax(scores, axis=1)]


def relative_size_errors(pred_sizes: np.ndarray, pred_rotations: np.ndarray,
                         gt_sizes: np.ndarray, gt_rotations: np.ndarray) -> np.ndarray:
    """Equation 5's ``e_i = |s_i - s_i^GT| / s_i^GT`` for matched boxes.

    Parameters
    ----------
    pred_sizes, gt_sizes : (M, 3) float
    pred_rotations, gt_rotations : (M, 3, 3) float

    Returns
    -------
    e : (M, 3) float, in the ground-truth axis order
    """
    perm = align_axes(np.asarray(pred_rotations, float), np.asarray(gt_rotations, float))
    s = np.take_along_axis(np.asarray(pred_sizes, float), perm, axis=1)
    g = np.asarray(gt_sizes, float)
    return np.abs(s - g) / g


@dataclass(frozen=True)
class SizeError:
    """The paper's size error (equations 5-6) and plain mean relative errors.

    Attributes
    ----------
    error : float
        Equation 6: ``sum c_i |e_i^init - e_i^opt| / sum c_i`` over all sides of all
        matched boxes, ``c_i = s_i^GT`` where the change exceeds ``eps`` else 0
        (0 when no side changed by more than ``eps``).
    improvement : float
        The same weighted mean of the signed ``e_i^init - e_i^opt`` (> 0: optimization
        brought the sides closer to the truth).
    n_changed : int
        Sides whose change exceeded ``eps``.
    mean_init, mean_opt : float
        ``sum s^GT e / sum s^GT`` over all sides, before and after.
    """

    error: float
    improvement: float
    n_changed: int
    mean_init: float
    mean_opt: float

    def to_json(self) -> dict:
        return {"error": self.error, "improvement": self.improvement,
                "n_changed": self.n_changed, "mean_init": self.mean_init,
                "mean_opt": self.mean_opt}


def paper_size_error(e_init: np.ndarray, e_opt: np.ndarray, gt_sizes: np.ndarray,
                     eps: float = SIZE_EPS) -> SizeError:
    """Equations 5-6 of the paper from per-side relative errors.

    Parameters
    ----------
    e_init, e_opt : (M, 3) float
        Relative side errors of the initial and optimized boxes (:func:`relative_size_errors`).
    gt_sizes : (M, 3) float
        True side lengths (the weights), same axis order.
    eps : float
        Changes of at most ``eps`` are attributed to sensor noise and ignored.
    """
    e_init, e_opt, g = (np.asarray(x, float).reshape(-1, 3) for x in (e_init, e_opt, gt_sizes))
    delta = e_init - e_opt
    c = np.where(np.abs(delta) > eps, g, 0.0)
    total = float(c.sum())
    gsum = float(g.sum())
    return SizeError(
        error=float((c * np.abs(delta)).sum() / total) if total > 0 else 0.0,
        improvement=float((c * delta).sum() / total) if total > 0 else 0.0,
        n_changed=int(np.count_nonzero(c)),
        mean_init=float((g * e_init).sum() / gsum) if gsum > 0 else 0.0,
        mean_opt=float((g * e_opt).sum() / gsum) if gsum > 0 else 0.0,
    )


# ============================================================================ score
@dataclass(frozen=True)
class Score:
    """Everything :func:`score_arrangement` measures.

    ``initial`` and ``size`` are ``None`` when there are no initial cuboids to compare.
    ``iou`` / ``iou_initial`` are per matched pair (``matching.pairs`` order).
    ``side_abs`` / ``side_len``: over every side of every matched (optimized) box, the
    summed absolute error ``|s - s^GT|`` and the summed true length (metres), so that
    scenes pool by adding them (:attr:`side_error`).
    """

    matching: CuboidMatch
    supports: dict[str, str]
    optimized: GraphScore
    initial: GraphScore | None
    iou: np.ndarray
    iou_initial: np.ndarray | None
    size: SizeError | None
    graph_source: str
    n_pred: int
    n_gt: int
    notes: tuple[str, ...] = field(default=())
    side_abs: float = 0.0
    side_len: float = 0.0

    @property
    def mean_iou(self) -> float:
        """Mean IoU over ground-truth cuboids (an unmatched one counts 0; NaN when the
        truth has none: nothing to overlap, not a perfect score)."""
        return float(self.iou.sum() / self.n_gt) if self.n_gt else float("nan")

    @property
    def matched_iou(self) -> float:
        """Mean IoU of the matched pairs (NaN when nothing matched)."""
        return float(self.iou.mean()) if len(self.iou) else float("nan")

    @property
    def side_error(self) -> float:
        """Relative side error of the matched boxes: ``sum |s - s^GT| / sum s^GT`` over
        all their sides (the paper's ``e_i`` weighted by true length; NaN when none)."""
        return self.side_abs / self.side_len if self.side_len > 0 else float("nan")

    def to_json(self) -> dict:
        def opt(x):
            return None if x is None else x.to_json()

        per = []
        for k, (p, g) in enumerate(self.matching.pairs):
            row = {"pred": p, "gt": g, "iou": float(self.iou[k]), "how": self.matching.how[k]}
            if self.iou_initial is not None:
                row["iou_initial"] = float(self.iou_initial[k])
            per.append(row)
        return {"n_pred": self.n_pred, "n_gt": self.n_gt, "graph_source": self.graph_source,
                "optimized": self.optimized.to_json(), "initial": opt(self.initial),
                "mean_iou": _finite(self.mean_iou), "matched_iou": _finite(self.matched_iou),
                "side_error": _finite(self.side_error), "size": opt(self.size), "cuboids": per,
                "unmatched_pred": list(self.matching.unmatched_pred),
                "unmatched_gt": list(self.matching.unmatched_gt),
                "supports": dict(self.supports), "notes": list(self.notes)}


def score_arrangement(pred: Arrangement, gt: Arrangement, *,
                      initial: Arrangement | None = None,
                      graph: GraphSource = "union", min_iou: float = MIN_MATCH_IOU,
                      eps: float = SIZE_EPS) -> Score:
    """Score a predicted (optimized) arrangement against the ground truth.

    Parameters
    ----------
    pred : the prediction (its ``observed`` boxes are the initial cuboids unless
        ``initial`` is given).
    gt : the ground truth (``scene.json``).
    initial : optional explicit initial arrangement; it is matched to the truth on its own.
    graph : which edges make an arrangement's graph (:func:`contact_graph`).  When
        :mod:`pipeline.contacts` is not available, ``listed`` is used and a note says so.
    """
    notes: list[str] = []
    try:
        pred_edges = contact_graph(pred, graph)
        gt_edges = contact_graph(gt, graph)
        source = graph
    except ImportError:
        pred_edges, gt_edges, source = listed_graph(pred), listed_graph(gt), "listed"
        notes.append("pipeline.contacts not available: graphs are the listed contacts")
    match = match_cuboids(pred, gt, min_iou=min_iou)
    supports = match_supports(pred, gt)
    mapping = {**match.pred_to_gt, **supports}
    optimized = compare_graphs(pred_edges, gt_edges, mapping)

    explicit = initial is not None
    has_initial = explicit or any(c.observed is not None or c.extra.get("hallucinated")
                                  for c in pred.cuboids)
    init_score = iou_init = size = None
    if has_initial:
        init_arr = initial if explicit else initial_arrangement(pred)
        init_match = (match_cuboids(init_arr, gt, min_iou=min_iou) if explicit else
                      _restrict(match, init_arr, gt))
        try:
            init_edges = initial_graph(init_arr)
            init_score = compare_graphs(init_edges, gt_edges,
                                        {**init_match.pred_to_gt, **match_supports(init_arr, gt)})
        except ImportError:
            notes.append("pipeline.contacts not available: no initial graph")
        iou_init, size = _initial_boxes(match, init_arr, init_match, pred, gt, eps)
    side_abs, side_len = matched_side_errors(pred, gt, match)
    return Score(match, supports, optimized, init_score, match.iou, iou_init, size, source,
                 len(pred.cuboids), len(gt.cuboids), tuple(notes), side_abs, side_len)


def matched_side_errors(pred: Arrangement, gt: Arrangement, match: CuboidMatch
                        ) -> tuple[float, float]:
    """``(sum |s - s^GT|, sum s^GT)`` over the three sides of every matched pair (metres),
    sides paired by axis direction (:func:`relative_size_errors`)."""
    if not match.pairs:
        return 0.0, 0.0
    ip = np.array([pred.index[p] for p, _ in match.pairs], dtype=np.intp)
    ig = np.array([gt.index[g] for _, g in match.pairs], dtype=np.intp)
    e = relative_size_errors(pred.sizes[ip], pred.rotations[ip], gt.sizes[ig], gt.rotations[ig])
    g = gt.sizes[ig]
    return float((e * g).sum()), float(g.sum())


def _finite(x: float) -> float | None:
    """``x``, or None for NaN (JSON has no NaN)."""
    return None if x != x else float(x)


def _restrict(match: CuboidMatch, init_arr: Arrangement, gt: Arrangement) -> CuboidMatch:
    """The optimized matching, kept for the cuboids present initially (same ids)."""
    keep = [k for k, (p, _) in enumerate(match.pairs) if p in init_arr.index]
    pairs = tuple(match.pairs[k] for k in keep)
    matched_g = {g for _, g in pairs}
    matched_p = {p for p, _ in pairs}
    return CuboidMatch(pairs, match.iou[keep], tuple(match.how[k] for k in keep),
                       tuple(i for i in init_arr.ids if i not in matched_p),
                       tuple(i for i in gt.ids if i not in matched_g))


def _initial_boxes(match: CuboidMatch, init_arr: Arrangement, init_match: CuboidMatch,
                   pred: Arrangement, gt: Arrangement,
                   eps: float) -> tuple[np.ndarray, SizeError | None]:
    """IoU of each optimized pair's initial box, and the size error over GT boxes matched in both."""
    gt_to_init = {g: p for p, g in init_match.pairs}
    rows = [(pred.index[p], init_arr.index[gt_to_init[g]], gt.index[g])
            for p, g in match.pairs if g in gt_to_init]
    iou_init = np.zeros(len(match.pairs))
    if not rows:
        return iou_init, None
    ip, ii, ig = (np.array(x, dtype=np.intp) for x in zip(*rows, strict=True))
    both = np.array([g in gt_to_init for _, g in match.pairs])
    iou_init[both] = _paired_iou(init_arr, ii, gt, ig)
    e_opt = relative_size_errors(pred.sizes[ip], pred.rotations[ip], gt.sizes[ig], gt.rotations[ig])
    e_init = relative_size_errors(init_arr.sizes[ii], init_arr.rotations[ii], gt.sizes[ig],
                                  gt.rotations[ig])
    return iou_init, paper_size_error(e_init, e_opt, gt.sizes[ig], eps)


def _paired_iou(a: Arrangement, ia: np.ndarray, b: Arrangement, ib: np.ndarray) -> np.ndarray:
    """IoU of box ``a[ia[k]]`` with box ``b[ib[k]]`` for each k."""
    inter = intersection_volumes(a.centers[ia], a.rotations[ia], a.sizes[ia],
                                 b.centers[ib], b.rotations[ib], b.sizes[ib])
    va = np.prod(a.sizes[ia], axis=1)
    vb = np.prod(b.sizes[ib], axis=1)
    return np.clip(inter / (va + vb - inter), 0.0, 1.0)
