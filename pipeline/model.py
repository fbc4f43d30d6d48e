"""The data model shared by every package: cuboids, supports, contacts, arrangements.

Small frozen dataclasses over read-only numpy arrays.  Conventions (also in the
README): SI units, world frame right-handed and z up, a rotation is a 3x3 matrix
whose *columns* are the box's local axes expressed in world coordinates, and
``size`` holds the *full* edge lengths (not half sizes).

An :class:`Arrangement` also exposes struct-of-arrays views (``centers (K, 3)``,
``rotations (K, 3, 3)``, ``sizes (K, 3)``, ``densities (K,)``) so numeric kernels
stay vectorised.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any, Literal

import numpy as np

from .constants import DEFAULT_DENSITY, ROTATION_TOL

ContactType = Literal["touch", "fixed"]
CONTACT_TYPES: tuple[str, ...] = ("touch", "fixed")


def _frozen(a: Any, shape: tuple[int, ...] | None = None, name: str = "array") -> np.ndarray:
    """Return a read-only float64 copy of ``a``, checking its shape."""
    arr = np.array(a, dtype=np.float64)
    if shape is not None and arr.shape != shape:
        raise ValueError(f"{name}: expected shape {shape}, got {arr.shape}")
    arr.setflags(write=False)
    return arr


def is_rotation(R: np.ndarray, tol: float = ROTATION_TOL) -> bool:
    """True when ``R (3, 3)`` is orthonormal with determinant +1 (within ``tol``)."""
    R = np.asarray(R, dtype=float)
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        return False
    return bool(np.allclose(R.T @ R, np.eye(3), atol=tol) and abs(np.linalg.det(R) - 1) < tol)


@dataclass(frozen=True)
class ObservedBox:
    """The box as the sensor saw it, before any extension (axis frame = the cuboid's)."""

    center: np.ndarray  #: (3,) float, metres
    size: np.ndarray  #: (3,) float, full extents, metres

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _frozen(self.center, (3,), "observed.center"))
        object.__setattr__(self, "size", _frozen(self.size, (3,), "observed.size"))


@dataclass(frozen=True)
class Cuboid:
    """An oriented box.

    Attributes
    ----------
    id : str
        Unique name within its arrangement.
    center : (3,) float
        Centre in world coordinates, metres.
    rotation : (3, 3) float
        Columns are the box's local x, y, z axes in world coordinates.
    size : (3,) float
        Full edge lengths along the local axes, metres.
    density : float
        kg/m^3.
    object : str or None
        The object this cuboid is a part of (a table of five cuboids is one object).
    observed : ObservedBox or None
        The box before extension into the unseen (same rotation).
    extra : dict
        Free-form per-cuboid data kept through read/write (e.g. ``points``, ``hallucinated``).
    """

    id: str
    center: np.ndarray
    rotation: np.ndarray
    size: np.ndarray
    density: float = DEFAULT_DENSITY
    object: str | None = None
    observed: ObservedBox | None = None
    extra: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _frozen(self.center, (3,), "center"))
        object.__setattr__(self, "rotation", _frozen(self.rotation, (3, 3), "rotation"))
        object.__setattr__(self, "size", _frozen(self.size, (3,), "size"))
        object.__setattr__(self, "density", float(self.density))

    @property
    def volume(self) -> float:
        return float(np.prod(self.size))

    @property
    def mass(self) -> float:
        return self.volume * self.density

    @property
    def half(self) -> np.ndarray:
        """(3,) half extents."""
        return self.size / 2.0

    def corners(self) -> np.ndarray:
        """(8, 3) world coordinates of the corners (see :func:`box_corners`)."""
        return box_corners(self.center[None], self.rotation[None], self.size[None])[0]

    def with_(self, **changes: Any) -> Cuboid:
        """A copy with some fields replaced."""
        return replace(self, **changes)


