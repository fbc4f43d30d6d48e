"""Cuboids from the points of one object (section 4.1 of the paper).

An upright object is oriented by the minimum-area rectangle of its points projected on
the ground (``cv2.minAreaRect``), voxelized in that frame, and its occupied voxels are
covered greedily by axis-aligned slabs that stay more than 70 % occupied, the slab
covering most voxels first, then recursively on what is left; every slab is a cuboid.
A sensor only sees surfaces, so a voxel counts as occupied when it holds a point or,
given a ``solid`` test (the depth image), when it lies behind the object's own observed
surface; without one, a column is filled from its highest point down to the object's
bottom (things rest on what is below them).  A leaning object (its dominant plane
neither horizontal nor vertical) gets one box whose frame comes from two orthogonal
RANSAC planes.  Specks (too few voxels or points) are dropped.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: A slab keeps growing while it stays more than this fraction occupied (the paper's 70 %).
SLAB_MIN_FILL = 0.7
#: Voxel size as a fraction of the scene diameter (paper: 0.005 of the unit sphere,
#: i.e. 0.0025 of the diameter; we use a coarser default for noisy Kinect depth).
CELL_REL = 0.005
#: Tilt of a dominant plane (degrees from horizontal/vertical) above which an object is slanted.
SLANT_MIN_DEG = 15.0
MAX_VOXELS = 1_500_000
#: A slab holding less than this fraction of its object's voxels or points is a speck.
SPECK_FRACTION = 0.02
#: A seen face's points spread along its normal (10th-90th percentile) by the noise, at
#: most this many cells, unless they spread as much across it (:func:`_face_at`).
FACE_SPREAD_CELLS = 3.0


@dataclass(frozen=True)
class FittedBox:
    """One fitted cuboid (world frame)."""

    center: np.ndarray  #: (3,) float
    rotation: np.ndarray  #: (3, 3) float, columns = local axes
    size: np.ndarray  #: (3,) float, full extents
    points: int  #: object points inside it
    slanted: bool = False


def ground_rotation(points: np.ndarray) -> np.ndarray:
    """(3, 3) rotation about z whose x/y axes are the minimum-area rectangle's edges.

    The angle is canonicalised to [0, 90) degrees so the result does not depend on
    point order.
    """
    import cv2

    xy = np.ascontiguousarray(points[:, :2], dtype=np.float32)
    if len(xy) < 3:
        return np.eye(3)
    corners = cv2.boxPoints(cv2.minAreaRect(xy)).astype(float)
    e = corners[1] - corners[0]
    if np.linalg.norm(e) < 1e-12:
        e = corners[2] - corners[1]
    a = np.arctan2(e[1], e[0]) % (np.pi / 2)
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def estimate_normals(points: np.ndarray, radius: float, max_nn: int = 30) -> np.ndarray:
    """Unit normals ``(n, 3)`` of ``points (n, 3)`` by local PCA (Open3D), unoriented."""
    import open3d as o3d

    if len(points) < 3:
        return np.tile([0.0, 0.0, 1.0], (len(points), 1))
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, dtype=float)))
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=float(radius), max_nn=max_nn))
    return np.asarray(pcd.normals)


def normal_yaw(normals: np.ndarray, min_count: int = 30,
               min_fraction: float = 0.1, min_coherence: float = 0.4) -> float | None:
    """Yaw (radians, in [0, pi/2)) of an upright box from the normals of its vertical faces.

    Normals with a clear horizontal part vote for their direction modulo 90 degrees
    (the mean of ``exp(4 i phi)`` weighted by the squared horizontal length), which
    stays right when only one or two faces were seen, where a minimum-area rectangle of
    a partial, noisy outline tilts.  None when too few normals are horizontal or their
    directions disagree (a round object): use :func:`ground_rotation`.
    """
    h = np.asarray(normals)[:, :2]
    w = np.einsum("ij,ij->i", h, h)
    keep = w > 0.75  # within 30 degrees of horizontal
    if keep.sum() < max(min_count, min_fraction * len(h)):
        return None
    phi = np.arctan2(h[keep, 1], h[keep, 0])
    z = np.sum(w[keep] * np.exp(4j * phi)) / np.sum(w[keep])
    if abs(z) < min_coherence:
        return None
    return float((np.angle(z) / 4.0) % (np.pi / 2))


#: A tilted frame from RANSAC planes must explain this much larger a share of the
#: normals than the upright frame does to be believed (small noisy parts fool RANSAC).
SLANT_MARGIN = 0.1


def aligned_share(normals: np.ndarray, R: np.ndarray, tol_deg: float = 15.0) -> float:
    """Share of ``normals (n, 3)`` within ``tol_deg`` of one of the axes of frame ``R``."""
    n = np.asarray(normals)
    if not len(n):
        return 0.0
    return float((np.abs(n @ R).max(axis=1) >= np.cos(np.radians(tol_deg))).mean())


def footprint_area(points: np.ndarray, R: np.ndarray) -> float:
    """Area (m^2) of the rectangle in frame ``R`` holding ``points (n, 3)`` from their
    1st to their 99th percentile along its two horizontal axes."""
    xy = np.asarray(points)[:, :2] @ np.asarray(R)[:2, :2]
    lo, hi = np.percentile(xy, [1.0, 99.0], axis=0)
    return float(np.prod(hi - lo))


def yaw_rotation(a: float) -> np.ndarray:
    """(3, 3) rotation about z by ``a`` radians."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


