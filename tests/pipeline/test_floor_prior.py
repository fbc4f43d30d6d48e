"""The floor from a prior: a camera pose, or ``--up`` with ``--floor-height``.

The rule (``pipeline.planes``): with a prior the floor is the prior, and RANSAC only
refines it; a RANSAC plane replaces it when its normal is within 5 degrees of the
prior's and its inliers lie (median) within 5 cm of the prior plane.  Otherwise the
prior is kept as given, even against a large visible floor elsewhere, and the report
says by how much RANSAC's plane disagreed.  A floor out of the picture is no error.
"""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from rgbd_fixtures import raycast, write_frame  # noqa: E402

from eval.cli import main  # noqa: E402
from pipeline.arrangement_io import read_arrangement  # noqa: E402
from pipeline.camera import backproject, read_pose, transform  # noqa: E402
from pipeline.errors import InputError  # noqa: E402
from pipeline.model import rotation_about_axis, rotation_about_z  # noqa: E402
from pipeline.planes import (  # noqa: E402
    FLOOR_PRIOR_MAX_DEG,
    FLOOR_PRIOR_MAX_OFFSET,
    find_frame,
)

#: a cabinet against the wall x = -0.8, filmed level from 1.4 m high: no floor in view
CABINET = [(np.array([-0.5, 0.0, 0.8]), rotation_about_z(0.0), np.array([0.5, 0.6, 1.6]))]
LEVEL_EYE, LEVEL_TARGET = (1.6, 0.3, 1.4), (-0.8, 0.0, 1.4)
#: boxes on a clearly visible floor (as in test_planes), the camera 1.5 m high
BOXES = [(np.array([0.0, 0.0, 0.2]), rotation_about_z(0.3), np.array([0.5, 0.3, 0.4])),
         (np.array([0.8, 0.5, 0.15]), rotation_about_z(-0.5), np.array([0.3, 0.3, 0.3]))]
EYE, TARGET = (1.6, -1.8, 1.5), (0.3, 0.2, 0.15)


@pytest.fixture(scope="module")
def no_floor():
    fr = raycast(CABINET, eye=LEVEL_EYE, target=LEVEL_TARGET, wall_x=-0.8)
    pts, _ = backproject(fr.depth, fr.intr)
    assert transform(fr.T_world_cam, pts)[:, 2].min() > 0.1  # the floor is out of the picture
    return fr, pts


@pytest.fixture(scope="module")
def floor():
    fr = raycast(BOXES, eye=EYE, target=TARGET)
    pts, _ = backproject(fr.depth, fr.intr)
    return fr, pts


def _up_in_camera(fr) -> np.ndarray:
    return fr.T_world_cam[:3, :3].T @ np.array([0.0, 0.0, 1.0])


# ------------------------------------------------------------------ the floor out of frame
def test_without_a_prior_a_floor_out_of_the_picture_is_an_error(no_floor):
    _, pts = no_floor
    with pytest.raises(InputError, match="no ground plane found.*--floor-height"):
        find_frame(pts, np.random.default_rng(0), camera_frame=True)


def test_a_pose_gives_the_floor_out_of_the_picture(no_floor):
    fr, pts = no_floor
    f = find_frame(pts, np.random.default_rng(0), T_world_input=fr.T_world_cam,
                   camera_frame=True)
    assert f.floor == "prior"
    assert np.array_equal(f.T_world_input, fr.T_world_cam)
    assert np.array_equal(f.ground.point, [0.0, 0.0, 0.0])
    assert np.array_equal(f.ground.normal, [0.0, 0.0, 1.0])
    assert (f.labels == 0).sum() == 0  # no point is floor
    assert len(f.walls) == 1 and f.walls[0].signed_distance(np.array([[-0.8, 0, 1]]))[0] \
        == pytest.approx(0.0, abs=5e-3)


def test_up_and_floor_height_give_the_floor_out_of_the_picture(no_floor):
    fr, pts = no_floor
    up = _up_in_camera(fr)
    assert np.allclose(up, [0.0, -1.0, 0.0])  # the camera is level: up is -y
    f = find_frame(pts, np.random.default_rng(0), up=up, floor_height=-1.4, camera_frame=True)
    assert f.floor == "prior"
    assert f.T_world_input[2, 3] == pytest.approx(1.4, abs=1e-12)  # the camera's height
    # the world the floor defines is the true one up to a turn about z and a shift in x, y
    M = f.T_world_input @ np.linalg.inv(fr.T_world_cam)
    assert M[2, 2] == pytest.approx(1.0, abs=1e-12) and M[2, 3] == pytest.approx(0.0, abs=1e-12)


