"""Edge refinement: snap each box's visible silhouette to Canny edges of the colour image.

For every box, points are sampled along the edges of its projected outline (the convex
hull of its projected corners is the outline of a convex box).  A rigid motion of the
box (yaw + translation for an upright box, full rotation for a slanted one) is found by
least squares on the reprojection distance to the closest Canny edge pixel, which is
looked up through ``cv2.distanceTransformWithLabels`` and re-found each iteration (an
ICP in the image).  The paper's rule decides: the moved box is kept only if its fit to
its own 3D points does not get worse.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera import Intrinsics, invert, project, transform
from .model import CORNER_SIGNS

#: A snap moves a box by at most this fraction of its largest edge ...
MAX_SHIFT_REL = 0.25
#: ... and turns it by at most this many degrees (edges only correct small errors).
MAX_TURN_DEG = 10.0


@dataclass(frozen=True)
class EdgeMap:
    """Canny edges and, per pixel, the coordinates of the nearest edge pixel."""

    edges: np.ndarray  #: (H, W) bool
    distance: np.ndarray  #: (H, W) float, pixels to the nearest edge
    nearest: np.ndarray  #: (H, W, 2) float, (u, v) of the nearest edge pixel


def edge_map(image: np.ndarray, valid: np.ndarray | None = None) -> EdgeMap:
    """Canny (thresholds from the image's own gradients) and its distance transform."""
    import cv2

    chans = [image[:, :, k] for k in range(3)] if image.ndim == 3 else [image]
    e = np.zeros(image.shape[:2], bool)
    for ch in chans:  # per colour channel: a red box on a grey floor has no grey-level edge
        g = cv2.GaussianBlur(np.ascontiguousarray(ch), (5, 5), 1.2)
        # thresholds from the gradients actually present (flat renders and photographs
        # alike): high = the 80th percentile of the non-flat pixels
        mag = np.abs(cv2.Sobel(g, cv2.CV_32F, 1, 0)) + np.abs(cv2.Sobel(g, cv2.CV_32F, 0, 1))
        moving = mag[mag > 8]
        high = float(min(np.percentile(moving, 80), 0.5 * moving.max())) if moving.size else 100.0
        high = max(high, 40.0)
        e |= cv2.Canny(g, 0.4 * high, high) > 0
    if valid is not None:
        e &= valid
    if not e.any():
        e[0, 0] = True
    dist, lab = cv2.distanceTransformWithLabels((~e).astype(np.uint8), cv2.DIST_L2, 5,
                                                labelType=cv2.DIST_LABEL_PIXEL)
    vu = np.argwhere(e)  # row-major: label k is the k-th edge pixel (1-based)
    nearest = vu[np.clip(lab - 1, 0, len(vu) - 1)][..., ::-1].astype(float)
    return EdgeMap(e, dist, nearest)


def point_box_distance(points: np.ndarray, center: np.ndarray, R: np.ndarray,
                       size: np.ndarray) -> np.ndarray:
    """(n,) unsigned distance of ``points (n, 3)`` to the surface of a box."""
    q = np.abs((points - center) @ R) - size / 2
    outside = np.linalg.norm(np.maximum(q, 0), axis=1)
    inside = -np.max(q, axis=1)
    return np.where(np.any(q > 0, axis=1), outside, inside)


def _rot(w: np.ndarray) -> np.ndarray:
    th = float(np.linalg.norm(w))
    if th < 1e-12:
        return np.eye(3)
    k = w / th
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * (K @ K)


def _pixel_jacobian(pose: tuple[np.ndarray, np.ndarray], samples: np.ndarray,
                    T_cw: np.ndarray, intr: Intrinsics, upright: bool) -> np.ndarray:
    """(2m, k) derivative of the pixels of ``samples`` (box-local) under the box pose
    ``(center, R)`` with respect to the pose parameters of :func:`refine_box` (yaw and
    translation for an upright box, a rotation vector and translation otherwise).  The
    rotation's derivative is taken at the current pose (``d(exp(w) v) ~ [dw]x v``): exact
    for the yaw, first order for a rotation vector, which stays within 10 degrees."""
    c, R = pose
    arm = samples @ R.T  # sample offsets from the centre, world frame
    q = (c + arm) @ T_cw[:3, :3].T + T_cw[:3, 3]
    z = q[:, 2]
    m = len(q)
    dproj = np.zeros((m, 2, 3))
    dproj[:, 0, 0] = intr.fx / z
    dproj[:, 0, 2] = -intr.fx * q[:, 0] / z ** 2
    dproj[:, 1, 1] = intr.fy / z
    dproj[:, 1, 2] = -intr.fy * q[:, 1] / z ** 2
    duv_dp = dproj @ T_cw[:3, :3]  # (m, 2, 3): pixel per world displacement
    if upright:
        dp_rot = np.stack([-arm[:, 1], arm[:, 0], np.zeros(m)], axis=1)[:, :, None]
    else:  # d(p)/d(w_k) = e_k x arm
        dp_rot = np.stack([np.cross(np.eye(3)[k], arm) for k in range(3)], axis=2)
    cols = [duv_dp @ dp_rot, duv_dp]
    return np.concatenate(cols, axis=2).reshape(2 * m, -1)


def silhouette_samples(center: np.ndarray, R: np.ndarray, size: np.ndarray,
                       T_cam_world: np.ndarray, intr: Intrinsics,
                       step_px: float = 3.0) -> np.ndarray:
    """Box-local sample points (m, 3) along the edges of the projected outline."""
    import cv2

    local = CORNER_SIGNS * (size / 2)
    cam = transform(T_cam_world, center + local @ R.T)
    if np.any(cam[:, 2] <= 1e-3):
        return np.zeros((0, 3))
    uv, _ = project(cam, intr)
    hull = cv2.convexHull(uv.astype(np.float32), returnPoints=False).ravel()
    a, b = hull, np.roll(hull, -1)
    length = np.linalg.norm(uv[b] - uv[a], axis=1)
    n = np.maximum(2, (length / step_px).astype(int))
    edge = np.repeat(np.arange(len(a)), n)
    t = np.concatenate([(np.arange(k) + 0.5) / k for k in n])
    return local[a][edge] + t[:, None] * (local[b][edge] - local[a][edge])


def refine_box(center: np.ndarray, R: np.ndarray, size: np.ndarray, points: np.ndarray,
               em: EdgeMap, intr: Intrinsics, T_world_cam: np.ndarray, *, upright: bool = True,
               max_px: float = 10.0, iterations: int = 6,
               ) -> tuple[np.ndarray, np.ndarray, dict]:
    """Rigidly move one box so its outline snaps to image edges.

    Returns
    -------
    center : (3,) float, rotation : (3, 3) float (unchanged when rejected)
    info : dict with ``accepted``, ``edge_px_before``, ``edge_px_after``,
        ``fit_before``, ``fit_after`` (mean point-to-surface distance, metres)
    """
    from scipy.optimize import least_squares

    T_cw = invert(T_world_cam)
    H, W = em.distance.shape
    samples = silhouette_samples(center, R, size, T_cw, intr)
    info = {"accepted": False}
    if len(samples) < 8:
        return center, R, info

    def pose(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        w = np.array([0.0, 0.0, x[0]]) if upright else x[:3]
        t = x[1:4] if upright else x[3:6]
        return center + t, _rot(w) @ R

    def uv_of(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        c, Rx = pose(x)
        uv, z = project(transform(T_cw, c + samples @ Rx.T), intr)
        ok = (z > 1e-3) & (uv[:, 0] >= 0) & (uv[:, 0] <= W - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= H - 1)
        return uv, ok

    def edge_err(x: np.ndarray) -> float:
        uv, ok = uv_of(x)
        if not ok.any():
            return float("inf")
        iu, iv = np.round(uv[ok]).astype(int).T
        return float(np.mean(np.minimum(em.distance[iv, iu], max_px)))

    x = np.zeros(4 if upright else 6)
    before = edge_err(x)
    for _ in range(iterations):
        uv, ok = uv_of(x)
        iu = np.clip(np.round(uv[:, 0]).astype(int), 0, W - 1)
        iv = np.clip(np.round(uv[:, 1]).astype(int), 0, H - 1)
        use = ok & (em.distance[iv, iu] < max_px)
        if use.sum() < 6:
            break
        target = em.nearest[iv[use], iu[use]]

        def resid(xx: np.ndarray, use: np.ndarray = use, target: np.ndarray = target) -> np.ndarray:
            u2, _ = uv_of(xx)
            return (u2[use] - target).ravel()

        def jac(xx: np.ndarray, use: np.ndarray = use) -> np.ndarray:
            return _pixel_jacobian(pose(xx), samples[use], T_cw, intr, upright)

        sol = least_squares(resid, x, jac=jac, loss="soft_l1", f_scale=2.0, max_nfev=30)
        if np.allclose(sol.x, x, atol=1e-7):
            break
        x = sol.x
    after = edge_err(x)
    c_new, R_new = pose(x)
    fit_before = float(np.mean(point_box_distance(points, center, R, size))) if len(points) else 0.0
    fit_after = float(np.mean(point_box_distance(points, c_new, R_new, size))) if len(points) else 0.0
    small = (np.linalg.norm(c_new - center) <= MAX_SHIFT_REL * float(np.max(size))
             and np.degrees(np.arccos(np.clip((np.trace(R_new @ R.T) - 1) / 2, -1, 1))) <= MAX_TURN_DEG)
    accepted = bool(after < before and small and fit_after <= fit_before + 1e-12)
    info = {"accepted": accepted, "edge_px_before": before, "edge_px_after": after,
            "fit_before": fit_before, "fit_after": fit_after}
    return (c_new, R_new, info) if accepted else (center, R, info)
