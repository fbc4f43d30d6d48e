"""Model retrieval (paper section 6 (ii)): a repository mesh per object, placed by its structure.

For each object of an arrangement (its cuboids, grouped by ``object``) every repository
model is

1. aligned upright: repository models stand on z = 0 with z up (the file's ``up`` axis
   turned to z); the structure's up is the ground normal, world z;
2. scaled into the structure's bounding box, for each sampled yaw: the box of all the
   object's cuboid corners in a frame turned by the yaw about z.  ``fit="axis"`` (the
   default) scales each axis so the model's bounding box *is* that box; ``"uniform"``
   scales by the smallest ratio (proportions kept), centred in x and y, on the box's
   bottom;
3. scored at every yaw: :data:`YAWS` evenly spread angles starting at the largest
   cuboid's horizontal edge, plus every cuboid's horizontal edge directions and their
   quarter turns;
4. the best-scoring pose of the best models is refined with Open3D ICP against the points
   the scan saw of the object (when given), kept upright (only the yaw and the horizontal
   shift of the ICP transform are applied).

Notes
-----
The score (the paper's, made precise) of a placed model ``M`` against the union ``C`` of
the object's cuboids is

.. math::

    S = \\underbrace{\\frac{|\\{x \\in X_M : x \\in C_\\tau\\}|}{|X_M|}}_{A:\\ model\\ covered}
      + \\underbrace{\\frac{|\\{y \\in Y_C : y \\in V(M)\\}|}{|Y_C|}}_{B:\\ structure\\ covered}
    \\in [0, 2]

* ``X_M``: :data:`N_SURFACE` points sampled uniformly by area on the model's surface
  (instead of its raw vertices, whose density follows the modeller's tessellation: a
  cylinder leg has 40 vertices, a table top 8);
* ``C_tau``: the cuboids grown by ``tau`` = :data:`TOL_REL` x the structure's diagonal
  (at least :data:`TOL_MIN` m), so a model face lying on a cuboid face counts;
* ``Y_C``: :data:`N_INTERIOR` points sampled uniformly by volume inside the cuboids;
* ``V(M)``: the model's solid: a :data:`GRID`\\ :sup:`3` occupancy grid over the model's
  bounding box in its own normalised coordinates, made of the voxels its surface passes
  through (a grid of surface points half a voxel apart) and the voxels they
  enclose (hole filling).  A thin board
  is therefore one voxel (``1/GRID`` of the model's extent) thick: "covered by the model"
  means "inside the model's solid at that resolution".

A model that is its own cuboid decomposition scores exactly 2 at its true pose.

Stretching a model unevenly into the box makes it another shape: a desk with a drawer
block squeezed into a chair's box covers it as a solid block, and so does a desk squeezed
into a monitor's.  The kinds are therefore compared by ``S - lambda ln(max k / min k)``,
``k`` the factors by which the placement scales the model's three axes and ``lambda`` =
:data:`STRETCH_COST` of score per factor of e between the most and the least stretched
axis (0 for ``fit="uniform"``, which keeps proportions; a model of the object's own
proportions pays nothing, whatever its size).  A kind enters that comparison with its
best model by this measure, not with the model the paper's score prefers: a plank
squeezed into a cube's box fills it exactly, and must not stand for its kind when an
L of the cube's proportions, one quarter short, is in the repository too.  Within the
kind that wins, the paper's score alone picks the model: the variants of one kind differ
in their parts, which ``S`` sees, and not in their proportions.
``RetrieveConfig(stretch_cost=0)`` is the paper's score alone.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .camera import transform
from .errors import InputError
from .model import Arrangement, box_corners, rotation_about_z

#: Score lost, when kinds are compared, per factor of e between a placement's most and
#: least stretched model axis (module notes); chosen among 0.3-1.0 on the retrieval
#: suite's scenes 1000-1005 and 1700-1705, judged on others (docs/results.md).
STRETCH_COST = 0.5
#: Evenly spread yaws sampled per model (15 degree steps).
YAWS = 24
#: The largest cuboids whose horizontal edges give yaws too.
EDGE_CUBOIDS = 3
#: Sampled yaws closer than this (degrees) are one.
YAW_MERGE_DEG = 1.0
#: Area samples on a model's surface (the score's ``X_M``).
N_SURFACE = 1500
#: Volume samples inside the structure (the score's ``Y_C``).
N_INTERIOR = 1500
#: Cells per axis of a model's occupancy grid over its bounding box.
GRID = 40
#: Cuboid growth for "model point covered by the structure", fraction of its diagonal.
TOL_REL = 0.01
#: ... and its floor, metres.
TOL_MIN = 0.005
#: Points ICP registers (a larger object's points are subsampled, seeded).
ICP_POINTS = 3000
#: ICP correspondence distance: fraction of the structure's diagonal (at least ICP_MIN m).
ICP_REL = 0.08
ICP_MIN = 0.02
#: A refined pose is kept unless it lowers the score by more than this.
ICP_SLACK = 0.05
#: Points this close to a support plane (m) are the support's, not an object's.
SUPPORT_BAND = 0.015
#: Model file types read.
MESH_SUFFIXES = (".glb", ".gltf", ".obj", ".ply", ".stl", ".off")
FITS = ("axis", "uniform")

#: model frame (z up) from a file's frame, per ``up`` axis.  "y": glTF's convention,
#: the exact inverse of the export turn (x, y, z) -> (x, z, -y).
_UP_TURNS = {
    "z": np.eye(3),
    "-z": np.diag([1.0, -1.0, -1.0]),
    "y": np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]),
    "-y": np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]),
    "x": np.array([[0.0, 1, 0], [0, 0, 1], [1, 0, 0]]),
    "-x": np.array([[0.0, -1, 0], [0, 0, 1], [-1, 0, 0]]),
}


# ----------------------------------------------------------------------------- models
@dataclass(frozen=True)
class RepoModel:
    """One repository model, ready to score.

    Attributes
    ----------
    file : str
        Its file name (relative to the repository folder).
    kind, variant : str
    vertices : (n, 3) float, faces : (m, 3) int
        The mesh in the model frame (z up), metres.
    lo, hi : (3,) float
        Its bounding box.
    surface : (N_SURFACE, 3) float
        Area samples in normalised coordinates ``(p - lo) / (hi - lo)`` in [0, 1]^3.
    grid : (GRID, GRID, GRID) bool
        The solid, over the normalised unit cube.
    T_model_file : (4, 4) float
        The file's frame to the model frame (the ``up`` turn).
    params : dict
    """

    file: str
    kind: str
    variant: str
    vertices: np.ndarray
    faces: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    surface: np.ndarray
    grid: np.ndarray
    T_model_file: np.ndarray
    params: dict = field(default_factory=dict)

    @property
    def extent(self) -> np.ndarray:
        return np.maximum(self.hi - self.lo, 1e-9)


def sample_surface(vertices: np.ndarray, faces: np.ndarray, n: int,
                   rng: np.random.Generator) -> np.ndarray:
    """(n, 3) points uniformly distributed by area on a triangle mesh."""
    tri = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if not area.sum() > 0:
        raise InputError("mesh has no area")
    k = rng.choice(len(faces), size=n, p=area / area.sum())
    r = rng.random((n, 2))
    flip = r.sum(axis=1) > 1
    r[flip] = 1 - r[flip]
    t = tri[k]
    return t[:, 0] + r[:, :1] * (t[:, 1] - t[:, 0]) + r[:, 1:] * (t[:, 2] - t[:, 0])


def surface_grid(vertices: np.ndarray, faces: np.ndarray, spacing: float) -> np.ndarray:
    """(n, 3) points covering every triangle at most ``spacing`` apart along its two
    edges from the first vertex (a barycentric grid of ``ceil(edge / spacing)`` steps
    each, the half beyond the third edge folded back into the triangle); deterministic."""
    tri = np.asarray(vertices, float)[np.asarray(faces, np.int64)]
    e0, e1 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    n0 = np.maximum(1, np.ceil(np.linalg.norm(e0, axis=1) / spacing)).astype(np.int64)
    n1 = np.maximum(1, np.ceil(np.linalg.norm(e1, axis=1) / spacing)).astype(np.int64)
    count = (n0 + 1) * (n1 + 1)
    t = np.repeat(np.arange(len(tri)), count)
    k = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
    a = (k // (n1[t] + 1)) / n0[t]
    b = (k % (n1[t] + 1)) / n1[t]
    fold = a + b > 1
    a[fold], b[fold] = 1 - a[fold], 1 - b[fold]
    return tri[t, 0] + a[:, None] * e0[t] + b[:, None] * e1[t]


def occupancy_grid(vertices_unit: np.ndarray, faces: np.ndarray, g: int = GRID) -> np.ndarray:
    """(g, g, g) bool solid of a mesh given in normalised coordinates ([0, 1]^3).

    The voxels the surface passes through (:func:`surface_grid` at half a voxel, so a
    closed surface marks a 26-connected shell) plus the voxels such shells enclose
    (``scipy.ndimage.binary_fill_holes``, 6-connected background)."""
    from scipy.ndimage import binary_fill_holes

    pts = surface_grid(vertices_unit, faces, 1.0 / (2 * g))
    idx = np.clip((pts * g).astype(np.int64), 0, g - 1)
    grid = np.zeros((g, g, g), bool)
    grid[idx[:, 0], idx[:, 1], idx[:, 2]] = True
    return binary_fill_holes(grid)


def make_model(vertices: np.ndarray, faces: np.ndarray, kind: str, variant: str = "default",
               file: str = "", rng: np.random.Generator | None = None,
               T_model_file: np.ndarray | None = None, params: dict | None = None) -> RepoModel:
    """A :class:`RepoModel` from a mesh in the model frame (z up, metres)."""
    rng = np.random.default_rng(0) if rng is None else rng
    v = np.asarray(vertices, float)
    f = np.asarray(faces, np.int64)
    lo, hi = v.min(axis=0), v.max(axis=0)
    ext = np.maximum(hi - lo, 1e-9)
    unit = (v - lo) / ext
    surface = (sample_surface(v, f, N_SURFACE, rng) - lo) / ext
    grid = occupancy_grid(unit, f)
    return RepoModel(file, kind, variant, v, f, lo, hi, surface, grid,
                     np.eye(4) if T_model_file is None else np.asarray(T_model_file, float),
                     dict(params or {}))


def _kind_from_name(stem: str) -> str:
    import re

    m = re.match(r"[A-Za-z]+(?:[_-][A-Za-z]+)*", stem)
    return (m.group(0) if m else stem).split("_")[0].split("-")[0].lower() or "model"


def read_index(folder: Path) -> list[dict]:
    """The entries of ``folder/index.json`` (``{"models": [...]}`` or a bare list), each
    with at least ``file`` and ``kind``; without an index, every mesh file in the folder
    with the kind read from its name (``chair_03.obj`` -> ``chair``)."""
    path = folder / "index.json"
    if not path.is_file():
        files = sorted(p for p in folder.iterdir() if p.suffix.lower() in MESH_SUFFIXES)
        if not files:
            raise InputError(f"--models {folder}: no index.json and no mesh files "
                             f"({', '.join(MESH_SUFFIXES)}); make one with 'unseen models make'")
        return [{"file": p.name, "kind": _kind_from_name(p.stem)} for p in files]
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: not a readable JSON index ({exc.__class__.__name__})") from None
    entries = data.get("models") if isinstance(data, dict) else data
    if not isinstance(entries, list) or not entries:
        raise InputError(f"{path}: expected {{\"models\": [{{\"file\": ..., \"kind\": ...}}, ...]}}")
    for i, e in enumerate(entries):
        if not isinstance(e, dict) or not isinstance(e.get("file"), str) \
                or not isinstance(e.get("kind"), str):
            raise InputError(f"{path}: models[{i}]: needs a string 'file' and 'kind'")
        up = e.get("up")
        if up is not None and up not in _UP_TURNS:
            raise InputError(f"{path}: models[{i}].up: one of {', '.join(_UP_TURNS)}, got {up!r}")
    return entries


def load_repository(folder: str | os.PathLike, kinds: tuple[str, ...] | None = None,
                    seed: int = 0) -> tuple[RepoModel, ...]:
    """Read a model repository folder (see :func:`read_index`), optionally only ``kinds``.

    ``up`` per entry says which file axis is up (default: ``y`` for glTF, whose
    specification is y up, ``z`` for the other formats).  Samples are seeded with ``seed``.
    """
    import trimesh

    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"--models {folder}: not a folder; make one with 'unseen models make'")
    entries = read_index(folder)
    if kinds:
        entries = [e for e in entries if e["kind"] in kinds]
        if not entries:
            raise InputError(f"--kinds {','.join(kinds)}: no model of these kinds in {folder}")
    rng = np.random.default_rng(seed)
    models = []
    for e in entries:
        path = folder / e["file"]
        if not path.is_file():
            raise InputError(f"{folder / 'index.json'}: {e['file']}: no such file")
        try:
            mesh = trimesh.load(path, force="mesh")
        except Exception as exc:  # noqa: BLE001 - any reader failure is bad input
            raise InputError(f"{path}: not a readable mesh ({exc.__class__.__name__})") from None
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            raise InputError(f"{path}: no triangles")
        up = e.get("up") or ("y" if path.suffix.lower() in (".glb", ".gltf") else "z")
        T = np.eye(4)
        T[:3, :3] = _UP_TURNS[up]
        v = np.asarray(mesh.vertices, float) @ T[:3, :3].T
        models.append(make_model(v, np.asarray(mesh.faces), e["kind"],
                                 str(e.get("variant", "default")), e["file"], rng, T,
                                 e.get("params")))
    return tuple(models)


# -------------------------------------------------------------------------- structure
@dataclass(frozen=True)
class Structure:
    """The cuboids of one object, struct of arrays."""

    centers: np.ndarray  #: (k, 3)
    rotations: np.ndarray  #: (k, 3, 3)
    sizes: np.ndarray  #: (k, 3)

    @classmethod
    def of(cls, cuboids) -> Structure:
        return cls(np.array([c.center for c in cuboids], float).reshape(-1, 3),
                   np.array([c.rotation for c in cuboids], float).reshape(-1, 3, 3),
                   np.array([c.size for c in cuboids], float).reshape(-1, 3))

    def corners(self) -> np.ndarray:
        """(8k, 3) all corners (:func:`pipeline.model.box_corners`)."""
        return box_corners(self.centers, self.rotations, self.sizes).reshape(-1, 3)

    def diagonal(self) -> float:
        c = self.corners()
        return float(np.linalg.norm(c.max(axis=0) - c.min(axis=0)))

    def contains(self, points: np.ndarray, tol: float = 0.0) -> np.ndarray:
        """(...) bool: the point lies in some cuboid grown by ``tol``."""
        p = np.asarray(points, float)
        flat = p.reshape(-1, 3)
        out = np.zeros(len(flat), bool)
        for c, R, s in zip(self.centers, self.rotations, self.sizes, strict=True):
            out |= np.all(np.abs((flat - c) @ R) <= s / 2 + tol, axis=1)   # R^T (p - c)
        return out.reshape(p.shape[:-1])

    def sample_interior(self, n: int, rng: np.random.Generator, per: str = "volume"
                        ) -> np.ndarray:
        """(n, 3) points uniformly distributed by volume in the cuboids (``per="volume"``),
        or as many in each cuboid, uniformly inside it (``per="cuboid"``)."""
        vol = np.prod(self.sizes, axis=1)
        if per == "cuboid":
            k = np.arange(n) % len(vol)
        else:
            k = rng.choice(len(vol), size=n, p=vol / vol.sum())
        local = (rng.random((n, 3)) - 0.5) * self.sizes[k]
        return np.einsum("nij,nj->ni", self.rotations[k], local) + self.centers[k]

    def yaws(self, n: int = YAWS) -> np.ndarray:
        """Candidate yaws (radians, in [0, 2 pi)): ``n`` evenly spread from the largest
        cuboid's horizontal edge, and the quarter turns of the horizontal edges of the
        :data:`EDGE_CUBOIDS` largest cuboids (angles closer than :data:`YAW_MERGE_DEG`
        merged)."""
        vol = np.prod(self.sizes, axis=1)
        dirs = []
        for k in np.argsort(-vol)[:EDGE_CUBOIDS]:
            R = self.rotations[k]
            horiz = np.abs(R[2]) < 0.5  # local axes within 30 deg of horizontal
            for j in np.flatnonzero(horiz):
                a = R[:2, j]
                if np.linalg.norm(a) > 1e-6:
                    dirs.append(float(np.arctan2(a[1], a[0])))
        base = dirs[0] if dirs else 0.0
        angles = [base + 2 * np.pi * i / n for i in range(n)]
        angles += [d + q * np.pi / 2 for d in dirs for q in range(4)]
        a = np.mod(np.array(angles), 2 * np.pi)
        a = np.sort(a)
        keep = np.concatenate([[True], np.diff(a) > np.radians(YAW_MERGE_DEG)])
        if len(a) > 1 and (a[-1] - a[0]) > 2 * np.pi - np.radians(YAW_MERGE_DEG):
            keep[-1] = False
        return a[keep]


def placements(model: RepoModel, structure: Structure, yaws: np.ndarray,
               fit: str = "axis") -> np.ndarray:
    """(Y, 4, 4) affine maps from the model's normalised coordinates to world, one per yaw.

    The structure's bounding box in the frame turned by the yaw, ``[lo, hi]``; ``axis``:
    the unit cube onto it; ``uniform``: onto a box of the model's proportions scaled by
    the smallest ratio, centred in x, y and standing on the bottom."""
    if fit not in FITS:
        raise InputError(f"--fit: one of {', '.join(FITS)}, got {fit!r}")
    corners = structure.corners()
    out = np.zeros((len(yaws), 4, 4))
    for i, yaw in enumerate(yaws):
        Rz = rotation_about_z(float(yaw))
        local = corners @ Rz                    # coordinates in the turned frame
        lo, hi = local.min(axis=0), local.max(axis=0)
        size = hi - lo
        if fit == "axis":
            scale, off = size, lo
        else:
            s = float(np.min(size / model.extent))
            scale = s * model.extent
            off = np.array([(lo[0] + hi[0] - scale[0]) / 2, (lo[1] + hi[1] - scale[1]) / 2, lo[2]])
        out[i, :3, :3] = Rz * scale[None, :]
        out[i, :3, 3] = Rz @ off
        out[i, 3, 3] = 1.0
    return out


def score(model: RepoModel, structure: Structure, M: np.ndarray, interior: np.ndarray,
          tol: float) -> tuple[np.ndarray, np.ndarray]:
    """The two shares of the score (module notes) for placements ``M (Y, 4, 4)``.

    Returns
    -------
    a : (Y,) float
        Share of the model's surface samples inside the grown cuboids.
    b : (Y,) float
        Share of the structure's interior samples inside the model's solid.
    """
    M = np.asarray(M, float).reshape(-1, 4, 4)
    world = np.matmul(model.surface, M[:, :3, :3].transpose(0, 2, 1)) + M[:, None, :3, 3]
    a = structure.contains(world, tol).mean(axis=1)
    Minv = np.linalg.inv(M)
    u = np.matmul(interior, Minv[:, :3, :3].transpose(0, 2, 1)) + Minv[:, None, :3, 3]
    g = model.grid.shape[0]
    inside = np.all((u >= 0) & (u <= 1), axis=-1)
    idx = np.clip((u * g).astype(np.int64), 0, g - 1)
    b = (inside & model.grid[idx[..., 0], idx[..., 1], idx[..., 2]]).mean(axis=1)
    return a, b


def stretch(model: RepoModel, M: np.ndarray) -> np.ndarray:
    """(Y,) ``ln(max k / min k)`` of placements ``M (Y, 4, 4)``: ``k`` the factors by which
    each of the model's axes is scaled (the placed axis' length over the model's extent);
    0 for a placement that keeps the model's proportions."""
    M = np.asarray(M, float).reshape(-1, 4, 4)
    k = np.log(np.linalg.norm(M[:, :3, :3], axis=1) / model.extent)
    return k.max(axis=1) - k.min(axis=1)


