"""Arrangement -> MJCF text (MuJoCo's XML), a pure function with no engine import.

Layout of the file:

- ``<compiler angle="radian">``; quaternions ``w x y z`` (converted here and only here);
  box ``size`` = half extents; floats at 12 significant digits so the file is stable.
- Supports (``ground``, ``wall:k``) are static ``plane`` geoms through ``Support.point``
  with their ``normal``: MuJoCo planes are infinite and one-sided, i.e. the half-space
  behind the plane is solid, which is exactly what a support means.
- One ``<body>`` per rigid body of :func:`simulate.export.rigid_bodies`: free bodies get a
  ``<freejoint/>``, a group fused to a support is a static body (no joint).  Each cuboid
  is a ``box`` geom named by its id (XML-escaped, so any id survives) carrying the
  cuboid's density; MuJoCo derives the body's mass, centre of mass and inertia from the
  geoms, which the tests compare with the closed form to 1e-9.
- ``welds="constraint"``: every cuboid its own body and each ``fixed`` contact an
  ``<equality><weld>`` with a stiff solref (``WELD_TIMECONST_STEPS``) (the default solref let a 0.8 m
  cantilever sag 17 degrees; see the measurements below).

Solver settings (``<option>`` and ``<default>``), chosen by measurement on this machine
(``tests/simulate/test_engines.py`` holds the oracles):

- ``cone="elliptic"``, ``impratio=10``, no noslip: on a 30 degree slope (mu = 0.7) a 10 cm
  cube creeps at 2.1 mm/s with the default pyramidal cone and impratio 1, 0.48 mm/s
  elliptic with impratio 1, 0.05 mm/s elliptic with impratio 10 (0.02 mm/s at 20
  degrees): 0.2 mm over the longest run, far below the thresholds.  ``noslip_iterations``
  stops creep entirely but also glues *separating* contacts: a shelf board whose centre
  of mass is beyond its bracket, its back touching the wall, hung on the wall by friction
  alone (5 of 500 random arrangements; analytic and PyBullet drop it), so it stays off.
- ``margin=0`` on every geom: a positive margin pushes touching boxes apart.
- friction ``mu`` on every geom (MuJoCo takes the max of the pair, so the pair gets mu),
  ``condim=3`` (sliding friction only, like the analytic model).
- time step 1 ms for 10 cm boxes, scaled with ``sqrt(size)`` (:func:`timestep_for`):
  4 and 5 ms steps made a standing 10-cube column and a 49 % overhang read as moving;
  2 ms gets those right but topples tall towers that statics calls stable with a
  tipping margin of 2 degrees (5 of 1000 random arrangements; PyBullet holds 3 of them),
  1 ms holds them all.  A 10-cube column (1 s simulated) takes about 0.2 s.
"""

from __future__ import annotations

from xml.sax.saxutils import quoteattr

import numpy as np

from pipeline.constants import DEFAULT_MU, GRAVITY
from pipeline.model import Arrangement

from .bodies import rigid_bodies

#: Simulation time step for a scene whose smallest box is ``REFERENCE_SIZE`` long, seconds;
#: :func:`timestep_for` scales it with ``sqrt(size)`` so every scene is simulated alike in
#: dimensionless time (soft-contact compression then stays a fixed fraction of box size).
TIMESTEP = 0.001
#: Box size (largest edge of the smallest cuboid) at which ``TIMESTEP`` applies, metres.
REFERENCE_SIZE = 0.1
#: Bounds of the scaled time step, seconds.
TIMESTEP_RANGE = (0.00025, 0.002)
#: Noslip post-solver iterations: 0 (see the module docstring: it glues separating contacts).
NOSLIP_ITERATIONS = 0
#: Ratio of frictional to normal constraint impedance; 10 stops creep with the elliptic cone.
IMPRATIO = 10.0
#: Contact softness: time constant in time steps (MuJoCo's lower bound is 2) and damping
#: ratio 1.  2.5 steps (2.5 ms at the reference step, MuJoCo's default is 20 ms) makes a
#: column of ten 10 cm cubes compress by 0.17 mm in all.
CONTACT_TIMECONST_STEPS = 2.5
#: Weld softness for ``welds="constraint"``: as stiff as the step allows (2 time steps).
WELD_TIMECONST_STEPS = 2.0
WELD_SOLIMP = (0.99, 0.999, 0.001)

_PREC = 12


def _f(x: float) -> str:
    """One float at fixed precision, tiny noise cleaned, no ``-0``."""
    x = float(x)
    if abs(x) < 1e-13:
        x = 0.0
    s = f"{x:.{_PREC}g}"
    return "0" if s in ("-0", "0") else s


def _v(a: np.ndarray) -> str:
    return " ".join(_f(x) for x in np.ravel(a))


def quat_wxyz_from_matrix(R: np.ndarray) -> np.ndarray:
    """(4,) unit quaternion ``w x y z`` of a rotation matrix ``R (3, 3)``, with w >= 0."""
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(np.asarray(R, float)).as_quat(scalar_first=True)
    return q if q[0] >= 0 else -q


