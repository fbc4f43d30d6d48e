"""Settle an arrangement in MuJoCo (``mujoco`` is imported only inside the functions).

The scene is the MJCF of :func:`simulate.mjcf.arrangement_to_mjcf` (its module
docstring lists the solver settings and the measurements behind them); this module
steps it from rest for ``duration`` seconds and reads every box geom's world pose
(``geom_xpos``, ``geom_xmat``), so fused cuboids are reported one by one.
"""

from __future__ import annotations

import time

import numpy as np

from pipeline.constants import DEFAULT_MU
from pipeline.errors import InputError
from pipeline.model import Arrangement

from .settling import DRIFT_WINDOW, SettleResult, StepClock, judge


def load_model(arr: Arrangement, *, mu: float = DEFAULT_MU, welds: str = "exact"):
    """Compile the arrangement's MJCF. Returns ``(model, bodies)``.

    Raises
    ------
    InputError
        MuJoCo refuses the model (e.g. a moving body lighter than its smallest mass).
    """
    import mujoco

    from .bodies import rigid_bodies
    from .mjcf import arrangement_to_mjcf

    try:
        model = mujoco.MjModel.from_xml_string(arrangement_to_mjcf(arr, mu=mu, welds=welds))
    except ValueError as exc:
        msg = " ".join(str(exc).split())
        raise InputError(f"mujoco cannot load this scene ({msg[:200]})") from None
    bodies, _ = rigid_bodies(arr, welds)
    return model, bodies


def settle(arr: Arrangement, *, mu: float = DEFAULT_MU, welds: str = "exact",
           duration: float = 2.0, budget: float | None = None, progress=None) -> SettleResult:
    """Simulate ``duration`` seconds in MuJoCo and judge (see :mod:`simulate.engines`)."""
    import mujoco

    t0 = time.perf_counter()
    model, bodies = load_model(arr, mu=mu, welds=welds)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    geom_ids = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, c.id)
                         for c in arr.cuboids])
    n_steps = max(1, int(round(duration / model.opt.timestep)))
    n_window = int(round(DRIFT_WINDOW * n_steps))
    clock = StepClock("mujoco", n_steps, len(arr.cuboids), budget, progress, t0)

    def step(k: int) -> None:
        mujoco.mj_step(model, data, nstep=k)

    def finite() -> bool:
        return bool(np.isfinite(data.qpos).all())

    before = None
    if clock.run(step, n_steps - n_window, chunk=50, finite=finite):
        before = data.geom_xpos[geom_ids].copy()
        clock.run(step, n_window, chunk=50, finite=finite)
    centers = data.geom_xpos[geom_ids].copy()
    rotations = data.geom_xmat[geom_ids].reshape(-1, 3, 3).copy()
    drift = (np.linalg.norm(centers - before, axis=1) if before is not None
             else np.zeros(len(geom_ids)))
    return judge(arr, "mujoco", centers, rotations, drift, [b.members for b in bodies],
                 n_steps * model.opt.timestep, time.perf_counter() - t0, welds)
