"""Structure-guided completion: a good scan of an object fills in a partial scan of one
of the same kind (section 6 (i) of the paper).

Evidence read: the cuboids of both objects (their arrangements from :func:`pipeline.run.
run_scan`), their points, the floor of each scan, and the partial scan's depth views.
Assumed about the world: both objects stand on their floor, upright, and are built of
corresponding parts whose sizes differ by the object's proportions, not its kind.

Steps (:func:`complete`):

1. **Matching** (:func:`spectral_match`, Leordeanu and Hebert 2005).  A candidate
   assignment ``a = (i, j)`` pairs template part ``i`` with partial part ``j``; it is
   pruned, as the paper does, when its height difference exceeds
   ``height_tol`` (0.05 m) *and* its horizontal length difference exceeds
   ``length_tol`` (0.1 m).  The affinity matrix ``M`` holds on its diagonal the
   agreement of the two parts' dimensions (log sizes, and sizes and heights relative to
   their object), off the diagonal the agreement of the pairwise geometry of two
   assignments ``a = (i, j)``, ``b = (k, l)``: the vertical offset and horizontal distance
   of part ``k`` from part ``i`` against those of ``l`` from ``j``, each relative to its
   object; assignments that share a part conflict (``M_ab = 0``).  The principal
   eigenvector ``x`` of ``M`` (power iteration) maximises ``x^T M x`` over ``|x| = 1``;
   it is discretised greedily: accept the largest ``x_a``, drop every assignment that
   shares a part with it, repeat while ``x_a`` is above a fraction of the largest.
2. **Ground-edge alignment** (:func:`edge_alignments`, :func:`align`).  Each horizontal
   footprint edge of a template cuboid against each footprint edge (both ways round) of a
   partial cuboid gives a rigid transform: the rotation about z turning one edge into
   the other, the translation carrying one projected midpoint onto the other, and the
   floor offset along z (of the objects' lowest points when one does not stand on its
   floor, :func:`level_offset`).  The paper pairs the matched cuboids only; here every
   pair is tried, as one view often shows too few parts for the matching to be right.
   Kept: of the poses nearest the partial points, the one whose transfer (steps 4-5 in
   that pose) explains the partial scan best, by the score that chooses the transfer.
3. **ICP** (Open3D point-to-plane): the partial points registered to the template
   points from that start, projected back to an upright transform (a yaw, a horizontal
   shift, the floor offset): both objects stand on their floors.
4. **Matching again, aligned** (:func:`refine_matching`): with the template in place,
   the parts are paired anew by their places in their objects' boxes and their
   dimensions (Hungarian), which tells an object from its mirror image, as distances
   between parts cannot.
5. **Transfer** (:func:`transfer`).  ``rigid``: the template points moved by the
   transform (the paper).  ``parts``: each template point of a matched part is carried
   from its part's box into the matched partial box (box coordinates scaled by the ratio
   of the box sizes, axes paired by the rigid transform), so a template of other
   proportions still lands on the partial object's parts; points of unmatched parts
   move by the affine map fitted to the matched boxes' corners.  ``auto`` (the default)
   does both and keeps the one whose points lie nearer the partial scan's points and
   less in space it saw empty (:func:`transfer_score`): the parts transfer trusts the
   partial scan's boxes, which a poor view can get wrong.  Transferred points that the partial scan's depth views saw through
   (:meth:`pipeline.evidence.Evidence.free_mask`) are removed (``carve``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .boxops import flat_axes_xy, footprints
from .model import Arrangement, Cuboid

#: Power iteration: at most this many steps, stopping when the vector moves less than
#: :data:`POWER_TOL` (Euclidean norm of the change of a unit vector).
POWER_ITERATIONS = 200
POWER_TOL = 1e-10
#: The greedy discretisation stops at assignments whose eigenvector entry is below this
#: fraction of the largest.
ACCEPT_REL = 0.05
#: Template points are thinned to one per cube of this edge (metres) before alignment.
TEMPLATE_VOXEL = 0.005
#: An object whose lowest part is this close to its floor stands on it (metres).
ON_FLOOR = 0.05
#: Most partial points used to score a candidate alignment ...
SCORE_POINTS = 3000
#: ... and most template points carried over to judge it (:func:`align`).
ALIGN_TEMPLATE_POINTS = 5000
#: Candidate alignments are ranked on about this many partial points; the best
#: :data:`KEEP_ALIGNMENTS` are judged by their transfers.
COARSE_POINTS, KEEP_ALIGNMENTS = 300, 16
#: Candidate poses closer than this in yaw (radians) and shift (metres) are one pose.
SAME_YAW, SAME_SHIFT = 1e-3, 1e-3
#: After alignment, a pair of parts costs the distance of their centres in their objects'
#: boxes scaled to unit cubes plus this times the distance of their log dimensions ...
LOG_WEIGHT = 0.15
#: ... and pairs costing more than this are not matched.
REMATCH_GATE = 0.5
TRANSFERS = ("auto", "parts", "rigid")
EDGE_PAIRS = ("all", "matched")


@dataclass(frozen=True)
class CompleteConfig:
    """Parameters of :func:`complete` (lengths in metres).

    Attributes
    ----------
    height_tol, length_tol : float
        The paper's pruning: a candidate pair of parts whose heights differ by more than
        ``height_tol`` and whose horizontal lengths differ by more than ``length_tol``.
    sigma_log : float
        Scale of the dimension agreement on log sizes (0.5: a factor 1.65 costs e^-0.5).
    sigma_rel : float
        Scale of agreement of sizes, heights and offsets relative to the object.
    score_cap : float
        Distances above this count as this much when an alignment is scored.
    icp_distance : float
        ICP's largest correspondence distance.
    icp_iterations : int
    transfer : {"auto", "parts", "rigid"}
        ``auto``: both, keeping the one that explains the partial scan better
        (:func:`transfer_score`).
    carve : bool
        Remove transferred points the partial scan saw through.
    edge_pairs : {"all", "matched"}
        Candidate alignments from every pair of parts, or the matched ones (the paper).
    """

    height_tol: float = 0.05
    length_tol: float = 0.10
    sigma_log: float = 0.5
    sigma_rel: float = 0.15
    score_cap: float = 0.10
    icp_distance: float = 0.05
    icp_iterations: int = 60
    transfer: str = "auto"
    carve: bool = True
    edge_pairs: str = "all"

    def __post_init__(self) -> None:
        for name in ("height_tol", "length_tol", "sigma_log", "sigma_rel", "score_cap",
                     "icp_distance"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name}: must be a positive number of metres, got {v}")
        if int(self.icp_iterations) < 0:
            raise ValueError(f"icp_iterations: must be >= 0, got {self.icp_iterations}")
        if self.transfer not in TRANSFERS:
            raise ValueError(f"transfer: must be one of {TRANSFERS}, got {self.transfer!r}")
        if self.edge_pairs not in EDGE_PAIRS:
            raise ValueError(f"edge_pairs: must be one of {EDGE_PAIRS}, got {self.edge_pairs!r}")


# ------------------------------------------------------------------------------ parts
@dataclass(frozen=True)
class Parts:
    """An object's cuboids as upright part descriptors (struct of arrays).

    Attributes
    ----------
    ids : tuple of str
        Cuboid ids.
    centers : (K, 3) float
    rotations : (K, 3, 3) float
    sizes : (K, 3) float
    height : (K,) float
        Vertical extent of each box.
    length, width : (K,) float
        Longer and shorter horizontal edge (the two local axes nearest horizontal).
    bottom : (K,) float
        Lowest z of each box.
    """

    ids: tuple[str, ...]
    centers: np.ndarray
    rotations: np.ndarray
    sizes: np.ndarray
    height: np.ndarray
    length: np.ndarray
    width: np.ndarray
    bottom: np.ndarray

    def __len__(self) -> int:
        return len(self.ids)

    @property
    def object_height(self) -> float:
        """Top of the highest part above the lowest bottom (metres, at least 1 mm)."""
        return max(float((self.bottom + self.height).max() - self.bottom.min()), 1e-3)

    @property
    def object_span(self) -> float:
        """Horizontal diameter of the parts' footprints (metres, at least 1 mm)."""
        fp = footprints(self.centers, self.rotations, self.sizes).reshape(-1, 2)
        return max(float(np.linalg.norm(fp.max(0) - fp.min(0))), 1e-3)


