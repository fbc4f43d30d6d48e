"""Scene directories: the DESIGN.md layout, scan <-> ground truth consistency, determinism."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("mujoco")

from pipeline.arrangement_io import dumps, read_arrangement  # noqa: E402
from synth_scenes.scene_dir import make_scene_dir  # noqa: E402

SCAN_FILES = ("color.png", "depth.png", "instance.png", "intrinsics.json", "camera_pose.json")


def _png(path):
    import cv2

    return cv2.imread(str(path), cv2.IMREAD_UNCHANGED)


@pytest.fixture(scope="module")
def stack_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("scene") / "stack"
    return make_scene_dir("stack", out, seed=2, noise="none", n_boxes=5)


def test_layout_and_scene_json(stack_dir):
    out = stack_dir.path
    assert stack_dir.truth.status == "ok"
    for name in (*SCAN_FILES, "points.ply"):
        assert (out / "scan" / name).is_file(), name
    arr = read_arrangement(out / "scene.json")
    assert dumps(arr) == dumps(stack_dir.truth.arrangement)
    assert len(arr.cuboids) == 5
    meta = arr.meta
    assert meta["family"] == "stack" and meta["seed"] == 2 and meta["options"] == {"n_boxes": 5}
    assert meta["validation"] == {"stable": True, "contacts_ok": True, "analytic": True,
                                  "engines": {"mujoco": True, "pybullet": True}}
    assert meta["scan"]["views"] == 1 and meta["scan"]["noise"] == "none"
    depth = _png(out / "scan" / "depth.png")
    inst = _png(out / "scan" / "instance.png")
    assert depth.dtype == np.uint16 and inst.dtype == np.uint16
    assert depth.shape == inst.shape == (480, 640)
    assert set(np.unique(inst)) <= set(range(len(arr.cuboids) + 1))
    assert len(set(np.unique(inst)) - {0}) >= 2            # several boxes are seen
    pose = np.array(json.loads((out / "scan" / "camera_pose.json").read_text()))
    assert pose.shape == (4, 4) and np.allclose(pose[:3, :3].T @ pose[:3, :3], np.eye(3))


def test_scan_points_lie_on_their_ground_truth_cuboid(stack_dir):
    """Instance id k of the PLY and the PNG names cuboid k-1 of scene.json: every point
    with id k lies on that box's surface (noise off: depth rounding only)."""
    from simulate.scan import read_ply

    arr = read_arrangement(stack_dir.path / "scene.json")
    pts, _, inst = read_ply(stack_dir.path / "scan" / "points.ply")
    assert inst is not None and len(pts) == stack_dir.n_points
    on = inst > 0
    assert on.sum() > 1000
    k = inst[on].astype(int) - 1
    local = np.einsum("nij,ni->nj", arr.rotations[k], pts[on] - arr.centers[k])
    half = arr.sizes[k] / 2
    tol = 0.003
    assert np.all(np.abs(local) <= half + tol)                      # inside its box
    assert np.all(np.min(half - np.abs(local), axis=1) <= tol)      # on its surface
    # points with id 0 are on the floor (the only support here)
    z0 = pts[~on][:, 2]
    assert np.abs(z0).max() < tol
    # and the PNG has the same ids as the PLY
    png = _png(stack_dir.path / "scan" / "instance.png")
    depth = _png(stack_dir.path / "scan" / "depth.png")
    assert np.array_equal(np.sort(png[depth > 0].ravel()), np.sort(inst))


def test_same_seed_byte_identical_other_seed_differs(tmp_path):
    a = make_scene_dir("chair", tmp_path / "a", seed=5)
    b = make_scene_dir("chair", tmp_path / "b", seed=5)
    c = make_scene_dir("chair", tmp_path / "c", seed=6)
    files = sorted(p.relative_to(a.path) for p in a.path.rglob("*") if p.is_file())
    assert len(files) == 7
    for f in files:
        assert (a.path / f).read_bytes() == (b.path / f).read_bytes(), f
    assert (a.path / "scene.json").read_bytes() != (c.path / "scene.json").read_bytes()
    assert (a.path / "scan/depth.png").read_bytes() != (c.path / "scan/depth.png").read_bytes()


