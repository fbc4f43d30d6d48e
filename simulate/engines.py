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

from dataclasses import replace as dataclass_replace

import numpy as np

from pipeline.constants import DEFAULT_MU
from pipeline.errors import InputError
from pipeline.model import Arrangement

from .settling import (  # noqa: F401 - re-exported: the engines' common API
    BLOWUP_REL,
    DRIFT_REL,
    DRIFT_WINDOW,
    ROTATION_DEG,
    TRANSLATION_REL,
    BodyMotion,
    SettleResult,
    body_sizes,
    default_duration,
    judge,
    rotation_angles_deg,
)

ENGINES = ("mujoco", "pybullet")


def settle(arr: Arrangement, engine: str, *, mu: float = DEFAULT_MU, welds: str = "exact",
           duration: float | None = None, budget: float | None = None,
           progress=None) -> SettleResult:
    """Settle ``arr`` in ``engine`` from rest and judge which cuboids moved.

    A scene outside :data:`~simulate.settling.ENGINE_EDGE_RANGE` (or with densities
    outside :data:`~simulate.settling.ENGINE_DENSITY_RANGE`) is simulated in the frame of
    :func:`~simulate.settling.engine_frame`, scaled by a power of ten, and its motions
    are mapped back: the verdict of a scene does not depend on its unit of length.

    Parameters
    ----------
    arr : Arrangement
    engine : {"mujoco", "pybullet"}
    mu : float
        Friction coefficient of every contact pair.
    welds : {"exact", "constraint"}
        ``fixed`` contacts as one rigid body (exact) or as engine weld constraints.
    duration : float, optional
        Simulated seconds in the engine's frame; default :func:`default_duration`.
    budget : float, optional
        Wall-time limit in seconds (load + simulate).  The run's total is extrapolated
        early, and a run that would exceed it stops with :class:`InputError` stating the
        estimate.  None: no limit.
    progress : callable(str), optional
        Receives a progress line every few seconds of a long run.

    Returns
    -------
    SettleResult
        ``length_scale`` records the factor of the engine frame (1.0 when unscaled);
        ``sim_time`` is in the scene's own time (the engine's divided by
        sqrt(length_scale)).

    Raises
    ------
    InputError
        Unknown engine or welds; a scene the engine cannot load or simulate within the
        budget (one line saying why).
    """
    from .bodies import check_welds
    from .settling import BudgetExceeded, engine_frame

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
    scaled, s, _ = engine_frame(arr)
    try:
        res = run(scaled, mu=mu, welds=welds,
                  duration=default_duration(scaled) if duration is None else float(duration),
                  budget=budget, progress=progress)
    except BudgetExceeded as exc:
        raise InputError(str(exc)) from None
    if s == 1.0 and scaled is arr:
        return res
    # motions back to the scene's own lengths and times (the judge is scale free)

    out = judge(arr, engine, np.asarray(res.centers) / s, res.rotations,
                np.asarray(res.drift) / s, _members(res, arr), res.sim_time / np.sqrt(s),
                res.wall_time, welds)
    return dataclass_replace(out, length_scale=s)


def _members(res: SettleResult, arr: Arrangement) -> list[np.ndarray]:
    from .bodies import rigid_bodies

    return [b.members for b in rigid_bodies(arr, res.welds)[0]]
