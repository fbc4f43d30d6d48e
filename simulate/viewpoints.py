"""Camera viewpoints around a scene: sampled in distance, height (or elevation) and azimuth.

A viewpoint is a Kinect-like pose: the camera at ``distance`` from the scene centre (the
centre of the cuboids' bounding box), looking at the centre with the world's z up.  By
default its eye is held at a ``height`` above the floor drawn over the range a person
films from (crouching to arms raised, :data:`FILMING_HEIGHT`), so that views from low
down, looking up under a table top, are as likely as views from above; the elevation
follows from height and distance.  Given an ``elevation`` range instead, the camera is
raised by that angle above the horizontal through the centre.  ``K`` views are spread evenly over the
azimuth range (a KinectFusion-like sweep) from a random start.  Walls are respected: the
camera stays in front of every wall (a room is seen from inside), moving closer along
its ray when needed, and with walls present the default azimuths face the open side.
Without walls, ``facing`` keeps the azimuths within an angle of a normal of the broad
side of the scene's footprint, as a person scanning a wall of boxes stands in front of
it rather than at its end.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.camera import Intrinsics, look_at
from pipeline.errors import InputError
from pipeline.model import Arrangement, box_corners

#: Keep the camera at least this far in front of any wall, metres.
WALL_MARGIN = 0.15
#: Eye heights above the floor a person films from, metres: crouching with the camera at
#: knee height up to holding it above the head.
FILMING_HEIGHT = (0.3, 2.0)
#: Distances to the scene centre, metres: from arm's length to across a room (the
#: Kinect's depth is useful to about 4 m; ``fit`` moves farther when the scene needs it).
FILMING_DISTANCE = (1.0, 3.5)
#: Steepest view in height mode: the camera never looks more than this far below or
#: above the horizontal (a camera looking straight down has no defined roll), degrees.
MAX_STEEPNESS_DEG = 75.0


@dataclass(frozen=True)
class ViewRanges:
    """Sampling ranges (closed intervals) of a viewpoint around the scene centre.

    ``height`` (metres above the floor, the default :data:`FILMING_HEIGHT`) places the
    eye at a sampled height; with ``height = None`` the camera is raised by a sampled
    ``elevation_deg`` above the horizontal through the centre instead.  A dict naming
    ``elevation`` (and no ``height``) selects the elevation mode.  In height mode a view
    steeper than :data:`MAX_STEEPNESS_DEG` moves back until it is not.

    ``azimuth_deg = None`` means the full circle without walls, and +-75 degrees around
    the open side (the mean wall normal) with walls.  ``fit`` moves the camera back so
    the scene's bounding sphere fills at most the image (never closer than sampled, and
    never farther than ``max_fit_distance``, the Kinect's useful range: a large room is
    then seen in part, as a real single scan would).  ``facing_deg`` (no walls, no
    azimuth range): azimuths within this angle of the outward normal of one long side
    (picked at random) of the footprint's minimum-area rectangle.
    """

    distance: tuple[float, float] = FILMING_DISTANCE
    elevation_deg: tuple[float, float] = (20.0, 45.0)
    azimuth_deg: tuple[float, float] | None = None
    fit: bool = True
    max_fit_distance: float = 4.0
    facing_deg: float | None = None
    height: tuple[float, float] | None = FILMING_HEIGHT

    @classmethod
    def from_dict(cls, d: dict | None) -> ViewRanges:
        """Build from ``{"distance": (a, b), "height": (a, b) | "elevation": (a, b),
        "azimuth": (a, b)}``."""
        if d is None:
            return cls()
        if isinstance(d, ViewRanges):
            return d
        known = {"distance", "elevation", "azimuth", "elevation_deg", "azimuth_deg", "fit",
                 "facing", "facing_deg", "height"}
        bad = set(d) - known
        if bad:
            raise InputError(f"view ranges: unknown keys {sorted(bad)}; expected distance, "
                             "height (m) or elevation, azimuth, facing (degrees), fit")
        out = {}
        if ("elevation" in d or "elevation_deg" in d) and d.get("height") is None:
            out["height"] = None  # an elevation range asks for the elevation mode
        for key, name in (("distance", "distance"), ("elevation", "elevation_deg"),
                          ("elevation_deg", "elevation_deg"), ("azimuth", "azimuth_deg"),
                          ("azimuth_deg", "azimuth_deg"), ("height", "height")):
            if key in d and d[key] is not None:
                v = d[key]
                if np.isscalar(v):
                    v = (v, v)
                lo, hi = (float(x) for x in v)
                if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
                    raise InputError(f"view ranges.{key}: need two finite numbers lo <= hi")
                out[name] = (lo, hi)
        if "distance" in out and out["distance"][0] <= 0:
            raise InputError("view ranges.distance: must be positive metres")
        if out.get("height") is not None and out["height"][0] <= 0:
            raise InputError("view ranges.height: must be positive metres above the floor")
        if "fit" in d:
            out["fit"] = bool(d["fit"])
        for key in ("facing", "facing_deg"):
            if d.get(key) is not None:
                f = float(d[key])
                if not (np.isfinite(f) and 0.0 <= f <= 180.0):
                    raise InputError(f"view ranges.{key}: need degrees in [0, 180], got {d[key]!r}")
                out["facing_deg"] = f
        return cls(**out)


def scene_center(arr: Arrangement) -> tuple[np.ndarray, float]:
    """Centre (3,) and radius of the cuboids' bounding box (origin and 0.5 m if empty)."""
    if not arr.cuboids:
        return np.zeros(3), 0.5
    corners = box_corners(arr.centers, arr.rotations, arr.sizes).reshape(-1, 3)
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    return (lo + hi) / 2, float(np.linalg.norm(hi - lo) / 2)


