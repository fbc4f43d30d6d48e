"""Arrangement -> URDF texts, pure functions with no engine import.

URDF is a tree and has no free-floating joint that PyBullet honours (it turns
``floating`` into ``fixed``), so an export is several files:

``scene.urdf``
    The whole scene as one tree for viewers and ``yourdfpy``: a root link ``world``;
    every support a slab link (``box`` of ``SUPPORT_SPAN`` x ``SUPPORT_SPAN`` x
    ``SUPPORT_THICKNESS`` scene extents, top face on the support plane) and every static
    body a link on ``fixed`` joints; every free body a link on a ``floating`` joint.
``urdf/world.urdf``
    What PyBullet loads with ``useFixedBase``: one link holding the supports as slabs
    (as PyBullet's own ``plane.urdf`` does: a wide, thick box whose top face is the
    plane; PyBullet's ``<plane>`` extension would be a true half-space but ``yourdfpy``
    and other URDF readers reject it) and the boxes of every static body.
``urdf/<body>.urdf``
    One file per free rigid body: one link whose frame is the world frame at export
    time (so loading it at the origin puts it in place), a ``box`` collision and visual
    per cuboid, named by the cuboid id (XML-escaped, any id survives), and an explicit
    ``<inertial>`` (mass, centre of mass, full inertia tensor in world axes): load it
    with ``URDF_USE_INERTIA_FROM_FILE``, otherwise PyBullet approximates a link of
    several boxes by its bounding box.

A fused group is always one link (never a cycle of fixed joints).  PyBullet multiplies
the two bodies' friction coefficients, so every link gets ``sqrt(mu)`` (supports too)
in a ``<contact>`` block with restitution 0 and no rolling or spinning friction.
Rotations are written as URDF ``rpy`` (fixed-axis x, then y, then z; radians),
converted here and only here.
"""

from __future__ import annotations

from xml.sax.saxutils import quoteattr

import numpy as np

from pipeline.constants import DEFAULT_MU
from pipeline.model import Arrangement

from .bodies import RigidBody, rigid_bodies, scene_extent
from .mjcf import _f, _frame_from_normal, _v

#: Edge of the square slab that stands for a support, in scene extents (at least 1 m).
SUPPORT_SPAN = 4.0
#: Thickness of that slab, in scene extents (thick, so nothing tunnels through it).
SUPPORT_THICKNESS = 0.5


def rpy_from_matrix(R: np.ndarray) -> np.ndarray:
    """(3,) URDF roll, pitch, yaw (radians) with ``R = Rz(yaw) Ry(pitch) Rx(roll)``.

    At gimbal lock (pitch = +-90 degrees) roll is set to 0 and yaw absorbs the rest.
    """
    R = np.asarray(R, float)
    pitch = float(np.arctan2(-R[2, 0], np.hypot(R[0, 0], R[1, 0])))
    if np.hypot(R[0, 0], R[1, 0]) > 1e-9:
        roll = float(np.arctan2(R[2, 1], R[2, 2]))
        yaw = float(np.arctan2(R[1, 0], R[0, 0]))
    else:  # cos(pitch) = 0: R = [[0, s(r-y)*sp..]]; pick roll = 0
        roll = 0.0
        yaw = float(np.arctan2(-R[0, 1], R[1, 1]))
    return np.array([roll, pitch, yaw])


def _origin(pos: np.ndarray, R: np.ndarray) -> str:
    return f'<origin xyz="{_v(pos)}" rpy="{_v(rpy_from_matrix(R))}"/>'


def _contact(mu: float) -> str:
    return (f'<contact><lateral_friction value="{_f(np.sqrt(mu))}"/>'
            '<rolling_friction value="0"/><spinning_friction value="0"/>'
            '<restitution value="0"/></contact>')


def _inertial(b: RigidBody) -> str:
    I = b.inertia
    return (f'<inertial><origin xyz="{_v(b.com)}" rpy="0 0 0"/><mass value="{_f(b.mass)}"/>'
            f'<inertia ixx="{_f(I[0, 0])}" ixy="{_f(I[0, 1])}" ixz="{_f(I[0, 2])}" '
            f'iyy="{_f(I[1, 1])}" iyz="{_f(I[1, 2])}" izz="{_f(I[2, 2])}"/></inertial>')


_ZERO_INERTIAL = ('<inertial><origin xyz="0 0 0" rpy="0 0 0"/><mass value="0"/>'
                  '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>')


