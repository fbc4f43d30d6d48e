"""Ground and walls by RANSAC, and the world frame they define (z up, ground at z = 0).

The lowest large plane whose normal is close to the expected up direction is the
ground (or the table top when the scan is of a table); large planes orthogonal to it
are walls.  When the input has no camera pose, the world frame is chosen here: z is the
ground normal, the origin is the foot of the camera centre on the ground, and x is the
camera's x axis projected on the ground, so the picture keeps its left and right.  With
a known pose the frame is kept and a ground fitted within a few degrees of its z is made
level (z is up for gravity, the statics and the engines; the fitted tilt is noise).

The floor from a prior
----------------------
A camera pose says where the floor is: the world of a pose is z up with the floor at
z = 0 (the contract of scene directories, multi-view folders and of ``unseen run``'s own
``meta.camera_pose``).  So do ``--up`` with ``--floor-height`` (metres along up in the
input frame).  With such a prior the floor is the prior, and RANSAC only refines it: a
RANSAC plane is taken instead when its normal is within :data:`FLOOR_PRIOR_MAX_DEG` of
the prior's and the floor height it gives (below the input frame's origin: the camera of
an RGB-D frame) is within :data:`FLOOR_PRIOR_MAX_OFFSET` of the prior's; the largest such
plane wins.  Otherwise the prior is kept as it is, even
against a large plane elsewhere (a table top, or a floor the user placed wrongly: the
given floor wins and the report says by how much RANSAC's plane disagreed).  A floor out
of the picture is then no error.

Rooms are square
----------------
Walls are plumb and meet at right angles.  A far wall is a slab of points several
centimetres thick (Kinect's axial noise is 5 cm at 5.5 m), and a RANSAC plane through
it errs by degrees, in yaw and in tilt; every box fixed to that wall, or turned onto its
yaw, inherits the error.  So a wall found after the first (the largest) whose normal
lies within :data:`WALL_SQUARE_DEG` of a right angle or of parallel to the first wall's,
in plan, takes that angle exactly, plumb, through the median of its own inliers along
its new normal; squared parallel to a wall already found and within
:data:`WALL_TWIN_DIST` of it, it is that wall's far layer, as any such plane is.  The
first wall, the reference, stays as fitted (making walls plumb alone did not pay on a
held-out pool, docs/results.md).  A wall further off stays as fitted (a bay window's
wall, a corridor's bend): the prior rounds the fit's error, not the room.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .camera import transform
from .errors import InputError
from .model import Support

#: A plane must hold this fraction of the (downsampled) points to count as large.
MIN_PLANE_FRACTION = 0.04
#: Normal within this angle of up: candidate ground.  Within 90 deg +/- this: wall.
GROUND_MAX_ANGLE_DEG = 25.0
WALL_MAX_TILT_DEG = 12.0
#: With a known camera pose (its z up), a ground whose fitted normal is within this
#: many degrees of z is taken as level (the tilt :func:`pipeline.imagine.align_boxes`
#: takes off a box that stands on it).
GROUND_LEVEL_MAX_DEG = 15.0
#: The ground is the lowest upward plane holding at least this share of the largest
#: upward plane's points (so a sofa seat below a table top does not win).
GROUND_MIN_SHARE = 0.8
#: The floor has (almost) nothing below it: when more than this share of the points lie
#: :data:`BELOW_MARGIN` or more under the chosen plane, the plane is a table top or a seat
#: and the floor is looked for lower down (:func:`lower_floor`).
GROUND_MAX_BELOW = 0.05
BELOW_MARGIN = 0.05
#: A floor found under a table top must hold at least this many points (and this share of
#: the points), within its normal this many degrees of the plane above.
LOWER_FLOOR_MIN_POINTS = 300
LOWER_FLOOR_MIN_SHARE = 0.002
LOWER_FLOOR_MAX_DEG = 10.0
#: A large horizontal plane this high above the ground with nothing above it is a ceiling.
CEILING_MIN_HEIGHT = 1.8
#: A vertical plane is a wall only if at most this fraction of the points lie behind it
#: (a box face has the rest of the box behind it).
WALL_MAX_BEHIND = 0.10
#: A vertical plane whose points the segmentation assigns to objects (an instance mask:
#: per-point ids > 0) for more than this share is an object's face, not a wall (the
#: coplanar fronts of a row of pillars, a wardrobe's door seen face-on).
WALL_MAX_OBJECT_SHARE = 0.5
#: A vertical plane parallel to a wall already found (normals within this many degrees)
#: and this close to it (metres) is the same wall: at 4 m a Kinect's depth noise makes a
#: wall a slab thicker than the RANSAC threshold, and RANSAC returns it as two planes.
WALL_TWIN_DEG = 5.0
WALL_TWIN_DIST = 0.10
#: A wall whose normal is within this many degrees (in plan) of a right angle or of
#: parallel to the first wall's is square to it: plumb, at that angle exactly.
WALL_SQUARE_DEG = 10.0
#: With a floor prior (a camera pose, or ``--up`` with ``--floor-height``), a RANSAC
#: plane refines the floor only when its normal is within this many degrees of the
#: prior's and the floor height it gives (below the input origin) within this many metres.
FLOOR_PRIOR_MAX_DEG = 5.0
FLOOR_PRIOR_MAX_OFFSET = 0.05


@dataclass(frozen=True)
class Plane:
    """``normal . p + offset = 0`` with a unit normal; ``count`` inliers of the sample."""

    normal: np.ndarray  #: (3,) float
    offset: float
    count: int

    def distance(self, points: np.ndarray) -> np.ndarray:
        """(n,) signed distance of ``points (n, 3)``."""
        return points @ self.normal + self.offset


@dataclass(frozen=True)
class SceneFrame:
    """The world frame the scan was put in, and its support planes.

    Attributes
    ----------
    T_world_input : (4, 4) float
        Maps input-frame points (camera frame for RGB-D) to world (z up, ground z = 0).
    ground : Support
    walls : tuple of Support
    labels : (n,) int
        Per input point: -1 not on a plane, 0 ground, k >= 1 wall k-1, -2 below ground,
        -3 ceiling (and above).
    planes : list of Plane
        Every plane RANSAC found (input frame), for the report.
    threshold : float
        RANSAC inlier distance used, metres.
    """

    T_world_input: np.ndarray
    ground: Support
    walls: tuple
    labels: np.ndarray
    planes: list = field(default_factory=list)
    threshold: float = 0.0
    #: where the floor came from: ``ransac`` (no prior), ``prior`` (kept as given) or
    #: ``prior+ransac`` (a RANSAC plane that agrees with the prior)
    floor: str = "ransac"
    #: what the report should say about the floor (a prior kept against RANSAC, ...)
    notes: tuple = ()


def scene_scale(points: np.ndarray) -> float:
    """Robust scene diameter (metres): the diagonal of the 1-99 % percentile box."""
    lo, hi = np.percentile(points, [1, 99], axis=0)
    return float(max(np.linalg.norm(hi - lo), 1e-6))


def fit_plane_lsq(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares plane of ``points (n, 3)``: (unit normal, offset)."""
    c = points.mean(0)
    _, _, vt = np.linalg.svd(points - c, full_matrices=False)
    n = vt[2]
    return n, float(-n @ c)


