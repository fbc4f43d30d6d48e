"""A structured-light (Kinect v1) depth noise model; every term can be switched off.

Terms, applied in this order to a clean metric depth image (``z``, metres, 0 = none):

1. **lateral** noise: each pixel reads the depth of a neighbour displaced by a Gaussian
   of ``sigma_L(theta)`` pixels (Nguyen, Izadi and Lovell 2012, eq. for the lateral
   noise: ``sigma_L [px] = 0.8 + 0.035 theta / (pi/2 - theta)``);
2. **flying pixels** at depth discontinuities: with probability ``flying_prob`` an edge
   pixel takes a depth between its own and the neighbour's across the edge;
3. **axial** noise: ``z += N(0, sigma_z)`` with (Nguyen et al. 2012, metres)
   ``sigma_z = 0.0012 + 0.0019 (z - 0.4)^2`` for ``theta <= 60 deg`` and
   ``+ 0.0001 / sqrt(z) * theta^2 / (pi/2 - theta)^2`` beyond;
4. **quantisation** of the disparity: ``d = f b / z`` in 1/8 pixel steps
   (``disparity_step``), so depth comes in steps of about ``z^2 / (8 f b)``
   (1.2 cm at 2 m for f = 525 px, b = 7.5 cm);
5. **dropout** at grazing incidence (none beyond ``grazing_deg``, a linear ramp from
   ``grazing_start_deg``) and outside the working range ``[min_depth, max_depth]``;
6. **projector shadows**: no depth where the IR projector, ``baseline`` metres along the
   camera's +x axis (Kinect v1: 7.5 cm, to the camera's right), cannot see the surface.

``theta`` is the angle between the surface normal and the viewing ray (Nguyen et al.
measure it at the image centre, where the ray is the optical axis); normals come from
the clean depth image (finite differences that do not cross depth edges).  Shadows are
found along epipolar lines (image rows: the projector is displaced along x only): a
point is shadowed when a point of the same row farther toward the projector maps to a
smaller projector column (it is in front of it on the projector's ray).  Occluders the
camera cannot see do not cast shadows (rare for a 7.5 cm baseline).

All randomness comes from the ``numpy.random.Generator`` passed in; each term draws
from its own child generator (``rng.spawn``) so switching one term off leaves the
others' draws unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.camera import Intrinsics

#: Names of the switchable terms, in the order they are applied.
TERMS = ("lateral", "flying_pixels", "axial", "quantization", "dropout", "shadows")


@dataclass(frozen=True)
class KinectNoise:
    """Parameters of the Kinect v1 noise model; set a term to ``False`` to switch it off."""

    lateral: bool = True
    flying_pixels: bool = True
    axial: bool = True
    quantization: bool = True
    dropout: bool = True
    shadows: bool = True
    #: projector offset along the camera's +x axis, metres (negative: to the left)
    baseline: float = 0.075
    #: disparity resolution, pixels (Kinect v1: 1/8 sub-pixel)
    disparity_step: float = 0.125
    #: beyond this incidence angle no depth is returned (degrees)
    grazing_deg: float = 80.0
    #: dropout probability ramps linearly from 0 here to 1 at ``grazing_deg``
    grazing_start_deg: float = 70.0
    #: working range, metres
    min_depth: float = 0.4
    max_depth: float = 6.0
    #: a jump between 4-neighbours larger than ``edge_jump * z`` is a depth edge
    edge_jump: float = 0.03
    #: probability that an edge pixel becomes a flying pixel
    flying_prob: float = 0.5

    @classmethod
    def none(cls) -> KinectNoise:
        """All terms off (the identity, apart from nothing)."""
        return cls(**{t: False for t in TERMS})

    @classmethod
    def only(cls, *terms: str) -> KinectNoise:
        """Just the named terms on (e.g. ``KinectNoise.only("axial")``)."""
        bad = set(terms) - set(TERMS)
        if bad:
            raise ValueError(f"unknown noise terms {sorted(bad)}; expected some of {TERMS}")
        return cls(**{t: (t in terms) for t in TERMS})


def axial_sigma(z: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Axial (depth) noise standard deviation, Nguyen et al. 2012.

    Parameters
    ----------
    z : (...) float, depth in metres
    theta : (...) float, incidence angle in radians (clamped to 80 degrees)

    Returns
    -------
    sigma : (...) float, metres
    """
    z = np.asarray(z)
    z = z if z.dtype == np.float32 else z.astype(float)
    th = np.minimum(np.abs(np.asarray(theta, dtype=z.dtype)), np.deg2rad(80.0).astype(z.dtype))
    sigma = 0.0012 + 0.0019 * (z - 0.4) ** 2
    steep = th > np.pi / 3
    if np.any(steep):
        ts, zs = th[steep], np.broadcast_to(z, th.shape)[steep]
        sigma = np.array(np.broadcast_to(sigma, th.shape))
        sigma[steep] += 0.0001 / np.sqrt(zs) * ts**2 / (np.pi / 2 - ts) ** 2
    return sigma


