"""The original camera view of a scan, metric, in its arrangement's world (image edits).

Frames: the arrangement's world (z up) maps onto the input's camera frame by
``meta.camera_pose`` after the input's scale (``p_world = T @ (input_scale * p_input)``);
pixels are OpenCV's (:mod:`pipeline.camera`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.camera import Intrinsics, check_same_frame
from pipeline.errors import InputError
from pipeline.model import Arrangement


@dataclass(frozen=True)
class View:
    """The original camera view of a scan, metric, in the arrangement's world.

    Attributes
    ----------
    image : (H, W, 3) uint8 RGB
    depth : (H, W) float, metres along the optical axis, 0 = no reading
    intrinsics : Intrinsics
    T_world_cam : (4, 4) float, camera (metres) to the arrangement's world
    """

    image: np.ndarray
    depth: np.ndarray
    intrinsics: Intrinsics
    T_world_cam: np.ndarray


def view_of(scan, arr: Arrangement, where: str = "SCAN") -> View:
    """The :class:`View` of a loaded scan (:func:`pipeline.run.load`) and its result.

    Raises :class:`InputError` (one line) when the scan has no colour image, depth or
    intrinsics, the result has no ``meta.camera_pose``, or their sizes disagree.
    """
    if getattr(scan, "views", ()):
        raise InputError(f"{where}: a multi-view scan; edits are made in one RGB-D frame "
                         "(give one view's folder, e.g. scan/view0, and its own run)")
    if scan.image is None or scan.depth is None or scan.intrinsics is None:
        raise InputError(f"{where}: no colour image with depth and intrinsics; edits are "
                         "made in the original colour image of an RGB-D frame")
    pose = arr.meta.get("camera_pose")
    try:
        T = np.asarray(pose, float)
    except (TypeError, ValueError):
        T = np.zeros(0)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise InputError("RESULT: its arrangement has no meta.camera_pose (a 4x4 camera-to-"
                         "world matrix); use the arrangement.json that 'unseen run' wrote")
    if arr.meta.get("input_frame", "camera") != "camera":
        raise InputError("RESULT: it was made from a point cloud without a camera; edits need "
                         "the run of an RGB-D frame")
    intr = scan.intrinsics
    H, W = scan.depth.shape
    if scan.image.shape[:2] != (H, W) or (intr.width, intr.height) != (W, H):
        raise InputError(f"{where}: colour, depth and intrinsics disagree in size")
    check_same_frame(arr.meta, intr, where)
    s = float(arr.meta.get("input_scale", 1.0))
    depth = np.where(np.isfinite(scan.depth) & (scan.depth > 0), scan.depth * s, 0.0)
    return View(np.ascontiguousarray(scan.image[:, :, :3]).astype(np.uint8), depth, intr, T)


__all__ = ["View", "view_of"]
