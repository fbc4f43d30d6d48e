"""Edge refinement: a perturbed box snaps back onto the image edges of the true box."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from rgbd_fixtures import raycast  # noqa: E402

from pipeline.camera import Intrinsics, backproject, invert, project, transform  # noqa: E402
from pipeline.edges import edge_map, point_box_distance, refine_box, silhouette_samples  # noqa: E402
from pipeline.model import box_corners, rotation_about_z  # noqa: E402


def test_point_box_distance_closed_form():
    pts = np.array([[0.0, 0, 0], [0.9, 0, 0], [2.0, 0, 0], [2.0, 2.0, 0]])
    d = point_box_distance(pts, np.zeros(3), np.eye(3), np.array([2.0, 2.0, 2.0]))
    assert np.allclose(d, [1.0, 0.1, 1.0, np.sqrt(2)])


def test_edge_map_nearest_edge_pixel():
    img = np.zeros((60, 80, 3), np.uint8)
    img[:, 40:] = 255
    em = edge_map(img)
    cols = np.nonzero(em.edges[30])[0]
    assert len(cols) and np.all(np.abs(cols - 39.5) < 2)
    # the nearest edge of a pixel far left is on the same row, at the step
    assert abs(em.nearest[30, 5, 1] - 30) <= 1 and abs(em.nearest[30, 5, 0] - 39.5) < 2


def test_outline_samples_lie_on_projected_hull_edges():
    intr = Intrinsics(320, 240, 260.0, 260.0, 159.5, 119.5)
    from pipeline.camera import look_at

    T = look_at(np.array([1.5, -1.5, 1.2]), np.zeros(3))
    s = silhouette_samples(np.zeros(3), np.eye(3), np.ones(3), invert(T), intr)
    assert len(s) > 20
    # every sample is on a box edge: two of its three local coordinates are +-0.5
    assert np.all((np.isclose(np.abs(s), 0.5)).sum(1) >= 2)


def test_refinement_undoes_a_small_rigid_error():
    intr = Intrinsics(320, 240, 260.0, 260.0, 159.5, 119.5)
    c, R, s = np.array([0.0, 0.0, 0.25]), rotation_about_z(0.3), np.array([0.6, 0.4, 0.5])
    fr = raycast([(c, R, s)], eye=(1.4, -1.6, 1.3), target=(0, 0, 0.2), intr=intr)
    pts, pix = backproject(fr.depth, fr.intr)
    on_box = fr.instance[pix[:, 0], pix[:, 1]] == 1
    world = transform(fr.T_world_cam, pts[on_box])
    em = edge_map(fr.color)
    c0, R0 = c + np.array([0.02, -0.015, 0.0]), rotation_about_z(0.3 + np.radians(3))
    c1, R1, info = refine_box(c0, R0, s, world, em, intr, fr.T_world_cam, upright=True)
    assert info["accepted"]
    assert info["edge_px_after"] < info["edge_px_before"]
    assert info["fit_after"] <= info["fit_before"]

    def corner_px(cc, RR):
        uv, _ = project(transform(invert(fr.T_world_cam), box_corners(cc[None], RR[None], s[None])[0]), intr)
        return uv

    err0 = np.linalg.norm(corner_px(c0, R0) - corner_px(c, R), axis=1).mean()
    err1 = np.linalg.norm(corner_px(c1, R1) - corner_px(c, R), axis=1).mean()
    assert err1 < 0.6 * err0 and err1 < 1.2  # pixels: the 320x240 edge map is the limit
    assert np.linalg.norm(c1 - c) < 0.5 * np.linalg.norm(c0 - c)


def test_refinement_rejected_when_points_disagree():
    """The paper's rule: a move that fits the edges but worsens the point fit is undone."""
    intr = Intrinsics(320, 240, 260.0, 260.0, 159.5, 119.5)
    c, R, s = np.array([0.0, 0.0, 0.25]), rotation_about_z(0.3), np.array([0.6, 0.4, 0.5])
    fr = raycast([(c, R, s)], eye=(1.4, -1.6, 1.3), target=(0, 0, 0.2), intr=intr)
    em = edge_map(fr.color)
    c0 = c + np.array([0.03, 0.0, 0.0])
    # points that say the box is exactly where it was put (c0): any move worsens their fit
    rng = np.random.default_rng(0)
    u = rng.uniform(-0.5, 0.5, (3000, 3))
    u[np.arange(3000), rng.integers(0, 3, 3000)] = 0.5
    pts = c0 + (u * s) @ R.T
    c1, R1, info = refine_box(c0, R, s, pts, em, intr, fr.T_world_cam)
    assert not info["accepted"]
    assert np.array_equal(c1, c0) and np.array_equal(R1, R)
    assert info["fit_after"] > info["fit_before"] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("upright", [True, False])
def test_the_pixel_jacobian_of_the_edge_fit_matches_finite_differences(upright):
    from pipeline.camera import look_at
    from pipeline.edges import _pixel_jacobian, _rot

    intr = Intrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)
    T_cw = invert(look_at(np.array([0.3, -2.0, 1.2]), np.array([0.0, 0.0, 0.4])))
    R = _rot(np.array([0.1, -0.2, 0.3]))
    c, size = np.array([0.1, 0.2, 0.4]), np.array([0.4, 0.3, 0.5])
    s = silhouette_samples(c, R, size, T_cw, intr)

    def pose(x):
        w = np.array([0.0, 0.0, x[0]]) if upright else x[:3]
        return c + (x[1:4] if upright else x[3:6]), _rot(w) @ R

    def pixels(x):
        cc, Rx = pose(x)
        return project(transform(T_cw, cc + s @ Rx.T), intr)[0].ravel()

    x = np.zeros(4 if upright else 6)
    J = _pixel_jacobian(pose(x), s, T_cw, intr, upright)
    numeric = np.stack([(pixels(x + 1e-6 * e) - pixels(x - 1e-6 * e)) / 2e-6
                        for e in np.eye(len(x))], axis=1)
    assert J.shape == numeric.shape
    assert np.abs(J - numeric).max() < 1e-5 * np.abs(numeric).max()
