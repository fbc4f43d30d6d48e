"""``unseen import``: MJCF / URDF of boxes -> arrangement.

Round trips through our own exporters (same boxes, contacts, supports, verdicts), a
hand-written MJCF checked against boxes computed by hand, and refused inputs.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from pipeline.arrangement_io import read_arrangement
from pipeline.contacts import find_contacts
from pipeline.errors import InputError
from pipeline.model import Arrangement, Contact, Cuboid, rotation_about_z
from pipeline.stability import check_stability
from simulate.export import export_all
from simulate.importers import (
    arrangement_from_mjcf,
    arrangement_from_urdf,
    fit_densities,
    import_scene,
)
from synth_scenes import families
from synth_scenes import random_arrangements as ra

UNSEEN = [sys.executable, "-m", "eval.cli"]


def _with_densities(arr: Arrangement, densities) -> Arrangement:
    return arr.with_(cuboids=tuple(c.with_(density=float(d))
                                   for c, d in zip(arr.cuboids, densities)))


def _scenes() -> dict[str, Arrangement]:
    """Small scenes of every kind the exporters treat differently."""
    rng = np.random.default_rng
    return {
        "stack": _with_densities(families.make_stack(rng(1), n_boxes=4), (300, 800, 1500, 2700)),
        "table": families.make_table(rng(0)),  # 5 parts fused into one free body
        "wall_shelf": families.make_wall_shelf(rng(2)),  # boards fused to wall:0 (static)
        "plank": ra.leaning_plank(30.0),  # on the ground and against a wall
        "plank_falls": ra.leaning_plank(12.0),
        "yawed_falls": ra.yawed_on_edge(0.02),  # a rotated box past its edge
        "trap": ra.side_friction_trap(),  # two static groups fused to the ground
        "cantilever": ra.cantilever(0.6),
        "furniture": ra.random_arrangement(rng(3), "furniture"),
        "counterweight": ra.random_arrangement(rng(2), "counterweight"),  # mixed densities
        "room": families.make_room(rng(0)),  # 46 boxes, two walls, static furniture
    }


SCENES = _scenes()


def _match(a: Arrangement, b: Arrangement, tol: float = 1e-6) -> np.ndarray:
    """Row of ``b`` for every box of ``a``, comparing the 8 corners as sets (so a box
    whose axes are relabelled is the same box); asserts every box has its twin."""
    assert len(a.cuboids) == len(b.cuboids)
    A, B = a.corners, b.corners  # (K, 8, 3)
    d = np.linalg.norm(A[:, None, :, None, :] - B[None, :, None, :, :], axis=-1)
    D = np.maximum(d.min(axis=3).max(axis=2), d.min(axis=2).max(axis=2))  # Hausdorff
    rows, cols = linear_sum_assignment(D)
    assert D[rows, cols].max() < tol, f"boxes differ by {D[rows, cols].max():.3g} m"
    np.testing.assert_allclose(a.centers, b.centers[cols], atol=tol)
    np.testing.assert_allclose(a.sizes.prod(axis=1), b.sizes[cols].prod(axis=1), rtol=1e-9)
    return cols


def _canonical(arr: Arrangement) -> dict[tuple[str, str], str]:
    """Every geometric contact typed by the rigid bodies the listed ``fixed`` contacts
    make (all supports one world node): ``fixed`` inside a body, ``touch`` between.
    Two files with the same canonical graph are the same physical scene."""
    K = len(arr.cuboids)
    node = {**arr.index, **{s: K for s in arr.support_ids}}
    e = np.array([(node[c.a], node[c.b]) for c in arr.contacts if c.type == "fixed"]
                 ).reshape(-1, 2).T
    label = connected_components(coo_matrix((np.ones(e.shape[1]), e), shape=(K + 1, K + 1)),
                                 directed=False)[1]
    cs = find_contacts(arr)
    return {tuple(sorted((cs.names[i], cs.names[j]))):
            "fixed" if label[node[cs.names[i]]] == label[node[cs.names[j]]] else "touch"
            for i, j in zip(cs.a.tolist(), cs.b.tolist())}


def _assert_same_scene(orig: Arrangement, back: Arrangement) -> None:
    cols = _match(orig, back)
    assert [back.cuboids[c].id for c in cols] == list(orig.ids)  # geoms are named by id
    np.testing.assert_allclose(back.densities[cols], orig.densities, rtol=1e-9)
    assert back.support_ids == orig.support_ids
    for s in orig.supports:
        t = back.support(s.id)
        np.testing.assert_allclose(t.normal, s.normal, atol=1e-9)
        assert abs((t.point - s.point) @ s.normal) < 1e-9
    assert _canonical(back) == _canonical(orig)
    assert back.meta["mu"] == pytest.approx(0.7, abs=1e-12)
    a, b = check_stability(orig), check_stability(back)
    assert a.stable == b.stable
    assert sorted(a.unstable_ids) == sorted(b.unstable_ids)


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("exported")
    for name, arr in SCENES.items():
        export_all(arr, root / name)
    return {name: root / name for name in SCENES}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_mjcf_round_trip(exported, name):
    back = arrangement_from_mjcf(exported[name] / "scene.xml")
    _assert_same_scene(SCENES[name], back)
    assert back.meta["source"] == {"path": str(exported[name] / "scene.xml"), "format": "mjcf"}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_urdf_round_trip(exported, name):
    back = arrangement_from_urdf(exported[name] / "scene.urdf")
    _assert_same_scene(SCENES[name], back)


@pytest.mark.parametrize("name", ["table", "wall_shelf", "cantilever"])
def test_mjcf_weld_constraints_fuse_bodies(tmp_path, name):
    """``--welds constraint`` writes one body per box and <weld> equalities: the import
    fuses welded bodies again (a weld to the world makes them static)."""
    export_all(SCENES[name], tmp_path, welds="constraint")
    _assert_same_scene(SCENES[name], import_scene(tmp_path / "scene.xml"))


def test_round_trip_keeps_listed_contacts_exactly(exported):
    """Where the original lists every touching pair and nothing is redundant, the
    imported contact list is the same set, types included."""
    for name in ("table", "stack", "plank", "cantilever", "wall_shelf", "trap"):
        orig = SCENES[name]
        for f in ("scene.xml", "scene.urdf"):
            back = import_scene(exported[name] / f)
            assert {(c.key, c.type) for c in back.contacts} == \
                {(c.key, c.type) for c in orig.contacts}, (name, f)


def test_verdicts_differ_across_scenes():
    """The round trip set holds stable and unstable scenes (so equal verdicts mean something)."""
    verdicts = {n: check_stability(a).stable for n, a in SCENES.items()}
    assert verdicts["plank"] and verdicts["table"] and verdicts["cantilever"]
    assert not verdicts["plank_falls"] and not verdicts["yawed_falls"]
    assert not verdicts["trap"]


def test_mixed_densities_in_one_body(tmp_path):
    """MJCF states every geom's density; URDF one mass, centre of mass and inertia per
    link, from which the import recovers the densities of the link's boxes."""
    table = SCENES["table"]
    arr = _with_densities(table, [600.0] + [900.0] * (len(table.cuboids) - 1))
    export_all(arr, tmp_path)
    for f in ("scene.xml", "scene.urdf"):
        back = import_scene(tmp_path / f)
        np.testing.assert_allclose(back.densities[_match(arr, back)], arr.densities, rtol=1e-9)