#: Sample points scored against all hypotheses at once in :func:`ransac_plane`.
SCORE_BLOCK = 2048


def ransac_plane(points: np.ndarray, threshold: float, rng: np.random.Generator,
                 hypotheses: int = 300, score_sample: int = 6000,
                 orthogonal_to: np.ndarray | None = None,
                 max_cos: float = 0.26) -> tuple[np.ndarray, float, int]:
    """One RANSAC plane, all hypotheses at once (vectorised numpy).

    ``hypotheses`` random point triples give candidate planes; each is scored by its
    inlier count on a random subsample of ``score_sample`` points; the best one is
    returned as (unit normal, offset, inlier count on all ``points``).  With
    ``orthogonal_to`` only planes whose normal makes |cos| < ``max_cos`` with it count.
    """
    n = len(points)
    tri = rng.integers(0, n, size=(hypotheses, 3))
    a, b, c = points[tri[:, 0]], points[tri[:, 1]], points[tri[:, 2]]
    nrm = np.cross(b - a, c - a)
    ln = np.linalg.norm(nrm, axis=1)
    ok = ln > 1e-12
    nrm, a = nrm[ok] / ln[ok, None], a[ok]
    if not len(nrm):  # every triple degenerate (collinear or repeated points)
        return np.array([0.0, 0.0, 1.0]), 0.0, 0
    if orthogonal_to is not None:
        keep = np.abs(nrm @ orthogonal_to) < max_cos
        if not keep.any():
            return np.asarray(orthogonal_to, float), 0.0, 0
        nrm, a = nrm[keep], a[keep]
    off = -np.einsum("ij,ij->i", nrm, a)
    sub = points[rng.integers(0, n, size=min(score_sample, n))]
    # inliers of every hypothesis, counted over blocks of the sample that stay in the
    # cache (three times faster than one sample-by-hypotheses array, the same counts)
    score = np.zeros(len(nrm), np.int64)
    buf = np.empty((min(SCORE_BLOCK, len(sub)), len(nrm)))
    for i in range(0, len(sub), SCORE_BLOCK):
        block = sub[i:i + SCORE_BLOCK]
        d = buf[:len(block)]
        np.matmul(block, nrm.T, out=d)
        d += off
        np.abs(d, out=d)
        score += np.count_nonzero(d < threshold, axis=0)
    k = int(np.argmax(score))
    cnt = int((np.abs(points @ nrm[k] + off[k]) < threshold).sum())
    return nrm[k], float(off[k]), cnt


