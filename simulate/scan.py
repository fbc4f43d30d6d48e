"""The virtual depth sensor: render views of an arrangement, add sensor noise, fuse, write.

Public API (used by ``synth_scenes`` and the pipeline):

* :func:`render` -- one noiseless :class:`Frame` (RGB, exact metric depth, instance ids);
* :func:`scan_arrangement` -- ``views`` frames from sampled or given poses, Kinect v1 noise,
  and the fused world point cloud (:class:`Scan`);
* :func:`write_scan` / :func:`read_scan_dir` -- the ``scan/`` folder of a scene directory;
* :func:`read_ply` / :func:`write_ply` -- point clouds with per-point instance ids.

Depth units: a :class:`Frame` from :func:`render` holds exact float depth; a scan's frames
hold depth rounded to whole millimetres (what ``depth.png`` stores), and its points are
back-projected from those millimetres, so a scan read back from disk equals the scan in
memory and every point reprojects onto its pixel with its depth.  The instance image is
the clean render (aligned with the colour image); a point carries the id of its pixel.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline import atomic
from pipeline.camera import (
    Intrinsics,
    backproject,
    read_intrinsics,
    read_pose,
    write_intrinsics,
    write_pose,
)
from pipeline.errors import InputError
from pipeline.model import Arrangement

BACKENDS = ("mujoco", "pybullet")
NOISE_MODELS = ("kinect", "none")


@dataclass(frozen=True)
class Frame:
    """One RGB-D view.

    Attributes
    ----------
    color : (H, W, 3) uint8, RGB
    depth : (H, W) float32, metres along the optical axis, 0 = no reading
    instance : (H, W) uint16, ``k`` = ``arr.cuboids[k - 1]``, 0 = background or support
    intrinsics : Intrinsics
    T_world_cam : (4, 4) float, camera-to-world (OpenCV camera frame)
    """

    color: np.ndarray
    depth: np.ndarray
    instance: np.ndarray
    intrinsics: Intrinsics
    T_world_cam: np.ndarray

    def __post_init__(self) -> None:
        H, W = self.intrinsics.height, self.intrinsics.width
        for name, shape, dtype in (("color", (H, W, 3), np.uint8), ("depth", (H, W), np.float32),
                                   ("instance", (H, W), np.uint16)):
            a = np.asarray(getattr(self, name))
            if a.shape != shape:
                raise ValueError(f"Frame.{name}: expected shape {shape}, got {a.shape}")
            a = np.array(a, dtype=dtype)
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        T = np.array(self.T_world_cam, dtype=float)
        if T.shape != (4, 4):
            raise ValueError(f"Frame.T_world_cam: expected shape (4, 4), got {T.shape}")
        T.setflags(write=False)
        object.__setattr__(self, "T_world_cam", T)

    def points(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """World points of the pixels with a reading, in row-major pixel order.

        Returns
        -------
        points : (n, 3) float, world coordinates
        colors : (n, 3) uint8
        instance : (n,) uint16
        """
        pc, pix = backproject(self.depth.astype(np.float64), self.intrinsics)
        v, u = pix[:, 0], pix[:, 1]
        R, t = self.T_world_cam[:3, :3], self.T_world_cam[:3, 3]
        # R @ p + t written out: a BLAS call on (n, 3) x (3, 3) is slower, and it spins
        # threads on a loaded machine
        world = (pc[:, 0:1] * R[:, 0] + pc[:, 1:2] * R[:, 1]) + (pc[:, 2:3] * R[:, 2] + t)
        return world, self.color[v, u], self.instance[v, u]


@dataclass(frozen=True)
class Scan:
    """Several frames and their fused world point cloud.

    Attributes
    ----------
    frames : tuple of Frame
    points : (n, 3) float, world coordinates, fused from all frames
    colors : (n, 3) uint8
    instance : (n,) uint16, same ids as the frames' instance images
    """

    frames: tuple[Frame, ...]
    points: np.ndarray
    colors: np.ndarray
    instance: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "frames", tuple(self.frames))
        pts = np.array(self.points, dtype=float).reshape(-1, 3)
        n = len(pts)
        cols = np.array(self.colors, dtype=np.uint8).reshape(-1, 3)
        inst = np.array(self.instance, dtype=np.uint16).reshape(-1)
        if len(cols) != n or len(inst) != n:
            raise ValueError(f"Scan: {n} points but {len(cols)} colours and {len(inst)} ids")
        for name, a in (("points", pts), ("colors", cols), ("instance", inst)):
            a.setflags(write=False)
            object.__setattr__(self, name, a)


# ---- rendering --------------------------------------------------------------------------

def _renderer(arr: Arrangement, intr: Intrinsics, backend: str):
    if backend == "mujoco":
        from .render_mujoco import MujocoRenderer

        return MujocoRenderer(arr, intr.width, intr.height)
    if backend == "pybullet":
        from .render_pybullet import PybulletRenderer

        return PybulletRenderer(arr)
    raise InputError(f"renderer: unknown backend {backend!r}; expected one of {BACKENDS}")


def render(arr: Arrangement, intrinsics: Intrinsics, T_world_cam: np.ndarray,
           backend: str = "mujoco") -> Frame:
    """Render one noiseless frame (exact float depth) with ``backend`` (mujoco|pybullet)."""
    with _renderer(arr, intrinsics, backend) as r:
        color, depth, instance = r.render(intrinsics, T_world_cam)
    return Frame(color, depth, instance, intrinsics, np.asarray(T_world_cam, float))


def depth_to_mm(depth: np.ndarray) -> np.ndarray:
    """(H, W) uint16 millimetres of a metric depth image (0 = none, also beyond 65.535 m)."""
    mm = np.rint(np.asarray(depth, np.float64) * 1000.0)
    return np.where((mm > 0) & (mm <= 65535), mm, 0).astype(np.uint16)


def fuse(frames: tuple[Frame, ...] | list[Frame], voxel: float | None = None
         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fuse frames into one world cloud: all points, or one per ``voxel`` (metres) cell.

    With ``voxel`` the first point (in frame order) of each occupied cell is kept, so the
    result is deterministic and every kept point is still a real pixel of some frame.

    Returns
    -------
    points : (n, 3) float, colors : (n, 3) uint8, instance : (n,) uint16
    """
    parts = [f.points() for f in frames]
    if not parts:
        return np.zeros((0, 3)), np.zeros((0, 3), np.uint8), np.zeros(0, np.uint16)
    pts = np.concatenate([p[0] for p in parts])
    cols = np.concatenate([p[1] for p in parts])
    inst = np.concatenate([p[2] for p in parts])
    if voxel is not None and voxel > 0 and len(pts):
        keys = np.floor(pts / voxel).astype(np.int64)
        _, first = np.unique(keys, axis=0, return_index=True)
        keep = np.sort(first)
        pts, cols, inst = pts[keep], cols[keep], inst[keep]
    return pts, cols, inst


