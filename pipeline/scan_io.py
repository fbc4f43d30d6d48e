"""Loading scans: scene directories, RGB-D folders, real-sensor depth formats, PLY/PCD clouds.

Everything becomes one :class:`ScanInput`: points in the input's own frame (the camera
frame for an RGB-D frame, the file's frame for a cloud), optional colours, per-point
instance ids, the colour/depth images with their intrinsics, and the camera-to-world
pose when the input carries one (``scan/camera_pose.json`` of a synthetic scene).

Supported inputs (see ``unseen run --help`` for the flags of each real data set):

* a scene directory written by ``unseen synth`` (its ``scan/`` sub-folder is read);
* an RGB-D folder with ``color.png``, ``depth.png``, ``intrinsics.json`` and optional
  ``camera_pose.json``, ``instance.png`` (16-bit ids), ``scribbles.png``;
* any folder plus ``color=`` / ``depth=`` file names and ``intrinsics=(fx, fy, cx, cy)``;
* depth encodings: 16-bit PNG / PGM divided by ``depth_scale`` (1000 = mm, 5000 = TUM),
  ``nyu-disparity`` (NYU raw PGM: little-endian despite the PGM spec, Kinect disparity,
  ``d = 351.3 / (1092.5 - raw)``), ``sun-bitrot`` (SUN RGB-D: ``mm = (v >> 3) | (v << 13)``),
  ``float32-dat`` (int32 rows, int32 cols, float32 metres: RAPter / Shao Kinect captures);
* point clouds: ``.ply`` (ascii / binary, vertex properties ``x y z`` and optional colour
  and ``instance``/``label``), ``.pcd`` (ascii, binary and binary_compressed, with an
  optional ``label`` field used as instance ids), ``.npz`` with key ``pc`` (N x 3 or 6; a file of one array may name it otherwise).

Organised clouds (PCD ``HEIGHT > 1``) are turned back into an RGB-D frame with the
given (or Kinect default) intrinsics, so overlays and visibility tests work on them.
"""

from __future__ import annotations

import os
import re
import struct
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .camera import Intrinsics, backproject, read_intrinsics, read_pose, transform
from .errors import InputError
from .safe_read import load_json, read_bytes, regular_file

#: Clouds larger than this are voxel-downsampled right after loading.
MAX_POINTS = 2_000_000
#: Largest point-cloud or depth file read, bytes (45 M points of 12 bytes).
MAX_CLOUD_BYTES = 512 * 2**20

DEPTH_FORMATS = ("auto", "png", "nyu-disparity", "sun-bitrot", "float32-dat")


@dataclass(frozen=True)
class ScanInput:
    """A scan, in the input's own frame.

    Attributes
    ----------
    points : (n, 3) float
        Points in the input frame (camera frame for RGB-D), metres; finite.
    colors : (n, 3) float or None
        RGB in [0, 1].
    instance : (n,) int or None
        Per-point instance id, 0 = background / unknown.
    pixels : (n, 2) int or None
        (v, u) pixel of each point when it came from an image.
    image : (H, W, 3) uint8 or None
        Colour image, RGB.
    depth : (H, W) float or None
        Depth in metres along z, 0 = no reading.
    intrinsics : Intrinsics or None
    T_world_cam : (4, 4) float or None
        Camera-to-world pose given by the input (None: the pipeline chooses one).
    scribbles : (H, W) int or None
        User strokes, one non-zero value per object (0 = none).
    instance_image : (H, W) int or None
    up : (3,) float or None
        Up direction in the input frame when the user gave it.
    floor_height : float or None
        The floor's height along up in the input frame (metres) when the user gave it
        (``--floor-height``): with ``up`` or a pose, the floor's prior
        (:func:`pipeline.planes.floor_prior`).
    source : str
        Where it came from (for reports).
    notes : list of str
        What the loader did (downsampled, dropped NaN, ...).
    views : tuple of ScanInput
        For a scan fused from several posed frames (``scan/view<k>/``), the frames.
    """

    points: np.ndarray
    colors: np.ndarray | None = None
    instance: np.ndarray | None = None
    pixels: np.ndarray | None = None
    image: np.ndarray | None = None
    depth: np.ndarray | None = None
    intrinsics: Intrinsics | None = None
    T_world_cam: np.ndarray | None = None
    scribbles: np.ndarray | None = None
    instance_image: np.ndarray | None = None
    up: np.ndarray | None = None
    floor_height: float | None = None
    source: str = ""
    notes: list = field(default_factory=list)
    #: instance id -> object name (a synthetic scene's ``scene.json``: id k = cuboids[k-1])
    instance_objects: dict = field(default_factory=dict)
    #: the frames a multi-view scan was fused from (each with its depth image and pose);
    #: ``points`` then holds all of them in the poses' world frame
    views: tuple = ()

    @property
    def n(self) -> int:
        return int(len(self.points))

    @property
    def has_image(self) -> bool:
        return self.image is not None and self.intrinsics is not None


# ----------------------------------------------------------------------------------- images
def _imread(path: Path, what: str, flags: int | None = None) -> np.ndarray:
    import cv2

    regular_file(path, f"{what} image")
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED if flags is None else flags)
    if img is None or img.size == 0:
        raise InputError(f"{path}: cannot read the {what} image (not a PNG/JPEG/PPM/PGM?)")
    return img