def lateral_sigma_px(theta: np.ndarray) -> np.ndarray:
    """Lateral noise standard deviation in pixels, Nguyen et al. 2012 (theta in radians)."""
    th = np.minimum(np.abs(np.asarray(theta, float)), np.deg2rad(80.0))
    return 0.8 + 0.035 * th / (np.pi / 2 - th)


def quantize_depth(z: np.ndarray, focal: float, baseline: float, step: float = 0.125
                   ) -> np.ndarray:
    """Round depth to the nearest representable disparity ``d = focal * baseline / z``.

    Parameters
    ----------
    z : (...) float, metres (0 = none, kept)
    focal : float, pixels
    baseline : float, metres
    step : float, disparity resolution in pixels

    Returns
    -------
    zq : (...) float, metres
    """
    z = np.asarray(z, float)
    fb = focal * abs(baseline)
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.round(fb / z / step) * step
        zq = np.where((z > 0) & (d > 0), fb / d, 0.0)
    return zq


def _shift(a: np.ndarray, dv: int, du: int, fill: float) -> np.ndarray:
    """``out[v, u] = a[v + dv, u + du]`` with ``fill`` outside the image."""
    out = np.full_like(a, fill)
    H, W = a.shape[:2]
    out[max(0, -dv):H - max(0, dv), max(0, -du):W - max(0, du)] = \
        a[max(0, dv):H - max(0, -dv), max(0, du):W - max(0, -du)]
    return out


def _one_sided_gradient(zz: np.ndarray, axis: int, edge_jump: float) -> np.ndarray:
    """Derivative of ``zz`` (float32, NaN = no reading) along ``axis``, per pixel: the
    forward or backward difference, whichever is smaller in magnitude; NaN where both
    jump by more than ``edge_jump * z`` or reach an invalid pixel."""
    diff = np.diff(zz, axis=axis)
    fwd = np.full_like(zz, np.nan)
    bwd = np.full_like(zz, np.nan)
    if axis == 1:
        fwd[:, :-1] = diff
        bwd[:, 1:] = diff
    else:
        fwd[:-1] = diff
        bwd[1:] = diff
    af = np.abs(fwd)
    ab = np.abs(bwd)
    g = np.where((af <= ab) | np.isnan(ab), fwd, bwd)
    with np.errstate(invalid="ignore"):
        g[np.fmin(af, ab) > edge_jump * zz] = np.nan
    return g


def _gradients(depth: np.ndarray, intr: Intrinsics, edge_jump: float):
    """float32 ``z``, ``fx z_u``, ``fy z_v`` and the ray components ``r_x (1, W)``,
    ``r_y (H, 1)``."""
    z = np.asarray(depth, dtype=np.float32)
    H, W = z.shape
    zz = np.where(z > 0, z, np.float32(np.nan))
    rx = ((np.arange(W, dtype=np.float32) - np.float32(intr.cx)) / np.float32(intr.fx))[None, :]
    ry = ((np.arange(H, dtype=np.float32) - np.float32(intr.cy)) / np.float32(intr.fy))[:, None]
    gu = _one_sided_gradient(zz, 1, edge_jump) * np.float32(intr.fx)
    gv = _one_sided_gradient(zz, 0, edge_jump) * np.float32(intr.fy)
    return z, gu, gv, rx, ry