# ------------------------------------------------------------------------------ result
@dataclass(frozen=True)
class Candidate:
    """One model placed on one object.

    ``M`` maps the model's normalised coordinates to world; :meth:`T_world_file` the
    model file's coordinates to world (for a viewer)."""

    model: int  #: index into the repository
    kind: str
    variant: str
    file: str
    M: np.ndarray  #: (4, 4)
    score: float  #: A + B at the final pose (+ F with ``select="structure+points"``)
    a: float
    b: float
    yaw: float  #: radians, the sampled yaw before ICP
    icp: dict | None = None  #: fitness, rmse (m), applied (bool), before/after score
    f: float | None = None  #: share of the observed points near the placed model
    stretch: float = 0.0  #: ln(max k / min k) of the placement (:func:`stretch`)
    penalty: float = 0.0  #: the stretch's cost (``stretch_cost`` x ``stretch``)

    @property
    def kind_score(self) -> float:
        """What the kinds are compared by: the score less the stretch's cost."""
        return self.score - self.penalty

    def T_world_file(self, model: RepoModel) -> np.ndarray:
        N = np.eye(4)
        N[:3, :3] = np.diag(1.0 / model.extent)
        N[:3, 3] = -model.lo / model.extent
        return self.M @ N @ model.T_model_file

    def to_json(self, model: RepoModel) -> dict:
        return {"model": self.file, "kind": self.kind, "variant": self.variant,
                "score": round(self.score, 6), "model_covered": round(self.a, 6),
                "structure_covered": round(self.b, 6), "stretch": round(self.stretch, 6),
                "kind_score": round(self.kind_score, 6),
                "yaw_deg": round(float(np.degrees(self.yaw)), 3),
                "transform": np.round(self.T_world_file(model), 6).tolist(),
                **({"icp": self.icp} if self.icp is not None else {})}


