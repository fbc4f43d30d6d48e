"""Pictures of arrangements: boxes over the camera image (``overlay.png``) and a 3D view
(``view.png``).  Reusable for initial, final and hallucinated boxes and contact graphs.

A *box set* is ``(boxes, colour, style)``: ``boxes`` an :class:`~pipeline.model.Arrangement`
or a tuple ``(centers (K, 3), rotations (K, 3, 3), sizes (K, 3))``; ``colour`` an RGB
tuple of 0-255 ints; ``style`` one of ``"solid"``, ``"dashed"``, ``"thin"``.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from . import atomic
from .camera import Intrinsics, invert, project, transform
from .model import Arrangement, box_corners

#: The 12 edges of a box as pairs of corner indices (corner k = CORNER_SIGNS[k]).
BOX_EDGES = np.array([[0, 1], [2, 3], [4, 5], [6, 7], [0, 2], [1, 3], [4, 6], [5, 7],
                      [0, 4], [1, 5], [2, 6], [3, 7]])

#: A colour per box for distinguishable overlays (RGB).
PALETTE = [(230, 25, 75), (60, 180, 75), (255, 225, 25), (0, 130, 200), (245, 130, 48),
           (145, 30, 180), (70, 240, 240), (240, 50, 230), (210, 245, 60), (250, 190, 212),
           (0, 128, 128), (220, 190, 255), (170, 110, 40), (128, 0, 0), (170, 255, 195)]


def _boxes(b: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if isinstance(b, Arrangement):
        return np.asarray(b.centers), np.asarray(b.rotations), np.asarray(b.sizes)
    c, R, s = b
    return np.asarray(c, float).reshape(-1, 3), np.asarray(R, float).reshape(-1, 3, 3), \
        np.asarray(s, float).reshape(-1, 3)


def depth_picture(depth: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 colour-mapped depth (near = warm), black where there is no reading."""
    import cv2

    d = np.asarray(depth, float)
    valid = d > 0
    out = np.zeros(d.shape + (3,), np.uint8)
    if valid.any():
        lo, hi = np.percentile(d[valid], [1, 99])
        g = (255 * (1 - np.clip((d - lo) / max(hi - lo, 1e-6), 0, 1))).astype(np.uint8)
        out = cv2.cvtColor(cv2.applyColorMap(g, cv2.COLORMAP_TURBO), cv2.COLOR_BGR2RGB)
        out[~valid] = 0
    return out


def _clip_segments(a: np.ndarray, b: np.ndarray, near: float = 1e-2) -> tuple[np.ndarray, ...]:
    """Clip camera-frame segments (m, 3) to z >= near; returns (a, b, keep)."""
    za, zb = a[:, 2], b[:, 2]
    keep = (za >= near) | (zb >= near)
    t = np.clip((near - za) / np.where(np.abs(zb - za) < 1e-12, 1e-12, zb - za), 0, 1)
    a2 = np.where((za < near)[:, None], a + t[:, None] * (b - a), a)
    b2 = np.where((zb < near)[:, None], a + t[:, None] * (b - a), b)
    return a2, b2, keep


