"""MJCF export: compiles in MuJoCo, mass properties equal the closed form, ids survive."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline.model import Arrangement, Contact, Support, box, ground, rotation_about_axis
from simulate.export import rigid_bodies
from simulate.mjcf import arrangement_to_mjcf, quat_wxyz_from_matrix
from synth_scenes.random_arrangements import KINDS, cantilever, random_arrangement

mujoco = pytest.importorskip("mujoco")


def _compile(arr: Arrangement, **kw):
    model = mujoco.MjModel.from_xml_string(arrangement_to_mjcf(arr, **kw))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def _trimesh_props(arr: Arrangement, members: np.ndarray):
    """Mass, centre of mass and inertia about it of the union of boxes, by trimesh."""
    import trimesh

    meshes = []
    for k in members:
        c = arr.cuboids[k]
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = c.rotation, c.center
        m = trimesh.creation.box(extents=c.size, transform=T)
        m.density = c.density
        meshes.append(m)
    mass = sum(m.mass for m in meshes)
    com = sum(m.mass * m.center_mass for m in meshes) / mass
    inertia = np.zeros((3, 3))
    for m in meshes:
        d = m.center_mass - com
        inertia += m.moment_inertia + m.mass * (d @ d * np.eye(3) - np.outer(d, d))
    return mass, com, inertia


def _fused_table() -> Arrangement:
    R = rotation_about_axis((0.3, -0.2, 1.0), 0.4)  # tilted: the whole table is rotated
    top = box("top", (0, 0, 0.7), (1.2, 0.6, 0.04), R)
    legs = [box(f"leg{i}", R @ np.array([sx * 0.55, sy * 0.25, -0.35]) + [0, 0, 0.7],
                (0.05, 0.05, 0.66), R, density=700.0)
            for i, (sx, sy) in enumerate([(-1, -1), (1, -1), (1, 1), (-1, 1)])]
    contacts = tuple(Contact(f"leg{i}", "top", "fixed") for i in range(4))
    return Arrangement((top, *legs), (ground(),), contacts)


@pytest.mark.parametrize("seed", range(6))
def test_masses_and_coms_match_trimesh(seed: int) -> None:
    rng = np.random.default_rng(seed)
    arrs = [_fused_table()] + [random_arrangement(rng, k) for k in sorted(KINDS)]
    for arr in arrs:
        model, data = _compile(arr)
        bodies, _ = rigid_bodies(arr)
        assert model.nbody == len(bodies) + 1
        for b in bodies:
            mass, com, inertia = _trimesh_props(arr, b.members)
            bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, b.name)
            assert model.body_mass[bid] == pytest.approx(mass, rel=1e-9)
            scale = float(np.abs(arr.centers).max() + arr.sizes.max())
            np.testing.assert_allclose(data.xipos[bid], com, rtol=0, atol=1e-9 * scale)
            # principal moments (MuJoCo diagonalises the body inertia)
            np.testing.assert_allclose(np.sort(model.body_inertia[bid]),
                                       np.sort(np.linalg.eigvalsh(inertia)), rtol=1e-9,
                                       atol=1e-12 * mass * scale ** 2)
            # and the cuboids sit where the arrangement puts them
            for k in b.members:
                gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, arr.cuboids[k].id)
                np.testing.assert_allclose(data.geom_xpos[gid], arr.centers[k], atol=1e-10)
                np.testing.assert_allclose(data.geom_xmat[gid].reshape(3, 3), arr.rotations[k],
                                           atol=1e-10)
                np.testing.assert_allclose(model.geom_size[gid], arr.sizes[k] / 2, rtol=1e-11)


def test_static_and_free_bodies() -> None:
    arr = cantilever(0.8)  # column fixed to ground, beam fixed to column: all static
    model, _ = _compile(arr)
    assert model.nbody == 2 and model.njnt == 0
    arr = cantilever(0.8, column_fixed=False)  # one free body of two geoms
    model, _ = _compile(arr)
    assert model.nbody == 2 and model.njnt == 1 and model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
    assert model.body_geomnum[1] == 2


def test_constraint_welds_become_equalities() -> None:
    arr = _fused_table()
    model, _ = _compile(arr, welds="constraint")
    assert model.nbody == 6 and model.neq == 4
    assert all(model.eq_type[i] == mujoco.mjtEq.mjEQ_WELD for i in range(4))
    assert (model.eq_solref[:, 0] <= 2 * model.opt.timestep + 1e-12).all()


def test_options_from_measurements() -> None:
    model, _ = _compile(_fused_table())
    assert model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    assert model.opt.impratio == pytest.approx(10.0)
    assert model.opt.noslip_iterations == 0  # noslip glues separating contacts
    assert (model.geom_margin == 0).all() and (model.geom_gap == 0).all()
    assert model.opt.gravity[2] == pytest.approx(-9.81)
    assert np.allclose(model.geom_friction[:, 0], 0.7)


def test_weird_ids_survive_and_text_is_stable() -> None:
    ids = ['a "quoted" box', "it's <&> here", "with space", "ünïcode"]
    cubes = tuple(box(i, (0.3 * k, 0, 0.05), (0.1, 0.1, 0.1)) for k, i in enumerate(ids))
    arr = Arrangement(cubes, (ground(),))
    text = arrangement_to_mjcf(arr)
    assert text == arrangement_to_mjcf(arr)
    model, _ = _compile(arr)
    assert [model.geom(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, i)).name
            for i in ids] == ids


def test_walls_are_one_sided_planes_along_their_normal() -> None:
    wall = Support("wall:0", (2.0, 0.0, 0.0), (-1.0, 0.0, 0.0))
    arr = Arrangement((box("b", (1.5, 0, 0.5), (1, 1, 1)),), (ground(), wall))
    model, data = _compile(arr)
    gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "support:wall:0")
    assert model.geom_type[gid] == mujoco.mjtGeom.mjGEOM_PLANE
    np.testing.assert_allclose(data.geom_xmat[gid].reshape(3, 3)[:, 2], [-1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(data.geom_xpos[gid], [2, 0, 0], atol=1e-12)


def test_quaternion_convention_wxyz() -> None:
    q = quat_wxyz_from_matrix(rotation_about_axis((0, 0, 1), np.pi / 2))
    np.testing.assert_allclose(q, [np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)], atol=1e-15)
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, q)
    np.testing.assert_allclose(R.reshape(3, 3), rotation_about_axis((0, 0, 1), np.pi / 2),
                               atol=1e-15)


def test_cuboid_named_like_a_support_geom_still_compiles() -> None:
    arr = Arrangement((box("support:ground", (0, 0, 0.05), (0.1, 0.1, 0.1)),), (ground(),))
    model, _ = _compile(arr)
    gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "support:ground")
    assert model.geom_type[gid] == mujoco.mjtGeom.mjGEOM_BOX


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(-np.pi, np.pi), st.floats(-2.0, 2.0))
def test_rigid_bodies_partition_and_conserve_mass(seed: int, yaw: float, shift: float) -> None:
    """Property: bodies partition the cuboids, conserve mass and move with the scene."""
    from synth_scenes.random_arrangements import with_yaw

    arr = random_arrangement(np.random.default_rng(seed))
    bodies, _ = rigid_bodies(arr)
    members = np.sort(np.concatenate([b.members for b in bodies]))
    assert np.array_equal(members, np.arange(len(arr.cuboids)))
    assert sum(b.mass for b in bodies) == pytest.approx(float(arr.masses.sum()), rel=1e-12)
    moved = with_yaw(arr, yaw)
    moved = moved.with_(cuboids=tuple(c.with_(center=c.center + [shift, 0, 0])
                                      for c in moved.cuboids))
    Rz = rotation_about_axis((0, 0, 1), yaw)
    for b, m in zip(bodies, rigid_bodies(moved)[0], strict=True):
        assert np.array_equal(b.members, m.members) and b.static == m.static
        np.testing.assert_allclose(m.com, Rz @ b.com + [shift, 0, 0], atol=1e-12)
        np.testing.assert_allclose(m.inertia, Rz @ b.inertia @ Rz.T,
                                   atol=1e-12 * max(1.0, float(np.abs(b.inertia).max())))
