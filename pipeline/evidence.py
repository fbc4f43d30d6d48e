"""What the scan says, built once per scan: depth views, noise, cameras, floor and walls.

The priors (:mod:`pipeline.priors`) and the candidate pruning (:mod:`pipeline.extend`)
read the scan only through this module, by one noise model:

* **seen empty**: a point some depth view saw past (it projects to a pixel whose nearest
  reading among the pixel and its 8 neighbours lies more than three noise deviations
  plus a margin behind it; :func:`visible_free_mask`).  A volume is seen empty when more
  than :data:`FREE_FRACTION_MAX` of its samples are, or when the median of its samples
  lies clearly in front of the depth (:func:`seen_in_front`);
* **in shadow**: a point hidden from the first camera by a box (:meth:`Evidence.in_shadow`);
* **observed points**: the back-projected depth with a tolerance per point
  (:meth:`Evidence.observed_cloud`, built on first use and kept with the evidence).

The noise model is Kinect v1's axial noise (Nguyen et al. 2012), :func:`depth_noise`.
Without a depth view (a bare point cloud) nothing is seen empty and nothing is in shadow.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from .camera import Intrinsics, invert, project, transform

#: A volume is seen empty when more than this fraction of its samples were seen through.
FREE_FRACTION_MAX = 0.1
#: The visibility test's extra tolerance, as a fraction of the scene's median box edge
#: (the boxes are fits to noisy points; their faces are no surer than that).
MARGIN_REL = 0.05
#: Observed points for yaw fits: every n-th row and column of every view.
CLOUD_STRIDE = 2


@dataclass(frozen=True, eq=False)
class DepthView:
    """One depth image with its camera, in the arrangement's world frame."""

    depth: np.ndarray  # (H, W) metres, 0 = no reading
    intrinsics: Intrinsics
    T_world_cam: np.ndarray

    @cached_property
    def nearest(self) -> np.ndarray:
        """The nearest reading among each pixel and its 8 neighbours (0 where none has one).

        A point is seen empty only when the sensor saw past it at its pixel and all
        around: a part thinner than a pixel (a shelf's side panel at 4 m) shares its
        pixels with the floor behind it, and a single pixel's reading would call the
        space under it empty."""
        import cv2

        big = np.where(self.depth > 0, self.depth, np.inf).astype(np.float32)
        near = cv2.erode(big, np.ones((3, 3), np.uint8), borderType=cv2.BORDER_REPLICATE)
        return np.where(np.isfinite(near), near, 0.0).astype(float)

    @property
    def eye(self) -> np.ndarray:
        """The camera centre in world coordinates."""
        return np.asarray(self.T_world_cam, float)[:3, 3]


def depth_noise(z: np.ndarray) -> np.ndarray:
    """Kinect v1 axial noise std (Nguyen et al. 2012, frontal): 0.0012 + 0.0019 (z - 0.4)^2."""
    return 0.0012 + 0.0019 * (np.asarray(z) - 0.4) ** 2


def slab_samples(arr, ext, n: int = 5, start: float = 0.0) -> np.ndarray:
    """(m, 3) world points filling the slab that extension ``ext`` (box, axis, side,
    length) adds to a cuboid of ``arr``, kept off its borders; with ``start``, only its
    layer beyond ``start`` metres from the face."""
    c = arr.cuboids[ext.box]
    half = c.size / 2
    ts = (np.arange(n) + 0.5) / n
    grids = []
    for k in range(3):
        if k == ext.axis:
            sgn = 1.0 if ext.side else -1.0
            grids.append(sgn * (half[k] + start + (ext.length - start) * (0.1 + 0.8 * ts)))
        else:
            grids.append((ts * 2 - 1) * half[k] * 0.85)
    g = np.stack(np.meshgrid(*grids, indexing="ij"), axis=-1).reshape(-1, 3)
    return c.center + g @ c.rotation.T


def slab_layers(arr, ext, ends):
    """The samples (:func:`slab_samples`) of each layer of the slab that extension
    ``ext`` adds, between consecutive distances ``ends`` from the face (the first 0),
    nearest first; lazily, so a caller can stop at the first layer seen empty."""
    for j in range(1, len(ends)):
        yield slab_samples(arr, replace(ext, length=ends[j]), start=ends[j - 1])