def test_several_views(tmp_path):
    from simulate.scan import read_ply

    res = make_scene_dir("stack", tmp_path / "mv", seed=1, views=3, noise="none", n_boxes=3)
    scan = res.path / "scan"
    for k in range(3):
        for name in SCAN_FILES:
            assert (scan / f"view{k}" / name).is_file()
    assert not (scan / "depth.png").exists()
    poses = [np.array(json.loads((scan / f"view{k}" / "camera_pose.json").read_text()))
             for k in range(3)]
    assert min(np.linalg.norm(poses[i][:3, 3] - poses[j][:3, 3])
               for i in range(3) for j in range(i + 1, 3)) > 0.3
    pts, _, inst = read_ply(scan / "points.ply")
    per_view = sum(len(read_ply(scan / f"view{k}" / "points.ply")[0]) for k in range(3))
    assert 0 < len(pts) <= per_view and inst is not None


def test_gave_up_writes_nothing(tmp_path, monkeypatch):
    import synth_scenes.truth as truth

    monkeypatch.setattr(truth, "validate",
                        lambda arr, *a, **k: truth.Validation(False, True, False, {}))
    res = make_scene_dir("table", tmp_path / "none", seed=0, max_attempts=2)
    assert res.truth.status == "gave_up" and res.truth.attempts == 2
    assert not (tmp_path / "none").exists()


def test_bad_scan_settings(tmp_path):
    from pipeline.errors import InputError

    with pytest.raises(InputError, match="--views"):
        make_scene_dir("chair", tmp_path / "x", views=0)
    with pytest.raises(InputError, match="--noise"):
        make_scene_dir("chair", tmp_path / "x", noise="tof")
    with pytest.raises(InputError, match="--renderer"):
        make_scene_dir("chair", tmp_path / "x", renderer="blender")


def test_rerun_with_other_views_leaves_no_stale_files(tmp_path):
    out = tmp_path / "re"
    make_scene_dir("chair", out, seed=1, views=2, noise="none")
    assert (out / "scan" / "view1" / "depth.png").is_file()
    (out / "scan" / "view1" / "notes.txt").write_text("mine")
    make_scene_dir("chair", out, seed=1, views=1, noise="none")
    assert not (out / "scan" / "view0").exists()
    assert sorted(p.name for p in (out / "scan" / "view1").iterdir()) == ["notes.txt"]
    assert (out / "scan" / "depth.png").is_file()
    make_scene_dir("chair", out, seed=1, views=2, noise="none")
    assert not (out / "scan" / "depth.png").exists()
    assert (out / "scan" / "view0" / "depth.png").is_file()


@pytest.mark.parametrize(("family", "height", "behind"), [
    ("chair", 0.3, True), ("chair", 2.0, False), ("table", 0.3, False), ("shelf", 2.0, True)])
def test_views_from_low_high_and_behind_see_a_scene_whose_truth_stands(tmp_path, family,
                                                                      height, behind):
    """The widened camera: knee or head height, in front of or behind the object (its
    back faces +y in its own frame, turned by the scene's yaw).  The truth stands, the
    eye is where it was asked to be, and the scan sees most of the scene's parts."""
    from simulate.viewpoints import scene_center
    from synth_scenes.registry import make
    from synth_scenes.truth import scene_rngs

    seed = 3
    arr = make(family, scene_rngs(seed)[0])  # the first sample (these seeds need one)
    back = arr.cuboids[0].rotation[:, 1]     # the object's local +y: toward its back
    az = float(np.rad2deg(np.arctan2(back[1], back[0]))) + (0.0 if behind else 180.0)
    made = make_scene_dir(family, tmp_path / "s", seed=seed,
                          view_ranges={"height": (height, height), "azimuth": (az, az)})
    gt = made.truth.arrangement
    assert made.truth.status == "ok" and gt.meta["validation"]["stable"] is True
    assert dumps(gt.with_(meta={})) == dumps(arr.with_(meta={}))
    T = np.array(json.loads((made.path / "scan" / "camera_pose.json").read_text()))
    assert T[2, 3] == pytest.approx(height)
    c, _ = scene_center(gt)
    view = np.rad2deg(np.arctan2(T[1, 3] - c[1], T[0, 3] - c[0]))
    assert abs((view - az + 180.0) % 360.0 - 180.0) < 1e-6
    inst = _png(made.path / "scan" / "instance.png")
    seen = len(set(np.unique(inst[inst > 0]).tolist()))
    assert seen >= 0.5 * len(gt.cuboids), (seen, len(gt.cuboids))