def draw_overlay(image: np.ndarray, intr: Intrinsics, T_world_cam: np.ndarray,
                 box_sets: Sequence[tuple[Any, Any, str]],
                 labels: Sequence[Sequence[str]] | None = None,
                 lines: Sequence[tuple[np.ndarray, np.ndarray, Any, str]] = ()) -> np.ndarray:
    """Draw box wireframes (and optional 3D line segments) over an image.

    Parameters
    ----------
    image : (H, W, 3) uint8 RGB (not modified)
    intr, T_world_cam : the camera (camera-to-world 4x4)
    box_sets : sequence of (boxes, colour, style); ``colour`` an RGB tuple, or
        ``"palette"`` for one colour per box
    labels : optional per set, per box text drawn at the box centre
    lines : (a (m, 3), b (m, 3), colour, style) world segments, e.g. contact edges

    Returns
    -------
    (H, W, 3) uint8 RGB, a new image
    """
    import cv2

    out = np.ascontiguousarray(image.copy())
    T_cw = invert(np.asarray(T_world_cam, float))
    scale = max(1, int(round(max(out.shape[:2]) / 640)))

    def seg(a: np.ndarray, b: np.ndarray, colour: tuple, style: str) -> None:
        a, b, keep = _clip_segments(transform(T_cw, a), transform(T_cw, b))
        ua, _ = project(a[keep], intr)
        ub, _ = project(b[keep], intr)
        th = (1 if style == "thin" else 2) * scale
        for p, q in zip(ua, ub, strict=True):  # a handful of segments: cv2 draws one at a time
            if not (np.all(np.isfinite(p)) and np.all(np.isfinite(q))):
                continue
            if style == "dashed":
                n = max(2, int(np.linalg.norm(q - p) / (8 * scale)))
                ts = np.linspace(0, 1, n + 1)
                for t0, t1 in zip(ts[0::2], ts[1::2], strict=False):
                    cv2.line(out, _pt(p + t0 * (q - p)), _pt(p + t1 * (q - p)), colour, th,
                             cv2.LINE_AA)
            else:
                cv2.line(out, _pt(p), _pt(q), colour, th, cv2.LINE_AA)

    for si, (boxes, colour, style) in enumerate(box_sets):
        c, R, s = _boxes(boxes)
        if len(c) == 0:
            continue
        corners = box_corners(c, R, s)  # (K, 8, 3)
        for k in range(len(c)):
            col = PALETTE[k % len(PALETTE)] if colour == "palette" else tuple(int(v) for v in colour)
            seg(corners[k][BOX_EDGES[:, 0]], corners[k][BOX_EDGES[:, 1]], col, style)
        if labels is not None and si < len(labels) and labels[si]:
            uv, z = project(transform(T_cw, c), intr)
            for k, text in enumerate(labels[si]):
                if z[k] > 0 and np.all(np.isfinite(uv[k])):
                    cv2.putText(out, str(text), _pt(uv[k]), cv2.FONT_HERSHEY_SIMPLEX,
                                0.4 * scale, (255, 255, 255), 1, cv2.LINE_AA)
    for a, b, colour, style in lines:
        seg(np.asarray(a, float).reshape(-1, 3), np.asarray(b, float).reshape(-1, 3),
            tuple(int(v) for v in colour), style)
    return out


def _pt(p: np.ndarray) -> tuple[int, int]:
    return int(round(float(np.clip(p[0], -1e5, 1e5)))), int(round(float(np.clip(p[1], -1e5, 1e5))))