def test_floor_height_needs_an_up_direction(no_floor):
    _, pts = no_floor
    with pytest.raises(InputError, match="--floor-height: give --up"):
        find_frame(pts, np.random.default_rng(0), floor_height=-1.4, camera_frame=True)
    with pytest.raises(InputError, match="finite"):
        find_frame(pts, np.random.default_rng(0), up=np.array([0.0, -1, 0]),
                   floor_height=float("nan"), camera_frame=True)


# ------------------------------------------------------- a visible floor refines the prior
@pytest.mark.parametrize("error", [0.0, 0.02, -0.04])
def test_a_floor_height_a_few_cm_off_is_refined_to_the_visible_floor(floor, error):
    fr, pts = floor
    f = find_frame(pts, np.random.default_rng(1), up=_up_in_camera(fr),
                   floor_height=-1.5 + error, camera_frame=True)
    assert f.floor == "prior+ransac" and f.notes == ()
    assert f.T_world_input[2, 3] == pytest.approx(1.5, abs=3e-3)


@pytest.mark.parametrize("tilt_deg, refined", [(3.0, True), (8.0, False)])
def test_an_up_a_few_degrees_off_is_refined_more_is_kept(floor, tilt_deg, refined):
    fr, pts = floor
    up = rotation_about_axis(np.array([1.0, 0, 0]), np.radians(tilt_deg)) @ _up_in_camera(fr)
    f = find_frame(pts, np.random.default_rng(1), up=up, floor_height=-1.5, camera_frame=True)
    assert tilt_deg < FLOOR_PRIOR_MAX_DEG if refined else tilt_deg > FLOOR_PRIOR_MAX_DEG
    n_input = f.T_world_input[2, :3]  # world z in input coordinates: the floor's normal
    if refined:
        assert f.floor == "prior+ransac"
        assert n_input @ _up_in_camera(fr) == pytest.approx(1.0, abs=1e-4)
    else:
        assert f.floor == "prior"
        assert np.allclose(n_input, up / np.linalg.norm(up), atol=1e-12)


def test_a_wrong_floor_height_against_a_visible_floor_keeps_the_given_floor(floor):
    """The rule: the user's floor wins; RANSAC's 30 cm away is not taken, and said."""
    fr, pts = floor
    f = find_frame(pts, np.random.default_rng(1), up=_up_in_camera(fr), floor_height=-1.8,
                   camera_frame=True)
    assert 0.3 > FLOOR_PRIOR_MAX_OFFSET
    assert f.floor == "prior"
    assert f.T_world_input[2, 3] == pytest.approx(1.8, abs=1e-12)
    assert len(f.notes) == 1 and "+0.300 m above" in f.notes[0] and "kept the given floor" in f.notes[0]
    # the visible floor is not ground: 30 cm above the given one
    world_z = transform(f.T_world_input, pts)[:, 2]
    assert (f.labels == 0).sum() == 0
    assert np.median(world_z[transform(fr.T_world_cam, pts)[:, 2] < 1e-6]) == \
        pytest.approx(0.3, abs=2e-3)


@pytest.mark.parametrize("shift, expected, source", [(0.03, 0.03, "prior+ransac"),
                                                     (0.10, 0.0, "prior")])
def test_a_pose_whose_floor_is_off_is_refined_within_5_cm(floor, shift, expected, source):
    fr, pts = floor
    T = fr.T_world_cam.copy()
    T[2, 3] += shift  # the pose's world: the floor at z = shift, not 0
    f = find_frame(pts, np.random.default_rng(1), T_world_input=T, camera_frame=True)
    assert f.floor == source
    assert np.array_equal(f.ground.normal, [0.0, 0.0, 1.0])
    assert f.ground.point[2] == pytest.approx(expected, abs=1e-3)
    assert bool(f.notes) is (source == "prior")


# --------------------------------------------------------------------------- unseen run
def _run(capsys, *argv):
    code = main(["run", *[str(a) for a in argv], "--stage", "initial"])
    return code, capsys.readouterr().err