@dataclass(frozen=True)
class ObjectRetrieval:
    """The retrieval of one object: the best candidate, the best per kind, every model's
    best coarse score."""

    object: str
    cuboids: tuple[str, ...]
    best: Candidate
    runner_up: Candidate | None  #: the best of another model
    per_kind: dict  #: kind -> Candidate (best of that kind, refined)
    coarse: np.ndarray  #: (n_models,) best A + B over yaws before ICP
    n_points: int  #: observed points used for ICP


@dataclass(frozen=True)
class RetrieveConfig:
    """How :func:`retrieve` places models.

    Attributes
    ----------
    fit : {"axis", "uniform"}
        Scale into the structure's bounding box per axis, or keeping proportions.
    yaws : int
        Evenly spread yaws sampled (plus the cuboids' edge directions).
    icp : bool
        Refine with ICP against the observed points (when given).
    refine_per_kind : int
        How many of each kind's best models (by coarse score) are refined; its best by
        coarse score less the stretch cost is refined too.
    kinds : tuple of str or None
        Only models of these kinds (the paper's keyword search); None: all.
    seed : int
        Seeds the interior and ICP samples.
    interior : {"volume", "cuboid"}
        The structure's samples (the score's ``Y_C``): uniform by volume (the paper), or
        as many in every cuboid (a leg weighs as much as a table top).
    select : {"structure", "structure+points"}
        Pick by ``A + B`` (the paper's matching score), or by ``A + B + F`` with ``F`` the
        share of the object's observed points within the ICP correspondence distance of
        the placed model (the paper's "best alignment" after ICP).
    stretch_cost : float
        Score lost, when kinds are compared, per factor of e of uneven stretch
        (:data:`STRETCH_COST`; 0: the paper's score alone).
    """

    fit: str = "axis"
    yaws: int = YAWS
    icp: bool = True
    refine_per_kind: int = 1
    kinds: tuple[str, ...] | None = None
    seed: int = 0
    interior: str = "volume"
    select: str = "structure"
    stretch_cost: float = STRETCH_COST


