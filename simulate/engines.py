"""Settle an arrangement in a physics engine and judge which bodies moved.

The common API of the engine modules (``simulate.mujoco_engine``,
``simulate.pybullet_engine``; each imports its engine only inside):

    settle(arr, engine, mu=0.7, welds="exact", duration=None) -> SettleResult

How a verdict is reached (the same for both engines): the arrangement is exported
(:mod:`simulate.mjcf` / :mod:`simulate.urdf`), loaded, released from rest and
simulated for ``duration`` seconds (default :func:`default_duration`, which grows with
the square root of the scene's size because a tipping box's time scale is
``sqrt(L / g)``).  Every cuboid then gets its translation ``|c_final - c_initial|`` and
its rotation angle (of ``R_final R_initial^T``).  A cuboid is *stable* when

- translation < ``TRANSLATION_REL`` x its body's size (largest edge of its rigid body's
  cuboids): soft contacts compress by a fraction of a millimetre, a toppled or sliding
  box moves by a good part of its size;
- rotation < ``ROTATION_DEG`` degrees;
- it moved less than ``DRIFT_REL`` x body size during the last quarter of the run (it
  is not still moving).  Displacement over a window, not the final speed: MuJoCo's soft
  contacts leave a box resting near an edge rocking at a few mm/s with no net motion
  (measured: a cube yawed 30 degrees, 3 mm inside the base edge, rocks at 9 mm/s while
  drifting 0.06 mm per 0.5 s).

The arrangement is stable when every cuboid is.  A simulation that produces NaN or
throws a body further than ``BLOWUP_REL`` scene extents is reported with
``status="blew_up"`` and ``stable=False``.

Measured on this machine (``tests/simulate/test_engines.py``, 20 cm cubes unless said):

============================  ==================  ==================
case                          MuJoCo              PyBullet
============================  ==================  ==================
10-cube column, 10 cm         0.17 mm, 0.00 deg   0.24 mm, 0.02 deg
cube overhanging 49 %         0.03 mm, 0.01 deg   0.04 mm, 0.01 deg
cube overhanging 51 %         toppled, 90 deg     toppled, 90 deg
plank 21 / 19 deg (L 1 m)     stands / slides     stands / slides
plank stands from             20.5 deg            20.0 deg
yawed cube 3 mm in / out      stands / topples    stands / topples
side-friction trap            drops 250 mm        drops 250 mm
fused 0.8 m cantilever        < 0.01 mm sag       < 0.01 mm sag
============================  ==================  ==================

so the thresholds (2 % of the body's size, 2 degrees, 0.5 % drift) sit well clear of
both sides.  The engines' ladder limit lies 0.4-0.9 degrees above the rigid-body one
(19.6 degrees for a 2 cm x 1 m plank): soft contacts.  Wall time (10 cm 10-cube column,
1 s simulated, load + simulate + judge): MuJoCo 0.1 s, PyBullet 0.6-1.1 s (the
range is the shared 2-core machine's load).  At 10 cm, 1 ms (MuJoCo) and 1/960 s
(PyBullet) steps; see :mod:`simulate.mjcf` and :mod:`simulate.pybullet_engine`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.constants import DEFAULT_MU, GRAVITY
from pipeline.errors import InputError
from pipeline.model import Arrangement

ENGINES = ("mujoco", "pybullet")

#: A cuboid that moved more than this fraction of its body's size is unstable.
TRANSLATION_REL = 0.02
#: A cuboid that turned more than this many degrees is unstable.
ROTATION_DEG = 2.0
#: A cuboid that moved more than this fraction of its body's size during the last quarter
#: of the run is still moving, and unstable.
DRIFT_REL = 0.005
#: The judged window: the last quarter of the simulated time.
DRIFT_WINDOW = 0.25
#: Positions beyond this many scene extents (or NaN) mean the simulation blew up.
BLOWUP_REL = 100.0


@dataclass(frozen=True)
class BodyMotion:
    """How far one cuboid moved while settling."""

    id: str  #: cuboid id (every cuboid is reported, fused ones too)
    translation: float  #: metres, |final centre - initial centre|
    rotation_deg: float  #: degrees, angle of R_final R_initial^T
    stable: bool


@dataclass(frozen=True)
class SettleResult:
    """The outcome of settling an arrangement in one engine.

    Attributes
    ----------
    engine : str
        ``"mujoco"`` or ``"pybullet"``.
    stable : bool
        Every cuboid stayed put (see the module docstring for the thresholds).
    bodies : tuple of BodyMotion
        One per cuboid, in the arrangement's order.
    centers : (K, 3) float
        Final cuboid centres.
    rotations : (K, 3, 3) float
        Final cuboid rotations.
    status : str
        ``"ok"`` or ``"blew_up"``.
    sim_time : float
        Simulated seconds.
    wall_time : float
        Wall-clock seconds (load + simulate).
    drift : (K,) float
        How far every cuboid's centre moved during the last ``DRIFT_WINDOW`` of the run, m.
    """

    engine: str
    stable: bool
    bodies: tuple[BodyMotion, ...]
    centers: np.ndarray
    rotations: np.ndarray
    status: str
    sim_time: float
    wall_time: float
    drift: np.ndarray | None = None
    welds: str = "exact"

    def to_json(self) -> dict:
        """A JSON-ready dict (the ``engines.<name>`` record of ``unseen check --json``)."""
        return {
            "engine": self.engine,
            "stable": bool(self.stable),
            "status": self.status,
            "bodies": [{"id": b.id, "stable": bool(b.stable),
                        "translation": float(b.translation),
                        "rotation_deg": float(b.rotation_deg)} for b in self.bodies],
            "sim_time": float(self.sim_time),
            "wall_time": float(self.wall_time),
            "welds": self.welds,
            "thresholds": {"translation_rel": TRANSLATION_REL, "rotation_deg": ROTATION_DEG,
                           "drift_rel": DRIFT_REL, "drift_window": DRIFT_WINDOW},
        }


def default_duration(arr: Arrangement) -> float:
    """Simulated seconds: ``clip(10 sqrt(L / g), 0.5, 4)`` with L the largest box edge.

    A box overhanging 51 % tips with a time constant of order ``sqrt(L / g)``; ten of
    them let it turn well past ``ROTATION_DEG`` (measured: a 1 m cube at 51 % turns
    > 10 degrees in 3.2 s).
    """
    L = float(arr.sizes.max()) if arr.cuboids else 1.0
    return float(np.clip(10.0 * np.sqrt(L / GRAVITY), 0.5, 4.0))


def body_sizes(arr: Arrangement, members_of: list[np.ndarray]) -> np.ndarray:
    """(K,) the size of every cuboid's rigid body: the largest edge among its members."""
    out = np.zeros(len(arr.cuboids))
    edge = arr.sizes.max(axis=1) if arr.cuboids else np.zeros(0)
    for m in members_of:
        out[m] = edge[m].max()
    return out


