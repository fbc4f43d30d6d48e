"""A box fitted through a support plane loses the part beyond it along the axis closest
to the plane's normal, or, where that axis has too little to give, along the axis that
costs the least share of its extent (``pipeline.boxops.lifted_from_plane``)."""

from __future__ import annotations

import numpy as np

from pipeline.boxops import lifted_from_plane
from pipeline.contacts import find_contacts
from pipeline.imagine import imagine
from pipeline.model import Arrangement, Support, box, ground

#: the wall x = 0, its free side +x
WALL = Support("wall:0", np.zeros(3), np.array([1.0, 0.0, 0.0]))


def _askew_bench(depth: float, angle_deg: float = 22.0):
    """A 1.34 x 0.15 x 0.48 m box standing on the floor, its long side ``angle_deg`` off
    the wall, whose far end is ``depth`` metres inside the wall (the sofa back of a
    Kinect frame fitted through a partition's plane)."""
    yaw = np.radians(90.0 - angle_deg)
    size = np.array([1.34, 0.15, 0.48])
    reach = 0.5 * (size[0] * abs(np.cos(yaw)) + size[1] * abs(np.sin(yaw)))
    return box("b0", (reach - depth, 0.0, 0.24), size, yaw=yaw), yaw


def test_a_box_askew_through_a_wall_loses_its_end_not_its_thickness():
    depth = 0.2
    b, yaw = _askew_bench(depth)
    cut = lifted_from_plane(b, WALL)
    d = WALL.signed_distance(cut.corners())
    # closed form: the long axis, at cos(yaw) to the wall's normal, is pushed in by
    # depth / cos(yaw); the thin axis (cos 0.93) would need 0.215 m of a 0.15 m box
    assert np.allclose(cut.size, [1.34 - depth / np.cos(yaw), 0.15, 0.48], atol=1e-9)
    assert abs(d.min()) < 1e-9  # touches the wall, no longer in it
    assert np.isclose(d.max(), WALL.signed_distance(b.corners()).max())  # far end stays
    assert np.allclose(cut.rotation, b.rotation)


def test_a_board_fitted_a_centimetre_into_a_wall_loses_thickness_not_length():
    # a 1 m board 3 cm thick along the wall x = 0, turned 3 degrees, its back 1 cm in the
    # wall (depth noise): the axis closest to the wall's normal can give way, so it does
    # (cutting the length would take 0.19 m of the 1 m, a smaller share than 1 cm of 3)
    yaw = np.radians(90.0 + 3.0)
    size = np.array([1.0, 0.03, 0.3])
    reach = 0.5 * (size[0] * abs(np.cos(yaw)) + size[1] * abs(np.sin(yaw)))
    b = box("b0", (reach - 0.01, 0.0, 1.0), size, yaw=yaw)
    cut = lifted_from_plane(b, WALL)
    assert np.allclose(cut.size, [1.0, 0.03 - 0.01 / abs(np.sin(yaw)), 0.3], atol=1e-9)
    assert abs(WALL.signed_distance(cut.corners()).min()) < 1e-9


def test_an_upright_box_sunk_into_the_floor_loses_its_bottom():
    b = box("b0", (0.0, 0.0, 0.2), (0.4, 0.3, 0.5), yaw=0.4)  # 5 cm below z = 0
    cut = lifted_from_plane(b, ground())
    assert np.allclose(cut.size, [0.4, 0.3, 0.45])
    assert np.isclose(cut.corners()[:, 2].min(), 0.0)
    assert np.isclose(cut.corners()[:, 2].max(), b.corners()[:, 2].max())


def test_a_box_askew_through_a_wall_is_cleared_and_the_search_makes_it_stand():
    # before the cut chose its axis by share, the box kept 0.2 m inside the wall (its
    # thickness could not give so much), every node of the search was an
    # interpenetration and the result fell back to gluing everything
    b, _ = _askew_bench(0.2)
    res = imagine(Arrangement((b,), (ground(), WALL)))
    out = res.arrangement
    assert not find_contacts(out).penetrations
    assert out.stability.stable
    assert np.isclose(out.cuboids[0].size[1], 0.15)  # its thickness kept
    assert {(c.a, c.b, c.type) for c in out.contacts} >= {("b0", "ground", "touch")}
    assert not [c for c in out.contacts if c.type == "fixed"]