def ransac_planes(points: np.ndarray, threshold: float, rng: np.random.Generator,
                  max_planes: int = 8, min_fraction: float = MIN_PLANE_FRACTION,
                  sample: int = 25000) -> list[Plane]:
    """Sequential RANSAC on a subsample of ``points``.

    Each plane is refined by least squares on its inliers; inliers are removed and the
    search repeats until a plane holds less than ``min_fraction`` of the sample.  (A
    vectorised numpy RANSAC rather than Open3D's ``segment_plane``: five times faster
    here, and bit-reproducible from ``rng`` whatever the thread count.)
    """
    n = len(points)
    idx = rng.choice(n, size=min(sample, n), replace=False) if n > sample else np.arange(n)
    pts = points[np.sort(idx)]
    total = len(pts)
    planes: list[Plane] = []
    remaining = pts
    for _ in range(max_planes):
        if len(remaining) < max(30, min_fraction * total):
            break
        nrm, off, cnt = ransac_plane(remaining, threshold, rng)
        if cnt < min_fraction * total:
            break
        inlier = np.abs(remaining @ nrm + off) < threshold
        n2, o2 = fit_plane_lsq(remaining[inlier])
        for tighter in (0.5, 0.25):  # refit on ever closer points: edges of things on it drop out
            close = np.abs(remaining @ n2 + o2) < tighter * threshold
            if close.sum() >= 3:
                n2, o2 = fit_plane_lsq(remaining[close])
        nrm, off = n2, o2
        inlier = np.abs(remaining @ nrm + off) < threshold
        planes.append(Plane(nrm, off, int(inlier.sum())))
        remaining = remaining[~inlier]
    return planes


def floor_prior(up: np.ndarray | None = None, T_world_input: np.ndarray | None = None,
                floor_height: float | None = None) -> Plane | None:
    """The floor a prior gives, as a plane in the input frame (normal = up), or None.

    ``floor_height`` (metres along up in the input frame, the up of ``up`` or else of
    the pose) wins over the pose; a pose alone puts the floor at world z = 0.
    """
    if floor_height is not None:
        h = float(floor_height)
        if not np.isfinite(h):
            raise InputError(f"--floor-height: must be a finite number of metres, got {h}")
        if up is not None:
            n = np.asarray(up, float) / np.linalg.norm(up)
        elif T_world_input is not None:
            n = np.asarray(T_world_input, float)[:3, :3].T @ np.array([0.0, 0.0, 1.0])
        else:
            raise InputError("--floor-height: give --up too (the direction the height is "
                             "measured along in the input frame), e.g. --up=-y")
        return Plane(n, -h, 0)
    if T_world_input is not None:
        T = np.asarray(T_world_input, float)
        # world z of an input point p is (R p + t)_z = n . p + t_z
        return Plane(T[:3, :3].T @ np.array([0.0, 0.0, 1.0]), float(T[2, 3]), 0)
    return None