def rotation_angles_deg(R0: np.ndarray, R1: np.ndarray) -> np.ndarray:
    """(K,) angle in degrees of ``R1[k] R0[k]^T`` for ``R0, R1 (K, 3, 3)``."""
    tr = np.einsum("kij,kij->k", R1, R0)  # trace(R1 R0^T)
    return np.degrees(np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0)))


def judge(arr: Arrangement, engine: str, centers: np.ndarray, rotations: np.ndarray,
          drift: np.ndarray, members_of: list[np.ndarray], sim_time: float,
          wall_time: float, welds: str = "exact") -> SettleResult:
    """Turn final poses into per-cuboid motions and the verdict (shared by the engines)."""
    from .export import scene_extent

    c0, R0 = np.asarray(arr.centers), np.asarray(arr.rotations)
    centers = np.asarray(centers, float)
    rotations = np.asarray(rotations, float)
    drift = np.asarray(drift, float)
    finite = bool(np.all(np.isfinite(centers)) and np.all(np.isfinite(rotations)))
    trans = np.linalg.norm(centers - c0, axis=1) if finite else np.full(len(c0), np.inf)
    blew = (not finite) or bool(np.any(trans > BLOWUP_REL * scene_extent(arr)))
    rot = rotation_angles_deg(R0, rotations) if finite else np.full(len(c0), np.inf)
    size = body_sizes(arr, members_of)
    ok = (trans < TRANSLATION_REL * size) & (rot < ROTATION_DEG) & (drift < DRIFT_REL * size)
    bodies = tuple(BodyMotion(c.id, float(t), float(r), bool(s))
                   for c, t, r, s in zip(arr.cuboids, trans, rot, ok, strict=True))
    for a in (centers, rotations, drift):
        a.setflags(write=False)
    return SettleResult(engine, bool(ok.all()) and not blew, bodies, centers, rotations,
                        "blew_up" if blew else "ok", float(sim_time), float(wall_time),
                        drift, welds)


def settle(arr: Arrangement, engine: str, *, mu: float = DEFAULT_MU, welds: str = "exact",
           duration: float | None = None) -> SettleResult:
    """Settle ``arr`` in ``engine`` from rest and judge which cuboids moved.

    Parameters
    ----------
    arr : Arrangement
    engine : {"mujoco", "pybullet"}
    mu : float
        Friction coefficient of every contact pair.
    welds : {"exact", "constraint"}
        ``fixed`` contacts as one rigid body (exact) or as engine weld constraints.
    duration : float, optional
        Simulated seconds; default :func:`default_duration`.

    Returns
    -------
    SettleResult
    """
    from .export import check_welds

    check_welds(welds)
    if engine == "mujoco":
        from .mujoco_engine import settle as run
    elif engine == "pybullet":
        from .pybullet_engine import settle as run
    else:
        raise InputError(f"engine: expected one of {', '.join(ENGINES)}, got {engine!r}")
    if not arr.cuboids:
        return SettleResult(engine, True, (), np.zeros((0, 3)), np.zeros((0, 3, 3)), "ok",
                            0.0, 0.0, np.zeros(0), welds)
    return run(arr, mu=mu, welds=welds,
               duration=default_duration(arr) if duration is None else float(duration))
