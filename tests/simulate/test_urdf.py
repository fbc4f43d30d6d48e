"""URDF export: loads in PyBullet with file inertias, parses with yourdfpy, ids survive."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipeline.model import Arrangement, Contact, box, ground, rotation_about_axis
from simulate.export import rigid_bodies
from simulate.urdf import arrangement_to_urdf_files, rpy_from_matrix
from synth_scenes.random_arrangements import KINDS, random_arrangement

pybullet = pytest.importorskip("pybullet")
yourdfpy = pytest.importorskip("yourdfpy")

WEIRD = ['a "quoted" box', "it's <&> here", "with space"]


@pytest.fixture
def client():
    cid = pybullet.connect(pybullet.DIRECT)
    yield cid
    pybullet.disconnect(cid)


def _write(arr: Arrangement, folder: Path, **kw) -> dict[str, Path]:
    out = {}
    for rel, text in arrangement_to_urdf_files(arr, **kw).items():
        path = folder / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
        out[rel] = path
    return out


def _fused_l() -> Arrangement:
    R = rotation_about_axis((1.0, 2.0, 3.0), 0.7)
    a = box(WEIRD[0], (0, 0, 1), (0.6, 0.1, 0.1), R)
    b = box(WEIRD[1], R @ np.array([0.35, 0.0, 0.2]) + [0, 0, 1], (0.1, 0.1, 0.5), R,
            density=300.0)
    c = box(WEIRD[2], (3, 0, 0.05), (0.1, 0.2, 0.1))
    return Arrangement((a, b, c), (ground(),), (Contact(WEIRD[0], WEIRD[1], "fixed"),
                                                Contact(WEIRD[2], "ground")))


def test_loads_in_pybullet_with_file_inertia(client, tmp_path: Path) -> None:
    rng = np.random.default_rng(7)
    arrs = [_fused_l()] + [random_arrangement(rng, k) for k in sorted(KINDS)]
    for n, arr in enumerate(arrs):
        files = _write(arr, tmp_path / str(n))
        bodies, _ = rigid_bodies(arr)
        pybullet.loadURDF(str(files["urdf/world.urdf"]), useFixedBase=True,
                          physicsClientId=client)
        for b in bodies:
            if b.static:
                assert f"urdf/{b.name}.urdf" not in files
                continue
            uid = pybullet.loadURDF(str(files[f"urdf/{b.name}.urdf"]),
                                    flags=pybullet.URDF_USE_INERTIA_FROM_FILE,
                                    physicsClientId=client)
            info = pybullet.getDynamicsInfo(uid, -1, physicsClientId=client)
            # independent truth: volume x density of the member boxes
            mass = float(sum(np.prod(arr.cuboids[k].size) * arr.cuboids[k].density
                             for k in b.members))
            assert info[0] == pytest.approx(mass, rel=1e-9)
            pos, _ = pybullet.getBasePositionAndOrientation(uid, physicsClientId=client)
            m = np.array([np.prod(arr.cuboids[k].size) * arr.cuboids[k].density
                          for k in b.members])
            com = (m[:, None] * arr.centers[b.members]).sum(0) / m.sum()
            np.testing.assert_allclose(pos, com, atol=1e-9)
            # principal inertia: PyBullet diagonalises the file's full tensor (float32 inside)
            np.testing.assert_allclose(np.sort(info[2]), np.sort(np.linalg.eigvalsh(b.inertia)),
                                       rtol=1e-5)
            shapes = pybullet.getCollisionShapeData(uid, -1, physicsClientId=client)
            assert len(shapes) == len(b.members)
            assert info[1] == pytest.approx(np.sqrt(0.7), rel=1e-9)  # lateral friction
            assert info[5] == 0.0  # restitution


def test_yourdfpy_parses_scene_and_ids_survive(tmp_path: Path) -> None:
    files = _write(_fused_l(), tmp_path)
    robot = yourdfpy.URDF.load(str(files["scene.urdf"]), build_scene_graph=True,
                               load_meshes=False)
    names = {c.name for link in robot.robot.links for c in link.collisions}
    assert set(WEIRD) <= names
    joints = {j.name: j.type for j in robot.robot.joints}
    assert joints == {"support:ground:joint": "fixed", "body0:joint": "floating",
                      "body1:joint": "floating"}
    for rel, path in files.items():
        if rel != "scene.urdf":
            yourdfpy.URDF.load(str(path), load_meshes=False)  # every file parses


def test_fused_group_is_one_link_never_a_cycle(tmp_path: Path) -> None:
    # four boxes fused in a ring (a weld cycle) become one link
    cubes = [box(f"r{i}", c, (0.1, 0.1, 0.1)) for i, c in
             enumerate([(0, 0, 0.05), (0.1, 0, 0.05), (0.1, 0.1, 0.05), (0, 0.1, 0.05)])]
    ring = [Contact("r0", "r1", "fixed"), Contact("r1", "r2", "fixed"),
            Contact("r2", "r3", "fixed"), Contact("r3", "r0", "fixed")]
    files = _write(Arrangement(tuple(cubes), (ground(),), tuple(ring)), tmp_path)
    assert sorted(files) == ["scene.urdf", "urdf/body0.urdf", "urdf/world.urdf"]
    robot = yourdfpy.URDF.load(str(files["urdf/body0.urdf"]), load_meshes=False)
    assert len(robot.robot.links) == 1 and len(robot.robot.links[0].collisions) == 4


def test_rpy_round_trip() -> None:
    from scipy.spatial.transform import Rotation

    Rs = Rotation.random(500, random_state=3).as_matrix()
    gimbal = [Rotation.from_euler("xyz", [0.3, s * np.pi / 2, -1.1]).as_matrix() for s in (1, -1)]
    for R in [*Rs, *gimbal]:
        r, p, y = rpy_from_matrix(R)
        # URDF: R = Rz(yaw) Ry(pitch) Rx(roll)
        back = (rotation_about_axis((0, 0, 1), y) @ rotation_about_axis((0, 1, 0), p)
                @ rotation_about_axis((1, 0, 0), r))
        np.testing.assert_allclose(back, R, atol=1e-12)