def refine_floor(planes: list[Plane], prior: Plane, max_deg: float = FLOOR_PRIOR_MAX_DEG,
                 max_offset: float = FLOOR_PRIOR_MAX_OFFSET) -> tuple[Plane | None, str]:
    """The RANSAC plane that agrees with the floor ``prior`` (largest first), or None.

    A plane agrees when its normal (turned to the prior's side) is within ``max_deg`` of
    the prior's and the floor height it gives differs from the prior's by at most
    ``max_offset`` metres.  Heights are measured where the prior's floor height is
    defined: below the input frame's origin (the camera of an RGB-D frame), so an up
    direction a few degrees off does not move the floor by metres far from the camera.
    Also returns a line for the report about the largest plane near the prior's
    direction that did not agree (empty when none).
    """
    best, near = None, None
    cos_max = np.cos(np.radians(max_deg))
    cos_near = np.cos(np.radians(GROUND_MAX_ANGLE_DEG))
    for p in planes:
        c = float(p.normal @ prior.normal)
        nrm, off = (p.normal, p.offset) if c > 0 else (-p.normal, -p.offset)
        q = Plane(nrm, off, p.count)
        if abs(c) < cos_near:
            continue
        # the origin is ``offset`` above a plane: the plane lies ``gap`` above the prior
        gap = float(prior.offset - off)
        if abs(c) >= cos_max and abs(gap) <= max_offset:
            if best is None or q.count > best.count:
                best = q
        elif near is None or q.count > near[0].count:
            near = (q, gap, float(np.degrees(np.arccos(min(1.0, abs(c))))))
    note = ""
    if near is not None and (best is None or near[0].count > best.count):
        note = (f"floor: kept the given floor; the largest plane RANSAC found near it lies "
                f"{near[1]:+.3f} m above it, tilted {near[2]:.1f} deg (a refinement must lie "
                f"within {max_offset:.2f} m and {max_deg:.0f} deg)")
    return best, note