def draw_view(points: np.ndarray | None, colors: np.ndarray | None,
              box_sets: Sequence[tuple[Any, Any, str]],
              contacts: Sequence[tuple[np.ndarray, np.ndarray, str]] | None = None, *,
              max_points: int = 30000, title: str = "", elev: float = 25.0,
              azim: float = -60.0, size_px: tuple[int, int] = (900, 700)) -> np.ndarray:
    """A 3D picture (matplotlib Agg) of points, box wireframes and contact lines.

    Parameters
    ----------
    points : (n, 3) world points or None; ``colors`` (n, 3) in [0, 1] or None
    box_sets : as in :func:`draw_overlay` (colours as RGB 0-255 or ``"palette"``)
    contacts : (a (3,), b (3,), type) segments; ``fixed`` drawn solid red, ``touch``
        dashed blue, anything else dotted grey
    Returns (H, W, 3) uint8 RGB.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(size_px[0] / 100, size_px[1] / 100), dpi=100)
    ax = fig.add_subplot(111, projection="3d")
    allp = []
    if points is not None and len(points):
        step = max(1, int(np.ceil(len(points) / max_points)))
        p = np.asarray(points)[::step]
        col = np.asarray(colors)[::step] if colors is not None else "0.5"
        ax.scatter(p[:, 0], p[:, 1], p[:, 2], s=0.3, c=col, depthshade=False, linewidths=0)
        allp.append(np.percentile(p, [1, 99], axis=0))
    for boxes, colour, style in box_sets:
        c, R, s = _boxes(boxes)
        if len(c) == 0:
            continue
        corners = box_corners(c, R, s)
        allp.append(np.stack([corners.reshape(-1, 3).min(0), corners.reshape(-1, 3).max(0)]))
        ls = {"dashed": "--", "thin": "-"}.get(style, "-")
        lw = 0.8 if style == "thin" else 1.6
        for k in range(len(c)):
            col = PALETTE[k % len(PALETTE)] if colour == "palette" else colour
            col = tuple(v / 255 for v in col)
            seg = corners[k][BOX_EDGES]  # (12, 2, 3)
            xs = np.concatenate([seg[:, :, 0], np.full((12, 1), np.nan)], 1).ravel()
            ys = np.concatenate([seg[:, :, 1], np.full((12, 1), np.nan)], 1).ravel()
            zs = np.concatenate([seg[:, :, 2], np.full((12, 1), np.nan)], 1).ravel()
            ax.plot(xs, ys, zs, ls, color=col, lw=lw)
    for a, b, kind in contacts or ():
        style = {"fixed": ("-", "red", 2.5), "touch": ("--", "blue", 1.5)}.get(kind, (":", "0.4", 1))
        ax.plot(*np.stack([a, b]).T, style[0], color=style[1], lw=style[2])
    if allp:
        box = np.concatenate(allp)
        lo, hi = box.min(0), box.max(0)
        mid, r = (lo + hi) / 2, max(float(np.max(hi - lo)) / 2, 1e-3)
        ax.set_xlim(mid[0] - r, mid[0] + r)
        ax.set_ylim(mid[1] - r, mid[1] + r)
        ax.set_zlim(max(mid[2] - r, lo[2] - 0.05 * r), max(mid[2] - r, lo[2] - 0.05 * r) + 2 * r)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.view_init(elev=elev, azim=azim)
    if title:
        ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.canvas.draw()
    img = np.asarray(fig.canvas.buffer_rgba())[:, :, :3].copy()
    plt.close(fig)
    return img


def write_png(path: str | os.PathLike, image: np.ndarray) -> None:
    """Write an RGB uint8 image as PNG, atomically."""
    import cv2

    ok, buf = cv2.imencode(".png", cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2BGR))
    if not ok:
        raise OSError(f"{path}: PNG encoding failed")
    atomic.write_bytes(path, buf.tobytes())


def splat_points(points: np.ndarray, colors: np.ndarray | None, intr: Intrinsics,
                 T_world_cam: np.ndarray, radius: int = 1) -> np.ndarray:
    """(H, W, 3) uint8: a z-buffered rendering of coloured points (for clouds without an image)."""
    H, W = intr.height, intr.width
    uv, z = project(transform(invert(T_world_cam), np.asarray(points, float)), intr)
    ok = (z > 0) & np.all(np.isfinite(uv), axis=1)
    col = (np.asarray(colors)[ok] * 255).astype(np.uint8) if colors is not None else None
    if col is None:
        zz = z[ok]
        g = (255 * (1 - (zz - zz.min()) / max(np.ptp(zz), 1e-9))).astype(np.uint8) if len(zz) else zz
        col = np.repeat(np.asarray(g, np.uint8)[:, None], 3, 1)
    out = np.full((H, W, 3), 255, np.uint8)
    zbuf = np.full(H * W, np.inf)
    u0 = np.round(uv[ok, 0]).astype(int)
    v0 = np.round(uv[ok, 1]).astype(int)
    zz = z[ok]
    for du in range(-radius, radius + 1):
        for dv in range(-radius, radius + 1):
            u, v = u0 + du, v0 + dv
            inb = (u >= 0) & (u < W) & (v >= 0) & (v < H)
            idx = v[inb] * W + u[inb]
            np.minimum.at(zbuf, idx, zz[inb])
    for du in range(-radius, radius + 1):
        for dv in range(-radius, radius + 1):
            u, v = u0 + du, v0 + dv
            inb = (u >= 0) & (u < W) & (v >= 0) & (v < H)
            idx = v[inb] * W + u[inb]
            win = zz[inb] <= zbuf[idx]
            out.reshape(-1, 3)[idx[win]] = col[inb][win]
    return out
