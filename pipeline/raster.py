"""A z-buffered triangle rasteriser in numpy (pictures of meshes, headless, no GL).

:func:`rasterize` draws triangles seen by a pinhole camera with flat Lambert shading:
every triangle's pixel bounding box is expanded into candidate pixels in one array,
kept where the pixel centre is inside the triangle (edge functions), and the nearest
candidate per pixel wins (depth interpolated perspective-correctly, ``1/z`` linear in the
image).  Triangles with a vertex behind the near plane are dropped, not clipped.
"""

from __future__ import annotations

import numpy as np

from .camera import Intrinsics, invert, transform

#: Triangles closer than this (m) are dropped.
NEAR = 0.05
#: At most this many candidate pixels per call (larger triangles are drawn anyway, the
#: rest of the batch in further passes).
MAX_CANDIDATES = 8_000_000


def rasterize(vertices: np.ndarray, faces: np.ndarray, face_colors: np.ndarray,
              intr: Intrinsics, T_world_cam: np.ndarray,
              light: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Render triangles.

    Parameters
    ----------
    vertices : (n, 3) float, world
    faces : (m, 3) int
    face_colors : (m, 3) uint8 RGB
    intr : the camera's intrinsics; ``T_world_cam`` (4, 4) its camera-to-world pose
    light : (3,) world direction *toward* the light (default: from above, behind the camera)

    Returns
    -------
    image : (H, W, 3) uint8, black where nothing was drawn
    depth : (H, W) float, camera z in metres, inf where nothing was drawn
    """
    H, W = intr.height, intr.width
    image = np.zeros((H, W, 3), np.uint8)
    zbuf = np.full(H * W, np.inf)
    faces = np.asarray(faces, np.int64)
    if len(faces) == 0:
        return image, zbuf.reshape(H, W)
    v_cam = transform(invert(T_world_cam), np.asarray(vertices, float))
    tri = v_cam[faces]                                        # (m, 3, 3)
    keep = np.all(tri[:, :, 2] > NEAR, axis=1)
    tri, cols, fidx = tri[keep], np.asarray(face_colors)[keep], np.flatnonzero(keep)
    if len(tri) == 0:
        return image, zbuf.reshape(H, W)
    # shading from the world normal
    tri_w = np.asarray(vertices, float)[faces[fidx]]
    n = np.cross(tri_w[:, 1] - tri_w[:, 0], tri_w[:, 2] - tri_w[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    cam_dir = T_world_cam[:3, 2]
    if light is None:
        light = np.array([0.0, 0.0, 1.0]) - 0.6 * cam_dir
    light = np.asarray(light, float) / np.linalg.norm(light)
    toward = -np.sign(n @ cam_dir)                              # two-sided: face the camera
    lam = np.clip((n * toward[:, None]) @ light, 0.0, 1.0)
    shade = (0.45 + 0.55 * lam)[:, None]
    shaded = np.clip(cols * shade, 0, 255).astype(np.uint8)

    u = intr.fx * tri[:, :, 0] / tri[:, :, 2] + intr.cx
    v = intr.fy * tri[:, :, 1] / tri[:, :, 2] + intr.cy
    inv_z = 1.0 / tri[:, :, 2]
    x0 = np.clip(np.floor(u.min(axis=1)), 0, W - 1).astype(np.int64)
    x1 = np.clip(np.ceil(u.max(axis=1)), 0, W - 1).astype(np.int64)
    y0 = np.clip(np.floor(v.min(axis=1)), 0, H - 1).astype(np.int64)
    y1 = np.clip(np.ceil(v.max(axis=1)), 0, H - 1).astype(np.int64)
    on = (u.max(axis=1) >= 0) & (u.min(axis=1) < W) & (v.max(axis=1) >= 0) & (v.min(axis=1) < H)
    w = np.where(on, x1 - x0 + 1, 0)
    h = np.where(on, y1 - y0 + 1, 0)
    count = w * h
    # batches of triangles whose candidate pixels fit the memory budget
    ends = np.searchsorted(np.cumsum(count), np.arange(1, 1 + count.sum() // MAX_CANDIDATES + 1)
                           * MAX_CANDIDATES)
    bounds = np.unique(np.concatenate([[0], np.minimum(ends + 1, len(count)), [len(count)]]))
    best_face = np.full(H * W, -1, np.int64)
    for s, e in zip(bounds[:-1], bounds[1:], strict=True):
        sl = slice(s, e)
        c = count[sl]
        if c.sum() == 0:
            continue
        t = np.repeat(np.arange(s, e), c)
        start = np.repeat(np.cumsum(c) - c, c)
        k = np.arange(int(c.sum())) - start
        px = x0[t] + k % w[t]
        py = y0[t] + k // w[t]
        cx, cy = px + 0.5, py + 0.5
        ax, ay, bx, by, qx, qy = (u[t, 0], v[t, 0], u[t, 1], v[t, 1], u[t, 2], v[t, 2])
        area = (bx - ax) * (qy - ay) - (by - ay) * (qx - ax)
        w0 = (bx - cx) * (qy - cy) - (by - cy) * (qx - cx)
        w1 = (qx - cx) * (ay - cy) - (qy - cy) * (ax - cx)
        w2 = (ax - cx) * (by - cy) - (ay - cy) * (bx - cx)
        ok = np.abs(area) > 1e-12
        sgn = np.sign(area)
        inside = ok & (w0 * sgn >= 0) & (w1 * sgn >= 0) & (w2 * sgn >= 0)
        if not inside.any():
            continue
        t, px, py = t[inside], px[inside], py[inside]
        area, w0, w1, w2 = area[inside], w0[inside], w1[inside], w2[inside]
        iz = (w0 * inv_z[t, 0] + w1 * inv_z[t, 1] + w2 * inv_z[t, 2]) / area
        z = 1.0 / np.maximum(iz, 1e-12)
        pix = py * W + px
        order = np.lexsort((z, pix))
        pix, z, t = pix[order], z[order], t[order]
        first = np.concatenate([[True], pix[1:] != pix[:-1]])
        pix, z, t = pix[first], z[first], t[first]
        closer = z < zbuf[pix]
        zbuf[pix[closer]] = z[closer]
        best_face[pix[closer]] = t[closer]
    drawn = best_face >= 0
    image.reshape(-1, 3)[drawn] = shaded[best_face[drawn]]
    return image, zbuf.reshape(H, W)