def parts_of(cuboids: tuple[Cuboid, ...] | list[Cuboid]) -> Parts:
    """:class:`Parts` of ``cuboids``."""
    if not cuboids:
        raise ValueError("parts_of: no cuboids")
    C = np.array([c.center for c in cuboids], float)
    R = np.array([c.rotation for c in cuboids], float)
    S = np.array([c.size for c in cuboids], float)
    height = np.einsum("kj,kj->k", np.abs(R[:, 2, :]), S)
    up_axis = np.argmax(np.abs(R[:, 2, :]), axis=1)
    mask = np.ones_like(S, bool)
    mask[np.arange(len(S)), up_axis] = False
    horiz = S[mask].reshape(-1, 2)
    return Parts(tuple(c.id for c in cuboids), C, R, S, height, horiz.max(1), horiz.min(1),
                 C[:, 2] - height / 2)


# --------------------------------------------------------------------------- matching
@dataclass(frozen=True)
class Matching:
    """What :func:`spectral_match` found.

    Attributes
    ----------
    pairs : tuple of (int, int)
        (template part index, partial part index), in the order accepted.
    confidence : tuple of float
        The eigenvector entry of each accepted pair (relative to the largest entry).
    candidates : int
        Assignments left after pruning.
    pruned : int
        Assignments the height/length rule removed.
    """

    pairs: tuple[tuple[int, int], ...]
    confidence: tuple[float, ...]
    candidates: int
    pruned: int