def object_groups(arr: Arrangement) -> dict[str, list]:
    """Object name -> its cuboids (a cuboid without ``object`` is an object of its own)."""
    groups: dict[str, list] = {}
    for c in arr.cuboids:
        groups.setdefault(c.object if c.object is not None else c.id, []).append(c)
    return groups


def points_by_object(world: np.ndarray, arr: Arrangement, margin: float = 0.03
                     ) -> dict[str, np.ndarray]:
    """Object name -> the world points within ``margin`` m of its cuboids (a point near
    several objects goes to each), leaving out points within :data:`SUPPORT_BAND` of a
    support plane (the floor under a leg, the wall behind a shelf)."""
    world = np.asarray(world, float)
    for sup in arr.supports:
        world = world[np.abs(sup.signed_distance(world)) > SUPPORT_BAND]
    out = {}
    for name, cubs in object_groups(arr).items():
        st = Structure.of(cubs)
        c = st.corners()
        lo, hi = c.min(axis=0) - margin, c.max(axis=0) + margin
        near = np.all((world >= lo) & (world <= hi), axis=1)
        sel = world[near]
        out[name] = sel[st.contains(sel, margin)] if len(sel) else sel
    return out


def _upright(T: np.ndarray, about: np.ndarray) -> np.ndarray:
    """The yaw and horizontal shift of a rigid transform, taken about the point ``about``
    (tilt and lift dropped)."""
    C = np.eye(4)
    C[:3, 3] = about
    Tc = np.linalg.inv(C) @ T @ C
    U = np.eye(4)
    U[:3, :3] = rotation_about_z(float(np.arctan2(Tc[1, 0], Tc[0, 0])))
    U[:2, 3] = Tc[:2, 3]
    return C @ U @ np.linalg.inv(C)