def scan_arrangement(arr: Arrangement, rng: np.random.Generator, views: int = 1,
                     noise: str | object = "kinect", intrinsics: Intrinsics | None = None,
                     poses: np.ndarray | list | None = None, renderer: str = "mujoco",
                     view_ranges: dict | object | None = None,
                     fuse_voxel: float | None = None) -> Scan:
    """Scan an arrangement like a Kinect v1: render, add noise, fuse.

    Parameters
    ----------
    arr : Arrangement
    rng : numpy.random.Generator
        Viewpoint sampling first, then one child generator per view for the noise.
    views : int
        Number of views (ignored when ``poses`` is given).
    noise : "kinect", "none" or simulate.noise.KinectNoise
    intrinsics : Intrinsics, optional
        Default Kinect v1 (640x480, f = 525).
    poses : (K, 4, 4) float, optional
        Camera-to-world poses; sampled with :func:`simulate.viewpoints.sample_viewpoints`
        when omitted.
    renderer : "mujoco" or "pybullet"
    view_ranges : dict or ViewRanges, optional
        ``{"distance": (1.5, 3), "elevation": (20, 45), "azimuth": (lo, hi)}`` (degrees).
    fuse_voxel : float, optional
        Keep one point per voxel of this size in the fused cloud (default: all points).

    Returns
    -------
    Scan
        Frames with depth in whole millimetres and the fused cloud back-projected from them.
    """
    from .noise import KinectNoise, apply_noise

    intr = intrinsics or Intrinsics.kinect_v1()
    if isinstance(noise, str):
        if noise not in NOISE_MODELS:
            raise InputError(f"noise: unknown model {noise!r}; expected one of {NOISE_MODELS}")
        model = KinectNoise() if noise == "kinect" else None
    elif isinstance(noise, KinectNoise):
        model = noise
    elif noise is None:
        model = None
    else:
        raise InputError(f"noise: expected 'kinect', 'none' or a KinectNoise, got {noise!r}")

    if poses is None:
        from .viewpoints import sample_viewpoints

        T_all = sample_viewpoints(arr, rng, views, view_ranges, intr)
    else:
        T_all = np.asarray(poses, dtype=float).reshape(-1, 4, 4)
        if len(T_all) == 0:
            raise InputError("poses: at least one camera pose is needed")
    noise_rngs = rng.spawn(len(T_all))

    frames = []
    with _renderer(arr, intr, renderer) as r:
        for T, g in zip(T_all, noise_rngs, strict=True):
            color, depth, instance = r.render(intr, T)
            if model is not None:
                depth = apply_noise(depth, intr, g, model)
            frames.append(Frame(color, _mm_to_metres(depth_to_mm(depth)), instance, intr, T))
    pts, cols, inst = fuse(frames, fuse_voxel)
    return Scan(tuple(frames), pts, cols, inst)