def find_frame(points: np.ndarray, rng: np.random.Generator, *, up: np.ndarray | None = None,
               T_world_input: np.ndarray | None = None, camera_frame: bool = False,
               threshold: float | None = None, floor_height: float | None = None,
               object_points: np.ndarray | None = None) -> SceneFrame:
    """Detect ground and walls and choose the world frame.

    Parameters
    ----------
    points : (n, 3) float, input frame
    up : (3,) float or None
        Up direction in the input frame (``--up``).  Default: from ``T_world_input``
        when given, else -y for a camera frame (cameras are held roughly upright),
        else +z.
    T_world_input : (4, 4) float or None
        A known camera pose (synthetic scenes): kept as is.  Its world puts the floor at
        z = 0: the floor comes from it and RANSAC only refines it (module docstring).
    camera_frame : bool
        The input frame is a camera (its origin is the eye).
    threshold : RANSAC inlier distance, metres; default 0.3 % of the scene diameter
        (5 to 20 mm).
    floor_height : float or None
        The floor's height along up in the input frame, metres (``--floor-height``); up
        is ``up``, else the pose's.  Like a pose, a prior RANSAC only refines.
    object_points : (n,) bool or None
        Points a segmentation (an instance mask) assigns to objects: a vertical plane
        made mostly of them (:data:`WALL_MAX_OBJECT_SHARE`) is an object's face, not a wall.
    """
    if len(points) < 50:
        raise InputError("fewer than 50 valid points: nothing to fit (empty or all-NaN scan?)")
    scale = scene_scale(points)
    thr = threshold if threshold is not None else float(np.clip(0.003 * scale, 0.005, 0.02))
    if T_world_input is not None:
        prior = T_world_input[:3, :3].T @ np.array([0.0, 0.0, 1.0])
    elif up is not None:
        prior = np.asarray(up, float) / np.linalg.norm(up)
    else:
        prior = np.array([0.0, -1.0, 0.0]) if camera_frame else np.array([0.0, 0.0, 1.0])
    floor0 = floor_prior(up, T_world_input, floor_height)
    if floor0 is not None:
        prior = floor0.normal
    given = T_world_input is not None or up is not None
    planes = ransac_planes(points, thr, rng)
    cos_g = np.cos(np.radians(GROUND_MAX_ANGLE_DEG if given else 45.0))
    cands = []
    for p in planes:
        c = float(p.normal @ prior)
        if abs(c) >= cos_g:
            nrm, off = (p.normal, p.offset) if c > 0 else (-p.normal, -p.offset)
            cands.append(Plane(nrm, off, p.count))
    notes: tuple = ()
    if floor0 is not None:
        g, note = refine_floor(planes, floor0)
        source = "prior" if g is None else "prior+ransac"
        if g is None:
            g = floor0
        if note:
            notes = (note,)
    else:
        source = "ransac"
        if not cands:
            hint = "" if given else "; give --up (e.g. --up=-y for a camera frame, --up z)"
            raise InputError(f"no ground plane found (no large plane within "
                             f"{GROUND_MAX_ANGLE_DEG if given else 45:.0f} deg of the up "
                             f"direction {np.round(prior, 2).tolist()}){hint}; give "
                             "--floor-height with --up, or a camera pose")
        biggest = max(c.count for c in cands)
        # the lowest large one: height along up of the plane = -offset; lowest = largest offset
        large = [c for c in cands if c.count >= GROUND_MIN_SHARE * biggest]
        g = max(large, key=lambda c: c.offset)
        lower = lower_floor(points, g, thr, rng)
        if lower is not None:
            g, share = lower
            notes = (f"floor: the largest level plane had {100 * share:.0f}% of the "
                     "points below it (a table top); the floor is the level plane under them",)
    n_up = g.normal

    # world frame
    if T_world_input is not None:
        T = np.asarray(T_world_input, float).copy()
        n_w = T[:3, :3] @ n_up
        # ground height in world along z, keeping the given frame
        p0 = -g.offset * n_up
        z0 = float(transform(T, p0[None])[0] @ n_w)
        ground = Support("ground", np.array([0.0, 0.0, z0 / max(n_w[2], 1e-9)]), n_w)
        if source == "prior" and floor_height is None:
            ground = Support("ground", np.zeros(3), np.array([0.0, 0.0, 1.0]))  # z = 0 exactly
        elif source != "prior" and n_w[2] >= np.cos(np.radians(GROUND_LEVEL_MAX_DEG)):
            # the frame's z is up (gravity is -z): the floor is level, at the median height
            # of its points; the fitted tilt is depth noise (0.2-0.3 deg at 3-4 m), and
            # upright boxes on a tilted floor stand on one edge and rock onto the slope
            on = np.abs(ground.signed_distance(transform(T, points))) < 1.5 * thr
            if np.any(on):
                h = float(np.median(transform(T, points[on])[:, 2]))
                ground = Support("ground", np.array([0.0, 0.0, h]), np.array([0.0, 0.0, 1.0]))
    else:
        ex = _across(np.array([1.0, 0.0, 0.0]) if camera_frame else _any_perp(n_up), n_up,
                     1e-6)
        if ex is None:
            ex = _any_perp(n_up)
        ey = np.cross(n_up, ex)
        R_in_w = np.stack([ex, ey, n_up], axis=1)  # columns: world axes in input coords
        origin = -g.offset * n_up  # foot of the input origin on the plane
        if not camera_frame:
            c = points.mean(0)
            origin = c - (c @ n_up + g.offset) * n_up
        T = np.eye(4)
        T[:3, :3] = R_in_w.T
        T[:3, 3] = -R_in_w.T @ origin
        ground = Support("ground", np.zeros(3), np.array([0.0, 0.0, 1.0]))

    world = transform(T, points)
    labels = np.full(len(points), -1, dtype=np.int64)
    hz = ground.signed_distance(world)
    labels[np.abs(hz) < 1.5 * thr] = 0
    labels[hz <= -1.5 * thr] = -2
    # ceilings: large horizontal planes high above the ground with (almost) nothing above
    for p in cands:
        if p is g:
            continue
        pt_w = transform(T, (-p.offset * p.normal)[None])[0]
        h = float(ground.signed_distance(pt_w[None])[0])
        if h > CEILING_MIN_HEIGHT and (hz > h + 1.5 * thr).mean() < WALL_MAX_BEHIND:
            labels[hz > h - 3.0 * thr] = -3
    walls = []
    sin_w = np.sin(np.radians(WALL_MAX_TILT_DEG))
    cam_w = T[:3, 3]
    for p in planes:
        if abs(p.normal @ n_up) > sin_w:
            continue
        n_w = T[:3, :3] @ p.normal
        pt_w = transform(T, (-p.offset * p.normal)[None])[0]
        ref = cam_w if camera_frame or T_world_input is not None else world.mean(0)
        if (ref - pt_w) @ n_w < 0:
            n_w = -n_w
        if walls:
            square = square_to(n_w, walls[0].normal, ground.normal, WALL_SQUARE_DEG)
            if square is not None:
                inliers = world[np.abs(p.distance(points)) < 1.5 * thr]
                if len(inliers):
                    n_w = square
                    at = np.median(inliers, axis=0)
                    pt_w = at - (float(at @ n_w) - float(np.median(inliers @ n_w))) * n_w
        twin = next((k for k, w in enumerate(walls)
                     if n_w @ w.normal > np.cos(np.radians(WALL_TWIN_DEG))
                     and abs(float(w.signed_distance(pt_w[None])[0])) < WALL_TWIN_DIST), None)
        if twin is not None:  # the far side of one noisy wall: its points are that wall's
            d = Support("twin", pt_w, n_w).signed_distance(world)
            labels[(np.abs(d) < 1.5 * thr) & (labels == -1)] = twin + 1
            continue
        wall = Support(f"wall:{len(walls)}", pt_w, n_w)
        d = wall.signed_distance(world)
        if object_points is not None:
            near_plane = np.abs(d) < 1.5 * thr
            if near_plane.any() and object_points[near_plane].mean() > WALL_MAX_OBJECT_SHARE:
                continue  # the segmentation says these are an object's points
        # the wall, what sticks out of it by a little (handles, skirting) and what is behind
        on = (d < 3.0 * thr) & (labels == -1)
        # only a wall if most points are on its free side (not a box face)
        if (d < -1.5 * thr).mean() > WALL_MAX_BEHIND:
            continue
        labels[on] = len(walls) + 1
        walls.append(wall)
    return SceneFrame(T, ground, tuple(walls), labels, planes, thr, source, notes)