def icp_samples(model: RepoModel, points: np.ndarray, rng: np.random.Generator
                ) -> tuple[np.ndarray, np.ndarray]:
    """What ICP and its fitness use: at most ``ICP_POINTS`` of the observed ``points``
    and 4000 samples of the model's surface (in its unit box), drawn from ``rng``."""
    pts = np.asarray(points, float)
    if len(pts) > ICP_POINTS:
        pts = pts[np.sort(rng.choice(len(pts), ICP_POINTS, replace=False))]
    dense = sample_surface((model.vertices - model.lo) / model.extent, model.faces, 4000, rng)
    return pts, dense


def icp_refine(model: RepoModel, M: np.ndarray, points: np.ndarray, diagonal: float,
               rng: np.random.Generator, samples: tuple[np.ndarray, np.ndarray] | None = None
               ) -> tuple[np.ndarray, float, float]:
    """Register the observed ``points`` to the placed model (Open3D point-to-point ICP,
    ``open3d.pipelines.registration.registration_icp``).

    Returns the refined placement (the upright part of the ICP motion, about the model's
    centre, applied to the model), and the fitness (share of ``points`` within the
    correspondence distance of the model) and RMSE of those (m) at the refined pose.
    ``samples``: :func:`icp_samples` already drawn (else drawn from ``rng``)."""
    import open3d as o3d

    pts, dense = samples if samples is not None else icp_samples(model, points, rng)
    target = transform(M, dense)
    src = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    tgt = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(target))
    dist = max(ICP_MIN, ICP_REL * diagonal)
    reg = o3d.pipelines.registration
    res = reg.registration_icp(src, tgt, dist, np.eye(4),
                               reg.TransformationEstimationPointToPoint(),
                               reg.ICPConvergenceCriteria(max_iteration=30))
    U = _upright(np.linalg.inv(np.asarray(res.transformation)), target.mean(axis=0))
    M2 = U @ M
    fitness, rmse = _fitness(transform(M2, dense), pts, dist)
    return M2, fitness, rmse