def incidence_angle(depth: np.ndarray, intr: Intrinsics, edge_jump: float = 0.03
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Surface normals and incidence angles from a depth image.

    For a pinhole camera, ``P(u, v) = z(u, v) r(u, v)`` with the ray
    ``r = ((u - cx) / fx, (v - cy) / fy, 1)``, and ``dP/du x dP/dv`` is parallel to
    ``m = (-fx z_u, -fy z_v, z + fx z_u r_x + fy z_v r_y)`` with ``m . r = z``, so
    ``cos(theta) = z / (|m| |r|)``.  Along each image axis the derivative is the forward or
    backward difference, whichever changes less (so it does not cross depth edges);
    where both jump by more than ``edge_jump * z`` the normal is unknown.

    Returns
    -------
    normals : (H, W, 3) float32, unit, camera frame, facing the camera (NaN: unknown)
    theta : (H, W) float32, radians between normal and viewing ray (NaN: unknown)
    """
    z, gu, gv, rx, ry = _gradients(depth, intr, edge_jump)
    mz = z + gu * rx + gv * ry
    norm_m = np.sqrt(gu * gu + gv * gv + mz * mz)
    with np.errstate(invalid="ignore", divide="ignore"):
        normals = np.stack([gu, gv, -mz], axis=-1) / norm_m[..., None]  # -m: toward camera
    return normals, _theta(z, norm_m, rx, ry)


def _theta(z: np.ndarray, norm_m: np.ndarray, rx: np.ndarray, ry: np.ndarray) -> np.ndarray:
    norm_r = np.sqrt(rx * rx + ry * ry + 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = z / (norm_m * norm_r)
    theta = np.arccos(np.clip(cos, 0.0, 1.0))
    theta[~np.isfinite(cos) | (z <= 0)] = np.nan
    return theta


def incidence_theta(depth: np.ndarray, intr: Intrinsics, edge_jump: float = 0.03
                    ) -> np.ndarray:
    """Just the angles of :func:`incidence_angle` ((H, W) float32 radians, NaN unknown)."""
    z, gu, gv, rx, ry = _gradients(depth, intr, edge_jump)
    mz = z + gu * rx + gv * ry
    return _theta(z, np.sqrt(gu * gu + gv * gv + mz * mz), rx, ry)


def projector_shadow(depth: np.ndarray, intr: Intrinsics, baseline: float = 0.075,
                     tol_px: float = 0.05) -> np.ndarray:
    """Pixels the projector cannot light (occluded from a point ``baseline`` along +x).

    The projector has the camera's intrinsics and orientation; a surface point at pixel
    ``u`` with depth ``z`` has projector column ``u_p = u - fx * baseline / z`` on the
    same row.  With the projector to the right (``baseline > 0``) a point is shadowed
    when some pixel to its right on the row has a smaller projector column (by more than
    ``tol_px``); mirrored for ``baseline < 0``.

    Returns
    -------
    shadow : (H, W) bool
    """
    d = np.asarray(depth, float)
    H, W = d.shape
    u = np.arange(W, dtype=float)[None, :]
    with np.errstate(divide="ignore"):
        up = np.where(d > 0, u - intr.fx * baseline / d, np.inf)
    if baseline < 0:  # mirror so the projector is always "to the right"
        up = -up[:, ::-1]
        up[~np.isfinite(up)] = np.inf
    # minimum projector column over the pixels strictly to the right
    right_min = np.minimum.accumulate(up[:, ::-1], axis=1)[:, ::-1]
    right_min = np.concatenate([right_min[:, 1:], np.full((H, 1), np.inf)], axis=1)
    shadow = np.isfinite(up) & (up > right_min + tol_px)
    if baseline < 0:
        shadow = shadow[:, ::-1]
    return shadow


def apply_noise(depth: np.ndarray, intr: Intrinsics, rng: np.random.Generator,
                model: KinectNoise | None = None) -> np.ndarray:
    """Corrupt a clean depth image with the Kinect v1 model.

    Parameters
    ----------
    depth : (H, W) float, clean metric depth (z), 0 = none
    intr : Intrinsics
    rng : numpy.random.Generator
        Source of all randomness (one child generator per term).
    model : KinectNoise, optional
        Which terms and their parameters (default: all on).

    Returns
    -------
    noisy : (H, W) float32, metres, 0 = no reading
    """
    m = KinectNoise() if model is None else model
    clean = np.asarray(depth, dtype=np.float32)  # float32 throughout: 2x less memory traffic
    H, W = clean.shape
    g_lat, g_fly, g_fly_w, g_ax, g_drop = rng.spawn(5)
    if m.lateral or m.axial or m.dropout:
        theta0 = np.nan_to_num(incidence_theta(clean, intr, m.edge_jump), nan=0.0)
    z = clean.copy()

    if m.lateral:
        s = lateral_sigma_px(theta0).astype(np.float32)
        off = np.rint(g_lat.standard_normal((2, H, W), dtype=np.float32) * s).astype(np.int32)
        rows = np.clip(np.arange(H, dtype=np.int32)[:, None] + off[0], 0, H - 1)
        cols = np.clip(np.arange(W, dtype=np.int32)[None, :] + off[1], 0, W - 1)
        z = np.take(clean.ravel(), rows * W + cols)

    if m.flying_pixels:
        best = np.zeros_like(z)
        for dv, du in ((0, 1), (0, -1), (1, 0), (-1, 0)):
            nb = _shift(z, dv, du, 0.0)
            diff = np.where(nb > 0, nb - z, 0.0)
            best = np.where(np.abs(diff) > np.abs(best), diff, best)
        ev, eu = np.nonzero((z > 0) & (np.abs(best) > m.edge_jump * z))  # edge pixels
        fly = g_fly.random(len(ev), dtype=np.float32) < m.flying_prob
        ev, eu = ev[fly], eu[fly]
        w = g_fly_w.random(len(ev), dtype=np.float32)
        z[ev, eu] += w * best[ev, eu]

    valid = z > 0
    if m.axial:
        sig = axial_sigma(np.where(valid, z, 1.0), theta0).astype(np.float32)
        z = np.where(valid, z + g_ax.standard_normal((H, W), dtype=np.float32) * sig, 0.0)
        z[z <= 0] = 0.0

    if m.quantization:
        z = quantize_depth(z, intr.fx, m.baseline, m.disparity_step).astype(np.float32)

    if m.dropout:
        ramp = (np.rad2deg(theta0) - m.grazing_start_deg) / max(
            m.grazing_deg - m.grazing_start_deg, 1e-9)
        gv, gu = np.nonzero(ramp > 0)  # grazing pixels only draw
        lost = g_drop.random(len(gv), dtype=np.float32) < np.minimum(ramp[gv, gu], 1.0)
        z[gv[lost], gu[lost]] = 0.0
        z[(z < m.min_depth) | (z > m.max_depth)] = 0.0

    if m.shadows:
        z[projector_shadow(clean, intr, m.baseline)] = 0.0

    return z.astype(np.float32)
