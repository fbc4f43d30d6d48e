import numpy as np
import pytest

from pipeline.contacts import find_contacts
from pipeline.model import Arrangement, Cuboid, box, ground, rotation_about_axis
from synth_scenes.brick_wall import brick_wall


def _polygon_area(pts: np.ndarray, normal: np.ndarray) -> float:
    """Area of a planar convex polygon given in any vertex order."""
    c = pts.mean(axis=0)
    u = pts[0] - c if np.linalg.norm(pts[0] - c) > 0 else np.array([1.0, 0, 0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    xy = np.stack([(pts - c) @ u, (pts - c) @ v], axis=1)
    order = np.argsort(np.arctan2(xy[:, 1], xy[:, 0]))
    x, y = xy[order, 0], xy[order, 1]
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def test_face_face_at_45_degrees_is_a_regular_octagon():
    arr = Arrangement((box("a", (0, 0, 0.5), (1, 1, 1)), box("b", (0, 0, 1.5), (1, 1, 1), yaw=np.pi / 4)))
    cs = find_contacts(arr)
    assert cs.pairs == [("a", "b")]
    poly = cs.polygon(0)
    assert len(poly) == 8
    np.testing.assert_allclose(poly[:, 2], 1.0, atol=1e-12)
    # two unit squares centred and rotated by 45 deg overlap in a regular octagon of area 2(sqrt2 - 1)
    assert _polygon_area(poly, np.array([0, 0, 1.0])) == pytest.approx(2 * (np.sqrt(2) - 1), rel=1e-9)
    # normal points from b (above) into a (below)
    np.testing.assert_allclose(cs.normal[0], [0, 0, -1], atol=1e-12)


def test_offset_faces_give_the_clipped_rectangle():
    arr = Arrangement((box("a", (0, 0, 0.5), (1, 1, 1)), box("b", (0.3, 0.2, 1.25), (1, 2, 0.5))))
    poly = find_contacts(arr).polygon(0)
    assert len(poly) == 4
    np.testing.assert_allclose(np.sort(poly[:, 0]), [-0.2, -0.2, 0.5, 0.5], atol=1e-12)
    np.testing.assert_allclose(np.sort(poly[:, 1]), [-0.5, -0.5, 0.5, 0.5], atol=1e-12)


def test_edge_and_vertex_contacts_with_the_ground():
    # a cube rotated 30 deg about x rests on an edge: 2 vertices
    R = rotation_about_axis([1, 0, 0], np.radians(30))
    c = Cuboid("e", np.zeros(3), R, np.ones(3))
    lift = -c.corners()[:, 2].min()
    edge = Arrangement((c.with_(center=np.array([0, 0, lift])),), (ground(),))
    cs = find_contacts(edge)
    assert cs.count == 1 and cs.n_vertices[0] == 2
    np.testing.assert_allclose(cs.vertices[:, 2], 0.0, atol=1e-12)
    # a cube standing on a corner (body diagonal vertical): 1 vertex
    diag = np.array([1.0, 1.0, 1.0]) / np.sqrt(3)
    axis = np.cross(diag, [0, 0, 1.0])
    R = rotation_about_axis(axis, np.arccos(diag[2]))
    c = Cuboid("v", np.zeros(3), R, np.ones(3))
    lift = -c.corners()[:, 2].min()
    cs = find_contacts(Arrangement((c.with_(center=np.array([0, 0, lift])),), (ground(),)))
    assert cs.count == 1 and cs.n_vertices[0] == 1


def test_edge_on_face_between_boxes():
    R = rotation_about_axis([1, 0, 0], np.pi / 4)  # a square prism with an edge pointing down
    top = Cuboid("t", np.array([0, 0, 1 + np.sqrt(2) / 2]), R, np.array([0.6, 1, 1]))
    cs = find_contacts(Arrangement((box("a", (0, 0, 0.5), (1, 1, 1)), top)))
    assert cs.count == 1 and cs.n_vertices[0] == 2
    np.testing.assert_allclose(np.sort(cs.vertices[:, 0]), [-0.3, 0.3], atol=1e-9)


def test_gap_within_tolerance_touches_beyond_does_not_and_overlap_is_reported():
    base = box("a", (0, 0, 0.5), (1, 1, 1))
    near = Arrangement((base, box("b", (0, 0, 1.5 + 0.005), (1, 1, 1))))
    far = Arrangement((base, box("b", (0, 0, 1.5 + 0.05), (1, 1, 1))))
    deep = Arrangement((base, box("b", (0, 0, 1.5 - 0.1), (1, 1, 1))))
    assert find_contacts(near).pairs == [("a", "b")]
    assert find_contacts(far).count == 0
    cs = find_contacts(deep)
    assert cs.count == 0 and cs.penetrations[0][:2] == ("a", "b")
    assert cs.penetrations[0][2] == pytest.approx(0.1)


def test_tolerance_is_relative_to_box_size():
    # the same configuration scaled by 1e-3 keeps the same contacts
    for s in (1e-3, 1.0, 1e3):
        arr = Arrangement((box("a", (0, 0, 0.5 * s), (s, s, s)), box("b", (0, 0, 1.505 * s), (s, s, s))))
        assert find_contacts(arr).count == 1


def test_brick_wall_contact_count_matches_its_construction():
    per, courses = 6, 5
    arr = brick_wall(per * courses + 2, per_course=per)  # odd courses have per + 1 bricks
    n_even, n_odd = 3 * per, 2 * (per + 1)
    assert len(arr.cuboids) == n_even + n_odd
    cs = find_contacts(arr)
    ground_contacts = sum(1 for a, b in cs.pairs if b == "ground")
    side = sum(1 for m in range(cs.count) if abs(cs.normal[m, 2]) < 1e-9)
    stacked = cs.count - ground_contacts - side
    assert ground_contacts == per
    assert side == 3 * (per - 1) + 2 * per
    # every pair of consecutive courses shares 2 * per bearing interfaces
    assert stacked == (courses - 1) * 2 * per


def test_sliver_interfaces_collapse_to_a_point_instead_of_failing():
    import shapely

    from pipeline.contacts import _clean

    sliver = shapely.Polygon([(0, 0), (1e-13, 0), (1e-13, 1e-13), (0, 1e-13)])
    out = _clean(np.array([sliver, shapely.box(0, 0, 1, 1)], dtype=object))
    assert out[0].geom_type == "Point"
    assert out[1].equals(shapely.box(0, 0, 1, 1))
