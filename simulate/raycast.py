"""Ray casting from a camera view: the first hit of pixel rays with oriented boxes and
support planes, in numpy (a slab test vectorised over rays and boxes).

Rays are parametrised by the camera-frame depth z (:func:`pixel_rays`), so a ray
parameter compares directly with a depth image.
"""

from __future__ import annotations

import numpy as np

from pipeline.model import Arrangement, Cuboid

from .view import View

#: Pixels cast per chunk in the ray caster (memory: chunk x boxes x 3 floats, several times).
RAY_CHUNK = 1 << 15


def pixel_rays(view: View, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World rays through pixel coordinates ``u, v (n,)``.

    Returns
    -------
    origin : (3,) float, the camera centre
    dirs : (n, 3) float, scaled so that the ray parameter is the camera-frame depth z
    """
    i = view.intrinsics
    d = np.stack([(np.asarray(u, float) - i.cx) / i.fx, (np.asarray(v, float) - i.cy) / i.fy,
                  np.ones(np.shape(u))], axis=-1)
    R = view.T_world_cam[:3, :3]
    return view.T_world_cam[:3, 3].copy(), d @ R.T


def cast_boxes(origin: np.ndarray, dirs: np.ndarray, centers: np.ndarray,
               rotations: np.ndarray, sizes: np.ndarray, grow: float = 0.0
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First hit of rays with oriented boxes (slab test, vectorised over rays and boxes).

    Parameters
    ----------
    origin : (3,) float, or (n, 3) one per ray
    dirs : (n, 3) float
    centers, rotations, sizes : (K, 3), (K, 3, 3), (K, 3) the boxes (full sizes)
    grow : float
        Added to every half size (metres).

    Returns
    -------
    t : (n,) float, ray parameter of the entry point (inf: no hit; rays starting inside a
        box do not hit it)
    box : (n,) int, the box hit (-1: none)
    face : (n,) int, ``2 * axis + (1 if the face is on the + side)``, -1 for none
    """
    dirs = np.asarray(dirs, float)
    n, K = len(dirs), len(centers)
    t_out = np.full(n, np.inf)
    box = np.full(n, -1, np.int64)
    face = np.full(n, -1, np.int64)
    if n == 0 or K == 0:
        return t_out, box, face
    half = np.asarray(sizes, float) / 2 + grow
    R = np.asarray(rotations, float)
    orig = np.asarray(origin, float)
    per_ray = orig.ndim == 2
    for s in range(0, n, RAY_CHUNK):
        d = np.einsum("kji,nj->nki", R, dirs[s:s + RAY_CHUNK])  # local directions (m, K, 3)
        if per_ray:
            o = np.einsum("kji,nkj->nki", R, orig[s:s + RAY_CHUNK, None, :] - centers[None])
        else:
            o = np.einsum("kji,kj->ki", R, orig[None] - centers)[None]  # (1, K, 3)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / d
            t1 = (-half[None] - o) * inv
            t2 = (half[None] - o) * inv
        t1 = np.where(np.isnan(t1), -np.inf, t1)
        t2 = np.where(np.isnan(t2), np.inf, t2)
        lo, hi = np.minimum(t1, t2), np.maximum(t1, t2)
        tn, tf = lo.max(axis=2), hi.min(axis=2)
        hit = (tn <= tf) & (tn > 0)
        tn = np.where(hit, tn, np.inf)
        k = np.argmin(tn, axis=1)
        rows = np.arange(len(k))
        tk = tn[rows, k]
        ok = np.isfinite(tk)
        axis = np.argmax(lo[rows, k], axis=1)
        plus = d[rows, k, axis] < 0  # entering through the + face when moving towards -
        sl = slice(s, s + len(k))
        t_out[sl] = tk
        box[sl] = np.where(ok, k, -1)
        face[sl] = np.where(ok, 2 * axis + plus, -1)
    return t_out, box, face


def cast_supports(origin: np.ndarray, dirs: np.ndarray, arr: Arrangement
                  ) -> tuple[np.ndarray, np.ndarray]:
    """First hit of rays with the support planes of ``arr`` (from their free side).

    Returns ``t (n,)`` (inf: none) and ``support (n,)`` (index into ``arr.supports``, -1).
    """
    n = len(dirs)
    t = np.full(n, np.inf)
    which = np.full(n, -1, np.int64)
    for s, sup in enumerate(arr.supports):
        dn = dirs @ sup.normal
        with np.errstate(divide="ignore", invalid="ignore"):
            ts = ((sup.point - origin) @ sup.normal) / dn
        ok = (dn < 0) & (ts > 0) & (ts < t)
        t = np.where(ok, ts, t)
        which = np.where(ok, s, which)
    return t, which


def box_arrays(cubs: list[Cuboid]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ``centers (K, 3)``, ``rotations (K, 3, 3)`` and full ``sizes (K, 3)`` of ``cubs``
    (the boxes :func:`cast_boxes` takes)."""
    if not cubs:
        return np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros((0, 3))
    return (np.stack([c.center for c in cubs]), np.stack([c.rotation for c in cubs]),
            np.stack([c.size for c in cubs]))


def inside_boxes(points: np.ndarray, cubs: list[Cuboid], grow: float = 0.0) -> np.ndarray:
    """(n,) bool: whether each point lies in one of ``cubs`` grown by ``grow`` metres."""
    C, R, S = box_arrays(cubs)
    out = np.zeros(len(points), bool)
    for k in range(len(cubs)):  # a handful of boxes; vectorised over points
        local = (points - C[k]) @ R[k]
        out |= np.all(np.abs(local) <= S[k] / 2 + grow, axis=1)
    return out


def silhouette(view: View, cubs: list[Cuboid]) -> np.ndarray:
    """(H, W) bool: the pixels whose centre ray meets one of ``cubs`` (occlusion ignored)."""
    H, W = view.depth.shape
    out = np.zeros((H, W), bool)
    if not cubs:
        return out
    v, u = np.mgrid[0:H, 0:W]
    o, d = pixel_rays(view, u.ravel(), v.ravel())
    t, _, _ = cast_boxes(o, d, *box_arrays(cubs))
    return np.isfinite(t).reshape(H, W)


def cast_scene(view: View, arr: Arrangement) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel: depth of the first surface of ``arr`` (cuboids and supports; inf: none)
    and its label (1 + cuboid index, -(1 + support index), 0 none)."""
    H, W = view.depth.shape
    v, u = np.mgrid[0:H, 0:W]
    o, d = pixel_rays(view, u.ravel(), v.ravel())
    tb, kb, _ = cast_boxes(o, d, *box_arrays(list(arr.cuboids)))
    ts, ks = cast_supports(o, d, arr)
    lab = np.where(tb <= ts, kb + 1, np.where(ks >= 0, -(ks + 1), 0))
    lab = np.where(np.isfinite(np.minimum(tb, ts)), lab, 0)
    return np.minimum(tb, ts).reshape(H, W), lab.reshape(H, W)


__all__ = ["RAY_CHUNK", "pixel_rays", "cast_boxes", "cast_supports", "box_arrays",
           "inside_boxes", "silhouette", "cast_scene"]
