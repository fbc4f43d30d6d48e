"""The verdict of a settling run, shared by both engines: motions, thresholds, result.

:func:`judge` turns the final poses an engine reports into per-cuboid motions and the
verdict (thresholds explained in :mod:`simulate.engines`).  This module imports nothing
from the engine modules; they and the dispatcher :mod:`simulate.engines` import it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.constants import GRAVITY
from pipeline.model import Arrangement

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
    welds : str
    length_scale : float
        The factor of the frame the engine simulated in (:func:`engine_frame`).
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
    length_scale: float = 1.0

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
            **({"length_scale": float(self.length_scale)} if self.length_scale != 1.0 else {}),
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
    from .bodies import scene_extent

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


# ------------------------------------------------------------------ the engines' frame
#: Scenes whose largest edge lies in this range (metres) are simulated as they are: the
#: solver settings of both engines were measured on such scenes.  Any other scene is
#: simulated in a frame scaled by a power of ten that brings its largest edge into
#: [1, 10) m (:func:`engine_frame`).  Under a uniform scale s of every length, with
#: gravity unchanged, motions scale by s and times by sqrt(s): a verdict judged relative
#: to body size is the same, while the engines' absolute tolerances (PyBullet's
#: collision margins, MuJoCo's smallest mass and inertia) are not.
ENGINE_EDGE_RANGE = (0.1, 100.0)
#: Densities (kg/m^3) simulated as they are; other scenes get every density multiplied
#: by one power of ten (a common factor changes no verdict: every force scales with it).
ENGINE_DENSITY_RANGE = (1.0, 1e5)
#: Largest ratio of the longest to the shortest edge the engines are asked to simulate
#: together (beyond it the small boxes' masses and time scales vanish next to the large).
MAX_EDGE_RATIO = 1e6


def engine_frame(arr: Arrangement) -> tuple[Arrangement, float, float]:
    """The arrangement the engines simulate, and its length and density factors.

    Returns
    -------
    scaled : Arrangement
        ``arr`` itself when its largest edge and densities are in the ranges above;
        else every length multiplied by ``length_scale`` and every density by
        ``density_scale``.
    length_scale, density_scale : float
        Powers of ten (1.0 when unchanged).

    Raises
    ------
    InputError
        Edges more than :data:`MAX_EDGE_RATIO` apart.
    """
    from pipeline.errors import InputError
    from pipeline.model import Cuboid, ObservedBox, Support

    if not arr.cuboids:
        return arr, 1.0, 1.0
    lo, hi = float(arr.sizes.min()), float(arr.sizes.max())
    if hi / lo > MAX_EDGE_RATIO:
        raise InputError(f"the engines cannot simulate edges from {lo:.3g} m to {hi:.3g} m in "
                         f"one scene (ratio {hi / lo:.3g}, at most {MAX_EDGE_RATIO:g}); use "
                         "--engine analytic")
    s = 1.0
    if not ENGINE_EDGE_RANGE[0] <= hi <= ENGINE_EDGE_RANGE[1]:
        s = 10.0 ** -np.floor(np.log10(hi))
    d = arr.densities
    r = 1.0
    if d.min() < ENGINE_DENSITY_RANGE[0] or d.max() > ENGINE_DENSITY_RANGE[1]:
        r = 10.0 ** (3 - np.floor(np.log10(d.max())))
    if s == 1.0 and r == 1.0:
        return arr, 1.0, 1.0
    cubs = tuple(Cuboid(c.id, c.center * s, c.rotation, c.size * s, c.density * r, c.object,
                        None if c.observed is None else
                        ObservedBox(c.observed.center * s, c.observed.size * s), c.extra)
                 for c in arr.cuboids)
    sups = tuple(Support(p.id, p.point * s, p.normal) for p in arr.supports)
    return arr.with_(cuboids=cubs, supports=sups), float(s), float(r)


# ------------------------------------------------------------------ budget and progress
#: Seconds between two progress lines of a long settling run.
PROGRESS_EVERY = 10.0
#: The run's total wall time is extrapolated once this much of it has passed (seconds) or
#: this share of the steps is done, whichever comes first.
ESTIMATE_AFTER = (1.0, 0.05)


class BudgetExceeded(ValueError):
    """Settling would take longer than its budget (raised early, with the estimate)."""


class StepClock:
    """Steps an engine in chunks, drawing progress lines and enforcing a wall-time budget.

    Parameters
    ----------
    engine : str
        Name used in messages.
    n_total : int
        Steps the whole run takes.
    n_cuboids : int
    budget : float or None
        Seconds of wall time (load + simulate) the run may take; None: no limit.
    progress : callable(str) or None
        Receives a progress line every :data:`PROGRESS_EVERY` seconds.
    t_start : float
        ``time.perf_counter()`` when the run (including loading) started.
    """

    def __init__(self, engine: str, n_total: int, n_cuboids: int, budget: float | None,
                 progress, t_start: float) -> None:
        self.engine, self.n_total, self.n_cuboids = engine, int(n_total), n_cuboids
        self.budget, self.progress, self.t_start = budget, progress, t_start
        self.done = 0
        self.t_steps = None
        self.checked = False
        self.last_line = t_start

    def run(self, step, n: int, chunk: int = 100, finite=None) -> bool:
        """Call ``step(k)`` until ``n`` steps are done; False if ``finite()`` turned False."""
        import time

        left = int(n)
        size = 1  # chunks grow to ``chunk`` steps or a quarter second, whichever is less
        while left > 0:
            if self.t_steps is None:
                self.t_steps = time.perf_counter()
            k = min(size, left)
            t = time.perf_counter()
            step(k)
            left -= k
            self.done += k
            now = time.perf_counter()
            size = int(np.clip(0.25 * k / max(now - t, 1e-9), 1, chunk))
            if finite is not None and not finite():
                return False
            stepping = now - self.t_steps
            if self.budget is not None and not self.checked and self.done < self.n_total and (
                    stepping >= ESTIMATE_AFTER[0] or self.done >= ESTIMATE_AFTER[1] * self.n_total):
                self.checked = True
                total = (self.t_steps - self.t_start) + stepping / self.done * self.n_total
                if total > self.budget:
                    raise BudgetExceeded(
                        f"{self.engine}: settling {self.n_cuboids} cuboids would take about "
                        f"{total:.0f} s, more than the budget of {self.budget:g} s; raise "
                        "--engine-budget or use --engine analytic")
            if self.progress is not None and now - self.last_line >= PROGRESS_EVERY:
                self.last_line = now
                rate = stepping / max(self.done, 1)
                self.progress(f"{self.engine}: {self.done}/{self.n_total} steps, "
                              f"{now - self.t_start:.0f} s elapsed, about "
                              f"{rate * (self.n_total - self.done):.0f} s left")
        return True
