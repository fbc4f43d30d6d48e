"""Assemble ground-truth scenes from object groups built in their own local frame.

An object builder (``synth_scenes.objects``) fills a :class:`Group`: boxes posed in
the group's local frame (z up, the floor at z = 0, a wall, when the group hangs on
one, is the plane y = 0 with its normal +y), the contacts it creates by construction
(between its own parts, with ``"ground"`` or with ``"wall"``) and an object label per
part.  A :class:`SceneBuilder` places groups on the floor (a planar pose: x, y, yaw) or
against a wall support, renames object labels to scene-unique names (``table0``,
``book3``) and numbers the cuboids ``b0..b{K-1}`` in placement order.

Contacts are listed *by construction*: every pair the builder makes touch is recorded
with its type (``fixed`` for fused parts, ``touch`` otherwise), and everything else
keeps a clearance well above the contact tolerance (see :data:`CLEARANCE`).  A test
checks the list equals :func:`pipeline.contacts.find_contacts` on every family.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pipeline.model import (
    Arrangement,
    Contact,
    Cuboid,
    Support,
    box_corners,
    ground,
    rotation_about_z,
)

#: Minimum gap, metres, between boxes that must *not* touch.  The contact tolerance is
#: 2 % of the smaller box's smallest edge (<= 1 cm for the largest part we build), so
#: 2 cm keeps every unlisted pair clearly apart.
CLEARANCE = 0.02


@dataclass
class Part:
    """One box of a group, in the group's local frame."""

    center: np.ndarray  #: (3,) float
    rotation: np.ndarray  #: (3, 3) float, columns = local axes
    size: np.ndarray  #: (3,) float, full extents
    label: str  #: object label inside the group, e.g. ``"table"`` or ``"book:2"``


@dataclass
class Group:
    """Boxes of one or a few objects in a local frame, with their contacts.

    ``contacts`` holds ``(i, j, type)`` where ``i`` is a part index and ``j`` a part
    index or a support name: ``"ground"`` or ``"wall"`` (the wall the group hangs on).
    """

    parts: list[Part] = field(default_factory=list)
    contacts: list[tuple[int, int | str, str]] = field(default_factory=list)
    _uid: int = 0

    def new_label(self, kind: str) -> str:
        """A group-unique object label ``<kind>:<n>`` (parts with one label are one object)."""
        self._uid += 1
        return f"{kind}:{self._uid}"

    def add(self, center, size, label: str, rotation=None) -> int:
        """Add a box; returns its part index."""
        R = np.eye(3) if rotation is None else np.asarray(rotation, float)
        self.parts.append(Part(np.asarray(center, float), R, np.asarray(size, float), label))
        return len(self.parts) - 1

    def touch(self, i: int, j: int | str) -> None:
        self.contacts.append((i, j, "touch"))

    def fix(self, i: int, j: int | str) -> None:
        self.contacts.append((i, j, "fixed"))

    def top(self, i: int) -> float:
        """z of the highest point of part ``i`` (its top face for an upright box)."""
        return float(self.corners()[i, :, 2].max())

    def corners(self) -> np.ndarray:
        """(K, 8, 3) corners of every part."""
        if not self.parts:
            return np.zeros((0, 8, 3))
        return box_corners(np.stack([p.center for p in self.parts]),
                           np.stack([p.rotation for p in self.parts]),
                           np.stack([p.size for p in self.parts]))

    def footprint(self) -> np.ndarray:
        """(2, 2) ``[[xmin, ymin], [xmax, ymax]]`` of every part projected on the floor."""
        c = self.corners().reshape(-1, 3)[:, :2]
        return np.stack([c.min(axis=0), c.max(axis=0)])

    def extend(self, other: Group, offset=(0.0, 0.0, 0.0), yaw: float = 0.0,
               ground_as: int | None = None) -> dict[int, int]:
        """Copy ``other``'s parts and contacts into this group, moved by ``yaw`` then ``offset``.

        ``ground_as``: put ``other`` (built standing on z = 0) on top of part ``ground_as``:
        its contacts with ``"ground"`` become contacts with that part.
        Returns the map from ``other``'s part indices to this group's.
        """
        Rz = rotation_about_z(yaw)
        t = np.asarray(offset, float)
        index = {}
        labels: dict[str, str] = {}
        for k, p in enumerate(other.parts):
            if p.label not in labels:
                labels[p.label] = self.new_label(p.label.split(":")[0])
            index[k] = self.add(Rz @ p.center + t, p.size, labels[p.label], Rz @ p.rotation)
        for i, j, kind in other.contacts:
            if isinstance(j, int):
                j = index[j]
            elif j == "ground" and ground_as is not None:
                j = ground_as
            self.contacts.append((index[i], j, kind))
        return index