def _fitness(surface: np.ndarray, points: np.ndarray, dist: float) -> tuple[float, float]:
    """Share of ``points`` within ``dist`` of the surface samples, and their RMS distance."""
    from scipy.spatial import cKDTree

    d, _ = cKDTree(surface).query(points)
    near = d <= dist
    return float(np.mean(near)), float(np.sqrt(np.mean(d[near] ** 2))) if near.any() else 0.0


def fitness(model: RepoModel, M: np.ndarray, points: np.ndarray, diagonal: float,
            rng: np.random.Generator, samples: tuple[np.ndarray, np.ndarray] | None = None
            ) -> float:
    """Share of ``points`` within the ICP correspondence distance of the placed model
    (``samples``: as for :func:`icp_refine`)."""
    pts, dense = samples if samples is not None else icp_samples(model, points, rng)
    return _fitness(transform(M, dense), pts, max(ICP_MIN, ICP_REL * diagonal))[0]


def retrieve_object(name: str, cuboids, models: tuple[RepoModel, ...],
                    points: np.ndarray | None = None, config: RetrieveConfig | None = None
                    ) -> ObjectRetrieval:
    """Score every model on one object's cuboids, refine the best of each kind, pick."""
    config = config or RetrieveConfig()
    rng = np.random.default_rng(config.seed)
    st = Structure.of(cuboids)
    diag = st.diagonal()
    tol = max(TOL_MIN, TOL_REL * diag)
    interior = st.sample_interior(N_INTERIOR, rng, config.interior)
    yaws = st.yaws(config.yaws)
    idx = [i for i, m in enumerate(models) if config.kinds is None or m.kind in config.kinds]
    if not idx:
        raise InputError("no repository model of the kinds asked for")
    coarse = np.full(len(models), -np.inf)
    best_pose: dict[int, tuple[np.ndarray, float, float, float, float]] = {}
    for i in idx:
        M = placements(models[i], st, yaws, config.fit)
        a, b = score(models[i], st, M, interior, tol)
        j = int(np.argmax(a + b))
        coarse[i] = a[j] + b[j]
        best_pose[i] = (M[j], float(a[j]), float(b[j]), float(yaws[j]),
                        float(stretch(models[i], M[j])[0]))
    pts = None if points is None or len(points) < 10 or not config.icp else np.asarray(points)
    per_kind: dict[str, Candidate] = {}
    refined: list[Candidate] = []
    for kind in dict.fromkeys(models[i].kind for i in idx):
        ranked = sorted((i for i in idx if models[i].kind == kind), key=lambda i: -coarse[i])
        # the kind's best by the paper's score, and its best as kinds are compared
        fair = max(ranked, key=lambda i: coarse[i] - config.stretch_cost * best_pose[i][4])
        for i in list(dict.fromkeys(ranked[:max(1, config.refine_per_kind)] + [fair])):
            M, a, b, yaw, k = best_pose[i]
            icp = None
            f = 0.0
            if pts is not None:
                # (the same draws for both, as each once drew them from a fresh rng)
                drawn = icp_samples(models[i], pts, np.random.default_rng(config.seed))
                fit0 = fitness(models[i], M, pts, diag, None, drawn)
                M2, fit2, rmse = icp_refine(models[i], M, pts, diag, None, drawn)
                a2, b2 = score(models[i], st, M2[None], interior, tol)
                applied = bool(a2[0] + b2[0] >= a + b - ICP_SLACK and fit2 >= fit0)
                icp = {"fitness_before": round(fit0, 6), "fitness": round(fit2, 6),
                       "rmse": round(rmse, 6), "applied": applied,
                       "score_before": round(a + b, 6)}
                f = fit0
                if applied:
                    M, a, b, f = M2, float(a2[0]), float(b2[0]), fit2
            total = a + b + (f if config.select == "structure+points" else 0.0)
            # ICP turns and shifts the model, never scales it: the stretch stays
            refined.append(Candidate(i, kind, models[i].variant, models[i].file, M, total, a, b,
                                     yaw, icp, f if pts is not None else None, k,
                                     config.stretch_cost * k))
        per_kind[kind] = max((c for c in refined if c.kind == kind), key=lambda c: c.score)
    # the kind by its least stretched fit, the model within it by the paper's score
    order = sorted(refined, key=lambda c: (-c.kind_score, c.model))
    best = per_kind[order[0].kind]
    runner = next((c for c in order if c is not best), None)
    return ObjectRetrieval(name, tuple(c.id for c in cuboids), best, runner, per_kind, coarse,
                           0 if pts is None else len(pts))


def retrieve(arr: Arrangement, models: tuple[RepoModel, ...],
             points: dict[str, np.ndarray] | None = None, config: RetrieveConfig | None = None,
             progress=None, min_cuboids: int = 1) -> tuple[ObjectRetrieval, ...]:
    """:func:`retrieve_object` for every object of ``arr`` with at least ``min_cuboids``
    cuboids (``points``: object name -> observed world points, e.g.
    :func:`points_by_object`); ``progress(done, total)``."""
    groups = {k: v for k, v in object_groups(arr).items() if len(v) >= min_cuboids}
    out = []
    for k, (name, cubs) in enumerate(groups.items()):
        out.append(retrieve_object(name, cubs, models, (points or {}).get(name), config))
        if progress is not None:
            progress(k + 1, len(groups))
    return tuple(out)


def placed_mesh(model: RepoModel, cand: Candidate) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (n, 3) world, faces (m, 3)) of a placed model."""
    unit = (model.vertices - model.lo) / model.extent
    return unit @ cand.M[:3, :3].T + cand.M[:3, 3], model.faces