#: An object whose points come this close to a wall (1st percentile of their distances
#: to its plane, metres) is turned square to that wall when that frame explains its
#: surface normals within :data:`WALL_SHARE_MARGIN` (of :func:`aligned_share`) as well as
#: its own, or holds its points in a footprint no larger.  The sensor sees furniture
#: from the front and its back is hidden: a bookcase or a desk against a wall shows
#: points that end its depth, 25-30 cm, off the wall (a wall shelf's board seen at 5 m
#: ends a few centimetres off it).
WALL_NEAR = 0.3
WALL_SHARE_MARGIN = 0.05


def wall_yaw(points: np.ndarray, walls, near: float = WALL_NEAR) -> float | None:
    """Yaw (radians, in [0, pi/2)) of the nearest upright wall in ``walls`` (supports)
    that ``points (n, 3)`` come within ``near`` of, or None."""
    best = None
    for w in walls:
        n = np.asarray(w.normal, float)
        if abs(n[2]) > 0.2 or not len(points):
            continue
        gap = float(np.percentile((points - w.point) @ n, 1.0))
        if gap < near and (best is None or gap < best[0]):
            best = (gap, float(np.arctan2(n[1], n[0]) % (np.pi / 2)))
    return None if best is None else best[1]


def upright_rotation(points: np.ndarray, normals: np.ndarray | None = None,
                     walls=()) -> np.ndarray:
    """The frame of an upright object: yaw from vertical-face normals when they agree
    (:func:`normal_yaw`), else the minimum-area rectangle (:func:`ground_rotation`).

    With ``walls`` (supports), an object that reaches a wall (:func:`wall_yaw`) stands
    square to it unless its normals clearly say otherwise: at 4-5 m the sensor's depth
    steps put ridges across a board that face the camera, and a wall shelf's normals
    then vote for the viewing direction.  Its footprint says so too: a box's points
    spread least in its own frame (the minimum-area rectangle's principle), so where
    the wall's frame holds the points in a footprint (1st-99th percentile extents) no
    larger than the normals' frame does, the normals are the ridges and the wall wins
    (a shelf against a wall seen obliquely: its boards' front edges, a few
    centimetres tall, smear into normals facing the camera).
    """
    has_normals = normals is not None and len(normals)
    a = normal_yaw(normals) if has_normals else None
    R = ground_rotation(points) if a is None else yaw_rotation(a)
    w = wall_yaw(points, walls) if has_normals and len(walls) else None
    if w is not None:
        Rw = yaw_rotation(w)
        if (aligned_share(normals, Rw) >= aligned_share(normals, R) - WALL_SHARE_MARGIN
                or footprint_area(points, Rw) <= footprint_area(points, R)):
            return Rw
    return R