def _mm_to_metres(mm: np.ndarray) -> np.ndarray:
    """float32 metres of uint16 millimetres; ``depth_to_mm`` of it gives ``mm`` back."""
    return (mm.astype(np.float64) / 1000.0).astype(np.float32)


# ---- files ------------------------------------------------------------------------------

_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
              "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
              "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
              "float64": "f8"}


def write_ply(path: str | os.PathLike, points: np.ndarray, colors: np.ndarray | None = None,
              instance: np.ndarray | None = None) -> None:
    """Write a binary little-endian PLY (x y z float, red green blue uchar, instance ushort).

    Parameters
    ----------
    points : (n, 3) float
    colors : (n, 3) uint8, optional
    instance : (n,) uint16, optional
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    if colors is not None:
        fields += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    if instance is not None:
        fields += [("instance", "<u2")]
    rec = np.zeros(len(pts), dtype=np.dtype(fields))
    rec["x"], rec["y"], rec["z"] = pts[:, 0], pts[:, 1], pts[:, 2]
    if colors is not None:
        c = np.asarray(colors, dtype=np.uint8).reshape(-1, 3)
        rec["red"], rec["green"], rec["blue"] = c[:, 0], c[:, 1], c[:, 2]
    if instance is not None:
        rec["instance"] = np.asarray(instance, dtype=np.uint16).reshape(-1)
    names = {"<f4": "float", "u1": "uchar", "<u2": "ushort"}
    header = ["ply", "format binary_little_endian 1.0", "comment written by unseen",
              f"element vertex {len(pts)}"]
    header += [f"property {names[t]} {n}" for n, t in fields]
    header.append("end_header")
    atomic.write_bytes(path, ("\n".join(header) + "\n").encode("ascii") + rec.tobytes())


def read_ply(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Read the vertices of an ASCII or binary PLY (also from other tools).

    Colours are read from ``red green blue`` (or ``r g b``, ``diffuse_*``; float colours in
    [0, 1] are scaled to 0-255); instance ids from ``instance``, ``instance_id`` or ``label``.

    Returns
    -------
    points : (n, 3) float
    colors : (n, 3) uint8 or None
    instance : (n,) uint16 or None
    """
    from pipeline.scan_io import read_ply as read_ply_columns

    path = Path(path)
    cols = read_ply_columns(path)  # the one PLY parser (ascii / binary, any endianness)
    if not all(k in cols for k in "xyz"):
        raise InputError(f"{path}: PLY vertices need x, y and z properties")
    points = np.stack([cols["x"], cols["y"], cols["z"]], axis=1)
    colors = None
    for r_, g_, b_ in (("red", "green", "blue"), ("r", "g", "b"),
                       ("diffuse_red", "diffuse_green", "diffuse_blue")):
        if r_ in cols and g_ in cols and b_ in cols:
            c = np.stack([cols[r_], cols[g_], cols[b_]], axis=1)
            if c.size and c.max() <= 1.0 and np.any(c != np.rint(c)):  # float colours in [0, 1]
                c = c * 255.0
            colors = np.clip(np.rint(c), 0, 255).astype(np.uint8)
            break
    instance = None
    for key in ("instance", "instance_id", "label"):
        if key in cols:
            instance = np.clip(cols[key], 0, 65535).astype(np.uint16)
            break
    return points, colors, instance


def _write_frame(frame: Frame, folder: Path, with_points: bool = True) -> None:
    import cv2

    with atomic.atomic_path(folder / "color.png") as tmp:
        if not cv2.imwrite(str(tmp), np.ascontiguousarray(frame.color[..., ::-1])):
            raise OSError(f"cannot write {folder / 'color.png'}")
    with atomic.atomic_path(folder / "depth.png") as tmp:
        cv2.imwrite(str(tmp), depth_to_mm(frame.depth))
    with atomic.atomic_path(folder / "instance.png") as tmp:
        cv2.imwrite(str(tmp), np.ascontiguousarray(frame.instance, dtype=np.uint16))
    write_intrinsics(frame.intrinsics, folder / "intrinsics.json")
    write_pose(frame.T_world_cam, folder / "camera_pose.json")
    if with_points:
        write_ply(folder / "points.ply", *frame.points())


