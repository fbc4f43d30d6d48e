"""Settle an arrangement in PyBullet (``pybullet`` is imported only inside the functions).

The scene is loaded from the URDF files of :func:`simulate.urdf.arrangement_to_urdf_files`
(written to a temporary folder): ``urdf/world.urdf`` with ``useFixedBase`` (supports as
plane half-spaces, static bodies) and one ``urdf/<body>.urdf`` per free body with
``URDF_USE_INERTIA_FROM_FILE``.  ``welds="constraint"`` adds a ``JOINT_FIXED`` constraint
per ``fixed`` contact.  Cuboid poses are read from each body's base pose composed with
the cuboid's pose relative to it at load time (PyBullet's base frame is the principal
inertial frame, not the URDF link frame).

Settings, chosen by measurement on this machine (``tests/simulate/test_engines.py``):

- DIRECT mode, one private client per call, gravity set explicitly (PyBullet's default
  is none);
- fixed time step ``TIMESTEP`` (1/960 s for 10 cm boxes, scaled with sqrt(size) like
  MuJoCo's) and ``SOLVER_ITERATIONS`` solver iterations: PyBullet's defaults (1/240 s,
  50 iterations) read a standing 10-cube column as fallen (8 mm, 0.75 degrees); 1/480 s
  needs 100 iterations for it (0.36 mm) and still topples two tall towers that statics
  calls stable with a 2 degree margin; 1/960 s holds them, and 40, 50 or 60 iterations
  give identical poses (the solver stops on its residual first);
- restitution 0, no linear/angular damping (PyBullet's default 0.04 would slow a tipping
  box), no rolling or spinning friction, lateral friction ``sqrt(mu)`` on every body and
  on the world (PyBullet multiplies the pair), sleeping disabled (a box that starts to
  tip slowly must not be frozen).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from pipeline.constants import DEFAULT_MU, GRAVITY
from pipeline.errors import InputError
from pipeline.model import Arrangement

from .settling import DRIFT_WINDOW, SettleResult, StepClock, judge

#: Time step for a scene whose smallest box is ``REFERENCE_SIZE`` long, seconds.
TIMESTEP = 1.0 / 960.0
#: Box size at which ``TIMESTEP`` applies, metres (see :func:`timestep_for`).
REFERENCE_SIZE = 0.1
TIMESTEP_RANGE = (1.0 / 4000.0, 1.0 / 480.0)
#: Sequential-impulse solver iterations per step.
SOLVER_ITERATIONS = 50


def timestep_for(arr: Arrangement) -> float:
    """``TIMESTEP * sqrt(L / REFERENCE_SIZE)`` clipped, L the largest edge of the smallest box."""
    if not arr.cuboids:
        return TIMESTEP
    L = float(arr.sizes.max(axis=1).min())
    return float(np.clip(TIMESTEP * np.sqrt(L / REFERENCE_SIZE), *TIMESTEP_RANGE))


def quat_xyzw_from_matrix(R: np.ndarray) -> np.ndarray:
    """(4,) PyBullet quaternion ``x y z w`` of ``R (3, 3)``."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(np.asarray(R, float)).as_quat()


