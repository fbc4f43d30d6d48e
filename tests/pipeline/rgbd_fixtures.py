"""Ray-cast RGB-D frames of boxes on a ground plane (numpy only), with exact truth.

Independent of the project's sensor (``simulate``): every pixel's ray is intersected with
the ground plane z = 0, an optional wall, and each oriented box by the slab method.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.camera import Intrinsics, invert, look_at, write_intrinsics, write_pose

BOX_COLOURS = np.array([[220, 40, 40], [40, 200, 60], [40, 80, 230], [230, 200, 30],
                        [200, 60, 200]], dtype=np.uint8)


@dataclass
class Frame:
    color: np.ndarray  # (H, W, 3) uint8
    depth: np.ndarray  # (H, W) float metres
    instance: np.ndarray  # (H, W) int, k + 1 for box k, 0 ground/wall/none
    intr: Intrinsics
    T_world_cam: np.ndarray


def raycast(boxes: list[tuple[np.ndarray, np.ndarray, np.ndarray]], eye, target,
            intr: Intrinsics | None = None, wall_x: float | None = None) -> Frame:
    """Render boxes ``(center, R, size)`` on the ground z = 0 from ``eye`` looking at ``target``."""
    intr = intr or Intrinsics(160, 120, 130.0, 130.0, 79.5, 59.5)
    T = look_at(np.asarray(eye, float), np.asarray(target, float))
    v, u = np.mgrid[0:intr.height, 0:intr.width]
    d_cam = np.stack([(u - intr.cx) / intr.fx, (v - intr.cy) / intr.fy, np.ones(u.shape)], -1)
    d_cam = d_cam.reshape(-1, 3)
    d = d_cam @ T[:3, :3].T  # world ray directions with unit camera-z component
    o = T[:3, 3]
    P = len(d)
    t_best = np.full(P, np.inf)
    inst = np.zeros(P, dtype=np.int64)
    shade = np.zeros(P)
    with np.errstate(divide="ignore", invalid="ignore"):
        tg = -o[2] / d[:, 2]
    hit = (tg > 0) & np.isfinite(tg)
    t_best[hit] = tg[hit]
    shade[hit] = 0.45
    if wall_x is not None:
        with np.errstate(divide="ignore", invalid="ignore"):
            tw = (wall_x - o[0]) / d[:, 0]
        hw = (tw > 0) & (tw < t_best) & np.isfinite(tw)
        t_best[hw] = tw[hw]
        shade[hw] = 0.7
    for k, (c, R, s) in enumerate(boxes):
        ol = (o - c) @ R
        dl = d @ R
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (-s / 2 - ol) / dl
            t2 = (s / 2 - ol) / dl
        tmin = np.nanmax(np.minimum(t1, t2), axis=1)
        tmax = np.nanmin(np.maximum(t1, t2), axis=1)
        hb = (tmax >= tmin) & (tmin > 0) & (tmin < t_best)
        t_best[hb] = tmin[hb]
        inst[hb] = k + 1
        # face shading: which slab was entered last
        face = np.argmax(np.minimum(t1, t2), axis=1)
        shade[hb] = 0.6 + 0.13 * face[hb]
    # t is the camera z (d_cam z = 1); a sensor reads up to 10 m
    depth = np.where(np.isfinite(t_best) & (t_best < 10.0), t_best, 0.0)
    col = np.full((P, 3), 0.0)
    base = np.where(inst[:, None] > 0, BOX_COLOURS[(inst - 1) % len(BOX_COLOURS)], 160)
    col = np.clip(base * shade[:, None] * 1.3, 0, 255).astype(np.uint8)
    H, W = intr.height, intr.width
    return Frame(col.reshape(H, W, 3), depth.reshape(H, W), inst.reshape(H, W), intr, T)


def write_frame(frame: Frame, folder: Path, pose: bool = True, instance: bool = False) -> Path:
    import cv2

    folder.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(folder / "color.png"), cv2.cvtColor(frame.color, cv2.COLOR_RGB2BGR))
    cv2.imwrite(str(folder / "depth.png"), np.round(frame.depth * 1000).astype(np.uint16))
    write_intrinsics(frame.intr, folder / "intrinsics.json")
    if pose:
        write_pose(frame.T_world_cam, folder / "camera_pose.json")
    if instance:
        cv2.imwrite(str(folder / "instance.png"), frame.instance.astype(np.uint16))
    return folder


def camera_points(frame: Frame) -> np.ndarray:
    """(n, 3) world points of the valid pixels."""
    from pipeline.camera import backproject, transform

    pts, _ = backproject(frame.depth, frame.intr)
    return transform(frame.T_world_cam, pts)


def visible_box(frame: Frame, k: int, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tight (center, size) in frame ``R`` of the visible points of box ``k`` (0-based)."""
    from pipeline.camera import backproject, transform

    pts, pix = backproject(frame.depth, frame.intr)
    sel = frame.instance[pix[:, 0], pix[:, 1]] == k + 1
    loc = transform(frame.T_world_cam, pts[sel]) @ R
    lo, hi = loc.min(0), loc.max(0)
    return R @ ((lo + hi) / 2), hi - lo


def inv(T: np.ndarray) -> np.ndarray:
    return invert(T)