@dataclass(frozen=True)
class Support:
    """A static support plane: the ground (``ground``) or a wall (``wall:<k>``).

    ``normal`` points out of the support into free space (up for the ground).
    """

    id: str
    point: np.ndarray  #: (3,) float, a point on the plane
    normal: np.ndarray  #: (3,) float, unit normal into free space

    def __post_init__(self) -> None:
        object.__setattr__(self, "point", _frozen(self.point, (3,), "point"))
        n = np.asarray(self.normal, dtype=float)
        norm = float(np.linalg.norm(n))
        if not np.isfinite(norm) or norm < 1e-12:
            raise ValueError(f"support {self.id!r}: normal must be a non-zero vector")
        object.__setattr__(self, "normal", _frozen(n / norm, (3,), "normal"))

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """(n,) signed distance of ``points (n, 3)`` from the plane (positive in free space)."""
        return (np.asarray(points) - self.point) @ self.normal


@dataclass(frozen=True)
class Contact:
    """A contact listed in an arrangement: an unordered pair and its type."""

    a: str
    b: str
    type: ContactType = "touch"

    @property
    def key(self) -> tuple[str, str]:
        """The unordered pair as a sorted tuple."""
        return (self.a, self.b) if self.a <= self.b else (self.b, self.a)


def is_support_id(name: str) -> bool:
    return name == "ground" or name.startswith("wall:")


@dataclass(frozen=True)
class StabilitySummary:
    """The optional ``stability`` record of an arrangement file."""

    energy: float
    stable: bool
    threshold: float


@dataclass(frozen=True)
class Arrangement:
    """Cuboids, the supports they may rest on, the contacts that are listed, and metadata."""

    cuboids: tuple[Cuboid, ...]
    supports: tuple[Support, ...] = ()
    contacts: tuple[Contact, ...] = ()
    up: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    stability: StabilitySummary | None = None
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "cuboids", tuple(self.cuboids))
        object.__setattr__(self, "supports", tuple(self.supports))
        object.__setattr__(self, "contacts", tuple(self.contacts))
        object.__setattr__(self, "up", _frozen(self.up, (3,), "up"))

    # ---- struct-of-arrays views -------------------------------------------------
    @cached_property
    def ids(self) -> tuple[str, ...]:
        return tuple(c.id for c in self.cuboids)

    @cached_property
    def index(self) -> dict[str, int]:
        """Cuboid id -> row in the arrays."""
        return {c.id: i for i, c in enumerate(self.cuboids)}

    @cached_property
    def centers(self) -> np.ndarray:
        """(K, 3) float."""
        return _stack([c.center for c in self.cuboids], (0, 3))

    @cached_property
    def rotations(self) -> np.ndarray:
        """(K, 3, 3) float."""
        return _stack([c.rotation for c in self.cuboids], (0, 3, 3))

    @cached_property
    def sizes(self) -> np.ndarray:
        """(K, 3) float, full extents."""
        return _stack([c.size for c in self.cuboids], (0, 3))

    @cached_property
    def densities(self) -> np.ndarray:
        """(K,) float."""
        d = np.array([c.density for c in self.cuboids], dtype=float)
        d.setflags(write=False)
        return d

    @cached_property
    def masses(self) -> np.ndarray:
        """(K,) float, kg."""
        m = np.prod(self.sizes, axis=1) * self.densities
        m.setflags(write=False)
        return m

    @cached_property
    def corners(self) -> np.ndarray:
        """(K, 8, 3) float, the corners of every cuboid (see :func:`box_corners`)."""
        out = box_corners(self.centers, self.rotations, self.sizes) if self.cuboids \
            else np.zeros((0, 8, 3))
        out.setflags(write=False)
        return out

    def inherit_views(self, other: Arrangement) -> Arrangement:
        """Fill this arrangement's stacked views (centres, rotations, sizes, corners) from
        those ``other`` has computed, recomputing only the rows whose cuboid is not the
        same object: an arrangement derived from another by changing a few cuboids skips
        the stacking.  Returns ``self``."""
        K = len(self.cuboids)
        if len(other.cuboids) != K or not K:
            return self
        diff = [k for k, (a, b) in enumerate(zip(self.cuboids, other.cuboids)) if a is not b]
        mine, theirs = self.__dict__, other.__dict__
        for name, attr in (("centers", "center"), ("rotations", "rotation"), ("sizes", "size")):
            if name in theirs and name not in mine:
                out = theirs[name].copy()
                for k in diff:
                    out[k] = getattr(self.cuboids[k], attr)
                out.setflags(write=False)
                mine[name] = out
        if "corners" in theirs and "corners" not in mine and \
                all(n in mine for n in ("centers", "rotations", "sizes")):
            out = theirs["corners"].copy()
            if diff:
                out[diff] = box_corners(self.centers[diff], self.rotations[diff],
                                        self.sizes[diff])
            out.setflags(write=False)
            mine["corners"] = out
        return self

    @property
    def support_ids(self) -> tuple[str, ...]:
        return tuple(s.id for s in self.supports)

    def support(self, name: str) -> Support:
        for s in self.supports:
            if s.id == name:
                return s
        raise KeyError(name)

    def cuboid(self, name: str) -> Cuboid:
        return self.cuboids[self.index[name]]

    def fixed_pairs(self) -> set[tuple[str, str]]:
        """The unordered pairs listed as ``fixed``."""
        return {c.key for c in self.contacts if c.type == "fixed"}

    def with_(self, **changes: Any) -> Arrangement:
        """A copy with some fields replaced (cached views of the cuboids are kept when
        the cuboids are the same, else rebuilt)."""
        out = replace(self, **changes)
        if out.cuboids is self.cuboids:
            for name in _CUBOID_VIEWS:
                if name in self.__dict__:
                    out.__dict__[name] = self.__dict__[name]
        return out

    def scale_length(self) -> float:
        """A characteristic length of the scene: the median of all box edges, metres."""
        if not self.cuboids:
            return 1.0
        return float(np.median(self.sizes))