def write_scan(scan: Scan, scan_dir: str | os.PathLike) -> None:
    """Write a scan folder (every file atomically).

    One view: ``color.png`` (8-bit RGB), ``depth.png`` (16-bit mm, 0 = none),
    ``instance.png`` (16-bit ids), ``intrinsics.json``, ``camera_pose.json`` (4x4
    camera-to-world) and ``points.ply`` in ``scan_dir``.  Several views: the same files per
    view in ``view0/``, ``view1/``, ... and the fused ``points.ply`` in ``scan_dir``.
    """
    scan_dir = Path(scan_dir)
    scan_dir.mkdir(parents=True, exist_ok=True)
    _remove_stale(scan_dir, len(scan.frames))
    if len(scan.frames) == 1:
        _write_frame(scan.frames[0], scan_dir, with_points=False)
    else:
        for k, frame in enumerate(scan.frames):
            sub = scan_dir / f"view{k}"
            sub.mkdir(exist_ok=True)
            _write_frame(frame, sub)
    write_ply(scan_dir / "points.ply", scan.points, scan.colors, scan.instance)


#: The files :func:`write_scan` writes per view.
VIEW_FILES = ("color.png", "depth.png", "instance.png", "intrinsics.json", "camera_pose.json",
              "points.ply")


def _remove_stale(scan_dir: Path, views: int) -> None:
    """Delete our own files of an earlier scan with another layout or more views.

    Only the names this module writes are removed (per-view files at the top when writing
    several views; ``view<k>/`` folders with ``k >= views``), so a re-used folder never
    mixes two scans; anything else in the folder is left alone.
    """
    if views > 1:
        for name in VIEW_FILES[:-1]:
            (scan_dir / name).unlink(missing_ok=True)
    for sub in scan_dir.iterdir():
        m = re.fullmatch(r"view(\d+)", sub.name)
        if m and sub.is_dir() and (views == 1 or int(m.group(1)) >= views):
            for name in VIEW_FILES:
                (sub / name).unlink(missing_ok=True)
            if not any(sub.iterdir()):
                sub.rmdir()


def _read_frame(folder: Path) -> Frame:
    import cv2

    def imread(name: str, flags: int) -> np.ndarray:
        p = folder / name
        img = cv2.imread(str(p), flags) if p.is_file() else None
        if img is None:
            raise InputError(f"{p}: missing or not an image")
        return img

    intr = read_intrinsics(folder / "intrinsics.json")
    T = read_pose(folder / "camera_pose.json")
    color = imread("color.png", cv2.IMREAD_COLOR)[..., ::-1]
    depth = imread("depth.png", cv2.IMREAD_UNCHANGED)
    if depth.dtype != np.uint16 or depth.ndim != 2:
        raise InputError(f"{folder / 'depth.png'}: must be a 16-bit single-channel PNG (mm)")
    if (folder / "instance.png").is_file():
        instance = imread("instance.png", cv2.IMREAD_UNCHANGED)
    else:
        instance = np.zeros(depth.shape, np.uint16)
    if depth.shape != (intr.height, intr.width) or color.shape[:2] != depth.shape:
        raise InputError(f"{folder}: image sizes do not match intrinsics.json "
                         f"({intr.width}x{intr.height})")
    return Frame(color, _mm_to_metres(depth), instance.astype(np.uint16), intr, T)


def read_scan_dir(scan_dir: str | os.PathLike) -> Scan:
    """Read a folder written by :func:`write_scan` (the inverse)."""
    scan_dir = Path(scan_dir)
    if not scan_dir.is_dir():
        raise InputError(f"{scan_dir}: no such scan folder")
    subs = sorted((p for p in scan_dir.iterdir() if p.is_dir() and re.fullmatch(r"view\d+", p.name)),
                  key=lambda p: int(p.name[4:]))
    frames = tuple(_read_frame(p) for p in subs) if subs else (_read_frame(scan_dir),)
    ply = scan_dir / "points.ply"
    if ply.is_file():
        pts, cols, inst = read_ply(ply)
        if cols is None:
            cols = np.zeros((len(pts), 3), np.uint8)
        if inst is None:
            inst = np.zeros(len(pts), np.uint16)
    else:
        pts, cols, inst = fuse(frames)
    return Scan(frames, pts, cols, inst)