def read_color(path: str | os.PathLike) -> np.ndarray:
    """(H, W, 3) uint8 RGB from any image cv2 reads (grey is replicated, alpha dropped)."""
    import cv2

    img = _imread(Path(path), "colour")
    if img.dtype == np.uint16:
        img = (img >> 8).astype(np.uint8)
    if img.dtype != np.uint8:
        raise InputError(f"{path}: colour image must be 8- or 16-bit, got {img.dtype}")
    if img.ndim == 2:
        return np.repeat(img[:, :, None], 3, axis=2)
    if img.shape[2] == 4:
        img = img[:, :, :3]
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def read_depth(path: str | os.PathLike, depth_format: str = "auto",
               depth_scale: float = 1000.0) -> np.ndarray:
    """(H, W) float depth in metres (0 = no reading) from any supported encoding.

    Parameters
    ----------
    path : depth file
    depth_format : one of :data:`DEPTH_FORMATS`; ``auto`` picks ``float32-dat`` for
        ``.dat`` and ``png`` (integer image / ``depth_scale``) otherwise.
    depth_scale : raw units per metre for ``png`` (1000 mm, 5000 TUM).
    """
    path = Path(path)
    if depth_format not in DEPTH_FORMATS:
        raise InputError(f"--depth-format {depth_format!r}: expected one of {', '.join(DEPTH_FORMATS)}")
    if depth_format == "auto":
        depth_format = "float32-dat" if path.suffix.lower() == ".dat" else "png"
    if depth_format == "float32-dat":
        return _read_dat(path)
    raw = _imread(path, "depth")
    if raw.ndim == 3:
        raise InputError(f"{path}: depth must be a single-channel 16-bit image, got {raw.shape[2]} "
                         "channels (is this the colour image?)")
    if raw.dtype != np.uint16:
        raise InputError(f"{path}: depth must be 16-bit (got {raw.dtype}); 8-bit depth loses "
                         "the range")
    if depth_format == "png":
        if not (depth_scale > 0 and np.isfinite(depth_scale)):
            raise InputError(f"--depth-scale {depth_scale}: must be a positive number")
        return raw.astype(np.float64) / depth_scale
    if depth_format == "sun-bitrot":
        mm = (raw >> 3) | (raw << 13)
        return mm.astype(np.float64) / 1000.0
    # nyu-disparity: cv2 reads PGM big-endian per spec; NYU wrote it little-endian.
    disp = raw.byteswap().astype(np.float64)
    with np.errstate(divide="ignore"):
        d = 351.3 / (1092.5 - disp)
    d[(disp >= 2047) | ~np.isfinite(d) | (d <= 0) | (d > 15)] = 0.0
    return d


def _read_dat(path: Path) -> np.ndarray:
    data = read_bytes(path, MAX_CLOUD_BYTES, "depth file")
    if len(data) < 8:
        raise InputError(f"{path}: too short for a float32 depth .dat (int32 rows, cols, floats)")
    rows, cols = struct.unpack("<ii", data[:8])
    if rows <= 0 or cols <= 0 or len(data) != 8 + 4 * rows * cols:
        raise InputError(f"{path}: header says {rows}x{cols} but the file has {len(data)} bytes; "
                         "expected int32 rows, int32 cols, rows*cols float32")
    d = np.frombuffer(data, dtype="<f4", offset=8).reshape(rows, cols).astype(np.float64)
    d[~np.isfinite(d) | (d < 0)] = 0.0
    return d


def intrinsic_numbers(text: str) -> list[float] | None:
    """The four numbers of ``"fx,fy,cx,cy"`` (commas or spaces), or None when ``text``
    is not four numbers."""
    try:
        vals = [float(x) for x in re.split(r"[,\s]+", text.strip())]
    except ValueError:
        return None
    return vals if len(vals) == 4 else None


def parse_intrinsics(text: str, width: int, height: int) -> Intrinsics:
    """``"fx,fy,cx,cy"`` (or a path to an intrinsics.json) -> validated :class:`Intrinsics`."""
    p = Path(text)
    if p.suffix == ".json" or p.is_file():
        intr = read_intrinsics(p)
        return intr
    vals = intrinsic_numbers(text)
    if vals is None:
        raise InputError(f"--intrinsics {text!r}: expected fx,fy,cx,cy (4 numbers) or a .json file")
    return Intrinsics.from_json({"width": width, "height": height, "fx": vals[0], "fy": vals[1],
                                 "cx": vals[2], "cy": vals[3]}, "--intrinsics")