def visible_free_fraction(points: np.ndarray, views, margin: float = 0.0) -> float:
    """Fraction of ``points`` that some view saw as empty (clearly in front of its depth)."""
    if not len(points) or not views:
        return 0.0
    return float(visible_free_mask(points, views, margin).mean())


def _readings(points: np.ndarray, view, margin: float):
    """(inside the picture, depth of each point along the view, the nearest reading around
    its pixel (0: none), the tolerance there) of ``points`` in ``view``."""
    uv, z = project(transform(invert(view.T_world_cam), points), view.intrinsics)
    H, W = view.depth.shape
    u = np.round(uv[:, 0])
    v = np.round(uv[:, 1])
    inside = (z > 0) & (u >= 0) & (u < W) & (v >= 0) & (v < H)
    iu = np.where(inside, u, 0).astype(int)
    iv = np.where(inside, v, 0).astype(int)
    d = view.nearest[iv, iu]
    return inside, z, d, 3 * depth_noise(d) + margin


def _visible(points: np.ndarray, views, margin: float, hidden: bool
             ) -> tuple[np.ndarray, np.ndarray | None]:
    """:func:`visible_masks`, the second mask only when ``hidden`` (the seen-empty test
    on the search's path needs the first alone)."""
    seen = np.zeros(len(points), bool)
    unseen = np.ones(len(points), bool) if hidden else None
    for view in views:
        inside, z, d, tol = _readings(points, view, margin)
        seen |= inside & (d > 0) & (z < d - tol)
        if hidden:
            unseen &= ~inside | (d <= 0) | (d < z - tol)
    return seen, unseen