def broad_side_azimuth(arr: Arrangement) -> float:
    """Azimuth (radians) of an outward normal of a long side of the footprint.

    The footprint is the minimum-area rectangle (OpenCV) around the cuboids' corners seen
    from above; of its two long-side normals the one with azimuth in [-pi/2, pi/2) is
    returned (the other is this plus pi).
    """
    import cv2

    if not arr.cuboids:
        return 0.0
    xy = box_corners(arr.centers, arr.rotations, arr.sizes).reshape(-1, 3)[:, :2]
    (_, _), (w, h), angle = cv2.minAreaRect(xy.astype(np.float32))
    a = np.deg2rad(angle)
    side = np.array([np.cos(a), np.sin(a)]) if w >= h else np.array([-np.sin(a), np.cos(a)])
    normal = np.array([-side[1], side[0]])  # perpendicular to the long side
    az = float(np.arctan2(normal[1], normal[0]))
    if not -np.pi / 2 <= az < np.pi / 2:
        az = az - np.pi if az >= np.pi / 2 else az + np.pi
    return az


def sample_viewpoints(arr: Arrangement, rng: np.random.Generator, views: int = 1,
                      ranges: ViewRanges | dict | None = None,
                      intrinsics: Intrinsics | None = None) -> np.ndarray:
    """Sample ``views`` camera poses around the scene.

    Parameters
    ----------
    arr : Arrangement
    rng : numpy.random.Generator
    views : int
    ranges : ViewRanges or dict, optional
    intrinsics : Intrinsics, optional
        Used by ``fit`` (default Kinect v1).

    Returns
    -------
    poses : (views, 4, 4) float, camera-to-world (OpenCV camera frame)
    """
    if views < 1:
        raise InputError(f"views: must be at least 1, got {views}")
    r = ViewRanges.from_dict(ranges) if not isinstance(ranges, ViewRanges) else ranges
    intr = intrinsics or Intrinsics.kinect_v1()
    center, radius = scene_center(arr)
    walls = [s for s in arr.supports if s.id != "ground"]

    if r.azimuth_deg is not None:
        a_lo, a_hi = np.deg2rad(r.azimuth_deg)
    elif walls:
        open_dir = np.sum([s.normal[:2] for s in walls], axis=0)
        mid = np.arctan2(open_dir[1], open_dir[0]) if np.linalg.norm(open_dir) > 1e-9 else 0.0
        a_lo, a_hi = mid - np.deg2rad(75), mid + np.deg2rad(75)
    elif r.facing_deg is not None:
        mid = broad_side_azimuth(arr) + np.pi * float(rng.integers(0, 2))
        a_lo, a_hi = mid - np.deg2rad(r.facing_deg), mid + np.deg2rad(r.facing_deg)
    else:
        a_lo, a_hi = 0.0, 2 * np.pi
    span = a_hi - a_lo
    start = rng.uniform(0.0, 1.0)
    az = a_lo + span * (start + np.arange(views)) / views  # evenly spread, random phase
    if r.height is None:
        el = np.deg2rad(rng.uniform(*r.elevation_deg, size=views))
    else:
        rise = rng.uniform(*r.height, size=views) - center[2]  # eye above the centre
    dist = rng.uniform(*r.distance, size=views)
    if r.fit:
        half_fov = np.arctan(min(intr.width / (2 * intr.fx), intr.height / (2 * intr.fy)))
        fit = min(1.1 * radius / np.sin(half_fov), r.max_fit_distance)
        dist = np.maximum(dist, fit)
    if r.height is not None:  # step back until the view is no steeper than allowed
        dist = np.maximum(dist, np.abs(rise) / np.sin(np.deg2rad(MAX_STEEPNESS_DEG)))
        el = np.arcsin(rise / dist)

    dirs = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=1)
    for s in walls:  # stay in front of each wall: clamp the distance along the ray
        dn = dirs @ s.normal
        h = s.signed_distance(center[None])[0] - WALL_MARGIN
        with np.errstate(divide="ignore"):
            limit = np.where(dn < 0, h / -dn, np.inf)
        dist = np.minimum(dist, np.maximum(limit, 0.3))
    eyes = center + dirs * dist[:, None]
    return np.stack([look_at(e, center) for e in eyes])