def test_fit_densities_recovers_mass_properties():
    """Boxes of random densities: their mass, first moment and inertia give the
    densities back; mass properties no boxes can have give the uniform density."""
    rng = np.random.default_rng(7)
    from scipy.spatial.transform import Rotation

    from simulate.bodies import rigid_bodies

    for n in (1, 2, 4, 7):
        cuboids = tuple(Cuboid(f"q{k}", rng.uniform(-1, 1, 3), Rotation.random(
            random_state=rng).as_matrix(), rng.uniform(0.1, 0.5, 3), rng.uniform(200, 3000))
            for k in range(n))
        arr = Arrangement(cuboids, (), tuple(Contact(f"q{k}", f"q{k + 1}", "fixed")
                                             for k in range(n - 1)))
        body = rigid_bodies(arr)[0][0]
        rho = fit_densities(body.mass, body.com, body.inertia, arr.centers, arr.rotations,
                            arr.sizes)
        np.testing.assert_allclose(rho, arr.densities, rtol=1e-9)
        wrong = fit_densities(body.mass, body.com + 0.3, body.inertia, arr.centers,
                              arr.rotations, arr.sizes)
        np.testing.assert_allclose(wrong, body.mass / arr.sizes.prod(axis=1).sum())


@pytest.mark.parametrize("name,stable", [("plank", True), ("yawed_falls", False)])
def test_mujoco_verdict_survives_round_trip(exported, name, stable):
    from simulate.engines import settle

    back = import_scene(exported[name] / "scene.xml")
    a, b = settle(SCENES[name], "mujoco"), settle(back, "mujoco")
    assert a.stable is b.stable is stable
    np.testing.assert_allclose(b.centers, a.centers, atol=1e-9)  # the same simulation


