"""Ground, walls and the world frame from ray-cast frames with exact truth."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from rgbd_fixtures import raycast  # noqa: E402

from pipeline.camera import backproject, invert, transform  # noqa: E402
from pipeline.errors import InputError  # noqa: E402
from pipeline.model import rotation_about_z  # noqa: E402
from pipeline.planes import find_frame, fit_plane_lsq, ransac_plane  # noqa: E402

BOXES = [(np.array([0.0, 0.0, 0.2]), rotation_about_z(0.3), np.array([0.5, 0.3, 0.4])),
         (np.array([0.8, 0.5, 0.15]), rotation_about_z(-0.5), np.array([0.3, 0.3, 0.3]))]


def test_ransac_plane_recovers_a_noisy_plane_among_outliers():
    rng = np.random.default_rng(0)
    n_true = np.array([0.2, -0.3, 0.93])
    n_true /= np.linalg.norm(n_true)
    u = np.cross(n_true, [1.0, 0, 0])
    u /= np.linalg.norm(u)
    v = np.cross(n_true, u)
    ab = rng.uniform(-1, 1, (3000, 2))
    pts = ab[:, :1] * u + ab[:, 1:] * v + 0.5 * n_true + rng.normal(0, 0.002, (3000, 1)) * n_true
    pts = np.concatenate([pts, rng.uniform(-1, 1, (2000, 3))])
    n, off, cnt = ransac_plane(pts, 0.01, rng)
    n2, off2 = fit_plane_lsq(pts[np.abs(pts @ n + off) < 0.01])
    assert abs(abs(n2 @ n_true) - 1) < 1e-4
    assert abs(abs(off2) - 0.5) < 2e-3
    assert 2900 < cnt < 3300


@pytest.mark.parametrize("eye", [(1.6, -1.8, 1.5), (-1.2, -2.0, 0.9), (2.2, 0.4, 2.0)])
def test_frame_puts_ground_at_z0_and_keeps_camera_height(eye):
    fr = raycast(BOXES, eye=eye, target=(0.3, 0.2, 0.15))
    pts, pix = backproject(fr.depth, fr.intr)
    f = find_frame(pts, np.random.default_rng(1), camera_frame=True)
    # the chosen world differs from the truth only by a rotation about z and a shift in x, y
    M = f.T_world_input @ invert(fr.T_world_cam)
    assert abs(M[2, 2] - 1) < 1e-4
    assert abs(M[2, 3]) < 2e-3
    # camera height above the ground is the true one
    assert f.T_world_input[2, 3] == pytest.approx(eye[2], abs=3e-3)
    # ground labels are the true ground pixels (those far from the boxes' feet)
    w_true = transform(fr.T_world_cam, pts)
    on_ground = fr.instance[pix[:, 0], pix[:, 1]] == 0
    assert np.all(f.labels[~on_ground & (w_true[:, 2] > 0.05)] != 0)
    assert (f.labels[on_ground] == 0).mean() > 0.99
    assert f.walls == ()


def test_wall_is_found_and_faces_the_camera():
    fr = raycast(BOXES, eye=(1.6, -1.8, 1.5), target=(0.3, 0.2, 0.15), wall_x=-0.8)
    pts, _ = backproject(fr.depth, fr.intr)
    f = find_frame(pts, np.random.default_rng(2), camera_frame=True)
    assert len(f.walls) == 1
    wall = f.walls[0]
    # the wall's normal is horizontal and points at the camera
    assert abs(wall.normal[2]) < 1e-3
    cam = f.T_world_input[:3, 3]
    assert wall.signed_distance(cam[None])[0] == pytest.approx(1.6 + 0.8, abs=5e-3)


def test_a_wall_seen_as_two_parallel_layers_is_one_wall():
    # far away a Kinect's depth noise makes a wall a slab thicker than the RANSAC
    # threshold; RANSAC then returns its two sides as two planes 5 cm apart
    fr = raycast(BOXES, eye=(1.6, -1.8, 1.5), target=(0.3, 0.2, 0.15), wall_x=-0.8)
    pts, _ = backproject(fr.depth, fr.intr)
    f0 = find_frame(pts, np.random.default_rng(2), camera_frame=True)
    n_input = f0.T_world_input[:3, :3].T @ f0.walls[0].normal  # towards the camera
    far = pts[f0.labels == 1][::4] - 0.05 * n_input  # a thinner layer behind the first
    both = np.concatenate([pts, far])
    f = find_frame(both, np.random.default_rng(2), camera_frame=True)
    assert len(f.walls) == 1
    assert (f.labels[len(pts):] == 1).mean() > 0.99  # the far layer belongs to the wall
    cam = f.T_world_input[:3, 3]
    assert f.walls[0].signed_distance(cam[None])[0] == pytest.approx(2.4, abs=0.06)


def test_given_pose_is_kept():
    fr = raycast(BOXES, eye=(1.6, -1.8, 1.5), target=(0.3, 0.2, 0.15))
    pts, _ = backproject(fr.depth, fr.intr)
    f = find_frame(pts, np.random.default_rng(3), T_world_input=fr.T_world_cam, camera_frame=True)
    assert np.array_equal(f.T_world_input, fr.T_world_cam)
    assert abs(f.ground.point[2]) < 2e-3 and f.ground.normal[2] > 0.9999


def test_with_a_given_pose_a_floor_fitted_a_little_tilted_is_level():
    # Kinect noise at 3-4 m tilts the fitted floor by 0.2-0.3 deg (Table 1 rooms); the
    # pose's z is up (gravity), so the floor is level at the median height of its points
    fr = raycast(BOXES, eye=(1.6, -1.8, 1.5), target=(0.3, 0.2, 0.15))
    pts, _ = backproject(fr.depth, fr.intr)
    w = transform(fr.T_world_cam, pts)
    floor = np.abs(w[:, 2]) < 1e-6
    c = w[floor].mean(axis=0)
    t = np.radians(0.3)
    R = np.array([[1, 0, 0], [0, np.cos(t), -np.sin(t)], [0, np.sin(t), np.cos(t)]])
    w[floor] = (w[floor] - c) @ R.T + c + [0, 0, 0.004]
    tilted = transform(invert(fr.T_world_cam), w)
    f = find_frame(tilted, np.random.default_rng(3), T_world_input=fr.T_world_cam,
                   camera_frame=True)
    assert np.array_equal(f.ground.normal, [0.0, 0.0, 1.0])
    assert f.ground.point[2] == pytest.approx(np.median(w[floor, 2]), abs=5e-4)
    assert (f.labels[floor] == 0).mean() > 0.95


@pytest.mark.parametrize("engine", ["mujoco", "pybullet"])
def test_upright_boxes_on_a_floor_tilted_by_noise_rock_onto_it_in_the_engines(engine):
    """Engine round trip: why the floor must be level.  A 1.5 m column stands upright
    (z is up) on a floor tilted 0.3 deg, its lowest edge on it and the rest within the
    contact tolerance: statics calls it stable, both engines rock it onto the slope
    (0.3 deg), and the 10 cm box on top moves 7.9-8.2 mm (> 2 % of its size, unstable);
    on a level floor both stand."""
    from pipeline.model import Arrangement, Support, box
    from pipeline.stability import check_stability
    from simulate.engines import settle

    def scene(tilt_deg: float) -> Arrangement:
        t = np.radians(tilt_deg)
        floor = Support("ground", np.zeros(3), np.array([np.sin(t), 0.0, np.cos(t)]))
        low = np.tan(t) * 0.15  # the floor's height under the column's lowest edge
        return Arrangement((box("column", (0, 0, low + 0.75), (0.3, 0.3, 1.5)),
                            box("top", (0, 0, low + 1.55), (0.1, 0.1, 0.1))), (floor,))

    tilted = scene(0.3)
    assert check_stability(tilted).stable
    moved = settle(tilted, engine)
    top = next(b for b in moved.bodies if b.id == "top")
    assert not moved.stable and top.translation > 0.006 and top.rotation_deg > 0.25
    assert settle(scene(0.0), engine).stable


def test_no_ground_plane_raises_with_up_hint():
    rng = np.random.default_rng(4)
    blob = rng.normal(size=(5000, 3))
    blob /= np.linalg.norm(blob, axis=1, keepdims=True)  # a sphere: no plane at all
    with pytest.raises(InputError, match="--up"):
        find_frame(blob, rng, camera_frame=False)


def test_up_flag_selects_ground_in_an_unusual_frame():
    fr = raycast(BOXES, eye=(1.6, -1.8, 1.5), target=(0.3, 0.2, 0.15))
    pts, _ = backproject(fr.depth, fr.intr)
    # express the cloud in the world frame rotated so that "up" is +x
    R = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])
    cloud = transform(fr.T_world_cam, pts) @ R.T
    f = find_frame(cloud, np.random.default_rng(5), up=np.array([1.0, 0, 0]))
    assert abs(abs(f.T_world_input[:3, :3].T[:, 2] @ np.array([1.0, 0, 0])) - 1) < 1e-4


def test_ransac_plane_of_collinear_points_finds_no_plane():
    line = np.outer(np.linspace(0.0, 1.0, 50), [1.0, 2.0, 3.0])
    n, off, cnt = ransac_plane(line, 0.01, np.random.default_rng(0))
    assert cnt == 0 and np.linalg.norm(n) == pytest.approx(1.0)


def test_a_plane_the_segmentation_gives_to_an_object_is_its_face_not_a_wall():
    # a wardrobe 2 m wide and 1.8 m tall seen face-on from low down, nothing behind it:
    # its front is a large vertical plane with (almost) nothing seen behind it, so
    # without a segmentation it passes for a wall; the instance mask says its points
    # are an object's, so it is not one.  A true wall behind is still a wall with it.
    wardrobe = [(np.array([0.0, 0.0, 0.9]), np.eye(3), np.array([0.6, 2.0, 1.8]))]
    fr = raycast(wardrobe, eye=(2.4, 0.1, 0.4), target=(0.0, 0.0, 0.9))
    pts, pix = backproject(fr.depth, fr.intr)
    ids = fr.instance[pix[:, 0], pix[:, 1]]
    blind = find_frame(pts, np.random.default_rng(1), camera_frame=True)
    assert len(blind.walls) == 1  # the face, taken for a wall without a mask
    seen = find_frame(pts, np.random.default_rng(1), camera_frame=True, object_points=ids > 0)
    assert seen.walls == ()
    assert np.all(seen.labels[ids > 0] != 1)
    fr = raycast(wardrobe, eye=(2.4, 0.1, 0.4), target=(0.0, 0.0, 0.9), wall_x=-0.6)
    pts, pix = backproject(fr.depth, fr.intr)
    ids = fr.instance[pix[:, 0], pix[:, 1]]
    both = find_frame(pts, np.random.default_rng(1), camera_frame=True, object_points=ids > 0)
    assert len(both.walls) == 1
    n = both.walls[0].normal
    assert abs(n[2]) < 0.05
    on_wall = (ids == 0) & (transform(both.T_world_input, pts)[:, 2] > 0.1)
    assert (both.labels[on_wall] == 1).mean() > 0.95


def _level(rng, n, z, half=1.0, centre=(0.0, 0.0)):
    xy = rng.uniform(-half, half, (n, 2)) + np.asarray(centre)
    return np.column_stack([xy, np.full(n, z) + rng.normal(0, 0.002, n)])


def test_a_table_top_with_the_room_below_it_is_not_taken_for_the_floor():
    from pipeline.planes import lower_floor

    rng = np.random.default_rng(0)
    top = _level(rng, 6000, 0.75, 0.6)  # the largest level plane
    seat = _level(rng, 1500, 0.45, 0.5, (1.5, 0.0))  # a sofa seat beside it
    floor = _level(rng, 600, 0.0, 0.3, (0.0, -1.0))  # a glimpse of the floor
    side = np.column_stack([rng.uniform(1.0, 2.0, 1500), np.full(1500, 0.5),
                            rng.uniform(0.0, 0.45, 1500)])  # the sofa's front
    pts = np.vstack([top, seat, floor, side])
    fr = find_frame(pts, np.random.default_rng(1), up=np.array([0.0, 0.0, 1.0]))
    assert any("floor" in n for n in fr.notes)
    z = transform(fr.T_world_input, pts)[:, 2]
    assert abs(np.median(z[-len(side) - len(floor):-len(side)])) < 0.01  # the floor at z = 0
    assert abs(np.median(z[:len(top)]) - 0.75) < 0.01
    # must not act: a table top filmed alone (nothing under it) stays the ground
    alone = np.vstack([top, _level(rng, 800, 0.85, 0.1)])
    fr = find_frame(alone, np.random.default_rng(1), up=np.array([0.0, 0.0, 1.0]))
    assert fr.notes == () and abs(np.median(transform(fr.T_world_input, top)[:, 2])) < 0.01
    # ... and neither does a floor with a little noise under it
    from pipeline.planes import Plane

    g = Plane(np.array([0.0, 0.0, 1.0]), 0.0, 1)
    assert lower_floor(np.vstack([floor, _level(rng, 10, -0.2, 0.3)]), g, 0.01, rng) is None


def _room(second_deg: float, at_y: float = 2.0, seed: int = 0) -> np.ndarray:
    """A floor (4 x 4 m), a large wall at x = -2 and a smaller one through (0, ``at_y``)
    turned ``second_deg`` degrees from square to it, points with 5 mm of noise along
    each plane's normal (z up)."""
    rng = np.random.default_rng(seed)
    floor = _level(rng, 10000, 0.0, 2.0)
    yz = rng.uniform([-2.0, 0.0], [2.0, 2.5], (8000, 2))
    first = np.column_stack([-2.0 + rng.normal(0, 0.005, len(yz)), yz])
    a = np.radians(second_deg)
    t = rng.uniform(-1.5, 1.5, 5000)
    z = rng.uniform(0.0, 2.5, 5000)
    along, normal = np.array([np.cos(a), np.sin(a)]), np.array([-np.sin(a), np.cos(a)])
    xy = np.array([0.0, at_y]) + t[:, None] * along + rng.normal(0, 0.005, 5000)[:, None] * normal
    second = np.column_stack([xy, z])
    return np.concatenate([floor, first, second])


