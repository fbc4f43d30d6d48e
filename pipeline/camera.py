"""The pinhole camera model shared by the sensor, the loaders and the pipeline.

Conventions: OpenCV camera frame (x right, y down, z forward); pixel (u, v) has its
centre at integer coordinates, u along columns, v along rows; ``T_world_cam`` is the
4x4 camera-to-world transform (``p_world = T_world_cam @ p_cam``).  Depth images hold
the z coordinate in the camera frame (not the ray length), metres in memory, 16-bit
millimetres on disk with 0 = no reading.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import atomic
from .errors import InputError


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics (pixels)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @property
    def K(self) -> np.ndarray:
        """(3, 3) float camera matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @classmethod
    def kinect_v1(cls) -> Intrinsics:
        """The PrimeSense/Kinect v1 default: 640x480, f = 525, centre (319.5, 239.5)."""
        return cls(640, 480, 525.0, 525.0, 319.5, 239.5)

    def to_json(self) -> dict:
        return {"width": self.width, "height": self.height, "fx": self.fx, "fy": self.fy,
                "cx": self.cx, "cy": self.cy}

    @classmethod
    def from_json(cls, data: object, where: str = "intrinsics") -> Intrinsics:
        """Validate and build; absurd values raise :class:`InputError` naming the field."""
        if not isinstance(data, dict):
            raise InputError(f"{where}: must be an object with width height fx fy cx cy")
        vals = {}
        for key in ("width", "height", "fx", "fy", "cx", "cy"):
            v = data.get(key)
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
                raise InputError(f"{where}.{key}: missing or not a finite number")
            vals[key] = v
        w, h = vals["width"], vals["height"]
        if int(w) != w or int(h) != h or not (8 <= w <= 20000 and 8 <= h <= 20000):
            raise InputError(f"{where}: width/height must be whole numbers in 8..20000, got {w}x{h}")
        for key in ("fx", "fy"):
            if not (0.05 * max(w, h) < vals[key] < 50 * max(w, h)):
                raise InputError(f"{where}.{key}: {vals[key]} px is absurd for a {int(w)}x{int(h)} "
                                 "image (expected roughly 0.3-3x the image width)")
        if not (-0.5 * w <= vals["cx"] <= 1.5 * w) or not (-0.5 * h <= vals["cy"] <= 1.5 * h):
            raise InputError(f"{where}: principal point ({vals['cx']}, {vals['cy']}) is far "
                             f"outside the {int(w)}x{int(h)} image")
        return cls(int(w), int(h), float(vals["fx"]), float(vals["fy"]), float(vals["cx"]),
                   float(vals["cy"]))


def read_intrinsics(path: str | os.PathLike) -> Intrinsics:
    from .safe_read import load_json, regular_file

    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such file (intrinsics.json with width height fx fy cx cy "
                         "is required)")
    data = load_json(regular_file(path, "intrinsics file"), "intrinsics file", limit=2**20)
    return Intrinsics.from_json(data, str(path))


def write_intrinsics(intr: Intrinsics, path: str | os.PathLike) -> None:
    atomic.write_text(path, json.dumps(intr.to_json(), indent=1) + "\n")


def read_pose(path: str | os.PathLike) -> np.ndarray:
    """Read a 4x4 camera-to-world matrix (a JSON list of 4 rows, ``{"T_world_cam": ...}``,
    or an ``arrangement.json`` of an earlier run: its ``meta.camera_pose``)."""
    from .safe_read import load_json

    data = load_json(path, "camera pose file", limit=2**20)
    if isinstance(data, dict):
        meta = data.get("meta") if isinstance(data.get("meta"), dict) else {}
        data = data.get("T_world_cam", data.get("camera_pose", meta.get("camera_pose")))
    try:
        T = np.array(data, dtype=float) if isinstance(data, list) else None
    except (ValueError, TypeError, OverflowError):
        T = None
    if T is None or T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise InputError(f"{path}: camera pose must be a 4x4 list of numbers (camera-to-world)")
    R = T[:3, :3]
    if not np.allclose(R.T @ R, np.eye(3), atol=1e-5) or np.linalg.det(R) < 0:
        raise InputError(f"{path}: the rotation part of the camera pose is not a rotation")
    return T


def write_pose(T_world_cam: np.ndarray, path: str | os.PathLike) -> None:
    atomic.write_text(path, json.dumps(np.asarray(T_world_cam, float).tolist(), indent=1) + "\n")


def check_same_frame(meta: dict, intr: Intrinsics, where: str, result: str = "RESULT") -> None:
    """Refuse (:class:`InputError`) a frame ``where`` whose intrinsics ``intr`` are not
    those a result recorded in ``meta["intrinsics"]`` (size and fx, fy, cx, cy): the
    result was made from another frame, and its camera pose would put this frame's pixels
    elsewhere.  A result without recorded intrinsics passes."""
    mi = meta.get("intrinsics")
    if not isinstance(mi, dict):
        return
    if (mi.get("width"), mi.get("height")) != (intr.width, intr.height):
        raise InputError(f"{result}: it was made from a {mi.get('width')}x{mi.get('height')} "
                         f"frame but {where} is {intr.width}x{intr.height}; give the scan the "
                         "result came from")
    for key in ("fx", "fy", "cx", "cy"):
        have, want = getattr(intr, key), mi.get(key)
        if isinstance(want, (int, float)) and not np.isclose(have, want, rtol=1e-6, atol=1e-6):
            raise InputError(f"{result}: it was made from a frame with {key} {want:g} but "
                             f"{where} has {key} {have:g}; give the scan the result came from")


def project(points_cam: np.ndarray, intr: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """Project camera-frame points.

    Parameters
    ----------
    points_cam : (n, 3) float

    Returns
    -------
    uv : (n, 2) float, pixel coordinates (u right, v down)
    z : (n,) float, depth along the optical axis
    """
    p = np.asarray(points_cam, dtype=float)
    z = p[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = intr.fx * p[:, 0] / z + intr.cx
        v = intr.fy * p[:, 1] / z + intr.cy
    return np.stack([u, v], axis=1), z


def backproject(depth: np.ndarray, intr: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """Back-project a metric depth image to camera-frame points.

    Parameters
    ----------
    depth : (H, W) float, metres along z, 0 or NaN = no reading

    Returns
    -------
    points_cam : (n, 3) float, one per valid pixel, row-major order
    pixels : (n, 2) int, (v, u) of each point
    """
    d = np.asarray(depth, dtype=float)
    valid = np.isfinite(d) & (d > 0)
    v, u = np.nonzero(valid)
    z = d[v, u]
    x = (u - intr.cx) * z / intr.fx
    y = (v - intr.cy) * z / intr.fy
    return np.stack([x, y, z], axis=1), np.stack([v, u], axis=1)


def transform(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a 4x4 rigid transform to ``points (n, 3)``."""
    return np.asarray(points) @ T[:3, :3].T + T[:3, 3]


def invert(T: np.ndarray) -> np.ndarray:
    """Inverse of a 4x4 rigid transform."""
    out = np.eye(4)
    out[:3, :3] = T[:3, :3].T
    out[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return out


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray = (0.0, 0.0, 1.0)) -> np.ndarray:
    """T_world_cam (4, 4) of an OpenCV camera at ``eye`` looking at ``target``, world ``up`` up."""
    eye = np.asarray(eye, float)
    z = np.asarray(target, float) - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, np.asarray(up, float))
    if np.linalg.norm(x) < 1e-9:  # looking straight along up: pick any x
        x = np.cross(z, np.array([0.0, 1.0, 0.0]))
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, eye
    return T