def spectral_match(a: Parts, b: Parts, config: CompleteConfig | None = None) -> Matching:
    """Match the parts of ``a`` (template) to those of ``b`` (partial), one to one.

    Notes
    -----
    Leordeanu and Hebert (2005): with ``M`` the non-negative symmetric affinity over the
    candidate assignments ``L``, find ``x* = argmax x^T M x`` subject to ``|x| = 1``,
    the principal eigenvector of ``M``, then impose the one-to-one constraints greedily.
    Unary terms (``M_aa`` for ``a = (i, j)``)::

        exp(-|log s_i - log s_j|^2 / (2 sigma_log^2) - |r_i - r_j|^2 / (2 sigma_rel^2))

    with ``s = (height, length, width)`` and ``r = (height / H, length / D, width / D,
    bottom / H)`` relative to the object's height ``H`` and horizontal span ``D``.
    Pairwise terms (``a = (i, j)``, ``b = (k, l)``, ``i != k``, ``j != l``)::

        exp(-((dz_ik - dz_jl)^2 + (dh_ik - dh_jl)^2) / (2 sigma_rel^2))

    with ``dz`` the vertical offset of the centres over ``H`` and ``dh`` their horizontal
    distance over ``D``; ``M_ab = 0`` when the assignments share a part.
    """
    cfg = config or CompleteConfig()
    na, nb = len(a), len(b)
    if na == 0 or nb == 0:
        return Matching((), (), 0, 0)
    I, J = np.meshgrid(np.arange(na), np.arange(nb), indexing="ij")
    I, J = I.ravel(), J.ravel()
    dh = np.abs(a.height[I] - b.height[J])
    dl = np.abs(a.length[I] - b.length[J])
    keep = ~((dh > cfg.height_tol) & (dl > cfg.length_tol))
    pruned = int((~keep).sum())
    I, J = I[keep], J[keep]
    if not len(I):
        return Matching((), (), 0, pruned)

    def rel(p: Parts) -> tuple[np.ndarray, np.ndarray]:
        H, D = p.object_height, p.object_span
        logs = np.log(np.maximum(np.stack([p.height, p.length, p.width], 1), 1e-4))
        r = np.stack([p.height / H, p.length / D, p.width / D,
                      (p.bottom - p.bottom.min()) / H], 1)
        return logs, r

    la, ra = rel(a)
    lb, rb = rel(b)
    unary = np.exp(-((la[I] - lb[J]) ** 2).sum(1) / (2 * cfg.sigma_log ** 2)
                   - ((ra[I] - rb[J]) ** 2).sum(1) / (2 * cfg.sigma_rel ** 2))

    def offsets(p: Parts) -> tuple[np.ndarray, np.ndarray]:
        c = p.centers
        dz = (c[None, :, 2] - c[:, None, 2]) / p.object_height
        dxy = np.linalg.norm(c[None, :, :2] - c[:, None, :2], axis=2) / p.object_span
        return dz, dxy

    za, ha = offsets(a)
    zb, hb = offsets(b)
    pair = np.exp(-((za[I[:, None], I[None, :]] - zb[J[:, None], J[None, :]]) ** 2
                    + (ha[I[:, None], I[None, :]] - hb[J[:, None], J[None, :]]) ** 2)
                  / (2 * cfg.sigma_rel ** 2))
    conflict = (I[:, None] == I[None, :]) | (J[:, None] == J[None, :])
    M = np.where(conflict, 0.0, pair)
    M[np.diag_indices_from(M)] = unary
    x = principal_eigenvector(M)
    top = float(x.max())
    order = np.argsort(-x, kind="stable")
    used_a, used_b = np.zeros(na, bool), np.zeros(nb, bool)
    pairs, conf = [], []
    for c in order:
        if top <= 0 or x[c] < ACCEPT_REL * top:
            break
        i, j = int(I[c]), int(J[c])
        if used_a[i] or used_b[j]:
            continue
        used_a[i] = used_b[j] = True
        pairs.append((i, j))
        conf.append(float(x[c] / top))
    return Matching(tuple(pairs), tuple(conf), int(len(I)), pruned)


def principal_eigenvector(M: np.ndarray, iterations: int = POWER_ITERATIONS) -> np.ndarray:
    """The unit principal eigenvector of a non-negative symmetric ``M (n, n)`` by power
    iteration from the uniform vector (entries >= 0 by Perron-Frobenius)."""
    n = len(M)
    x = np.full(n, 1.0 / np.sqrt(max(n, 1)))
    for _ in range(iterations):
        y = M @ x
        norm = float(np.linalg.norm(y))
        if norm == 0.0:
            return x
        y /= norm
        if float(np.linalg.norm(y - x)) < POWER_TOL:
            return y
        x = y
    return x


# -------------------------------------------------------------------------- alignment
def upright_transform(yaw: float, t: np.ndarray) -> np.ndarray:
    """(4, 4) rotation by ``yaw`` about z then translation ``t (3,)``."""
    c, s = np.cos(yaw), np.sin(yaw)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:3, 3] = np.asarray(t, float)
    return T