def _plan_cos(a: np.ndarray, b: np.ndarray) -> float:
    a, b = np.array([a[0], a[1]]), np.array([b[0], b[1]])
    return float(abs(a @ b) / (np.linalg.norm(a) * np.linalg.norm(b)))


def test_a_wall_fitted_a_few_degrees_off_square_to_the_first_is_square_and_plumb(
        monkeypatch):
    """Rooms are square: the second wall, built 6 degrees off square (a far wall's fit
    errs so), is found at exactly a right angle to the first, plumb, through the middle
    of its own points; 30 degrees off, it is a room's bend, not the fit's error, and
    stays as fitted."""
    pts = _room(6.0)
    f = find_frame(pts, np.random.default_rng(0), up=np.array([0.0, 0.0, 1.0]))
    assert len(f.walls) == 2
    first, second = f.walls
    assert _plan_cos(first.normal, second.normal) < 1e-9  # exactly a right angle
    assert abs(second.normal[2]) < 1e-12  # plumb
    mid = transform(f.T_world_input, np.array([[0.0, 2.0, 1.0]]))
    assert abs(second.signed_distance(mid)[0]) < 0.01
    # without the rule RANSAC's plane keeps the 6 degrees
    import pipeline.planes as planes

    with monkeypatch.context() as m:
        m.setattr(planes, "WALL_SQUARE_DEG", 0.0)
        raw = find_frame(pts, np.random.default_rng(0), up=np.array([0.0, 0.0, 1.0]))
    assert _plan_cos(raw.walls[0].normal, raw.walls[1].normal) == pytest.approx(
        np.sin(np.radians(6.0)), abs=0.005)
    # (further back, so that no floor lies behind the slanted wall)
    bend = find_frame(_room(30.0, at_y=3.2), np.random.default_rng(0),
                      up=np.array([0.0, 0.0, 1.0]))
    assert len(bend.walls) == 2
    assert _plan_cos(bend.walls[0].normal, bend.walls[1].normal) == pytest.approx(
        np.sin(np.radians(30.0)), abs=0.01)


def test_square_to_rounds_only_within_its_angle():
    """Just inside and outside ``WALL_SQUARE_DEG`` (10), of a right angle and of
    parallel; a normal already square is left as it is."""
    from pipeline.planes import WALL_SQUARE_DEG, square_to

    up = np.array([0.0, 0.0, 1.0])
    first = np.array([1.0, 0.0, 0.0])

    def at(deg, tilt=0.0):
        a, t = np.radians(deg), np.radians(tilt)
        return np.array([np.cos(a) * np.cos(t), np.sin(a) * np.cos(t), np.sin(t)])

    assert WALL_SQUARE_DEG == 10.0
    np.testing.assert_allclose(square_to(at(90 - 9.9, tilt=3.0), first, up), [0, 1, 0],
                               atol=1e-12)
    assert square_to(at(90 - 10.1), first, up) is None
    np.testing.assert_allclose(square_to(at(180 + 9.9), first, up), [-1, 0, 0], atol=1e-12)
    assert square_to(at(10.1), first, up) is None
    assert square_to(at(90.0), first, up) is None  # already square: nothing to round