def matrices_from_quat_xyzw(q: np.ndarray) -> np.ndarray:
    """(n, 3, 3) rotations of PyBullet quaternions ``q (n, 4)`` (x y z w)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(np.asarray(q, float).reshape(-1, 4)).as_matrix()


class Scene:
    """An arrangement loaded into a private PyBullet DIRECT client (close it after use).

    Attributes
    ----------
    client : int
    bodies : list of RigidBody
    ids : list of int
        PyBullet body id of every rigid body (-1 for static ones: they live in ``world``).
    world : int
        PyBullet id of the static world.
    """

    def __init__(self, arr: Arrangement, *, mu: float = DEFAULT_MU, welds: str = "exact",
                 timestep: float | None = None, iterations: int = SOLVER_ITERATIONS) -> None:
        from .bodies import rigid_bodies
        from .pybullet_import import pybullet
        from .urdf import arrangement_to_urdf_files

        p = pybullet()
        self.p = p
        self.arr = arr
        self.dt = timestep_for(arr) if timestep is None else float(timestep)
        self.bodies, weld_list = rigid_bodies(arr, welds)
        self.client = p.connect(p.DIRECT)
        cid = self.client
        try:
            p.setGravity(0, 0, -GRAVITY, physicsClientId=cid)
            p.setPhysicsEngineParameter(fixedTimeStep=self.dt, numSolverIterations=iterations,
                                        numSubSteps=0, restitutionVelocityThreshold=0,
                                        physicsClientId=cid)
            files = arrangement_to_urdf_files(arr, mu=mu, welds=welds)
            flags = p.URDF_USE_INERTIA_FROM_FILE
            with tempfile.TemporaryDirectory(prefix="unseen-urdf-") as tmp:
                for rel, text in files.items():
                    path = Path(tmp) / rel
                    path.parent.mkdir(parents=True, exist_ok=True)
                    path.write_text(text, encoding="utf-8")
                try:
                    self.world = p.loadURDF(str(Path(tmp) / "urdf/world.urdf"),
                                            useFixedBase=True, flags=flags, physicsClientId=cid)
                    self.ids = [-1 if b.static else
                                p.loadURDF(str(Path(tmp) / f"urdf/{b.name}.urdf"), flags=flags,
                                           physicsClientId=cid)
                                for b in self.bodies]
                except p.error as exc:
                    raise InputError(f"pybullet cannot load this scene ({exc})") from None
            f = float(np.sqrt(mu))
            for bid in [self.world, *[i for i in self.ids if i >= 0]]:
                p.changeDynamics(bid, -1, lateralFriction=f, restitution=0.0,
                                 rollingFriction=0.0, spinningFriction=0.0,
                                 linearDamping=0.0, angularDamping=0.0,
                                 activationState=p.ACTIVATION_STATE_DISABLE_SLEEPING,
                                 physicsClientId=cid)
            # pose of every cuboid relative to its body's base (inertial) frame at load time
            K = len(arr.cuboids)
            self.body_of = np.zeros(K, dtype=np.int64)
            self.local_c = np.zeros((K, 3))
            self.local_R = np.zeros((K, 3, 3))
            p0, R0 = self.base_poses()
            for j, b in enumerate(self.bodies):
                self.body_of[b.members] = j
            Rb = R0[self.body_of]
            self.local_c = np.einsum("kji,kj->ki", Rb, arr.centers - p0[self.body_of])
            self.local_R = np.einsum("kji,kjl->kil", Rb, arr.rotations)
            total_weight = GRAVITY * float(arr.masses.sum())
            for w in weld_list:
                self._weld(w.a, w.b, p0, R0, total_weight)
        except BaseException:
            p.disconnect(cid)
            raise

    def _weld(self, a: int, b: int, p0: np.ndarray, R0: np.ndarray, max_force: float) -> None:
        """A JOINT_FIXED constraint holding bodies ``a`` and ``b`` at their initial relative pose."""
        p, cid = self.p, self.client
        ia, ib = self.ids[a], self.ids[b]
        if ia < 0 and ib < 0:
            return
        if ia < 0:  # parent must be dynamic
            a, b, ia, ib = b, a, ib, ia
        # joint frame = the parent's base frame; the child's frame expressed in it
        child_pos = R0[b].T @ (p0[a] - p0[b]) if ib >= 0 else p0[a]
        child_R = R0[b].T @ R0[a] if ib >= 0 else R0[a]
        c = p.createConstraint(ia, -1, ib, -1, p.JOINT_FIXED, [0, 0, 0], [0, 0, 0],
                               child_pos.tolist(), [0, 0, 0, 1],
                               quat_xyzw_from_matrix(child_R).tolist(), physicsClientId=cid)
        p.changeConstraint(c, maxForce=1e4 * max_force, physicsClientId=cid)

    def base_poses(self) -> tuple[np.ndarray, np.ndarray]:
        """(B, 3) positions and (B, 3, 3) rotations of every body's base frame (static: identity)."""
        p, cid = self.p, self.client
        pos = np.zeros((len(self.bodies), 3))
        quat = np.tile([0.0, 0.0, 0.0, 1.0], (len(self.bodies), 1))
        for j, bid in enumerate(self.ids):
            if bid >= 0:
                pp, qq = p.getBasePositionAndOrientation(bid, physicsClientId=cid)
                pos[j], quat[j] = pp, qq
        return pos, matrices_from_quat_xyzw(quat)

    def cuboid_poses(self) -> tuple[np.ndarray, np.ndarray]:
        """(K, 3) centres and (K, 3, 3) rotations of every cuboid now."""
        pos, R = self.base_poses()
        Rb = R[self.body_of]
        centers = pos[self.body_of] + np.einsum("kij,kj->ki", Rb, self.local_c)
        rotations = np.einsum("kij,kjl->kil", Rb, self.local_R)
        return centers, rotations

    def step(self, n: int) -> None:
        p, cid = self.p, self.client
        for _ in range(n):
            p.stepSimulation(physicsClientId=cid)

    def close(self) -> None:
        self.p.disconnect(self.client)


def settle(arr: Arrangement, *, mu: float = DEFAULT_MU, welds: str = "exact",
           duration: float = 2.0, budget: float | None = None, progress=None) -> SettleResult:
    """Simulate ``duration`` seconds in PyBullet and judge (see :mod:`simulate.engines`)."""
    t0 = time.perf_counter()
    scene = Scene(arr, mu=mu, welds=welds)
    try:
        n = max(1, int(round(duration / scene.dt)))
        n_window = int(round(DRIFT_WINDOW * n))
        clock = StepClock("pybullet", n, len(arr.cuboids), budget, progress, t0)
        clock.run(scene.step, n - n_window)
        before, _ = scene.cuboid_poses()
        clock.run(scene.step, n_window)
        centers, rotations = scene.cuboid_poses()
        drift = np.linalg.norm(centers - before, axis=1)
    finally:
        scene.close()
    return judge(arr, "pybullet", centers, rotations, drift,
                 [b.members for b in scene.bodies], n * scene.dt, time.perf_counter() - t0, welds)