HAND_MJCF = """\
<mujoco model="hand">
  <compiler angle="degree"/>
  <default>
    <geom friction="0.6 0.005 0.0001"/>
    <default class="brick">
      <geom type="box" size="0.1 0.05 0.025" density="500"/>
    </default>
  </default>
  <worldbody>
    <include file="floor.xml"/>
    <body name="base" pos="0 0 0.025" euler="0 0 90">
      <freejoint/>
      <geom name="brick0" class="brick"/>
      <body name="top" pos="0.05 0 0.05" euler="0 0 90">
        <geom name="brick1" class="brick"/>
      </body>
    </body>
    <body name="turned" pos="0.5 0 0.05" axisangle="0 0 1 30">
      <freejoint/>
      <geom name="cube" type="box" size="0.05 0.05 0.05"/>
      <geom name="eye" type="box" size="0.01 0.01 0.01" contype="0" conaffinity="0"/>
    </body>
    <body name="post" pos="-0.5 0 0.2">
      <geom name="pillar" type="box" size="0.05 0.05 0.2" euler="0 0 45"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_hand_written_mjcf(tmp_path):
    """Default classes, an include, euler and axisangle in degrees, a nested body."""
    p = tmp_path / "hand.xml"
    p.write_text(HAND_MJCF)
    (tmp_path / "floor.xml").write_text(
        '<mujoco><geom name="floor" type="plane" size="2 2 0.1"/></mujoco>')
    arr = import_scene(p)
    assert arr.ids == ("brick0", "brick1", "cube", "pillar")  # the visual-only geom skipped
    want = {  # centre, rotation, full size, density, object, worked out by hand
        "brick0": ((0, 0, 0.025), rotation_about_z(np.pi / 2), (0.2, 0.1, 0.05), 500, "base"),
        # top's frame: base's pose composed with pos (0.05, 0, 0.05) and a further 90 deg
        "brick1": ((0, 0.05, 0.075), rotation_about_z(np.pi), (0.2, 0.1, 0.05), 500, "base"),
        "cube": ((0.5, 0, 0.05), rotation_about_z(np.pi / 6), (0.1, 0.1, 0.1), 1000, "turned"),
        "pillar": ((-0.5, 0, 0.2), rotation_about_z(np.pi / 4), (0.1, 0.1, 0.4), 1000, "post"),
    }
    for cid, (c, R, s, rho, obj) in want.items():
        box = arr.cuboid(cid)
        np.testing.assert_allclose(box.center, c, atol=1e-12)
        np.testing.assert_allclose(box.rotation, R, atol=1e-12)
        np.testing.assert_allclose(box.size, s, rtol=1e-12)
        assert box.density == rho and box.object == obj
    assert arr.support_ids == ("ground",)
    np.testing.assert_allclose(arr.supports[0].normal, (0, 0, 1), atol=1e-12)
    assert {(c.key, c.type) for c in arr.contacts} == {
        (("brick0", "ground"), "touch"), (("brick0", "brick1"), "fixed"),
        (("cube", "ground"), "touch"), (("ground", "pillar"), "fixed")}
    assert arr.meta["mu"] == 0.6
    assert check_stability(arr, mu=0.6).stable


HAND_URDF = """\
<robot name="hand">
  <link name="world"/>
  <link name="floor">
    <collision name="support:ground"><origin xyz="0 0 -0.05"/><geometry><box size="2 2 0.1"/></geometry></collision>
  </link>
  <joint name="to_floor" type="fixed"><parent link="world"/><child link="floor"/></joint>
  <link name="crate">
    <inertial><origin xyz="0 0 0.1"/><mass value="4"/>
      <inertia ixx="0.0266666666667" iyy="0.0266666666667" izz="0.0266666666667" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision name="bin"><origin xyz="0 0 0.1" rpy="0 0 0.5"/><geometry><box size="0.2 0.2 0.2"/></geometry></collision>
  </link>
  <joint name="free" type="floating"><parent link="world"/><child link="crate"/><origin xyz="1 0 0"/></joint>
  <link name="lid">
    <inertial><mass value="0.8"/>
      <inertia ixx="0.00269333333333" iyy="0.00269333333333" izz="0.00533333333333" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision name="lid"><geometry><box size="0.2 0.2 0.02"/></geometry></collision>
  </link>
  <joint name="shut" type="fixed"><parent link="crate"/><child link="lid"/><origin xyz="0 0 0.21" rpy="0 0 0.5"/></joint>