def _face_at(local: np.ndarray, on_face: np.ndarray, axis: int, side: int,
             cell: float | None) -> float | None:
    """Where along ``axis`` the points ``local[on_face]`` ((n, 3), box frame), whose
    normals face along ``side`` (+1 or -1) of it, put that face of the box: their median,
    or None where they are not a face.

    With ``cell`` (metres) they must be one: a face is a plane that bounds the object,
    its points spread across it at least as much as along its normal, where they spread
    only by the noise (at most :data:`FACE_SPREAD_CELLS` cells), and most of the
    object's points lie inside it.  Normals estimated on a strip a few pixels wide (a
    panel's front edge seen from afar) or next to another part point anywhere: those
    that happen to face along the strip lie all along it, and a few that face sideways
    halfway along a board would cut it there.
    """
    face = local[on_face]
    at = float(np.median(face[:, axis]))
    if cell is None:
        return at
    q10, q90 = np.percentile(face, [10.0, 90.0], axis=0)
    spread = q90 - q10
    across = max(spread[b] for b in range(3) if b != axis)
    if spread[axis] > max(FACE_SPREAD_CELLS * cell, across):
        return None
    outside = side * (local[:, axis] - at) > max(cell, spread[axis])
    return at if outside.mean() < 0.5 else None


def face_extents(local: np.ndarray, local_normals: np.ndarray, *, face_cos: float = 0.85,
                 min_face: int = 15, trim: float = 1.0,
                 eye: np.ndarray | None = None,
                 cell: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Box extents (lo (3,), hi (3,)) in the box frame from noisy surface points.

    A face that was seen is placed at the median of its own points (points whose normal
    is within ``acos(face_cos)`` of its axis): depth noise scatters a face on both sides
    of it, so its extreme points overshoot by two to three standard deviations.  A face
    not seen gets the ``trim`` / ``100 - trim`` percentile of all points (the edges of the
    faces that were seen).

    Which face a point lies on: with ``eye`` ((3,), the centre of the camera that saw
    every point, box frame), the side its normal faces once turned towards the camera,
    for a sensor sees only the faces turned to it.  This holds for a box
    thinner than the noise, whose one seen face scatters across the box's middle.
    Without it, the half of the box the point lies in.

    With ``cell`` (the voxel size, metres) a face's points must also lie on a plane that
    bounds the points (:func:`_face_at`); otherwise that face counts as not seen.
    """
    lo = np.percentile(local, trim, axis=0)
    hi = np.percentile(local, 100.0 - trim, axis=0)
    mid = (lo + hi) / 2
    if eye is not None:
        flip = np.sum(local_normals * (np.asarray(eye, float) - local), axis=1) < 0
        local_normals = np.where(flip[:, None], -local_normals, local_normals)
    need = max(min_face, int(0.03 * len(local)))
    for a in range(3):
        on = np.abs(local_normals[:, a]) >= face_cos
        if eye is not None:
            sel_lo, sel_hi = on & (local_normals[:, a] < 0), on & (local_normals[:, a] > 0)
        else:
            sel_lo, sel_hi = on & (local[:, a] < mid[a]), on & (local[:, a] >= mid[a])
        for sel, side, ends in ((sel_lo, -1, lo), (sel_hi, 1, hi)):
            at = _face_at(local, sel, a, side, cell) if sel.sum() >= need else None
            if at is not None:
                ends[a] = at
        if hi[a] < lo[a]:
            lo[a] = hi[a] = float(np.median(local[:, a]))
    return lo, hi


def fit_part(points: np.ndarray, normals: np.ndarray, cell: float, rotation: np.ndarray,
             min_points: int = 20, viewpoint: np.ndarray | None = None) -> list[FittedBox]:
    """One cuboid for the points of one part (a segmentation that names parts), in the
    frame ``rotation``, its faces placed by :func:`face_extents` (``viewpoint``: the
    camera's centre, world, that saw every point)."""
    if len(points) < min_points:
        return []
    local = points @ rotation
    eye = None if viewpoint is None else np.asarray(viewpoint, float) @ rotation
    lo, hi = face_extents(local, normals @ rotation, eye=eye, cell=cell)
    size = np.maximum(hi - lo, 0.5 * cell)
    return [FittedBox(rotation @ ((lo + hi) / 2), rotation.copy(), size, len(points))]


def _sat(occ: np.ndarray) -> np.ndarray:
    """3D summed-area table with a zero border: S[i,j,k] = occ[:i,:j,:k].sum()."""
    S = np.zeros(tuple(np.array(occ.shape) + 1), dtype=np.int64)
    S[1:, 1:, 1:] = occ.astype(np.int64).cumsum(0).cumsum(1).cumsum(2)
    return S


def _boxsum(S: np.ndarray, lo, hi) -> int:
    """Sum over the inclusive index box [lo, hi] (sequences of 3 ints)."""
    a0, b0, c0 = int(lo[0]), int(lo[1]), int(lo[2])
    a1, b1, c1 = int(hi[0]) + 1, int(hi[1]) + 1, int(hi[2]) + 1
    return int(S[a1, b1, c1] - S[a0, b1, c1] - S[a1, b0, c1] - S[a1, b1, c0]
               + S[a0, b0, c1] + S[a0, b1, c0] + S[a1, b0, c0] - S[a0, b0, c0])


def grow_slab(S: np.ndarray, shape: tuple, seed: np.ndarray,
              min_fill: float = SLAB_MIN_FILL) -> tuple[np.ndarray, np.ndarray, int]:
    """Grow an axis-aligned index box from ``seed``, one layer at a time, best layer first.

    A layer is added while it is at least ``min_fill`` occupied and the whole box stays
    above ``min_fill``.  Returns (lo, hi, occupied count).
    """
    lo = [int(v) for v in seed]
    hi = list(lo)
    count = _boxsum(S, lo, hi)
    dims = [int(d) for d in shape]
    while True:
        best, best_fill, best_count = None, -1.0, 0
        for ax in range(3):
            o1, o2 = [k for k in range(3) if k != ax]
            area = (hi[o1] - lo[o1] + 1) * (hi[o2] - lo[o2] + 1)
            for side in (-1, 1):
                if side < 0:
                    if lo[ax] == 0:
                        continue
                    at = lo[ax] - 1
                else:
                    if hi[ax] == dims[ax] - 1:
                        continue
                    at = hi[ax] + 1
                llo, lhi = list(lo), list(hi)
                llo[ax] = lhi[ax] = at
                lc = _boxsum(S, llo, lhi)
                lfill = lc / area
                if lfill > best_fill:
                    best, best_fill, best_count = (ax, side, at), lfill, lc
        if best is None or best_fill < min_fill:
            break
        ax, side, at = best
        nlo, nhi = list(lo), list(hi)
        if side < 0:
            nlo[ax] = at
        else:
            nhi[ax] = at
        vol = (nhi[0] - nlo[0] + 1) * (nhi[1] - nlo[1] + 1) * (nhi[2] - nlo[2] + 1)
        total = count + best_count
        if total / vol <= min_fill:
            break
        lo, hi, count = nlo, nhi, total
    return np.array(lo), np.array(hi), count


def slabs(occ: np.ndarray, min_voxels: int, min_fill: float = SLAB_MIN_FILL,
          max_slabs: int = 12, seeds: int = 5,
          seed_mask: np.ndarray | None = None) -> list[tuple[np.ndarray, np.ndarray, int]]:
    """Cover the occupied voxels of ``occ (nx, ny, nz) bool`` by greedy slabs.

    Each round grows slabs from the ``seeds`` densest unassigned voxels (3x3x3
    neighbourhood count), keeps the one covering most voxels, removes its voxels and
    repeats until fewer than ``min_voxels`` remain or a slab would be a speck.

    Returns
    -------
    list of (lo (3,) int, hi (3,) int inclusive, occupied count)
    """
    from scipy.ndimage import uniform_filter

    left = occ.copy()
    out = []
    while left.sum() >= max(min_voxels, 1) and len(out) < max_slabs:
        S = _sat(left)
        dens = uniform_filter(left.astype(np.float32), size=3, mode="constant")
        dens[~left] = -1
        if seed_mask is not None:  # grow only from observed voxels
            dens[~seed_mask] = -1
        best = None
        for _ in range(seeds):
            f = int(np.argmax(dens))  # first maximum: deterministic
            s = np.array(np.unravel_index(f, occ.shape))
            if dens[tuple(s)] < 0:
                break
            lo, hi, cnt = grow_slab(S, occ.shape, s, min_fill)
            dens[lo[0]:hi[0] + 1, lo[1]:hi[1] + 1, lo[2]:hi[2] + 1] = -1
            key = (cnt, -int(np.prod(hi - lo + 1)))
            if best is None or key > best[0]:
                best = (key, lo, hi, cnt)
        if best is None or best[3] < min_voxels:
            break
        _, lo, hi, cnt = best
        out.append((lo, hi, cnt))
        left[lo[0]:hi[0] + 1, lo[1]:hi[1] + 1, lo[2]:hi[2] + 1] = False
        if seed_mask is not None:
            seed_mask = seed_mask & left
    return out


def _column_fill(occ: np.ndarray) -> np.ndarray:
    """Fill each (x, y) column from its highest occupied voxel down to the object's bottom."""
    zs = np.nonzero(occ.any(axis=(0, 1)))[0]
    if len(zs) == 0:
        return occ
    above = np.flip(np.cumsum(np.flip(occ, 2), 2), 2) > 0
    above[:, :, : zs[0]] = False
    return occ | above


def evidence_fill(surf: np.ndarray, hidden: np.ndarray) -> np.ndarray:
    """Occupancy from surface voxels and hidden ones that observed surface supports.

    A hidden voxel (behind the object's own surface) counts as occupied only when both
    the x-slice and the y-slice through it hold an observed voxel at its height or
    below: a box seen from the front and side fills, the space under a table top does
    not (only where its legs are).
    """
    ev_x = np.cumsum(surf.any(axis=1), axis=1) > 0  # (nx, nz): seen at or below z in slice x
    ev_y = np.cumsum(surf.any(axis=0), axis=1) > 0  # (ny, nz)
    return surf | (hidden & ev_x[:, None, :] & ev_y[None, :, :])


def merge_slabs(boxes: list[tuple[np.ndarray, np.ndarray]], occ: np.ndarray,
                loose: np.ndarray | None = None, min_fill: float = SLAB_MIN_FILL,
                max_free: float = 0.15) -> list[tuple[np.ndarray, np.ndarray]]:
    """Merge slabs of one object into their joint bounding box when that adds no space
    the sensor saw as empty.

    Two slabs merge when their joint box is more than ``min_fill`` occupied in ``occ``
    (fragments a greedy cover left side by side), or, given ``loose`` (observed or
    hidden), when at most ``max_free`` of the volume the merge adds was seen free: a box
    seen from the top and one side gives a top and a side slab and is one box; a table
    top and a leg stay apart, because the sensor saw the floor under the table.
    """
    boxes = [(np.asarray(a), np.asarray(b)) for a, b in boxes]
    S = _sat(occ)
    SF = _sat(~loose) if loose is not None else None

    def vol(lo: np.ndarray, hi: np.ndarray) -> int:
        return int(np.prod(np.maximum(hi - lo + 1, 0)))

    while len(boxes) > 1:
        best = None
        for i in range(len(boxes)):
            for j in range(i + 1, len(boxes)):
                (a0, a1), (b0, b1) = boxes[i], boxes[j]
                lo, hi = np.minimum(a0, b0), np.maximum(a1, b1)
                v = float(vol(lo, hi))
                score = _boxsum(S, lo, hi) / v
                ok = score > min_fill
                if not ok and SF is not None:
                    o0, o1 = np.maximum(a0, b0), np.minimum(a1, b1)
                    overlap = vol(o0, o1)
                    added = v - vol(a0, a1) - vol(b0, b1) + overlap
                    free = (_boxsum(SF, lo, hi) - _boxsum(SF, a0, a1) - _boxsum(SF, b0, b1)
                            + (_boxsum(SF, o0, o1) if overlap else 0))
                    # little of what the merge adds was seen free, relative to what it
                    # adds or (for boxes that overlap already) to the whole joint box
                    ok = added <= 0 or free <= max_free * added or free <= 0.05 * v
                    score = 1.0 - free / max(added, 1)
                if ok and (best is None or score > best[0]):
                    best = (score, i, j, lo, hi)
        if best is None:
            break
        _, i, j, lo, hi = best
        boxes = [b for k, b in enumerate(boxes) if k not in (i, j)] + [(lo, hi)]
    return boxes


def fit_upright(points: np.ndarray, cell: float, *,
                solid: Callable[[np.ndarray], np.ndarray] | None = None,
                min_voxels: int = 6, min_points: int = 20,
                rotation: np.ndarray | None = None) -> list[FittedBox]:
    """Ground-aligned cuboids for one object's world points ``(n, 3)`` (z up).

    Parameters
    ----------
    cell : voxel edge, metres
    solid : callable mapping world points (m, 3) -> (m,) bool, True where the space
        is hidden behind the object's own surface (may be occupied); None: column fill.
    rotation : the box frame (3, 3); default :func:`ground_rotation`.
    """
    if len(points) < min_points:
        return []
    R = ground_rotation(points) if rotation is None else rotation
    local = points @ R
    pmin, pmax = local.min(0), local.max(0)
    ext = pmax - pmin
    c = cell
    while np.prod(np.ceil(ext / c) + 1) > MAX_VOXELS:
        c *= 1.25
    dims = np.maximum(np.ceil(ext / c).astype(int), 1)
    idx = np.minimum(np.floor((local - pmin) / c).astype(int), dims - 1)
    surf = np.zeros(tuple(dims), dtype=bool)
    surf[idx[:, 0], idx[:, 1], idx[:, 2]] = True
    if solid is not None:
        g = np.stack(np.meshgrid(*[np.arange(d) for d in dims], indexing="ij"), -1).reshape(-1, 3)
        centers = (pmin + (g + 0.5) * c) @ R.T
        hidden = np.asarray(solid(centers), bool).reshape(surf.shape) & ~surf
        occ, loose = evidence_fill(surf, hidden), surf | hidden
    else:
        occ = loose = _column_fill(surf)
    out = []
    min_vox = max(min_voxels, int(SPECK_FRACTION * surf.sum()))
    min_pts = max(min_points, int(SPECK_FRACTION * len(points)))
    for lo, hi in merge_slabs([(lo, hi) for lo, hi, _ in slabs(occ, min_vox, seed_mask=surf)], occ, loose):
        blo = np.maximum(pmin + lo * c, pmin)
        bhi = np.minimum(pmin + (hi + 1) * c, pmax)
        size = np.maximum(bhi - blo, 0.5 * c)
        inside = np.all((idx >= lo) & (idx <= hi), axis=1)
        npts = int(inside.sum())
        if npts < min_pts:
            continue
        # a face with points in its boundary voxel layer was seen: move it onto them
        qlo, qhi = local[inside].min(0), local[inside].max(0)
        blo = np.where(qlo < blo + c, qlo, blo)
        bhi = np.where(qhi > bhi - c, qhi, bhi)
        size = np.maximum(bhi - blo, 0.5 * c)
        center = R @ ((blo + bhi) / 2)
        out.append(FittedBox(center, R.copy(), size, npts))
    return out


def dominant_planes(points: np.ndarray, threshold: float, rng: np.random.Generator,
                    min_fraction: float = 0.2) -> list[np.ndarray]:
    """Up to two unit normals of large RANSAC planes of ``points``, the second roughly
    orthogonal to the first (vectorised RANSAC of :mod:`pipeline.planes`)."""
    from .planes import ransac_plane

    if len(points) < 30:
        return []
    n1, o1, c1 = ransac_plane(points, threshold, rng, hypotheses=200, score_sample=3000)
    if c1 < min_fraction * len(points):
        return []
    rest = np.abs(points @ n1 + o1) >= threshold
    out = [n1]
    if rest.sum() >= 30:
        n2, _, c2 = ransac_plane(points[rest], threshold, rng, hypotheses=600, score_sample=3000,
                                 orthogonal_to=n1)
        if c2 >= 0.5 * min_fraction * len(points) and abs(n1 @ n2) < 0.26:
            out.append(n2)
    return out


def slant_frame(normals: list[np.ndarray]) -> np.ndarray | None:
    """Box frame (3, 3) from dominant plane normals when the first one is tilted, else None."""
    if len(normals) < 2:  # the paper's rule: two orthogonal planes give a slanted frame
        return None
    n1 = normals[0]
    tilt = np.degrees(np.arccos(min(1.0, abs(n1[2]))))
    if not (SLANT_MIN_DEG < tilt < 90 - SLANT_MIN_DEG):
        return None
    a2 = normals[1] - (normals[1] @ n1) * n1
    a2 /= np.linalg.norm(a2)
    R = np.stack([n1, a2, np.cross(n1, a2)], axis=1)
    return R


#: A leaning board seen by its broad face only: the one tilted RANSAC plane must hold
#: this share of the object's points (the rest: its edges and the noise around them).
LEAN_MIN_SHARE = 0.85


def lean_frame(points: np.ndarray, normal: np.ndarray, threshold: float) -> np.ndarray | None:
    """Box frame (3, 3) of a board that leans, seen by one face only, or None.

    Evidence: one large plane tilted between :data:`SLANT_MIN_DEG` and its complement
    from the vertical, holding :data:`LEAN_MIN_SHARE` of the object's points and wide
    enough in both directions for its tilt to be known: across a width ``w`` a plane
    of points within ``threshold`` turns by up to ``atan(2 threshold / w)``, which must
    stay under half of :data:`SLANT_MIN_DEG` (a board's edge strip, 3 cm wide, turns
    freely about its length).
    Principle: a box that leans rests on one of its edges (on the floor, on a shelf),
    and an edge that rests on a level surface is level; so one axis of the box is the
    horizontal line in the seen face, the second its line of steepest slope, the third
    the face's normal.  The paper's rule needs a second, orthogonal plane, which a thin
    board seen from the front does not show (its edge holds 1-3 % of the points)."""
    n = np.asarray(normal, float)
    tilt = np.degrees(np.arccos(min(1.0, abs(n[2]))))
    if not (SLANT_MIN_DEG < tilt < 90 - SLANT_MIN_DEG):
        return None
    d = points @ n
    on = np.abs(d - np.median(d)) < 2.0 * threshold
    if on.mean() < LEAN_MIN_SHARE:
        return None
    level = np.cross([0.0, 0.0, 1.0], n)
    level /= np.linalg.norm(level)
    # a uniform spread of width w has deviation w / sqrt(12)
    q = points[on] - points[on].mean(0)
    cov = np.cov(np.c_[q @ level, q @ np.cross(n, level)].T)
    width = np.sqrt(12.0 * max(float(np.linalg.eigvalsh(cov)[0]), 0.0))
    if width < 2.0 * threshold / np.tan(np.radians(SLANT_MIN_DEG / 2)):
        return None
    return np.stack([n, level, np.cross(n, level)], axis=1)


#: A box turned within its one seen face (standing on an edge or a corner, leaning): the
#: face's minimum-area rectangle must be turned by more than :data:`SLANT_MIN_DEG` from
#: upright, fill at least this share of itself with the face's points (counted on a grid
#: of half a voxel), be at most this share of the upright rectangle's area, and the face
#: must hold this many points (a smaller face's outline is its sampling's).
FACE_RECT_MIN_FILL = 0.7
FACE_RECT_MAX_AREA = 0.85
FACE_MIN_POINTS = 300


def face_turn_frame(points: np.ndarray, normal: np.ndarray, threshold: float,
                    cell: float) -> np.ndarray | None:
    """Box frame (3, 3) of a box turned within its one large, near-vertical seen face,
    or None.

    Evidence: the outline of the face.  Principle: a face of a box is a rectangle; when
    its minimum-area rectangle (OpenCV ``minAreaRect`` of the face's points in its
    plane) is turned from upright by more than :data:`SLANT_MIN_DEG`, fills itself
    (:data:`FACE_RECT_MIN_FILL` of it covered at half the voxel size ``cell``), holds
    :data:`FACE_MIN_POINTS` points, and is clearly
    smaller than the upright rectangle around the same points
    (:data:`FACE_RECT_MAX_AREA`), the box is turned by that angle about the face's
    normal: a board standing on its corner, a box leaning sideways on another.  The
    surface normals cannot tell this turn (they all point along the face normal)."""
    import cv2

    n = np.asarray(normal, float)
    if abs(n[2]) > np.sin(np.radians(SLANT_MIN_DEG)):
        return None
    n = np.array([n[0], n[1], 0.0]) / np.linalg.norm(n[:2])
    u = np.cross([0.0, 0.0, 1.0], n)
    on = np.abs((points - points.mean(0)) @ n) < threshold
    if on.sum() < FACE_MIN_POINTS:
        return None
    xy = np.stack([points[on] @ u, points[on, 2]], axis=1).astype(np.float32)
    (cx, cy), (w, h), ang = cv2.minAreaRect(xy)
    turn = ang % 90.0
    if min(turn, 90.0 - turn) <= SLANT_MIN_DEG:
        return None
    lo, hi = xy.min(0), xy.max(0)
    upright_area = float(np.prod(hi - lo))
    area = float(w * h)
    g = cell / 2
    cells = len(np.unique(np.floor(xy / g).astype(np.int64), axis=0))
    if (area <= 0 or area > FACE_RECT_MAX_AREA * upright_area
            or cells * g * g < FACE_RECT_MIN_FILL * area):
        return None
    t = np.radians(ang)
    a1 = np.cos(t) * u + np.sin(t) * np.array([0.0, 0.0, 1.0])
    a2 = np.cross(n, a1)
    return np.stack([n, a1, a2], axis=1)


def fit_object(points: np.ndarray, cell: float, rng: np.random.Generator, *,
               solid: Callable[[np.ndarray], np.ndarray] | None = None,
               plane_threshold: float | None = None, min_points: int = 20,
               normals: np.ndarray | None = None, rotation: np.ndarray | None = None,
               single: bool = False, viewpoint: np.ndarray | None = None) -> list[FittedBox]:
    """Cuboids for one object: one slanted box, or ground-aligned boxes.

    Parameters
    ----------
    normals : (n, 3) unit normals of ``points`` (:func:`estimate_normals`); they orient
        a single part (:func:`upright_rotation`) and place seen faces (:func:`face_extents`).
    rotation : the upright frame to use (e.g. shared by the parts of one object).
    single : the points are one part (the segmentation names parts): one box
        (:func:`fit_part`) instead of the slab cover of :func:`fit_upright`.
    viewpoint : (3,) the centre of the one camera that saw every point, world; it tells
        which face a point lies on (:func:`face_extents`).
    """
    if len(points) < min_points:
        return []
    from .segment import point_spacing

    # a voxel must catch a point on every sampled surface, whatever the caller's cell
    cell = max(cell, 3.0 * point_spacing(points))
    thr = plane_threshold if plane_threshold is not None else 1.0 * cell
    planes = dominant_planes(points, thr, rng)
    R = slant_frame(planes)
    if R is None and len(planes) == 1:
        R = lean_frame(points, planes[0], thr)
    if R is None and len(planes) == 1:
        R = face_turn_frame(points, planes[0], thr, cell)
    elif R is not None and normals is not None and (
            aligned_share(normals, upright_rotation(points, normals))
            >= aligned_share(normals, R) - SLANT_MARGIN):
        R = None  # the surface normals fit an upright frame as well: the planes were noise
    if R is not None:
        local = points @ R
        if normals is not None:
            eye = None if viewpoint is None else np.asarray(viewpoint, float) @ R
            lo, hi = face_extents(local, normals @ R, trim=0.5, eye=eye, cell=cell)
        else:
            lo, hi = np.percentile(local, [0.5, 99.5], axis=0)
        size = np.maximum(hi - lo, cell)
        return [FittedBox(R @ ((lo + hi) / 2), R, size, len(points), slanted=True)]
    if single and normals is not None:
        if rotation is None:
            rotation = upright_rotation(points, normals)
        return fit_part(points, normals, cell, rotation, min_points, viewpoint)
    # an object of several parts: its outline's rectangle orients the slab cover
    return fit_upright(points, cell, solid=solid, min_points=min_points, rotation=rotation)


def box_iou(c1: np.ndarray, R1: np.ndarray, s1: np.ndarray, c2: np.ndarray, R2: np.ndarray,
            s2: np.ndarray, samples: int = 200_000, rng: np.random.Generator | None = None) -> float:
    """Monte-Carlo 3D IoU of two oriented boxes (sample the union's bounding box)."""
    from .model import box_corners

    rng = rng or np.random.default_rng(0)
    corners = box_corners(np.stack([c1, c2]), np.stack([R1, R2]), np.stack([s1, s2])).reshape(-1, 3)
    lo, hi = corners.min(0), corners.max(0)
    p = lo + rng.random((samples, 3)) * (hi - lo)
    in1 = np.all(np.abs((p - c1) @ R1) <= s1 / 2, axis=1)
    in2 = np.all(np.abs((p - c2) @ R2) <= s2 / 2, axis=1)
    union = (in1 | in2).sum()
    return float((in1 & in2).sum() / union) if union else 0.0