def _boxes(arr: Arrangement, members: np.ndarray, indent: str) -> list[str]:
    out = []
    for k in members:
        c = arr.cuboids[k]
        geo = f'<geometry><box size="{_v(c.size)}"/></geometry>'
        org = _origin(c.center, c.rotation)
        name = quoteattr(c.id)
        out.append(f"{indent}<collision name={name}>{org}{geo}</collision>")
        out.append(f"{indent}<visual name={name}>{org}{geo}"
                   f'<material name="box"><color rgba="0.75 0.6 0.45 1"/></material></visual>')
    return out


def body_urdf(arr: Arrangement, body: RigidBody, *, mu: float = DEFAULT_MU) -> str:
    """URDF of one rigid body: a single link in world coordinates with explicit inertia."""
    lines = [f"<robot name={quoteattr(body.name)}>",
             f"  <link name={quoteattr(body.name)}>",
             f"    {_contact(mu)}",
             f"    {_inertial(body)}"]
    lines += _boxes(arr, body.members, "    ")
    lines += ["  </link>", "</robot>"]
    return "\n".join(lines) + "\n"


def world_urdf(arr: Arrangement, bodies: list[RigidBody], *, mu: float = DEFAULT_MU) -> str:
    """URDF of everything static, for PyBullet (supports as ``<plane>`` half-spaces)."""
    lines = ['<robot name="world">', '  <link name="world">', f"    {_contact(mu)}",
             f"    {_ZERO_INERTIAL}"]
    for s in arr.supports:
        lines.append(f"    <collision name={quoteattr('support:' + s.id)}>"
                     f"{_slab(arr, s)}</collision>")
    for b in bodies:
        if b.static:
            lines += _boxes(arr, b.members, "    ")
    lines += ["  </link>", "</robot>"]
    return "\n".join(lines) + "\n"


def _slab(arr: Arrangement, s) -> str:
    """``<origin/><geometry/>`` of the slab standing for support ``s``."""
    ext = scene_extent(arr)
    span, thick = SUPPORT_SPAN * ext, SUPPORT_THICKNESS * ext
    centre = s.point - s.normal * (thick / 2)
    return (f"{_origin(centre, _frame_from_normal(s.normal))}"
            f'<geometry><box size="{_f(span)} {_f(span)} {_f(thick)}"/></geometry>')


def scene_urdf(arr: Arrangement, bodies: list[RigidBody], *, mu: float = DEFAULT_MU,
               welds: list | None = None) -> str:
    """The whole scene as one URDF tree (supports as slabs, free bodies ``floating``)."""
    lines = ['<robot name="scene">',
             "  <!-- PyBullet turns floating joints into fixed ones: to simulate, load",
             "       urdf/world.urdf (useFixedBase) and urdf/<body>.urdf for each free body. -->",
             '  <link name="world"/>']
    for s in arr.supports:
        link = "support:" + s.id
        lines += [f"  <link name={quoteattr(link)}>", f"    {_contact(mu)}",
                  f"    {_ZERO_INERTIAL}"]
        lines += [f"    <collision>{_slab(arr, s)}</collision>",
                  f"    <visual>{_slab(arr, s)}"
                  '<material name="support"><color rgba="0.5 0.5 0.5 1"/></material></visual>',
                  "  </link>",
                  f"  <joint name={quoteattr(link + ':joint')} type=\"fixed\">"
                  f'<parent link="world"/><child link={quoteattr(link)}/></joint>']
    for b in bodies:
        lines += [f"  <link name={quoteattr(b.name)}>", f"    {_contact(mu)}",
                  f"    {_inertial(b)}"]
        lines += _boxes(arr, b.members, "    ")
        kind = "fixed" if b.static else "floating"
        lines += ["  </link>",
                  f"  <joint name={quoteattr(b.name + ':joint')} type=\"{kind}\">"
                  f'<parent link="world"/><child link={quoteattr(b.name)}/></joint>']
    for w in welds or []:
        lines.append(f"  <!-- weld constraint: {bodies[w.a].name} - {bodies[w.b].name} -->")
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


def arrangement_to_urdf_files(arr: Arrangement, *, mu: float = DEFAULT_MU,
                              welds: str = "exact") -> dict[str, str]:
    """Every URDF file of an export: relative path -> text.

    Returns
    -------
    dict
        ``scene.urdf``, ``urdf/world.urdf`` and ``urdf/<body>.urdf`` for every free body
        (``<body>`` = :attr:`simulate.export.RigidBody.name`).
    """
    bodies, weld_list = rigid_bodies(arr, welds)
    files = {"scene.urdf": scene_urdf(arr, bodies, mu=mu, welds=weld_list),
             "urdf/world.urdf": world_urdf(arr, bodies, mu=mu)}
    for b in bodies:
        if not b.static:
            files[f"urdf/{b.name}.urdf"] = body_urdf(arr, b, mu=mu)
    return files