</robot>
"""


def test_hand_written_urdf(tmp_path):
    """A floating link with a child on a fixed joint is one free body of two fused boxes;
    the slab named support:ground is the ground, its top face the plane."""
    p = tmp_path / "hand.urdf"
    p.write_text(HAND_URDF)
    arr = import_scene(p)
    R = rotation_about_z(0.5)
    for cid, c, s in (("bin", (1, 0, 0.1), (0.2, 0.2, 0.2)), ("lid", (1, 0, 0.21), (0.2, 0.2, 0.02))):
        box = arr.cuboid(cid)
        np.testing.assert_allclose(box.center, c, atol=1e-12)
        np.testing.assert_allclose(box.rotation, R, atol=1e-12)
        np.testing.assert_allclose(box.size, s, rtol=1e-12)
        assert box.object == "crate"
    # densities from each link's mass, centre of mass and inertia: 4 kg and 0.8 kg boxes
    assert (arr.cuboid("bin").density, arr.cuboid("lid").density) == (500.0, 1000.0)
    assert arr.support_ids == ("ground",)
    np.testing.assert_allclose(arr.supports[0].point, (0, 0, 0), atol=1e-12)
    np.testing.assert_allclose(arr.supports[0].normal, (0, 0, 1), atol=1e-12)
    assert {(c.key, c.type) for c in arr.contacts} == {
        (("bin", "lid"), "fixed"), (("bin", "ground"), "touch")}
    assert "mu" not in arr.meta  # the file states no friction


def _mjcf(body: str) -> str:
    return (f'<mujoco><worldbody><geom name="floor" type="plane" size="1 1 1"/>{body}'
            "</worldbody></mujoco>")


@pytest.mark.parametrize("body,match", [
    ('<body name="ball" pos="0 0 1"><freejoint/><geom type="sphere" size="0.1"/></body>',
     r"body 'ball' is a sphere; unseen handles boxes only"),
    ('<body name="arm" pos="0 0 1"><joint type="hinge"/><geom type="box" size=".1 .1 .1"/>'
     "</body>", r"body 'arm' has a hinge joint"),
    ('<body name="two" pos="0 0 1"><freejoint/><geom name="p" type="box" size=".1 .1 .1"/>'
     '<geom name="q" type="box" size=".1 .1 .1" pos="1 0 0"/></body>',
     r"geom 'p' of body 'two' and geom 'q' of body 'two' are one rigid body but do not touch"),
    ('<body name="lap" pos="0 0 1"><freejoint/><geom name="p" type="box" size=".1 .1 .1"/>'
     '<geom name="q" type="box" size=".1 .1 .1" pos=".1 0 0"/></body>', r"overlap by 0.1 m"),
    ('<body name="a" pos="0 0 1"><freejoint/><geom type="box" size=".1 .1 .1"/></body>'
     '</worldbody><equality><connect body1="a" anchor="0 0 0"/></equality><worldbody>',
     r"a connect equality constraint; unseen models rigid welds only"),
    ('<body name="hang" pos="0 0 1"><geom name="lamp" type="box" size=".1 .1 .1"/></body>',
     r"geom 'lamp' of body 'hang' is welded to the world but touches no ground or wall"),
    ('<body pos="0 0 1"><freejoint/><geom type="sphere" size="0.1"/></body>',
     r"geom #1 of an unnamed body is a sphere"),
    ('<body name="b" pos="0 0 0.1"><freejoint/><geom type="box" size=".1 .1 1e400"/></body>',
     r"<geom> size='.1 .1 1e400' holds NaN or infinity"),
])
def test_refused_scenes(tmp_path, body, match):
    p = tmp_path / "scene.xml"
    p.write_text(_mjcf(body))
    with pytest.raises(InputError, match=match):
        import_scene(p)


def test_names_that_read_as_numbers_are_names(tmp_path):
    # "inf" and "nan" in a name attribute are names; only numeric attributes are checked
    p = tmp_path / "scene.xml"
    p.write_text(_mjcf('<body name="inf" pos="0 0 0.1"><freejoint/>'
                       '<geom name="nan" type="box" size=".1 .1 .1"/></body>'))
    arr = import_scene(p)
    assert [(c.id, c.object) for c in arr.cuboids] == [("nan", "inf")]


def _cli(*args):
    return subprocess.run(UNSEEN + ["import", *map(str, args)], capture_output=True, text=True,
                          timeout=120)


def test_cli_writes_arrangement_and_summary(exported, tmp_path):
    out = tmp_path / "arr.json"
    r = _cli(exported["table"] / "scene.xml", "--out", out)
    assert r.returncode == 0, r.stderr
    assert r.stdout.count("\n") == 1
    assert "12 cuboids in 8 bodies (0 static), 15 contacts of which 4 fixed" in r.stdout
    back = read_arrangement(out)
    _match(SCENES["table"], back)
    assert not list(tmp_path.glob(".*"))  # no temporary file left behind


@pytest.mark.parametrize("content,match", [
    (b"hello world\n", "not an XML file"),
    (_mjcf('<body name="ball"><freejoint/><geom type="sphere" size="0.1"/></body>').encode(),
     "is a sphere"),
    (b"<robot name='r'><link name='a'><collision><geometry><cylinder radius='1' length='1'/>"
     b"</geometry></collision></link></robot>", "is a cylinder"),
    (b"<robot name='r'><link name='p'><collision><geometry><plane normal='0 0 1'/>"
     b"</geometry></collision></link></robot>", "a URDF <plane>"),
    (b"<scene/>", "neither MJCF <mujoco> nor URDF <robot>"),
    (None, "no such file"),
])
def test_cli_bad_input_one_line_exit_2(tmp_path, content, match):
    p = tmp_path / "in.xml"
    if content is not None:
        p.write_bytes(content)
    out = tmp_path / "out.json"
    r = _cli(p, "--out", out)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert r.stderr.startswith("unseen import: error: ") and match in r.stderr, r.stderr
    assert not out.exists()
    if content is not None:
        assert p.read_bytes() == content  # the input is never modified


def test_cli_refuses_to_overwrite_its_input(exported):
    src = exported["stack"] / "scene.xml"
    before = src.read_bytes()
    r = _cli(src, "--out", src)
    assert r.returncode == 2 and "is the input file" in r.stderr
    assert src.read_bytes() == before


def test_cli_replaces_an_arrangement_but_never_another_file(exported, tmp_path):
    # an earlier import (an arrangement) is replaced by the new one; a user's file of any
    # other kind (a scan) is left byte-identical and the import refused
    out = tmp_path / "arr.json"
    assert _cli(exported["stack"] / "scene.xml", "--out", out).returncode == 0
    assert _cli(exported["table"] / "scene.xml", "--out", out).returncode == 0
    _match(SCENES["table"], read_arrangement(out))
    scan = tmp_path / "scan.json"
    scan.write_text('{"points": [[0, 0, 0]]}')
    r = _cli(exported["table"] / "scene.xml", "--out", scan)
    assert r.returncode == 2 and "exists and is not an arrangement file" in r.stderr
    assert scan.read_text() == '{"points": [[0, 0, 0]]}'