#: cached views of :class:`Arrangement` that depend on its cuboids alone
_CUBOID_VIEWS = ("ids", "index", "centers", "rotations", "sizes", "densities", "masses",
                 "corners")


def _stack(items: list[np.ndarray], empty_shape: tuple[int, ...]) -> np.ndarray:
    out = np.stack(items) if items else np.zeros(empty_shape)
    out.setflags(write=False)
    return out


#: Corner sign pattern: corner k has local coordinates ``_SIGNS[k] * half``.
CORNER_SIGNS = np.array(
    [[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float
)


def box_corners(centers: np.ndarray, rotations: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """Corners of many boxes at once.

    Parameters
    ----------
    centers : (K, 3) float
    rotations : (K, 3, 3) float, columns = local axes in world
    sizes : (K, 3) float, full extents

    Returns
    -------
    corners : (K, 8, 3) float
        Corner ``k`` has local coordinates ``CORNER_SIGNS[k] * size / 2``.
    """
    local = CORNER_SIGNS[None, :, :] * (np.asarray(sizes)[:, None, :] / 2.0)  # (K, 8, 3)
    return np.asarray(centers)[:, None, :] + np.einsum("kij,knj->kni", rotations, local)


def rotation_about_z(angle: float) -> np.ndarray:
    """(3, 3) rotation by ``angle`` radians about +z."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rotation_about_axis(axis: np.ndarray, angle: float) -> np.ndarray:
    """(3, 3) rotation by ``angle`` radians about unit ``axis`` (Rodrigues)."""
    k = np.asarray(axis, dtype=float)
    k = k / np.linalg.norm(k)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * (K @ K)


def ground(height: float = 0.0) -> Support:
    """The horizontal ground plane z = ``height``."""
    return Support("ground", np.array([0.0, 0.0, height]), np.array([0.0, 0.0, 1.0]))


def box(
    id: str,
    center: Any,
    size: Any,
    rotation: Any = None,
    *,
    yaw: float | None = None,
    density: float = DEFAULT_DENSITY,
    object: str | None = None,
) -> Cuboid:
    """Convenience constructor: ``box("b0", (0, 0, 0.5), (1, 1, 1), yaw=0.3)``."""
    if rotation is None:
        rotation = rotation_about_z(yaw or 0.0)
    return Cuboid(id, np.asarray(center, float), np.asarray(rotation, float),
                  np.asarray(size, float), density=density, object=object)