def visible_masks(points: np.ndarray, views, margin: float = 0.0
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Per point of ``points``, from one projection into each view: whether some view saw
    it as empty (clearly in front of its depth), and whether every view was kept from
    seeing it (a reading clearly nearer than it, no reading at its pixel, or outside the
    picture)."""
    return _visible(points, views, margin, hidden=True)


def visible_free_mask(points: np.ndarray, views, margin: float = 0.0) -> np.ndarray:
    """Per point of ``points``: whether some view saw it as empty (clearly in front of
    its depth; :func:`visible_masks`)."""
    return _visible(points, views, margin, hidden=False)[0]


#: Added volume lies, taken as a whole, in front of what the sensor saw when the median
#: of its samples' gaps to the depth (nearest reading around each pixel) exceeds this many
#: noise standard deviations and :data:`SEEN_IN_FRONT_MIN_GAP` metres (at close range
#: the fit of a box's faces, not the sensor, limits what a centimetre means), over at
#: least :data:`SEEN_IN_FRONT_MIN` samples with a reading.
SEEN_IN_FRONT_SIGMAS = 1.0
SEEN_IN_FRONT_MIN_GAP = 0.03
SEEN_IN_FRONT_MIN = 20


def seen_in_front(points: np.ndarray, views) -> bool:
    """Whether some view saw past ``points (n, 3)`` as a whole.

    The per-sample test (:func:`visible_free_mask`) asks each sample to lie three noise
    deviations in front of the nearest reading around its pixel; at 5 m that is 20 cm,
    and a bracket 9 cm deep grown down a wall 12 cm behind it passes.  The median of
    many samples' gaps is far less noisy: it must lie :data:`SEEN_IN_FRONT_SIGMAS`
    deviations, and at least :data:`SEEN_IN_FRONT_MIN_GAP`, in front.
    """
    for view in views:
        uv, z = project(transform(invert(view.T_world_cam), points), view.intrinsics)
        H, W = view.depth.shape
        u, v = np.round(uv[:, 0]), np.round(uv[:, 1])
        inside = (z > 0) & (u >= 0) & (u < W) & (v >= 0) & (v < H)
        d = view.nearest[v[inside].astype(int), u[inside].astype(int)]
        ok = d > 0
        if ok.sum() < SEEN_IN_FRONT_MIN:
            continue
        gap = float(np.median(d[ok] - z[inside][ok]))
        if gap > max(SEEN_IN_FRONT_SIGMAS * float(np.median(depth_noise(d[ok]))),
                     SEEN_IN_FRONT_MIN_GAP):
            return True
    return False


def observed_points(views, stride: int = CLOUD_STRIDE) -> tuple[np.ndarray, np.ndarray]:
    """World points of every ``stride``-th pixel of the views and a distance tolerance
    per point (twice the sensor's axial noise at its depth, at least a centimetre)."""
    from .camera import backproject

    pts, tol = [np.zeros((0, 3))], [np.zeros(0)]
    for v in views:
        d = np.zeros_like(np.asarray(v.depth, float))
        d[::stride, ::stride] = np.asarray(v.depth, float)[::stride, ::stride]
        p, _ = backproject(d, v.intrinsics)
        tol.append(np.maximum(0.01, 2 * depth_noise(p[:, 2])))
        pts.append(transform(np.asarray(v.T_world_cam, float), p))
    return np.concatenate(pts), np.concatenate(tol)


@dataclass(frozen=True, eq=False)
class Evidence:
    """Everything the scan says, for the priors.

    Attributes
    ----------
    views : tuple of DepthView
        The depth images in the arrangement's world frame (empty for a bare cloud).
    margin : float
        Extra tolerance of the visibility test, metres (:data:`MARGIN_REL` of the
        scene's median box edge once :meth:`scaled_to` an arrangement; 0 before).
    """

    views: tuple[DepthView, ...] = ()
    margin: float = 0.0
    _memo: dict = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def from_scan(cls, scan, pose) -> Evidence:
        """The depth image(s) of a loaded scan, in the world frame that ``pose`` (the 4x4
        input-to-world transform the initial step chose) maps it to: every frame of a
        fused multi-view scan.  No depth (a bare point cloud): no views."""
        if scan is None or pose is None:
            return cls()
        T = np.asarray(pose, float)
        frames = [(f, T @ np.asarray(f.T_world_cam, float)) for f in getattr(scan, "views", ())]
        if not frames:
            frames = [(scan, T)]
        return cls(tuple(DepthView(np.asarray(f.depth, float), f.intrinsics, P)
                         for f, P in frames
                         if getattr(f, "depth", None) is not None and f.intrinsics is not None))

    def scaled_to(self, arr) -> Evidence:
        """This evidence with its margin set for the boxes of ``arr`` (the observed cloud
        is shared)."""
        margin = MARGIN_REL * arr.scale_length() if self.views else 0.0
        return Evidence(self.views, margin, self._memo)

    def __bool__(self) -> bool:
        return bool(self.views)

    @property
    def eye(self) -> np.ndarray | None:
        """The first view's camera centre (None without views)."""
        return self.views[0].eye if self.views else None

    def free_fraction(self, points: np.ndarray) -> float:
        """The fraction of ``points`` some view saw empty."""
        return visible_free_fraction(points, self.views, self.margin)

    def free_mask(self, points: np.ndarray) -> np.ndarray:
        """Per point: whether some view saw it empty."""
        return visible_free_mask(points, self.views, self.margin)

    def seen_empty(self, points: np.ndarray, max_fraction: float = FREE_FRACTION_MAX) -> bool:
        """Whether a volume sampled by ``points`` was seen empty: more than
        ``max_fraction`` of the samples."""
        return bool(self.views) and self.free_fraction(points) > max_fraction

    def free_and_hidden(self, points: np.ndarray) -> tuple[float, float]:
        """The share of ``points`` some view saw empty (0 without views) and the share no
        view could see (1 without views), from one projection (:func:`visible_masks`)."""
        if not len(points) or not self.views:
            return 0.0, 1.0
        free, hidden = visible_masks(points, self.views, self.margin)
        return float(free.mean()), float(hidden.mean())

    def in_front(self, points: np.ndarray) -> bool:
        """Whether some view saw past the samples ``points`` taken as a whole."""
        return seen_in_front(points, self.views)

    def in_shadow(self, points: np.ndarray, box) -> np.ndarray:
        """Per point: whether ``box`` hides it from the first view's camera."""
        from .boxops import in_shadow

        if not self.views:
            return np.zeros(len(points), bool)
        return in_shadow(points, self.eye, box)

    def observed_cloud(self):
        """(points, tolerances, KD-tree or None) of :func:`observed_points`, built once."""
        if "cloud" not in self._memo:
            from scipy.spatial import cKDTree

            pts, tol = observed_points(self.views)
            self._memo["cloud"] = (pts, tol, cKDTree(pts) if len(pts) else None)
        return self._memo["cloud"]


__all__ = ["Evidence", "DepthView", "depth_noise", "slab_samples", "slab_layers", "visible_free_fraction",
           "visible_free_mask", "visible_masks", "seen_in_front", "observed_points",
           "FREE_FRACTION_MAX"]