class SceneBuilder:
    """Places groups in a scene and produces the ground-truth :class:`Arrangement`."""

    def __init__(self, supports: tuple[Support, ...] | None = None) -> None:
        self.supports: list[Support] = list(supports) if supports is not None else [ground()]
        self.centers: list[np.ndarray] = []
        self.rotations: list[np.ndarray] = []
        self.sizes: list[np.ndarray] = []
        self.objects: list[str] = []
        self.contacts: list[tuple[int, int | str, str]] = []
        self._counts: dict[str, int] = {}

    def object_name(self, kind: str) -> str:
        """A fresh scene-unique object name ``<kind><n>``."""
        n = self._counts.get(kind, 0)
        self._counts[kind] = n + 1
        return f"{kind}{n}"

    def place(self, group: Group, x: float = 0.0, y: float = 0.0, yaw: float = 0.0,
              wall: str | None = None) -> list[int]:
        """Add ``group`` rotated by ``yaw`` about z and moved to ``(x, y)`` on the floor.

        ``wall`` names the support that the group's contacts with ``"wall"`` refer to.
        Returns the scene indices of the group's parts.
        """
        Rz = rotation_about_z(yaw)
        t = np.array([x, y, 0.0])
        names: dict[str, str] = {}
        first = len(self.centers)
        for p in group.parts:
            if p.label not in names:
                names[p.label] = self.object_name(p.label.split(":")[0])
            self.centers.append(Rz @ p.center + t)
            self.rotations.append(Rz @ p.rotation)
            self.sizes.append(p.size.copy())
            self.objects.append(names[p.label])
        for i, j, kind in group.contacts:
            if isinstance(j, str):
                if j == "wall":
                    if wall is None:
                        raise ValueError("group has a wall contact but no wall was given")
                    j = wall
                self.contacts.append((first + i, j, kind))
            else:
                self.contacts.append((first + i, first + j, kind))
        return list(range(first, len(self.centers)))

    def place_on_wall(self, group: Group, wall: Support, along: float) -> list[int]:
        """Hang ``group`` (built against the wall y = 0, normal +y) on vertical ``wall``.

        ``along`` is the position along the wall, metres from ``wall.point``.
        """
        n = wall.normal
        yaw = float(np.arctan2(n[1], n[0]) - np.pi / 2)  # local +y -> n
        tangent = np.array([np.cos(yaw), np.sin(yaw), 0.0])  # local +x
        origin = wall.point + along * tangent
        return self.place(group, float(origin[0]), float(origin[1]), yaw, wall=wall.id)

    def build(self, meta: dict | None = None) -> Arrangement:
        """The arrangement: cuboids ``b0..``, supports, typed contacts (sorted), ``meta``."""
        ids = [f"b{k}" for k in range(len(self.centers))]
        cuboids = tuple(
            Cuboid(ids[k], self.centers[k], _orthonormal(self.rotations[k]), self.sizes[k],
                   object=self.objects[k])
            for k in range(len(ids)))
        seen: dict[tuple[str, str], str] = {}
        for i, j, kind in self.contacts:
            a = ids[i]
            b = j if isinstance(j, str) else ids[j]
            key = (a, b) if _order(a) <= _order(b) else (b, a)
            if key in seen and seen[key] != kind:
                raise ValueError(f"contact {key} listed as both {seen[key]} and {kind}")
            seen[key] = kind
        contacts = tuple(Contact(a, b, kind) for (a, b), kind in sorted(
            seen.items(), key=lambda item: (_order(item[0][0]), _order(item[0][1]))))
        return Arrangement(cuboids, tuple(self.supports), contacts, meta=dict(meta or {}))


def _order(name: str) -> tuple[int, int, str]:
    """Sort key: cuboids by number, then supports by name."""
    if name.startswith("b") and name[1:].isdigit():
        return (0, int(name[1:]), "")
    return (1, 0, name)


def _orthonormal(R: np.ndarray) -> np.ndarray:
    """Snap float dust (|r| < 1e-15) to 0 so axis-aligned boxes stay exactly axis-aligned."""
    out = np.array(R, dtype=float)
    out[np.abs(out) < 1e-15] = 0.0
    return out