# ------------------------------------------------------------------------------ RGB-D frame
def from_rgbd(color: np.ndarray | None, depth: np.ndarray, intr: Intrinsics, *,
              T_world_cam: np.ndarray | None = None, instance_image: np.ndarray | None = None,
              scribbles: np.ndarray | None = None, up: np.ndarray | None = None,
              source: str = "", max_depth: float | None = None) -> ScanInput:
    """Build a :class:`ScanInput` from an RGB-D frame (depth metres, 0 = none)."""
    H, W = depth.shape
    if color is not None and color.shape[:2] != (H, W):
        raise InputError(f"{source}: colour is {color.shape[1]}x{color.shape[0]} but depth is "
                         f"{W}x{H}; they must be registered at the same size")
    if (intr.width, intr.height) != (W, H):
        raise InputError(f"{source}: intrinsics are for {intr.width}x{intr.height} but depth is "
                         f"{W}x{H}")
    for name, img in (("instance", instance_image), ("scribbles", scribbles)):
        if img is not None and img.shape[:2] != (H, W):
            raise InputError(f"{source}: {name} image is {img.shape[1]}x{img.shape[0]} but depth "
                             f"is {W}x{H}")
    d = np.where(np.isfinite(depth), depth, 0.0)
    if max_depth is not None:
        if np.any(d > 0) and not np.any((d > 0) & (d <= max_depth)):
            raise InputError(f"{source}: no depth reading within --max-depth {max_depth:g} m "
                             f"(the nearest is {float(d[d > 0].min()):.3g} m); raise --max-depth")
        d = np.where(d > max_depth, 0.0, d)
    pts, pix = backproject(d, intr)
    if len(pts) == 0:
        raise InputError(f"{source}: the depth image has no valid reading (all zero/NaN); wrong "
                         "--depth-format or --depth-scale?")
    colors = color[pix[:, 0], pix[:, 1]].astype(np.float64) / 255.0 if color is not None else None
    inst = (instance_image[pix[:, 0], pix[:, 1]].astype(np.int64)
            if instance_image is not None else None)
    return ScanInput(points=pts, colors=colors, instance=inst, pixels=pix, image=color, depth=d,
                     intrinsics=intr, T_world_cam=T_world_cam, scribbles=scribbles,
                     instance_image=instance_image, up=up, source=source)


# ------------------------------------------------------------------------------------- PLY
_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
              "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
              "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
              "float64": "f8"}