def square_to(normal: np.ndarray, first: np.ndarray, up: np.ndarray,
              max_deg: float = WALL_SQUARE_DEG) -> np.ndarray | None:
    """The plumb unit normal at an exact multiple of 90 degrees (in plan) from the wall
    normal ``first`` that is nearest to ``normal``, when within ``max_deg`` of it in
    plan and not ``normal`` itself; else None (``up``: the ground's normal)."""
    up = np.asarray(up, float) / np.linalg.norm(up)
    a, f = _across(normal, up), _across(first, up)
    if a is None or f is None:
        return None
    g = np.cross(up, f)  # in plan, a right angle from the first wall's normal
    options = (f, -f, g, -g)
    best = max(options, key=lambda o: float(o @ a))
    if float(best @ a) < np.cos(np.radians(max_deg)):
        return None
    if float(best @ np.asarray(normal, float)) >= 1.0 - 1e-12:
        return None
    return best


def lower_floor(points: np.ndarray, g: Plane, thr: float, rng: np.random.Generator
                ) -> tuple[Plane, float] | None:
    """The floor under ``g`` when ``g`` cannot be the floor, else None.

    Nothing rests below a floor: if more than :data:`GROUND_MAX_BELOW` of the points lie
    :data:`BELOW_MARGIN` or more under ``g`` (a table top filmed from above, the floor
    only at the picture's edge), the floor is the lowest thin level slab under it that
    RANSAC fits with a normal within :data:`LOWER_FLOOR_MAX_DEG` of ``g``'s, holding
    enough points (:data:`LOWER_FLOOR_MIN_POINTS`, :data:`LOWER_FLOOR_MIN_SHARE`) and
    itself with no more than that share below it.  Returns (that plane, the share of the
    points that lay below ``g``), or None when ``g`` has
    nothing under it or no such slab exists (then ``g`` stays: a tabletop scan)."""
    d = points @ g.normal + g.offset
    below = d < -max(BELOW_MARGIN, 3 * thr)
    share = float(below.mean())
    if share <= GROUND_MAX_BELOW:
        return None
    need = max(LOWER_FLOOR_MIN_POINTS, LOWER_FLOOR_MIN_SHARE * len(points))
    width = 2.0 * thr
    h, under = d[below], points[below]
    lo = float(h.min())
    edges = np.arange(lo, float(h.max()) + width, width)
    counts, _ = np.histogram(h, bins=edges) if len(edges) > 1 else (np.zeros(0), None)
    cos_max = np.cos(np.radians(LOWER_FLOOR_MAX_DEG))
    for k in np.flatnonzero(counts >= need / 2):
        mid = edges[k] + width / 2
        slab = under[np.abs(h - mid) < 2 * width]
        if len(slab) < need:
            continue
        nrm, off, cnt = ransac_plane(slab, thr, rng)
        c = float(nrm @ g.normal)
        if abs(c) < cos_max or cnt < need:
            continue
        nrm, off = (nrm, off) if c > 0 else (-nrm, -off)
        if float(np.mean(points @ nrm + off < -max(BELOW_MARGIN, 3 * thr))) > GROUND_MAX_BELOW:
            continue
        return Plane(nrm, off, int(cnt)), share
    return None


def _across(v: np.ndarray, n: np.ndarray, tol: float = 1e-9) -> np.ndarray | None:
    """The unit direction of ``v``'s part across the unit normal ``n`` (in plan, for
    ``n`` up); None when that part is no longer than ``tol``."""
    v = np.asarray(v, float)
    v = v - (v @ n) * n
    length = float(np.linalg.norm(v))
    return v / length if length > tol else None


def _any_perp(n: np.ndarray) -> np.ndarray:
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    return _across(a, n)