def _frame_from_normal(n: np.ndarray) -> np.ndarray:
    """(3, 3) rotation whose z column is the unit vector ``n`` (identity for +z)."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    helper = np.array([0.0, 1.0, 0.0]) if abs(n[1]) < 0.9 else np.array([0.0, 0.0, 1.0])
    x = np.cross(helper, n)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(n, x), n])


def timestep_for(arr: Arrangement) -> float:
    """Time step for ``arr``: ``TIMESTEP * sqrt(L / REFERENCE_SIZE)`` clipped to
    ``TIMESTEP_RANGE``, with L the largest edge of the smallest cuboid."""
    if not arr.cuboids:
        return TIMESTEP
    L = float(arr.sizes.max(axis=1).min())
    return float(np.clip(TIMESTEP * np.sqrt(L / REFERENCE_SIZE), *TIMESTEP_RANGE))


def _pose_attrs(pos: np.ndarray, R: np.ndarray) -> str:
    q = quat_wxyz_from_matrix(R)
    if np.allclose(q, [1, 0, 0, 0], atol=1e-15):
        return f'pos="{_v(pos)}"'
    return f'pos="{_v(pos)}" quat="{_v(q)}"'


def arrangement_to_mjcf(arr: Arrangement, *, mu: float = DEFAULT_MU, welds: str = "exact",
                        model: str = "unseen", timestep: float | None = None) -> str:
    """MJCF text of an arrangement.

    Parameters
    ----------
    arr : Arrangement
    mu : float
        Coulomb friction of every geom (and so of every pair).
    welds : {"exact", "constraint"}
        How ``fixed`` contacts are modelled (see the module docstring).
    model : str
        The ``<mujoco model=...>`` name.
    timestep : float, optional
        Simulation step, seconds; default :func:`timestep_for`.

    Returns
    -------
    str
        The XML; ``mujoco.MjModel.from_xml_string`` compiles it.  Body ``bodyN`` is the
        N-th body of :func:`simulate.export.rigid_bodies`; geom names are the cuboid ids.
    """
    bodies, weld_list = rigid_bodies(arr, welds)
    dt = timestep_for(arr) if timestep is None else float(timestep)
    contact_solref = (CONTACT_TIMECONST_STEPS * dt, 1.0)
    weld_solref = (WELD_TIMECONST_STEPS * dt, 1.0)
    lines = [
        f"<mujoco model={quoteattr(model)}>",
        '  <compiler angle="radian" inertiafromgeom="true" autolimits="true"/>',
        f'  <option timestep="{_f(dt)}" gravity="0 0 {_f(-GRAVITY)}" cone="elliptic" '
        f'impratio="{_f(IMPRATIO)}" noslip_iterations="{NOSLIP_ITERATIONS}" '
        'integrator="implicitfast"/>',
        "  <default>",
        f'    <geom condim="3" friction="{_f(mu)} 0.005 0.0001" margin="0" gap="0" '
        f'solref="{_v(contact_solref)}" rgba="0.75 0.6 0.45 1"/>',
        "  </default>",
        "  <worldbody>",
    ]
    taken = set(arr.ids)
    for s in arr.supports:
        name = "support:" + s.id
        # geom names must be unique: a cuboid that happens to be called "support:..." wins
        name_attr = f"name={quoteattr(name)} " if name not in taken else ""
        lines.append(
            f'    <geom {name_attr}type="plane" size="0 0 1" '
            f'{_pose_attrs(s.point, _frame_from_normal(s.normal))} rgba="0.5 0.5 0.5 1"/>')
    sizes, centers, rots, dens = arr.sizes, arr.centers, arr.rotations, arr.densities
    for b in bodies:
        lines.append(f"    <body name={quoteattr(b.name)} {_pose_attrs(b.com, b.rotation)}>")
        if not b.static:
            lines.append(f"      <freejoint name={quoteattr(b.name + ':free')}/>")
        RbT = b.rotation.T
        for k in b.members:
            pos = RbT @ (centers[k] - b.com)
            R_local = RbT @ rots[k]
            lines.append(
                f'      <geom name={quoteattr(arr.cuboids[k].id)} type="box" '
                f'size="{_v(sizes[k] / 2)}" {_pose_attrs(pos, R_local)} '
                f'density="{_f(dens[k])}"/>')
        lines.append("    </body>")
    lines.append("  </worldbody>")
    if weld_list:
        lines.append("  <equality>")
        for w in weld_list:
            assert w.b is not None  # welds to the world were made static by rigid_bodies
            lines.append(
                f"    <weld body1={quoteattr(bodies[w.a].name)} body2={quoteattr(bodies[w.b].name)} "
                f'solref="{_v(weld_solref)}" solimp="{_v(WELD_SOLIMP)}"/>')
        lines.append("  </equality>")
    lines.append("</mujoco>")
    return "\n".join(lines) + "\n"