def test_cli_floor_out_of_frame(tmp_path, capsys, no_floor):
    fr, _ = no_floor
    bare = write_frame(fr, tmp_path / "bare", pose=False)
    code, err = _run(capsys, bare, "--out", tmp_path / "o0")
    assert code == 2 and "no ground plane found" in err and "--floor-height" in err
    assert len(err.strip().splitlines()) == 1
    code, err = _run(capsys, bare, "--out", tmp_path / "o1", "--floor-height", "-1.4")
    assert code == 2 and "--floor-height: give --up" in err
    code, err = _run(capsys, bare, "--out", tmp_path / "o2", "--up=-y",
                     "--floor-height", "-1.4")
    assert code == 0, err
    arr = read_arrangement(tmp_path / "o2" / "arrangement.json")
    assert np.asarray(arr.meta["camera_pose"])[2, 3] == pytest.approx(1.4, abs=1e-9)
    assert len(arr.cuboids) == 1  # the cabinet
    # as a user types it: a value starting with a dash is the option's value, not an option
    for name, up in (("o2b", "-y"), ("o2c", "-0.0,-1,0.0")):
        code, err = _run(capsys, bare, "--out", tmp_path / name, "--up", up,
                         "--floor-height", "-1.4")
        assert code == 0, err
        same = read_arrangement(tmp_path / name / "arrangement.json")
        assert [(c.center.tolist(), c.size.tolist()) for c in same.cuboids] == [
            (c.center.tolist(), c.size.tolist()) for c in arr.cuboids]
    with pytest.raises(SystemExit) as stop:  # a forgotten value is still argparse's error
        _run(capsys, bare, "--up", "--out", tmp_path / "o2d")
    assert stop.value.code == 2
    assert "--up: expected one argument" in capsys.readouterr().err
    posed = write_frame(fr, tmp_path / "posed", pose=True)
    code, err = _run(capsys, posed, "--out", tmp_path / "o3")
    assert code == 0, err
    arr = read_arrangement(tmp_path / "o3" / "arrangement.json")
    assert np.allclose(arr.meta["camera_pose"], fr.T_world_cam)
    assert np.array_equal(arr.support("ground").point, [0.0, 0.0, 0.0])
    # an earlier run's arrangement.json is a pose (its meta.camera_pose)
    assert np.allclose(read_pose(tmp_path / "o3" / "arrangement.json"), fr.T_world_cam)
    code, err = _run(capsys, bare, "--out", tmp_path / "o4", "--pose",
                     tmp_path / "o3" / "arrangement.json")
    assert code == 0, err
    again = read_arrangement(tmp_path / "o4" / "arrangement.json")
    assert np.allclose(again.meta["camera_pose"], fr.T_world_cam)
    assert [c.size.tolist() for c in again.cuboids] == [c.size.tolist() for c in arr.cuboids]


def test_cli_multi_view_folder_with_the_floor_out_of_frame(tmp_path, capsys):
    folder = tmp_path / "mv"
    for k, eye in enumerate((LEVEL_EYE, (1.6, -0.4, 1.4))):
        fr = raycast(CABINET, eye=eye, target=LEVEL_TARGET, wall_x=-0.8)
        write_frame(fr, folder / f"view{k}", pose=True)
    code, err = _run(capsys, folder, "--out", tmp_path / "o")
    assert code == 0, err
    arr = read_arrangement(tmp_path / "o" / "arrangement.json")
    assert np.array_equal(arr.support("ground").point, [0.0, 0.0, 0.0])
    code, err = _run(capsys, folder, "--out", tmp_path / "o2", "--pose",
                     folder / "view0" / "camera_pose.json")
    assert code == 2 and "multi-view" in err
    shutil.rmtree(folder / "view1")
    (folder / "view0" / "camera_pose.json").write_text(json.dumps({"meta": {}}))
    code, err = _run(capsys, folder, "--out", tmp_path / "o3")
    assert code == 2 and "camera pose must be a 4x4" in err


def test_cli_wrong_floor_height_is_kept_and_reported(tmp_path, capsys, floor):
    fr, _ = floor
    bare = write_frame(fr, tmp_path / "bare", pose=False)
    up = ",".join(f"{v:.12f}" for v in _up_in_camera(fr))
    code, err = _run(capsys, bare, "--out", tmp_path / "o", f"--up={up}",
                     "--floor-height", "-1.8")
    assert code == 0, err
    arr = read_arrangement(tmp_path / "o" / "arrangement.json")
    assert np.asarray(arr.meta["camera_pose"])[2, 3] == pytest.approx(1.8, abs=1e-9)
    report = (tmp_path / "o" / "report.md").read_text()
    assert "kept the given floor" in report and "+0.300 m above" in report