def subsample(points: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``points`` when there are at most ``n``, else ``n`` of them drawn by ``rng`` (in order)."""
    if len(points) <= n:
        return points
    return points[np.sort(rng.choice(len(points), n, replace=False))]


def edge_alignments(a: Parts, b: Parts, pairs, dz: float) -> np.ndarray:
    """Every candidate transform (template -> partial) from matched ground edges.

    For each matched pair ``(i, j)``, each footprint edge ``e`` of template box ``i`` and
    each footprint edge ``f`` of partial box ``j`` taken both ways round: the rotation
    about z turning ``e``'s direction into ``f``'s, then the translation carrying
    ``e``'s midpoint onto ``f``'s (the least-squares rigid fit of the two pairs of end
    points), and ``dz`` along z (the floor offset).

    Returns
    -------
    (n, 4, 4) float, ``n = 32 * len(pairs)``.
    """
    if not len(pairs):
        return np.zeros((0, 4, 4))
    pairs = np.asarray(pairs, int)
    fa = footprints(a.centers, a.rotations, a.sizes)[pairs[:, 0]]  # (P, 4, 2)
    fb = footprints(b.centers, b.rotations, b.sizes)[pairs[:, 1]]
    ea = np.stack([fa, np.roll(fa, -1, axis=1)], 2)  # (P, 4, 2 ends, 2)
    eb = np.stack([fb, np.roll(fb, -1, axis=1)], 2)
    eb = np.concatenate([eb, eb[:, :, ::-1]], 1)  # (P, 8, 2, 2): both ways round
    da = ea[:, :, 1] - ea[:, :, 0]
    db = eb[:, :, 1] - eb[:, :, 0]
    ang_a = np.arctan2(da[..., 1], da[..., 0])  # (P, 4)
    ang_b = np.arctan2(db[..., 1], db[..., 0])  # (P, 8)
    yaw = (ang_b[:, None, :] - ang_a[:, :, None]).reshape(-1)  # (P*32,)
    ma = ea.mean(2)  # (P, 4, 2)
    mb = eb.mean(2)  # (P, 8, 2)
    ma = np.broadcast_to(ma[:, :, None, :], (len(pairs), 4, 8, 2)).reshape(-1, 2)
    mb = np.broadcast_to(mb[:, None, :, :], (len(pairs), 4, 8, 2)).reshape(-1, 2)
    c, s = np.cos(yaw), np.sin(yaw)
    rot_ma = np.stack([c * ma[:, 0] - s * ma[:, 1], s * ma[:, 0] + c * ma[:, 1]], 1)
    T = np.zeros((len(yaw), 4, 4))
    T[:, 0, 0], T[:, 0, 1], T[:, 1, 0], T[:, 1, 1] = c, -s, s, c
    T[:, 2, 2] = T[:, 3, 3] = 1.0
    T[:, :2, 3] = mb - rot_ma
    T[:, 2, 3] = dz
    return T


def score_alignments(Ts: np.ndarray, template_points: np.ndarray, partial_points: np.ndarray,
                     cap: float) -> np.ndarray:
    """(n,) mean distance (each truncated at ``cap``) from the partial points to the
    template points moved by each ``Ts[k]`` (template -> partial)."""
    from scipy.spatial import cKDTree

    if not len(Ts):
        return np.zeros(0)
    tree = cKDTree(template_points)
    R = Ts[:, :3, :3]
    t = Ts[:, :3, 3]
    # partial points in the template frame: R^T (p - t), every candidate at once
    q = np.einsum("nji,nmj->nmi", R, partial_points[None, :, :] - t[:, None, :])
    d, _ = tree.query(q.reshape(-1, 3), distance_upper_bound=cap)
    return np.minimum(d, cap).reshape(len(Ts), -1).mean(1)


def icp_refine(T0: np.ndarray, template_points: np.ndarray, partial_points: np.ndarray,
               config: CompleteConfig) -> tuple[np.ndarray, dict]:
    """Refine ``T0`` (template -> partial) by point-to-plane ICP of the partial points
    onto the template points (Open3D), projected to an upright transform: ICP's yaw
    about z, the horizontal shift that keeps the partial points' centroid where ICP put
    it, and ``T0``'s vertical offset (both objects stand on their floors).

    Returns
    -------
    T : (4, 4) float
    info : dict
        ``fitness`` (share of partial points with a template point within
        ``icp_distance``) and ``rmse`` (metres, over those) at ``T0`` (``*_before``) and
        at ``T``.
    """
    import open3d as o3d

    reg = o3d.pipelines.registration
    src = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(partial_points))
    dst = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(template_points))
    dst.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(
        radius=max(4 * TEMPLATE_VOXEL, config.icp_distance / 2), max_nn=30))
    before = reg.evaluate_registration(src, dst, config.icp_distance, np.linalg.inv(T0))
    T = np.asarray(T0, float)
    if config.icp_iterations > 0 and len(partial_points) >= 3:
        res = reg.registration_icp(
            src, dst, config.icp_distance, np.linalg.inv(T0),
            reg.TransformationEstimationPointToPlane(),
            reg.ICPConvergenceCriteria(max_iteration=int(config.icp_iterations)))
        G = np.asarray(res.transformation)  # partial -> template
        Tf = np.linalg.inv(G)
        yaw = float(np.arctan2(Tf[1, 0], Tf[0, 0]))
        ctr = partial_points.mean(0)
        q = G[:3, :3] @ ctr + G[:3, 3]
        t = ctr - upright_transform(yaw, np.zeros(3))[:3, :3] @ q
        t[2] = T0[2, 3]
        T = upright_transform(yaw, t)
    after = reg.evaluate_registration(src, dst, config.icp_distance, np.linalg.inv(T))
    return T, {"fitness_before": float(before.fitness), "rmse_before": float(before.inlier_rmse),
               "fitness": float(after.fitness), "rmse": float(after.inlier_rmse)}


def align(a: Parts, b: Parts, matching: Matching, template_points: np.ndarray,
          partial_points: np.ndarray, dz: float, config: CompleteConfig | None = None,
          rng: np.random.Generator | None = None, views=None) -> tuple[np.ndarray, dict]:
    """The rigid transform template -> partial: the best ground-edge alignment, then ICP.

    Candidates (:func:`edge_alignments`) from every template part against every partial
    part (``config.edge_pairs == "all"``), so a wrong or empty spectral matching (a view
    showing two of four parts) still leaves the right pair, or from ``matching``'s pairs
    (``"matched"``, the paper).  Ranked by the mean distance, truncated at
    ``score_cap``, from about :data:`COARSE_POINTS` partial points to the moved template,
    the :data:`KEEP_ALIGNMENTS` best are judged as :func:`complete` judges its result:
    parts matched anew in that pose (:func:`refine_matching`), a template sample carried
    by both transfers (whatever ``config.transfer`` and ``carve`` say), scored by
    :func:`transfer_score` (distance plus the share ``views`` saw through); rigidly, a
    template turned to keep its other proportions out of the space seen empty would
    win.  ``views``: anything with ``free_mask(points) -> (n,) bool``, or None.

    Returns ``(T (4, 4), info)``; ``info`` holds the number of distinct candidate poses,
    the best one's score (metres), its part pair and ICP's figures."""
    cfg = config or CompleteConfig()
    rng = rng or np.random.default_rng(0)
    sample = subsample(partial_points, SCORE_POINTS, rng)
    tsample = subsample(template_points, ALIGN_TEMPLATE_POINTS, rng)
    pairs = (list(matching.pairs) if cfg.edge_pairs == "matched"
             else [(i, j) for i in range(len(a)) for j in range(len(b))])
    Ts = edge_alignments(a, b, pairs, dz)
    source = np.repeat(np.arange(len(pairs)), len(Ts) // max(len(pairs), 1))  # pose's pair
    if not len(Ts):  # no pairs: centroids on each other, no turn
        t = partial_points.mean(0) - template_points.mean(0)
        Ts = upright_transform(0.0, [t[0], t[1], dz])[None]
        source = np.array([-1])
    # one of each pose (a box's edges give one pose several times over)
    yaw = np.mod(np.arctan2(Ts[:, 1, 0], Ts[:, 0, 0]), 2 * np.pi)
    key = np.round(np.column_stack([yaw / SAME_YAW, Ts[:, :3, 3] / SAME_SHIFT])).astype(np.int64)
    key[:, 0] %= int(round(2 * np.pi / SAME_YAW))
    first = np.sort(np.unique(key, axis=0, return_index=True)[1])
    Ts, source = Ts[first], source[first]
    n_candidates = len(Ts)
    coarse = score_alignments(Ts, template_points,
                              sample[::max(1, len(sample) // COARSE_POINTS)], cfg.score_cap)
    keep = np.sort(np.argsort(coarse, kind="stable")[:KEEP_ALIGNMENTS])
    Ts, source = Ts[keep], source[keep]

    def judged(T: np.ndarray) -> float:
        return min(sc for sc, *_ in judge_transfers(
            tsample, a, b, refine_matching(a, b, T, cfg, matching), T, ("parts", "rigid"),
            views, sample, cfg.score_cap))

    scores = np.array([judged(T) for T in Ts])
    best = int(np.argmin(scores))
    T_icp, icp = icp_refine(Ts[best], template_points, partial_points, cfg)
    icp_score = judged(T_icp)  # ICP is kept unless its transfer explains the scan worse
    icp["kept"] = bool(icp_score <= scores[best] + 1e-9)
    T = T_icp if icp["kept"] else Ts[best]
    info = {"candidates": int(n_candidates), "edge_score": float(scores[best]),
            "edge_pair": list(pairs[source[best]]) if source[best] >= 0 else None,
            "edge_transform": Ts[best].tolist(), "icp": icp,
            "score": min(icp_score, float(scores[best]))}
    return T, info


def refine_matching(a: Parts, b: Parts, T: np.ndarray, config: CompleteConfig | None = None,
                    spectral: Matching | None = None) -> Matching:
    """The one-to-one matching once the template is aligned: the assignment (Hungarian)
    of least total cost

        |n_i - n_j| + LOG_WEIGHT * |log s_i - log s_j|

    where ``n`` is a part's centre in its object's bounding box, scaled to the unit cube,
    both boxes taken along the partial object's axes (the template's after ``T``), and
    ``s`` its sorted upright dimensions; pairs costing more than :data:`REMATCH_GATE` are
    left out.  Spectral matching sees only distances between parts, so it cannot tell an
    object from its mirror image (a chair's left legs from its right ones); the aligned
    positions can.  Scaling each object to its own box lets a template of other
    proportions find its parts, so the paper's absolute pruning (made for the search,
    :func:`spectral_match`) is not applied here; the cost on dimensions keeps a part from
    a partner of another shape.  Pairs of ``spectral`` whose parts both stay unmatched
    are added after (confidence 0).  ``candidates`` counts the pairs under the gate."""
    from scipy.optimize import linear_sum_assignment

    from .model import box_corners

    if not len(a) or not len(b):
        return Matching((), (), 0, 0)
    # the partial object's horizontal axes: those of its largest part
    k = int(np.argmax(np.prod(b.sizes, axis=1)))
    ax = flat_axes_xy(b.rotations)[k, 0]
    yaw = float(np.arctan2(ax[1], ax[0]))
    F = upright_transform(yaw, np.zeros(3))[:3, :3]  # columns: the frame's axes in world

    def normalised(p: Parts, M: np.ndarray) -> np.ndarray:
        R = M[:3, :3]
        centers = (p.centers @ R.T + M[:3, 3]) @ F
        corners = box_corners(p.centers, p.rotations, p.sizes).reshape(-1, 3)
        corners = (corners @ R.T + M[:3, 3]) @ F
        lo, hi = corners.min(0), corners.max(0)
        return (centers - (lo + hi) / 2) / np.maximum(hi - lo, 1e-6)

    na, nb = normalised(a, T), normalised(b, np.eye(4))
    la = np.log(np.maximum(np.stack([a.height, a.length, a.width], 1), 1e-4))
    lb = np.log(np.maximum(np.stack([b.height, b.length, b.width], 1), 1e-4))
    cost = (np.linalg.norm(na[:, None, :] - nb[None], axis=2)
            + LOG_WEIGHT * np.linalg.norm(la[:, None, :] - lb[None], axis=2))
    ok = cost <= REMATCH_GATE
    rows, cols = linear_sum_assignment(np.where(ok, cost, 1e6))
    keep = ok[rows, cols]
    order = np.argsort(cost[rows[keep], cols[keep]], kind="stable")
    r, c = rows[keep][order], cols[keep][order]
    pairs = [(int(i), int(j)) for i, j in zip(r, c, strict=True)]
    conf = [float(v) for v in np.exp(-cost[r, c])]
    if spectral is not None:
        used_a, used_b = {i for i, _ in pairs}, {j for _, j in pairs}
        for i, j in spectral.pairs:
            if i not in used_a and j not in used_b:
                pairs.append((i, j))
                conf.append(0.0)
                used_a.add(i)
                used_b.add(j)
    return Matching(tuple(pairs), tuple(conf), int(ok.sum()), 0)


def box_affine(a: Parts, b: Parts, T: np.ndarray) -> np.ndarray:
    """(4, 4) ``T`` followed by the scaling, along the partial object's horizontal axes
    and z, that turns the moved template object's bounding box into the partial
    object's (each object's box around its cuboids); ``T`` when a scale would leave
    [0.5, 2]."""
    from .model import box_corners

    k = int(np.argmax(np.prod(b.sizes, axis=1)))
    ax = flat_axes_xy(b.rotations)[k, 0]
    F = upright_transform(float(np.arctan2(ax[1], ax[0])), np.zeros(3))[:3, :3]
    ca = box_corners(a.centers, a.rotations, a.sizes).reshape(-1, 3) @ T[:3, :3].T + T[:3, 3]
    cb = box_corners(b.centers, b.rotations, b.sizes).reshape(-1, 3)
    qa, qb = ca @ F, cb @ F
    lo_a, hi_a, lo_b, hi_b = qa.min(0), qa.max(0), qb.min(0), qb.max(0)
    scale = (hi_b - lo_b) / np.maximum(hi_a - lo_a, 1e-6)
    if np.any(scale < 0.5) or np.any(scale > 2.0):
        return T
    # in the frame F: q -> lo_b + (q - lo_a) * scale, with z kept on the floor (lo of z)
    S = F @ np.diag(scale) @ F.T
    shift = F @ (lo_b - lo_a * scale)
    A = np.eye(4)
    A[:3, :3] = S @ T[:3, :3]
    A[:3, 3] = S @ T[:3, 3] + shift
    return A


def affine_of_pairs(a: Parts, b: Parts, matching: Matching, T: np.ndarray) -> np.ndarray:
    """(4, 4) affine map template -> partial fitted (least squares) to the corners of the
    matched boxes, each template corner paired with the partner box's corner through the
    axis pairing; :func:`box_affine` when fewer than two pairs or the fit is degenerate."""
    from .model import CORNER_SIGNS

    if len(matching.pairs) < 2:
        return box_affine(a, b, T)
    src, dst = [], []
    for i, j in matching.pairs:
        P = axis_pairing(T[:3, :3] @ a.rotations[i], b.rotations[j])
        loc_a = CORNER_SIGNS * a.sizes[i] / 2
        src.append(a.centers[i] + loc_a @ a.rotations[i].T)
        loc_b = (CORNER_SIGNS @ P.T) * b.sizes[j] / 2
        dst.append(b.centers[j] + loc_b @ b.rotations[j].T)
    src, dst = np.concatenate(src), np.concatenate(dst)
    X = np.hstack([src, np.ones((len(src), 1))])
    sol, _, rank, _ = np.linalg.lstsq(X, dst, rcond=None)
    if rank < 4:
        return box_affine(a, b, T)
    A = np.eye(4)
    A[:3, :3], A[:3, 3] = sol[:3].T, sol[3]
    # a fit that flips or squashes the object is no better than the rigid transform
    sv = np.linalg.svd(A[:3, :3], compute_uv=False)
    if np.linalg.det(A[:3, :3]) <= 0 or sv.min() < 0.5 or sv.max() > 2.0:
        return box_affine(a, b, T)
    return A


# --------------------------------------------------------------------------- transfer
def box_distance(points: np.ndarray, parts: Parts) -> np.ndarray:
    """(n, K) distance of each point from each box (0 inside)."""
    local = np.einsum("kji,nkj->nki", parts.rotations, points[:, None, :] - parts.centers[None])
    out = np.maximum(np.abs(local) - parts.sizes[None] / 2, 0.0)
    return np.linalg.norm(out, axis=2)


def surface_distance(points: np.ndarray, parts: Parts) -> np.ndarray:
    """(n,) distance of each point from the nearest face of any box (outside a box: its
    distance to the box; inside: its depth below the box's nearest face)."""
    if not len(points):
        return np.zeros(0)
    local = np.einsum("kji,nkj->nki", parts.rotations, points[:, None, :] - parts.centers[None])
    gap = np.abs(local) - parts.sizes[None] / 2  # (n, K, 3), > 0 outside along that axis
    outside = np.linalg.norm(np.maximum(gap, 0.0), axis=2)
    depth = -gap.max(2)  # > 0 inside
    return np.where(depth > 0, depth, outside).min(1)


def axis_pairing(R_from: np.ndarray, R_to: np.ndarray) -> np.ndarray:
    """(3, 3) signed permutation ``P`` with ``R_to @ P ~ R_from``: local axis ``k`` of the
    first box is ``P[:, k]`` in the second box's local axes."""
    from scipy.optimize import linear_sum_assignment

    M = R_to.T @ R_from
    rows, cols = linear_sum_assignment(-np.abs(M))
    P = np.zeros((3, 3))
    P[rows, cols] = np.sign(M[rows, cols]) + (M[rows, cols] == 0)
    return P


def transfer(template_points: np.ndarray, a: Parts, b: Parts, matching: Matching,
             T: np.ndarray, mode: str = "parts") -> np.ndarray:
    """Template points carried into the partial scan's frame.

    ``rigid``: ``T`` applied to every point.  ``parts``: a point whose nearest template
    box is a matched part ``i`` (matched to partial box ``j``) gets box ``i``'s local
    coordinates, re-ordered to box ``j``'s axes through ``T``'s rotation and scaled by
    ``size_j / size_i`` axis by axis, placed in box ``j``; other points move by the
    affine map fitted to the matched boxes' corners (:func:`affine_of_pairs`).
    """
    pts = np.asarray(template_points, float)
    moved = pts @ T[:3, :3].T + T[:3, 3]
    if mode == "rigid" or not matching.pairs or not len(pts):
        return moved
    if mode != "parts":
        raise ValueError(f"transfer: mode must be one of {TRANSFERS}, got {mode!r}")
    owner = np.argmin(box_distance(pts, a), axis=1)
    A = affine_of_pairs(a, b, matching, T)
    out = pts @ A[:3, :3].T + A[:3, 3]
    for i, j in matching.pairs:
        sel = owner == i
        if not sel.any():
            continue
        P = axis_pairing(T[:3, :3] @ a.rotations[i], b.rotations[j])
        u = (pts[sel] - a.centers[i]) @ a.rotations[i]  # template box coordinates
        size_i_in_j = np.abs(P) @ a.sizes[i]
        v = (u @ P.T) * (b.sizes[j] / np.maximum(size_i_in_j, 1e-9))
        out[sel] = b.centers[j] + v @ b.rotations[j].T
    return out


def transfer_score(moved: np.ndarray, seen_through: np.ndarray, partial_points: np.ndarray,
                   cap: float, rng: np.random.Generator | None = None) -> float:
    """How badly transferred points explain the partial scan (metres, lower is better):
    the mean distance, truncated at ``cap``, from the partial points to the kept
    transferred points, plus ``cap`` times the share of transferred points the scan saw
    through (``seen_through``)."""
    from scipy.spatial import cKDTree

    kept = moved[~seen_through]
    if not len(kept):
        return float(2 * cap)
    sample = subsample(partial_points, SCORE_POINTS, rng or np.random.default_rng(0))
    d, _ = cKDTree(kept).query(sample, distance_upper_bound=cap)
    return float(np.minimum(d, cap).mean() + cap * seen_through.mean())


def judge_transfers(template_points: np.ndarray, a: Parts, b: Parts, matching: Matching,
                    T: np.ndarray, modes, views, partial_points: np.ndarray, cap: float,
                    rng: np.random.Generator | None = None) -> list[tuple]:
    """Per transfer of ``modes``: ``(score, mode, moved points, seen-through mask)``, scored
    by :func:`transfer_score`; ``views`` None: nothing seen through."""
    out = []
    for mode in modes:
        moved = transfer(template_points, a, b, matching, T, mode)
        free = views.free_mask(moved) if views is not None else np.zeros(len(moved), bool)
        out.append((transfer_score(moved, free, partial_points, cap, rng), mode, moved, free))
    return out


# --------------------------------------------------------------------------- objects
def object_names(arrangement: Arrangement) -> list[str]:
    """Object names of an arrangement's cuboids, in first-seen order."""
    return list(dict.fromkeys(c.object for c in arrangement.cuboids if c.object is not None))


def object_points(report: dict, name: str) -> np.ndarray:
    """(n, 3) world points of object ``name`` in a run's initial report (its
    ``world``, ``labels`` and ``objects``)."""
    names = list(report["objects"])
    ks = [k for k, n in enumerate(names) if n == name]
    return np.asarray(report["world"], float)[np.isin(report["labels"], ks)]


def largest_object(report: dict, arrangement: Arrangement) -> str:
    """The object of ``arrangement`` with the most points in the run's report."""
    names = object_names(arrangement)
    if not names:
        raise ValueError("the arrangement has no objects")
    counts = [len(object_points(report, n)) for n in names]
    return names[int(np.argmax(counts))]


def floor_height(arrangement: Arrangement) -> float:
    """z of the ground support at the origin (0 without one)."""
    for s in arrangement.supports:
        if s.id == "ground":
            n = s.normal
            return float(s.point @ n / n[2]) if abs(n[2]) > 1e-6 else 0.0
    return 0.0


def level_offset(a: Parts, b: Parts, floor_a: float, floor_b: float) -> float:
    """Vertical offset template -> partial: the difference of the floors when both
    objects stand on theirs (lowest part within :data:`ON_FLOOR` of it), else of the
    objects' lowest points (an object on a table or on another box)."""
    if abs(a.bottom.min() - floor_a) <= ON_FLOOR and abs(b.bottom.min() - floor_b) <= ON_FLOOR:
        return float(floor_b - floor_a)
    return float(b.bottom.min() - a.bottom.min())


def voxel_thin(points: np.ndarray, voxel: float) -> np.ndarray:
    """Indices of one point per occupied cube of edge ``voxel`` (the first in order)."""
    if not len(points):
        return np.zeros(0, int)
    keys = np.floor(points / voxel).astype(np.int64)
    _, first = np.unique(keys, axis=0, return_index=True)
    return np.sort(first)


# --------------------------------------------------------------------------- the step
@dataclass(frozen=True)
class Completion:
    """What :func:`complete` returns.

    Attributes
    ----------
    points : (n, 3) float
        The completed cloud: the partial object's points, then the transferred
        template points.
    source : (n,) uint8
        0 for a partial point, 1 for a template point.
    T_partial_template : (4, 4) float
        The rigid transform from the template scan's world to the partial scan's.
    matching : Matching
        The matching once aligned (:func:`refine_matching`), indices into
        ``template_parts`` and ``partial_parts``; the transfer follows it.
    template_parts, partial_parts : Parts
    objects : (str, str)
        The template's and the partial scan's object names.
    alignment : dict
        Candidate count, edge score, ICP fitness and RMSE (:func:`align`).
    carved : int
        Transferred points removed because the partial scan saw through them.
    transfer : str
        The transfer used (``parts`` or ``rigid``; ``auto`` picks one).
    spectral : Matching or None
        The spectral matching the alignment came from (:func:`spectral_match`).
    """

    points: np.ndarray
    source: np.ndarray
    T_partial_template: np.ndarray
    matching: Matching
    template_parts: Parts
    partial_parts: Parts
    objects: tuple[str, str]
    alignment: dict = field(default_factory=dict)
    carved: int = 0
    transfer: str = "parts"
    spectral: Matching | None = None

    @property
    def partial_points(self) -> np.ndarray:
        return self.points[self.source == 0]

    @property
    def template_points(self) -> np.ndarray:
        return self.points[self.source == 1]

    def matching_ids(self, spectral: bool = False) -> list[tuple[str, str, float]]:
        """(template cuboid id, partial cuboid id, confidence) per matched pair (of the
        spectral matching with ``spectral``)."""
        m = self.spectral if spectral else self.matching
        if m is None:
            return []
        return [(self.template_parts.ids[i], self.partial_parts.ids[j], c)
                for (i, j), c in zip(m.pairs, m.confidence, strict=True)]


def complete(partial, template, config: CompleteConfig | None = None, *,
             partial_object: str | None = None, template_object: str | None = None,
             rng: np.random.Generator | None = None) -> Completion:
    """Complete the partial scan's object with the template scan's.

    Parameters
    ----------
    partial, template : pipeline.run.Result
        :func:`pipeline.run.run_scan` results (their arrangements, points and, for
        ``partial``, depth views).
    config : CompleteConfig
    partial_object, template_object : str, optional
        Object names (default: the object with the most points in each scan).
    rng : numpy.random.Generator, optional
        Picks the partial points that score alignments.

    Raises
    ------
    ValueError
        An object name that is not in its scan, or an object without points.
    """
    cfg = config or CompleteConfig()
    names = []
    for res, name, role in ((partial, partial_object, "partial"),
                            (template, template_object, "template")):
        arr = res.arrangement
        have = object_names(arr)
        if name is None:
            name = largest_object(res.initial_report, arr)
        elif name not in have:
            raise ValueError(f"{role} object {name!r}: not in the scan; it has "
                             f"{', '.join(have) or 'no objects'}")
        names.append(name)
    p_name, t_name = names
    pp = object_points(partial.initial_report, p_name)
    tp_all = object_points(template.initial_report, t_name)
    for pts, role, name in ((pp, "partial", p_name), (tp_all, "template", t_name)):
        if len(pts) < 10:
            raise ValueError(f"{role} object {name!r}: only {len(pts)} points")
    tp = tp_all[voxel_thin(tp_all, TEMPLATE_VOXEL)]
    a = parts_of([c for c in template.arrangement.cuboids if c.object == t_name])
    b = parts_of([c for c in partial.arrangement.cuboids if c.object == p_name])
    spectral = spectral_match(a, b, cfg)
    dz = level_offset(a, b, floor_height(template.arrangement),
                      floor_height(partial.arrangement))
    views = partial.evidence.scaled_to(partial.arrangement) if partial.evidence else None
    T, info = align(a, b, spectral, tp, pp, dz, cfg, rng, views=views)
    matching = refine_matching(a, b, T, cfg, spectral)
    scored = judge_transfers(tp, a, b, matching, T, ("parts", "rigid") if cfg.transfer == "auto"
                             else (cfg.transfer,), views if cfg.carve else None, pp,
                             cfg.score_cap, rng)
    info["transfer_scores"] = {mode: float(sc) for sc, mode, _, _ in scored}
    _, chosen, moved, free = min(scored, key=lambda x: x[0])
    moved, carved = moved[~free], int(free.sum())
    points = np.concatenate([pp, moved])
    source = np.concatenate([np.zeros(len(pp), np.uint8), np.ones(len(moved), np.uint8)])
    return Completion(points, source, T, matching, a, b, (t_name, p_name), info, carved,
                      chosen, spectral)


__all__ = ["CompleteConfig", "Completion", "Matching", "Parts", "affine_of_pairs", "align",
           "box_affine", "complete", "edge_alignments", "icp_refine", "largest_object", "level_offset",
           "object_points", "parts_of", "refine_matching", "spectral_match",
           "surface_distance", "transfer", "transfer_score"]