def read_ply(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Vertex properties of a PLY (ascii / binary little / big endian) as ``name -> (n,)``."""
    path = Path(path)
    data = read_bytes(path, MAX_CLOUD_BYTES, "point cloud")
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise InputError(f"{path}: not a PLY file (no 'ply' magic / end_header)")
    body = data.index(b"\n", end) + 1
    header = data[:end].decode("ascii", "replace").splitlines()
    fmt, elements, current = None, [], None
    for line in header:
        tok = line.split()
        if not tok:
            continue
        if tok[0] == "format":
            fmt = tok[1]
        elif tok[0] == "element":
            try:
                current = [tok[1], int(tok[2]), []]
            except (IndexError, ValueError):
                raise InputError(f"{path}: malformed PLY element line {line!r}") from None
            if current[1] < 0:
                raise InputError(f"{path}: negative PLY element count {current[1]}")
            elements.append(current)
        elif tok[0] == "property" and current is not None:
            if tok[1] == "list":
                if current[0] == "vertex":
                    raise InputError(f"{path}: list properties on vertices are not supported")
                current[2].append(("__list__", tok[2], tok[3]))
            else:
                if tok[1] not in _PLY_TYPES:
                    raise InputError(f"{path}: unknown PLY property type {tok[1]!r}")
                current[2].append((tok[2], _PLY_TYPES[tok[1]]))
    if not elements or elements[0][0] != "vertex":
        raise InputError(f"{path}: PLY has no leading 'vertex' element")
    name, n, props = elements[0]
    if not props:
        raise InputError(f"{path}: PLY vertices have no properties")
    if n * len(props) * (1 if fmt != "ascii" else 2) > len(data) - body:
        raise InputError(f"{path}: PLY header claims {n} vertices but the file is only "
                         f"{len(data)} bytes; truncated or corrupt")
    if fmt == "ascii":
        text = data[body:].decode("ascii", "replace").split("\n")[:n]
        try:
            arr = np.array([r.split()[: len(props)] for r in text], dtype=np.float64)
        except ValueError:
            raise InputError(f"{path}: malformed ASCII PLY vertex rows") from None
        if arr.shape != (n, len(props)):
            raise InputError(f"{path}: expected {n} vertex rows of {len(props)} values")
        return {p[0]: arr[:, i] for i, p in enumerate(props)}
    if fmt not in ("binary_little_endian", "binary_big_endian"):
        raise InputError(f"{path}: unknown PLY format {fmt!r}")
    bo = "<" if fmt == "binary_little_endian" else ">"
    dt = np.dtype([(p[0], bo + p[1]) for p in props])
    if len(data) - body < n * dt.itemsize:
        raise InputError(f"{path}: truncated PLY ({n} vertices announced)")
    rec = np.frombuffer(data, dtype=dt, count=n, offset=body)
    return {p[0]: rec[p[0]].astype(np.float64) for p in props}


# ------------------------------------------------------------------------------------- PCD
def lzf_decompress(src: bytes, size: int) -> bytes:
    """Decompress LibLZF data (the codec of PCD ``binary_compressed``) to ``size`` bytes."""
    out = bytearray(size)
    ip, op, n = 0, 0, len(src)
    while ip < n:
        ctrl = src[ip]
        ip += 1
        if ctrl < 32:  # literal run of ctrl + 1 bytes
            ln = ctrl + 1
            out[op:op + ln] = src[ip:ip + ln]
            ip += ln
            op += ln
        else:  # back reference
            ln = ctrl >> 5
            ref = op - ((ctrl & 0x1F) << 8) - 1
            if ln == 7:
                ln += src[ip]
                ip += 1
            ref -= src[ip]
            ip += 1
            ln += 2
            if ref < 0:
                raise ValueError("corrupt LZF stream")
            if op - ref >= ln:
                out[op:op + ln] = out[ref:ref + ln]
            else:  # overlapping copy repeats the period
                period = bytes(out[ref:op])
                rep = (period * (ln // len(period) + 1))[:ln]
                out[op:op + ln] = rep
            op += ln
    if op != size:
        raise ValueError(f"LZF stream gave {op} bytes, header says {size}")
    return bytes(out)


def read_pcd(path: str | os.PathLike) -> tuple[dict[str, np.ndarray], int, int]:
    """Fields of a PCD v0.7 file (ascii / binary / binary_compressed).

    Returns
    -------
    fields : dict name -> (n,) or (n, count) array in the stored dtype
    width, height : int (height > 1 means an organised cloud)
    """
    path = Path(path)
    data = read_bytes(path, MAX_CLOUD_BYTES, "point cloud")
    hdr: dict[str, list[str]] = {}
    pos = 0
    while True:
        nl = data.find(b"\n", pos)
        if nl < 0:
            raise InputError(f"{path}: PCD header has no DATA line")
        line = data[pos:nl].decode("ascii", "replace").strip()
        pos = nl + 1
        if not line or line.startswith("#"):
            continue
        tok = line.split()
        hdr[tok[0].upper()] = tok[1:]
        if tok[0].upper() == "DATA":
            break
    try:
        names = hdr["FIELDS"]
        sizes = [int(s) for s in hdr["SIZE"]]
        types = hdr["TYPE"]
        counts = [int(c) for c in hdr.get("COUNT", ["1"] * len(names))]
        width, height = int(hdr["WIDTH"][0]), int(hdr.get("HEIGHT", ["1"])[0])
        npts = int(hdr.get("POINTS", [str(width * height)])[0])
        mode = hdr["DATA"][0].lower()
    except (KeyError, ValueError, IndexError):
        raise InputError(f"{path}: malformed PCD header (FIELDS/SIZE/TYPE/WIDTH/DATA)") from None
    for key, vals in (("SIZE", sizes), ("TYPE", types), ("COUNT", counts)):
        if len(vals) != len(names):
            raise InputError(f"{path}: PCD header {key} has {len(vals)} entries but FIELDS has "
                             f"{len(names)}; every field needs one")
    valid = {"F": (4, 8), "U": (1, 2, 4, 8), "I": (1, 2, 4, 8)}
    for nm, t, sz, c in zip(names, types, sizes, counts, strict=True):
        if t.upper() not in valid or sz not in valid[t.upper()] or not 1 <= c <= 1024:
            raise InputError(f"{path}: PCD field {nm!r} has TYPE {t} SIZE {sz} COUNT {c}; "
                             "expected F 4/8, U or I 1/2/4/8, COUNT 1-1024")
    if width < 1 or height < 1 or npts != width * height:
        raise InputError(f"{path}: PCD header says WIDTH {width} x HEIGHT {height} but POINTS "
                         f"{npts}; they must agree")
    dts = [np.dtype({"F": "f", "U": "u", "I": "i"}[t.upper()] + str(s)).newbyteorder("<")
           for t, s in zip(types, sizes, strict=True)]
    point_bytes = sum(dt.itemsize * c for dt, c in zip(dts, counts, strict=True))
    body = len(data) - pos
    # every point takes at least point_bytes (binary), 2 bytes per value (ascii), and LZF
    # packs at most 88 bytes into 3: refuse a count the file cannot hold before allocating
    least = {"binary": npts * point_bytes, "ascii": 2 * npts * sum(counts),
             "binary_compressed": npts * point_bytes // 90}.get(mode, 0)
    if least > body:
        raise InputError(f"{path}: PCD header claims {npts} points ({npts * point_bytes} bytes) "
                         f"but the file holds {body} bytes of data; truncated or corrupt")
    fields: dict[str, np.ndarray] = {}
    if mode == "ascii":
        txt = data[pos:].decode("ascii", "replace").split()
        ncol = sum(counts)
        try:
            arr = np.array(txt[: npts * ncol], dtype=np.float64).reshape(npts, ncol)
        except ValueError:
            raise InputError(f"{path}: malformed ASCII PCD data ({npts} points announced)") from None
        col = 0
        for nm, dt, c in zip(names, dts, counts, strict=True):
            vals = arr[:, col:col + c]
            fields[nm] = (vals[:, 0] if c == 1 else vals).astype(dt) if dt.kind != "f" else (
                vals[:, 0] if c == 1 else vals)
            col += c
    elif mode == "binary":
        rec_dt = np.dtype([(nm, dt, (c,)) if c > 1 else (nm, dt)
                           for nm, dt, c in zip(names, dts, counts, strict=True)])
        if len(data) - pos < npts * rec_dt.itemsize:
            raise InputError(f"{path}: truncated binary PCD")
        rec = np.frombuffer(data, dtype=rec_dt, count=npts, offset=pos)
        fields = {nm: np.array(rec[nm]) for nm in names}
    elif mode == "binary_compressed":
        if body < 8:
            raise InputError(f"{path}: truncated binary_compressed PCD (no size words)")
        csize, usize = struct.unpack("<II", data[pos:pos + 8])
        if usize != npts * point_bytes or csize > body - 8 or usize > 90 * csize + 64:
            raise InputError(f"{path}: binary_compressed PCD sizes ({csize} compressed, {usize} "
                             f"uncompressed) do not fit {npts} points of {point_bytes} bytes "
                             f"in a file of {len(data)} bytes; corrupt")
        try:
            raw = lzf_decompress(data[pos + 8:pos + 8 + csize], usize)
        except (ValueError, IndexError):
            raise InputError(f"{path}: corrupt binary_compressed PCD data") from None
        off = 0
        for nm, dt, c in zip(names, dts, counts, strict=True):
            nbytes = npts * dt.itemsize * c
            vals = np.frombuffer(raw, dtype=dt, count=npts * c, offset=off)
            fields[nm] = vals.reshape(npts, c) if c > 1 else vals.copy()
            off += nbytes
    else:
        raise InputError(f"{path}: unknown PCD DATA mode {mode!r}")
    return fields, width, height


def _unpack_rgb(v: np.ndarray) -> np.ndarray:
    """PCD packed rgb/rgba (float32 or uint32 bits, 0x00RRGGBB) -> (n, 3) float in [0, 1]."""
    u = np.ascontiguousarray(v).view(np.uint32) if v.dtype.itemsize == 4 else v.astype(np.uint32)
    return np.stack([(u >> 16) & 255, (u >> 8) & 255, u & 255], axis=1).astype(np.float64) / 255.0


# ------------------------------------------------------------------------------- the clouds
def load_cloud(path: str | os.PathLike, *, intrinsics: str | None = None,
               up: np.ndarray | None = None, label_divisor: int = 0,
               rng: np.random.Generator | None = None) -> ScanInput:
    """Load a ``.ply`` / ``.pcd`` / ``.npz`` point cloud.

    ``label_divisor`` > 0 maps PCD labels to object ids as ``label // label_divisor``
    (mOSD: 10); 0 means auto (10 when labels reach 20 or more and come in decades, as in
    mOSD, else the label itself).
    """
    path = regular_file(path, "point cloud")
    suffix = path.suffix.lower()
    colors = inst = None
    width = height = 1
    if suffix == ".ply":
        f = read_ply(path)
        if not {"x", "y", "z"} <= f.keys():
            raise InputError(f"{path}: PLY vertices need x, y, z properties")
        pts = np.stack([f["x"], f["y"], f["z"]], axis=1)
        if {"red", "green", "blue"} <= f.keys():
            c = np.stack([f["red"], f["green"], f["blue"]], axis=1)
            colors = c / (255.0 if c.max(initial=0) > 1.0 else 1.0)
        for key in ("instance", "instance_id", "label", "segment"):
            if key in f:
                inst = f[key].astype(np.int64)
                break
    elif suffix == ".pcd":
        f, width, height = read_pcd(path)
        if not {"x", "y", "z"} <= f.keys():
            raise InputError(f"{path}: PCD needs x, y, z fields")
        pts = np.stack([f["x"], f["y"], f["z"]], axis=1).astype(np.float64)
        for key in ("rgb", "rgba"):
            if key in f:
                colors = _unpack_rgb(f[key])
        if "label" in f:
            lab = f["label"].astype(np.int64)
            div = label_divisor
            if div == 0:
                div = 10 if lab.max(initial=0) >= 20 else 1
            inst = lab // div
    elif suffix == ".npz":
        try:
            z = np.load(path)
            keys = list(z.files)
        except (OSError, ValueError):
            raise InputError(f"{path}: cannot read a point array from this .npz") from None
        if "pc" not in keys and len(keys) != 1:
            held = f"among {', '.join(map(repr, keys))}" if keys else "(it holds no arrays)"
            raise InputError(f"{path}: no array 'pc' (N x 3 or N x 6 points) {held}; save "
                             "the points under the key 'pc'")
        try:
            pc = np.asarray(z["pc" if "pc" in keys else keys[0]], dtype=np.float64)
        except (OSError, ValueError, KeyError, IndexError):
            raise InputError(f"{path}: cannot read a point array from this .npz") from None
        if pc.ndim != 2 or pc.shape[1] < 3:
            raise InputError(f"{path}: expected an (N, 3) or (N, 6) array, got {pc.shape}")
        pts = pc[:, :3]
        if pc.shape[1] >= 6:
            colors = np.clip(pc[:, 3:6] / (255.0 if pc[:, 3:6].max() > 1.0 else 1.0), 0, 1)
        if up is None:
            up = np.array([0.0, 0.0, 1.0])  # SUN RGB-D upright coordinates
    else:
        raise InputError(f"{path}: unknown point-cloud type {suffix!r} (expected .ply, .pcd, .npz)")

    finite = np.all(np.isfinite(pts), axis=1)
    if not finite.any():
        raise InputError(f"{path}: the cloud has no finite point (empty or all NaN)")

    if height > 1 and suffix == ".pcd" and finite.sum() > 100:
        # Organised cloud: rebuild the RGB-D frame so overlays and visibility work.
        intr = (parse_intrinsics(intrinsics, width, height) if intrinsics
                else Intrinsics(width, height, 525.0 * width / 640, 525.0 * width / 640,
                                (width - 1) / 2, (height - 1) / 2))
        zz = np.where(finite, pts[:, 2], 0.0).reshape(height, width)
        img = None
        if colors is not None:
            img = (np.where(finite[:, None], colors, 0) * 255 + 0.5).astype(np.uint8).reshape(
                height, width, 3)
        inst_img = inst.reshape(height, width) if inst is not None else None
        scan = from_rgbd(img, zz, intr, instance_image=inst_img, up=up, source=str(path))
        return scan

    pts = pts[finite]
    colors = colors[finite] if colors is not None else None
    inst = inst[finite] if inst is not None else None
    notes = []
    if len(pts) > MAX_POINTS:
        pts, colors, inst = downsample(pts, colors, inst, MAX_POINTS)
        notes.append(f"downsampled {int(finite.sum())} -> {len(pts)} points")
    return ScanInput(points=pts, colors=colors, instance=inst, up=up, source=str(path),
                     notes=notes)


def downsample(points: np.ndarray, colors: np.ndarray | None, inst: np.ndarray | None,
               target: int) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Voxel-grid downsample to about ``target`` points (first point per voxel, deterministic)."""
    lo, hi = points.min(0), points.max(0)
    ext = np.maximum(hi - lo, 1e-9)
    cell = float(np.prod(ext) / target) ** (1 / 3)
    keep = None
    for _ in range(8):
        key = np.floor((points - lo) / cell).astype(np.int64)
        dims = key.max(0) + 1
        flat = (key[:, 0] * dims[1] + key[:, 1]) * dims[2] + key[:, 2]
        _, first = np.unique(flat, return_index=True)
        keep = np.sort(first)
        if len(keep) <= target:
            break
        cell *= (len(keep) / target) ** 0.5
    assert keep is not None
    return (points[keep], colors[keep] if colors is not None else None,
            inst[keep] if inst is not None else None)


# ------------------------------------------------------------------------------ entry point
def load_scan(path: str | os.PathLike, *, color: str | None = None, depth: str | None = None,
              intrinsics: str | None = None, depth_format: str = "auto",
              depth_scale: float | None = None, up: str | np.ndarray | None = None,
              max_depth: float | None = None, instance: str | None = None,
              scribbles: str | None = None, floor_height: float | None = None,
              pose: str | os.PathLike | None = None) -> ScanInput:
    """Load any supported input (scene dir, RGB-D folder, single depth file, cloud).

    ``color``/``depth``/``instance``/``scribbles`` are file names, relative to a folder
    ``path`` or absolute; ``intrinsics`` is ``"fx,fy,cx,cy"`` or a JSON file;
    ``depth_scale`` None means 1000 (millimetres).  A depth file of a known public data
    set (see :func:`known_layout`) fills in whatever of colour, encoding and intrinsics
    was not given.  ``floor_height`` (metres along up in the input frame) is kept for the
    floor's prior; ``pose`` is a camera-to-world file (a 4x4 JSON, or the
    ``arrangement.json`` of an earlier run, whose ``meta.camera_pose`` is used) that
    replaces the input's own ``camera_pose.json``.
    """
    scan = _load_scan(path, color=color, depth=depth, intrinsics=intrinsics,
                      depth_format=depth_format, depth_scale=depth_scale, up=up,
                      max_depth=max_depth, instance=instance, scribbles=scribbles)
    if pose is not None:
        if scan.views:
            raise InputError(f"--pose: {scan.source} is a multi-view folder; each view "
                             "carries its own camera_pose.json")
        scan = replace(scan, T_world_cam=read_pose(pose), notes=[*scan.notes, f"pose from {pose}"])
    if floor_height is not None:
        scan = replace(scan, floor_height=float(floor_height))
    return scan


def _load_scan(path: str | os.PathLike, *, color: str | None = None, depth: str | None = None,
               intrinsics: str | None = None, depth_format: str = "auto",
               depth_scale: float | None = None, up: str | np.ndarray | None = None,
               max_depth: float | None = None, instance: str | None = None,
               scribbles: str | None = None) -> ScanInput:
    path = Path(path)
    up_vec = parse_up(up) if isinstance(up, str) else (None if up is None else np.asarray(up, float))
    if not path.exists():
        raise InputError(f"{path}: no such file or folder")
    if not path.is_dir():
        regular_file(path, "input")
    if path.is_file():
        if path.suffix.lower() in (".ply", ".pcd", ".npz"):
            return load_cloud(path, intrinsics=intrinsics, up=up_vec)
        # a single depth image / .dat file: its folder is the frame folder
        depth = str(path) if depth is None else depth
        path = path.parent
    folder = path / "scan" if (path / "scan").is_dir() else path

    def resolve(name: str | None, default: str | None, flag: str = "") -> Path | None:
        """A file named by an option: absolute, or relative to INPUT (its scan/ first),
        or to the working folder; the defaults are looked up in the frame folder only."""
        if name is None:
            if default is None:
                return None
            p = folder / default
            return p if p.exists() else None
        p = Path(name)
        if p.is_absolute():
            return p
        for base in dict.fromkeys((folder, path)):
            if (base / p).exists():
                return base / p
        if p.exists():
            return p
        raise InputError(f"{flag} {name}: no such file in {folder}"
                         + (f", {path}" if folder != path else "") + " or the working folder")

    depth_p = resolve(depth, "depth.png", "--depth")
    if depth_p is None and depth is None and (folder / "view0" / "depth.png").is_file():
        return load_views(folder, color=color, intrinsics=intrinsics, depth_format=depth_format,
                          depth_scale=depth_scale, up=up, max_depth=max_depth, instance=instance)
    if depth_p is None:
        clouds = sorted(folder.glob("*.ply")) + sorted(folder.glob("*.pcd"))
        if clouds and not (folder / "color.png").exists():
            return load_cloud(clouds[0], intrinsics=intrinsics, up=up_vec)
        raise InputError(f"{folder}: no depth.png here (give --depth FILE, or a .ply/.pcd cloud)")
    preset = known_layout(depth_p)
    notes = [f"recognised {preset['name']}"] if preset else []
    if depth_format == "auto" and "depth_format" in preset:
        depth_format = preset["depth_format"]
    if depth_scale is None:
        depth_scale = preset.get("depth_scale", 1000.0)
    if intrinsics is None and "intrinsics" in preset and not (folder / "intrinsics.json").exists():
        intrinsics = preset["intrinsics"]
    if color is None and "color" in preset and not (folder / "color.png").exists():
        color = str(preset["color"])
    if max_depth is None:
        max_depth = preset.get("max_depth")
    d = read_depth(depth_p, depth_format, depth_scale)
    H, W = d.shape
    color_p = resolve(color, "color.png", "--color")
    img = read_color(color_p) if color_p is not None else None
    if intrinsics is not None:
        intr = parse_intrinsics(intrinsics, W, H)
    elif (folder / "intrinsics.json").exists():
        intr = read_intrinsics(folder / "intrinsics.json")
    else:
        raise InputError(f"{depth_p}: no intrinsics (no {folder / 'intrinsics.json'}); give "
                         "--intrinsics fx,fy,cx,cy (Kinect v1 default: 525,525,319.5,239.5)")
    pose = read_pose(folder / "camera_pose.json") if (folder / "camera_pose.json").exists() else None
    inst_p = resolve(instance, "instance.png", "--instance")
    inst_img = _imread(inst_p, "instance").astype(np.int64) if inst_p is not None else None
    if inst_img is not None and inst_img.ndim == 3:
        raise InputError(f"{inst_p}: instance image must be single-channel ids")
    scr_p = resolve(scribbles, "scribbles.png", "--scribbles")
    scr = None
    if scr_p is not None:
        s = _imread(scr_p, "scribbles")
        if s.ndim == 3:  # colour strokes: one id per distinct colour
            flat = s[:, :, :3].reshape(-1, 3).astype(np.int64)
            code = (flat[:, 0] << 16) | (flat[:, 1] << 8) | flat[:, 2]
            _, ids = np.unique(code, return_inverse=True)
            bg = ids[np.argmin(code)] if (code == 0).any() else -1
            ids = np.where(ids == bg, 0, ids + (1 if bg < 0 else 0))
            scr = ids.reshape(s.shape[:2])
        else:
            scr = s.astype(np.int64)
    scan = from_rgbd(img, d, intr, T_world_cam=pose, instance_image=inst_img, scribbles=scr,
                     up=up_vec, source=str(depth_p), max_depth=max_depth)
    scan.notes.extend(notes)
    if inst_img is not None:
        scan = replace(scan, instance_objects=_scene_objects(folder))
    return scan


def _scene_objects(folder: Path) -> dict:
    """Instance id -> object name from the ``scene.json`` of a synthetic scene directory
    (``folder`` is its ``scan/`` or a ``scan/view<k>/``); empty elsewhere."""
    for up_dir in (folder, folder.parent):
        if up_dir.name == "scan" and (up_dir.parent / "scene.json").is_file():
            data = read_json(up_dir.parent / "scene.json")
            cubs = data.get("cuboids", []) if isinstance(data, dict) else []
            return {k + 1: str(c.get("object") or c.get("id", k)) for k, c in enumerate(cubs)
                    if isinstance(c, dict)}
    return {}


def load_views(folder: Path, **options) -> ScanInput:
    """A scan of several posed RGB-D frames ``folder/view0/``, ``view1/``, ... fused into one.

    Every frame needs its ``camera_pose.json`` (the poses put the frames in one world
    frame).  The result holds all points in that frame (``T_world_cam`` the identity,
    no single image) with their colours and instance ids, and the frames themselves in
    ``views`` for what needs the images (visibility, mask borders).
    """
    dirs = sorted((d for d in folder.iterdir()
                   if d.is_dir() and re.fullmatch(r"view\d+", d.name)),
                  key=lambda d: int(d.name[4:]))
    frames = []
    for d in dirs:
        if not (d / "depth.png").is_file():
            continue
        f = load_scan(d, **options)
        if f.T_world_cam is None:
            raise InputError(f"{d}: camera_pose.json missing; every view of a multi-view scan "
                             "needs its camera-to-world pose")
        frames.append(f)
    if not frames:
        raise InputError(f"{folder}: no view<k>/depth.png here")
    pts = np.concatenate([transform(f.T_world_cam, f.points) for f in frames])
    colors = (np.concatenate([f.colors for f in frames])
              if all(f.colors is not None for f in frames) else None)
    inst = (np.concatenate([f.instance for f in frames])
            if all(f.instance is not None for f in frames) else None)
    return ScanInput(points=pts, colors=colors, instance=inst, T_world_cam=np.eye(4),
                     up=frames[0].up, source=str(folder),
                     notes=[f"fused {len(frames)} views ({', '.join(d.name for d in dirs)})"],
                     instance_objects=frames[0].instance_objects, views=tuple(frames))


#: Kinect v1 / PrimeSense default intrinsics at 640x480 (what Open3D assumes for its test data).
KINECT_DEFAULT = "525,525,319.5,239.5"
#: RAPter's ``Intrinsics::TIANJIAS``: the Kinect of Shao et al.'s box captures (registered depth).
SHAO_TIANJIAS = "519.30334103339817,518.16401430246583,328.50951551345941,252.82555217253503"


def known_layout(depth: Path) -> dict:
    """Defaults for a depth file of a known public data set, from its name and siblings.

    ============================  ==========================================================
    ``<x>_depth16bits.dat``        Shao/RAPter Kinect: float32-dat, ``derived/<x>_rgb_640x480.png``,
                                   TIANJIAS intrinsics
    ``sync_depth_<k>.png``         Metric3D NYU: ``rgb_<k>.jpg``; ``cam_in`` and ``depth_scale``
                                   from ``test_annotations.json``
    ``NYU_depth.pgm``              Open3D test data NYU raw: nyu-disparity, ``NYU_color.ppm``
    ``TUM_depth.png``              TUM: depth / 5000, ``TUM_color.png``
    ``SUN_depth.png``              SUN: sun-bitrot, ``SUN_color.jpg``, depth cut at 7 m
    ``<k>_depth_mm.png``           SUN RGB-D (mmdet3d): K from ``<k>_calib.txt`` (column-major),
                                   ``<k>_image.jpg`` (same folder or its parent)
    ============================  ==========================================================

    Returns a dict with some of ``name color depth_format depth_scale intrinsics max_depth``
    (empty when the file is not recognised).
    """
    name, folder = depth.name, depth.parent
    m = re.fullmatch(r"(.+)_depth16bits\.dat", name)
    if m:
        out = {"name": "Shao/RAPter Kinect capture", "depth_format": "float32-dat",
               "intrinsics": SHAO_TIANJIAS}
        col = folder / "derived" / f"{m[1]}_rgb_640x480.png"
        if col.is_file():
            out["color"] = col
        return out
    m = re.fullmatch(r"sync_depth_(\d+)\.png", name)
    if m:
        out = {"name": "Metric3D NYU frame", "depth_scale": 1000.0}
        if (folder / f"rgb_{m[1]}.jpg").is_file():
            out["color"] = folder / f"rgb_{m[1]}.jpg"
        ann = folder / "test_annotations.json"
        if ann.is_file():
            try:
                files = load_json(ann).get("files", [])
                entry = next(f for f in files if str(f.get("depth", "")).endswith(name))
                out["intrinsics"] = ",".join(str(float(v)) for v in entry["cam_in"])
                out["depth_scale"] = float(entry.get("depth_scale", 1000.0))
            except (OSError, ValueError, StopIteration, KeyError, TypeError, AttributeError):
                pass  # InputError is a ValueError: a broken annotation file gives no defaults
        return out
    m = re.fullmatch(r"(NYU|TUM|SUN)_depth\.(pgm|png)", name)
    if m:
        kind = m[1]
        out = {"name": f"Open3D test data {kind} frame", "intrinsics": KINECT_DEFAULT}
        out.update({"NYU": {"depth_format": "nyu-disparity"}, "TUM": {"depth_scale": 5000.0},
                    "SUN": {"depth_format": "sun-bitrot", "max_depth": 7.0}}[kind])
        for ext in ("ppm", "png", "jpg"):
            if (folder / f"{kind}_color.{ext}").is_file():
                out["color"] = folder / f"{kind}_color.{ext}"
                break
        return out
    m = re.fullmatch(r"(\d+)_depth_mm\.png", name)
    if m:
        out = {"name": "SUN RGB-D frame", "depth_scale": 1000.0}
        for base in (folder, folder.parent):
            calib, image = base / f"{m[1]}_calib.txt", base / f"{m[1]}_image.jpg"
            if image.is_file():
                out["color"] = image
            if calib.is_file():
                try:
                    K = np.array(calib.read_text().splitlines()[1].split(), dtype=float)
                    out["intrinsics"] = f"{K[0]},{K[4]},{K[6]},{K[7]}"  # column-major 3x3
                except (OSError, ValueError, IndexError):
                    pass
        return out
    return {}


def parse_up(text: str) -> np.ndarray:
    """``"0,-1,0"`` or ``+y``/``-y``/``z``... -> unit (3,) vector in the input frame."""
    t = text.strip().lower()
    axes = {"x": 0, "y": 1, "z": 2}
    if t.lstrip("+-") in axes:
        v = np.zeros(3)
        v[axes[t.lstrip("+-")]] = -1.0 if t.startswith("-") else 1.0
        return v
    try:
        v = np.array([float(x) for x in re.split(r"[,\s]+", t)], dtype=float)
    except ValueError:
        v = np.zeros(0)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) < 1e-9:
        raise InputError(f"--up {text!r}: expected a direction such as -y or 0,-1,0")
    return v / np.linalg.norm(v)


def read_json(path: Path) -> dict:
    return load_json(path)
