"""Scoring metrics against hand-computed truth and independent geometry (shapely, manifold)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from eval.metrics import (
    MIN_MATCH_IOU,
    PRF,
    align_axes,
    box_iou,
    compare_graphs,
    contact_graph,
    initial_arrangement,
    initial_graph,
    match_cuboids,
    match_supports,
    pairwise_iou,
    paper_size_error,
    relative_size_errors,
    score_arrangement,
    valence_stats,
)
from pipeline.model import (
    Arrangement,
    Contact,
    ObservedBox,
    Support,
    box,
    ground,
    rotation_about_axis,
    rotation_about_z,
)


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


# ------------------------------------------------------------------ IoU: closed forms
def test_iou_unit_cubes_offset_half_is_one_third():
    a = box("a", (0, 0, 0), (1, 1, 1))
    b = box("b", (0.5, 0, 0), (1, 1, 1))
    # intersection 0.5, union 1.5
    assert box_iou(a, b) == pytest.approx(1 / 3, abs=1e-9)


def test_iou_cube_and_its_45_degree_turn():
    a = box("a", (0, 0, 0), (1, 1, 1))
    b = box("b", (0, 0, 0), (1, 1, 1), yaw=math.pi / 4)
    # regular octagon of inradius 1/2: area 8 r^2 tan(pi/8) = 2 (sqrt2 - 1); IoU = 1/sqrt2
    inter = 2 * (math.sqrt(2) - 1)
    assert box_iou(a, b) == pytest.approx(inter / (2 - inter), abs=1e-9)
    assert box_iou(a, b) == pytest.approx(1 / math.sqrt(2), abs=1e-9)


def test_iou_identical_touching_disjoint_nested():
    a = box("a", (0.3, -0.2, 1.0), (0.4, 0.5, 0.6), yaw=0.7)
    assert box_iou(a, a) == pytest.approx(1.0, abs=1e-9)
    face_touch = box("b", (1.0, 0, 0), (1, 1, 1))
    unit = box("u", (0, 0, 0), (1, 1, 1))
    assert box_iou(unit, face_touch) == pytest.approx(0.0, abs=1e-9)
    assert box_iou(unit, box("c", (3, 0, 0), (1, 1, 1))) == 0.0
    inner = box("i", (0.1, 0.1, 0.1), (0.2, 0.3, 0.4), yaw=0.3)
    assert box_iou(unit, inner) == pytest.approx(0.2 * 0.3 * 0.4, rel=1e-9)


def test_iou_tilted_cube_corner_through_face():
    # A cube standing on its corner? Use rotation about x by 45 deg: cross-section in y-z is
    # the octagon again, extruded along x; a 2-long box along x keeps the same ratio.
    a = box("a", (0, 0, 0), (2, 1, 1))
    b = box("b", (0, 0, 0), (2, 1, 1), rotation=rotation_about_axis([1, 0, 0], math.pi / 4))
    assert box_iou(a, b) == pytest.approx(1 / math.sqrt(2), abs=1e-9)


@settings(max_examples=60, deadline=None)
@given(
    st.tuples(*[st.floats(-0.6, 0.6)] * 3), st.tuples(*[st.floats(0.1, 1.5)] * 3),
    st.tuples(*[st.floats(0.1, 1.5)] * 3), st.floats(0, 2 * math.pi), st.floats(0, 2 * math.pi),
)
def test_iou_matches_shapely_for_yawed_boxes(offset, size_a, size_b, yaw_a, yaw_b):
    shapely = pytest.importorskip("shapely")
    from shapely import affinity

    a = box("a", (0, 0, 0), size_a, yaw=yaw_a)
    b = box("b", offset, size_b, yaw=yaw_b)

    def footprint(c):
        sx, sy = c.size[0] / 2, c.size[1] / 2
        poly = shapely.geometry.box(-sx, -sy, sx, sy)
        yaw = math.atan2(c.rotation[1, 0], c.rotation[0, 0])
        poly = affinity.rotate(poly, yaw, origin=(0, 0), use_radians=True)
        return affinity.translate(poly, c.center[0], c.center[1])

    dz = min(a.center[2] + a.size[2] / 2, b.center[2] + b.size[2] / 2) - max(
        a.center[2] - a.size[2] / 2, b.center[2] - b.size[2] / 2)
    inter = footprint(a).intersection(footprint(b)).area * max(dz, 0.0)
    truth = inter / (a.volume + b.volume - inter)
    assert box_iou(a, b) == pytest.approx(truth, abs=1e-9)
    assert box_iou(b, a) == pytest.approx(truth, abs=1e-9)


def test_iou_matches_manifold_boolean_for_random_rotations():
    trimesh = pytest.importorskip("trimesh")
    pytest.importorskip("manifold3d")
    rng = np.random.default_rng(7)
    n = 25
    ca = rng.uniform(-0.3, 0.3, (n, 3))
    cb = rng.uniform(-0.3, 0.3, (n, 3))
    sa = rng.uniform(0.2, 1.2, (n, 3))
    sb = rng.uniform(0.2, 1.2, (n, 3))
    ra = np.stack([_random_rotation(rng) for _ in range(n)])
    rb = np.stack([_random_rotation(rng) for _ in range(n)])
    iou = pairwise_iou(ca, ra, sa, cb, rb, sb)
    for k in range(n):
        meshes = []
        for c, r, s in ((ca[k], ra[k], sa[k]), (cb[k], rb[k], sb[k])):
            t = np.eye(4)
            t[:3, :3], t[:3, 3] = r, c
            meshes.append(trimesh.creation.box(extents=s, transform=t))
        inter = trimesh.boolean.intersection(meshes, engine="manifold").volume
        truth = inter / (np.prod(sa[k]) + np.prod(sb[k]) - inter)
        assert iou[k, k] == pytest.approx(truth, abs=1e-7), k


def test_iou_invariant_under_rigid_motion_and_pairwise_consistent():
    rng = np.random.default_rng(3)
    c = rng.uniform(-0.4, 0.4, (6, 3))
    r = np.stack([_random_rotation(rng) for _ in range(6)])
    s = rng.uniform(0.3, 1.0, (6, 3))
    iou = pairwise_iou(c, r, s, c, r, s)
    assert iou.shape == (6, 6)
    np.testing.assert_allclose(np.diag(iou), 1.0, atol=1e-9)
    np.testing.assert_allclose(iou, iou.T, atol=1e-9)
    g = _random_rotation(rng)
    t = rng.normal(size=3)
    moved = pairwise_iou(c @ g.T + t, g[None] @ r, s, c @ g.T + t, g[None] @ r, s)
    np.testing.assert_allclose(moved, iou, atol=1e-9)
    # a box rotated by 180 degrees about its own axis is the same box
    flipped = r @ np.diag([-1.0, -1.0, 1.0])
    np.testing.assert_allclose(np.diag(pairwise_iou(c, r, s, c, flipped, s)), 1.0, atol=1e-9)


# ------------------------------------------------------------------ graphs
def test_three_edge_graph_one_wrong_type_by_hand():
    gt = [("a", "b", "touch"), ("b", "c", "fixed"), ("a", "ground", "touch")]
    pred = [("x", "y", "touch"), ("y", "z", "touch"), ("x", "ground", "touch")]
    mapping = {"x": "a", "y": "b", "z": "c", "ground": "ground"}
    s = compare_graphs(pred, gt, mapping)
    # typed: 2 of 3 predicted right, 2 of 3 true found
    assert (s.typed.tp, s.typed.n_pred, s.typed.n_gt) == (2, 3, 3)
    assert s.typed.precision == pytest.approx(2 / 3)
    assert s.typed.recall == pytest.approx(2 / 3)
    assert s.typed.f1 == pytest.approx(2 / 3)
    # untyped: every pair right
    assert (s.untyped.precision, s.untyped.recall, s.untyped.f1) == (1.0, 1.0, 1.0)
    assert s.false_positives == (("b", "c", "touch"),)
    assert s.false_negatives == (("b", "c", "fixed"),)


def test_graph_extra_edge_unmatched_node_and_order_free():
    gt = [("a", "b", "touch"), ("b", "c", "fixed"), ("a", "ground", "touch")]
    # edges given in reversed order; one edge to an unmatched predicted box q
    pred = [("y", "x", "touch"), ("z", "y", "fixed"), ("q", "x", "touch")]
    s = compare_graphs(pred, gt, {"x": "a", "y": "b", "z": "c"})
    # typed: tp 2 of 3 predicted, 2 of 3 true -> P = R = 2/3
    assert (s.typed.tp, s.typed.n_pred, s.typed.n_gt) == (2, 3, 3)
    assert ("?q", "a", "touch") in s.false_positives
    assert s.false_negatives == (("a", "ground", "touch"),)
    # a fourth predicted edge that is wrong: P = 2/4, R = 2/3, F1 = 2PR/(P+R) = 4/7
    s4 = compare_graphs(pred + [("x", "z", "touch")], gt, {"x": "a", "y": "b", "z": "c"})
    assert s4.typed.precision == pytest.approx(0.5)
    assert s4.typed.recall == pytest.approx(2 / 3)
    assert s4.typed.f1 == pytest.approx(4 / 7)


def test_valence_by_hand():
    edges = [("a", "b", "touch"), ("b", "c", "fixed"), ("a", "ground", "touch"),
             ("c", "ground", "touch"), ("b", "wall:0", "fixed"), ("b", "a", "touch")]
    v = valence_stats(edges, ["a", "b", "c", "d"])
    # degrees a 2, b 3, c 2, d 0 (the duplicate b-a counts once)
    assert (v.n_proxies, v.n_contacts, v.n_support_contacts) == (4, 5, 3)
    assert (v.max, v.median, v.mean, v.min) == (3, 2.0, 7 / 4, 0)


def test_prf_edge_cases_and_micro_sum():
    assert PRF(0, 0, 0).f1 == 1.0
    assert PRF(0, 0, 4).f1 == 0.0 and PRF(0, 3, 0).precision == 0.0
    total = PRF(2, 3, 4) + PRF(1, 1, 2)
    assert (total.tp, total.n_pred, total.n_gt) == (3, 4, 6)
    assert total.f1 == pytest.approx(2 * (3 / 4) * (3 / 6) / (3 / 4 + 3 / 6))


# ------------------------------------------------------------------ matching
def _stack_scene() -> Arrangement:
    cubes = (box("g0", (0, 0, 0.25), (1.0, 0.8, 0.5), object="o0"),
             box("g1", (0.1, 0, 0.7), (0.6, 0.6, 0.4), object="o1"),
             box("g2", (2.0, 0, 0.3), (0.4, 0.4, 0.6), yaw=0.4, object="o2"))
    return Arrangement(cubes, (ground(),),
                       (Contact("g0", "ground"), Contact("g1", "g0", "fixed"),
                        Contact("g2", "ground")))


def test_hungarian_matching_recovers_permuted_noisy_boxes():
    gt = _stack_scene()
    rng = np.random.default_rng(0)
    order = [2, 0, 1]
    preds = tuple(box(f"p{k}", gt.cuboids[i].center + rng.normal(0, 0.01, 3),
                      gt.cuboids[i].size * 0.95, rotation=gt.cuboids[i].rotation)
                  for k, i in enumerate(order))
    m = match_cuboids(Arrangement(preds), gt)
    assert m.pred_to_gt == {"p0": "g2", "p1": "g0", "p2": "g1"}
    assert set(m.how) == {"iou"} and np.all(m.iou > 0.7)
    assert m.unmatched_pred == () and m.unmatched_gt == ()


def test_instance_ids_choose_among_overlapping_parts_but_a_match_must_overlap():
    gt = _stack_scene()
    # p straddles g0 (more overlap) and g1; the scan's instance mask says it is g1
    # (index 2 -> cuboids[1]): it matches g1, not the part it overlaps more
    p = box("p", (0.05, 0, 0.45), (0.8, 0.7, 0.5))
    assert box_iou(p, gt.cuboids[0]) > box_iou(p, gt.cuboids[1]) >= MIN_MATCH_IOU
    m = match_cuboids(Arrangement((p.with_(extra={"instance": 2}),)), gt)
    assert m.pred_to_gt == {"p": "g1"} and m.how == ("instance",)
    # p0 sits on g0 but names g2 (index 3), which it does not overlap: no match at all,
    # not even with g0; p1 (no instance) takes g0 by IoU
    p0 = box("p0", gt.cuboids[0].center, gt.cuboids[0].size).with_(extra={"instance": 3})
    p1 = box("p1", gt.cuboids[0].center, gt.cuboids[0].size)
    m = match_cuboids(Arrangement((p0, p1)), gt)
    assert m.pred_to_gt == {"p1": "g0"} and m.how == ("iou",)
    assert m.unmatched_pred == ("p0",) and m.unmatched_gt == ("g1", "g2")
    # far away box: no IoU match
    far = box("f", (10, 10, 10), (1, 1, 1))
    assert match_cuboids(Arrangement((far,)), gt).unmatched_pred == ("f",)


@pytest.mark.parametrize(("shift", "matched"), [(0.80, True), (0.83, False)])
def test_every_match_needs_iou_of_at_least_the_threshold(shift, matched):
    # a unit cube slid by d along x keeps IoU (1 - d) / (1 + d): 0.111 at 0.80, 0.093 at 0.83
    gt = Arrangement((box("g0", (0, 0, 0.5), (1, 1, 1), object="o"),), (ground(),))
    p = box("p0", (shift, 0, 0.5), (1, 1, 1))
    assert box_iou(p, gt.cuboids[0]) == pytest.approx((1 - shift) / (1 + shift), abs=1e-9)
    assert MIN_MATCH_IOU == 0.1
    by_instance = p.with_(extra={"instance": 1})
    by_object = p.with_(object="o")
    for q, how in ((by_instance, "instance"), (by_object, "object"), (p, "iou")):
        m = match_cuboids(Arrangement((q,)), gt)
        assert m.pred_to_gt == ({"p0": "g0"} if matched else {})
        assert m.how == ((how,) if matched else ())


def test_a_box_far_from_its_part_loses_exactly_that_parts_contacts():
    # The desk case: every box carries the right instance id, one of them (p1) was fitted
    # beside its part.  Matching by id alone credited all four contacts; now p1 is
    # unmatched, its two contacts are false positives and g1's two true ones are missed.
    gt = Arrangement((box("g0", (0, 0, 0.25), (1.0, 0.8, 0.5)),
                      box("g1", (0.1, 0, 0.7), (0.6, 0.6, 0.4)),
                      box("g2", (0.1, 0, 1.0), (0.3, 0.3, 0.2)),
                      box("g3", (2.0, 0, 0.3), (0.4, 0.4, 0.6))), (ground(),),
                     (Contact("g0", "ground"), Contact("g1", "g0", "fixed"),
                      Contact("g2", "g1"), Contact("g3", "ground")))
    cubes = [c.with_(id=f"p{k}", extra={"instance": k + 1}) for k, c in enumerate(gt.cuboids)]
    contacts = (Contact("p0", "ground"), Contact("p1", "p0", "fixed"), Contact("p2", "p1"),
                Contact("p3", "ground"))
    good = Arrangement(tuple(cubes), gt.supports, contacts)
    s = score_arrangement(good, gt, graph="listed")
    assert s.optimized.typed == PRF(4, 4, 4) and s.matched_iou == pytest.approx(1.0)
    # p1 grown into a 70 cm cube beside its part (IoU 0.025)
    moved = cubes[1].with_(center=np.array([0.65, 0.0, 0.35]), size=np.array([0.7, 0.7, 0.7]))
    assert 0.02 < box_iou(moved, gt.cuboids[1]) < 0.03
    bad = good.with_(cuboids=(cubes[0], moved, cubes[2], cubes[3]))
    s = score_arrangement(bad, gt, graph="listed")
    assert s.matching.unmatched_pred == ("p1",) and s.matching.unmatched_gt == ("g1",)
    assert s.optimized.typed == PRF(2, 4, 4) and s.optimized.untyped == PRF(2, 4, 4)
    assert s.optimized.false_positives == (("?p1", "g0", "fixed"), ("?p1", "g2", "touch"))
    assert s.optimized.false_negatives == (("g0", "g1", "fixed"), ("g1", "g2", "touch"))
    # the geometry of what matched is untouched by the unmatched box
    assert s.matched_iou == pytest.approx(1.0) and s.side_error == pytest.approx(0.0, abs=1e-12)
    assert s.mean_iou == pytest.approx(3 / 4)


def test_side_error_and_matched_iou_by_hand():
    gt = Arrangement((box("g0", (0, 0, 0.5), (1.0, 1.0, 1.0)),
                      box("g1", (3, 0, 1.0), (1.0, 0.5, 2.0))), (ground(),))
    # p0 half as tall (IoU 0.5, one side 0.5 m short); p1 is g1 turned 90 degrees about z
    # with its x and y sizes swapped (the same box: IoU 1, no side error)
    p0 = box("p0", (0, 0, 0.25), (1.0, 1.0, 0.5))
    p1 = box("p1", (3, 0, 1.0), (0.5, 1.0, 2.0), yaw=math.pi / 2)
    s = score_arrangement(Arrangement((p0, p1), (ground(),)), gt, graph="listed")
    assert s.matching.pred_to_gt == {"p0": "g0", "p1": "g1"}
    np.testing.assert_allclose(s.iou, [0.5, 1.0], atol=1e-9)
    assert s.matched_iou == pytest.approx(0.75)
    assert s.side_abs == pytest.approx(0.5) and s.side_len == pytest.approx(3.0 + 3.5)
    assert s.side_error == pytest.approx(0.5 / 6.5)
    js = s.to_json()
    assert js["matched_iou"] == pytest.approx(0.75) and js["side_error"] == pytest.approx(0.5 / 6.5)
    none = score_arrangement(Arrangement((), (ground(),)), gt, graph="listed")
    assert none.matched_iou != none.matched_iou and none.to_json()["side_error"] is None


def test_object_names_restrict_matching():
    gt = _stack_scene()
    # straddles g0 (more overlap) and g1; without a name it goes to g0
    p = box("p", (0.05, 0, 0.45), (0.8, 0.7, 0.5))
    assert match_cuboids(Arrangement((p,)), gt).pred_to_gt == {"p": "g0"}
    # it says it belongs to object o1: it may only match g1
    m = match_cuboids(Arrangement((p.with_(object="o1"),)), gt)
    assert m.pred_to_gt == {"p": "g1"} and m.how == ("object",)
    # names that are not GT object names are ignored
    m = match_cuboids(Arrangement((p.with_(object="cluster7"),)), gt)
    assert m.pred_to_gt == {"p": "g0"}
    # a sliver of its object that overlaps the part too little is no match either
    sliver = box("s", (0.1, 0.33, 0.93), (0.6, 0.2, 0.2), object="o1")  # IoU 0.018
    assert box_iou(sliver, gt.cuboids[1]) < MIN_MATCH_IOU
    assert match_cuboids(Arrangement((sliver,)), gt).pred_to_gt == {}
    assert match_cuboids(Arrangement((sliver.with_(object=None),)), gt).pred_to_gt == {}


@pytest.mark.parametrize("family", ["table", "shelf", "sofa", "room"])
def test_matching_recovers_perturbed_synthetic_scenes(family):
    from synth_scenes.registry import make

    rng = np.random.default_rng(1)
    for seed in range(2):
        gt = make(family, np.random.default_rng(seed))
        perm = rng.permutation(len(gt.cuboids))
        cubes = []
        for k, i in enumerate(perm):
            c = gt.cuboids[i]
            turn = rotation_about_axis(rng.normal(size=3), math.radians(rng.uniform(-3, 3)))
            cubes.append(c.with_(id=f"p{k}", object=None, rotation=turn @ c.rotation,
                                 center=c.center + rng.normal(0, 0.01, 3) * c.size,
                                 size=c.size * rng.uniform(0.95, 1.05, 3)))
        m = match_cuboids(Arrangement(tuple(cubes)), gt)
        assert m.pred_to_gt == {f"p{k}": gt.cuboids[i].id for k, i in enumerate(perm)}


def test_support_matching_by_plane():
    gt = Arrangement((), (ground(), Support("wall:0", (3, 0, 0), (-1, 0, 0)),
                          Support("wall:1", (0, 3, 0), (0, -1, 0))))
    tilt = rotation_about_z(math.radians(5)) @ np.array([0.0, -1.0, 0.0])
    pred = Arrangement((), (ground(0.01), Support("wall:0", (0.2, 3.05, 0), tilt),
                            Support("wall:1", (-3, 0, 0), (1, 0, 0))))  # faces the wrong way
    assert match_supports(pred, gt) == {"ground": "ground", "wall:0": "wall:1"}


# ------------------------------------------------------------------ sizes
def test_paper_size_error_hand_example():
    gt = np.array([[1.0, 2.0, 4.0], [2.0, 2.0, 2.0]])
    init = np.array([[0.5, 2.0, 4.0], [2.0, 1.0, 2.0]])
    opt = np.array([[0.9, 2.0, 4.1], [2.0, 2.4, 2.0]])
    eye = np.broadcast_to(np.eye(3), (2, 3, 3))
    e_init = relative_size_errors(init, eye, gt, eye)
    e_opt = relative_size_errors(opt, eye, gt, eye)
    np.testing.assert_allclose(e_init, [[0.5, 0, 0], [0, 0.5, 0]])
    np.testing.assert_allclose(e_opt, [[0.1, 0, 0.025], [0, 0.2, 0]])
    s = paper_size_error(e_init, e_opt, gt)
    # changes 0.4 (weight 1) and 0.3 (weight 2) pass eps = 5 %; the 0.025 change does not
    assert s.n_changed == 2
    assert s.error == pytest.approx((1 * 0.4 + 2 * 0.3) / 3)
    assert s.improvement == pytest.approx((1 * 0.4 + 2 * 0.3) / 3)
    assert s.mean_init == pytest.approx((1 * 0.5 + 2 * 0.5) / 13)  # sum of true sides = 13
    assert s.mean_opt == pytest.approx((1 * 0.1 + 4 * 0.025 + 2 * 0.2) / 13)
    assert paper_size_error(e_init, e_init, gt).error == 0.0


def test_size_errors_follow_axes_not_order():
    # predicted box turned 90 degrees about z: its local x is the GT's y, so sizes swap
    gt_r = np.eye(3)[None]
    pr = rotation_about_z(math.pi / 2)[None]
    np.testing.assert_array_equal(align_axes(pr, gt_r), [[1, 0, 2]])
    e = relative_size_errors(np.array([[2.0, 1.1, 3.0]]), pr, np.array([[1.0, 2.0, 3.0]]), gt_r)
    np.testing.assert_allclose(e, [[0.1, 0.0, 0.0]], atol=1e-12)


# ------------------------------------------------------------------ whole score
def _prediction(gt: Arrangement) -> Arrangement:
    """The truth seen partially: each box observed at 60 % of its height, then extended back."""
    cubes = []
    for k, c in enumerate(gt.cuboids):
        obs_size = c.size * np.array([1.0, 1.0, 0.6])
        obs_center = c.center + np.array([0, 0, 0.2 * c.size[2]])
        cubes.append(c.with_(id=f"p{k}", object=None, observed=ObservedBox(obs_center, obs_size)))
    contacts = (Contact("p0", "ground"), Contact("p1", "p0", "touch"), Contact("p2", "ground"))
    return Arrangement(tuple(cubes), gt.supports, contacts)


def test_score_listed_graph_perfect_boxes_one_wrong_type():
    gt = _stack_scene()
    s = score_arrangement(_prediction(gt), gt, graph="listed")
    assert s.matching.pred_to_gt == {"p0": "g0", "p1": "g1", "p2": "g2"}
    np.testing.assert_allclose(s.iou, 1.0, atol=1e-9)
    assert s.mean_iou == pytest.approx(1.0)
    assert s.optimized.typed.f1 == pytest.approx(2 / 3)
    assert s.optimized.untyped.f1 == 1.0
    # initial boxes: 60 % of the height inside the truth -> IoU 0.6; size error 0.4 on z sides
    np.testing.assert_allclose(s.iou_initial, 0.6, atol=1e-9)
    assert s.size.error == pytest.approx(0.4) and s.size.improvement == pytest.approx(0.4)
    assert s.size.mean_opt == pytest.approx(0.0, abs=1e-12)
    js = s.to_json()
    assert js["optimized"]["typed"]["tp"] == 2 and len(js["cuboids"]) == 3


def test_score_truth_against_itself_is_perfect():
    gt = _stack_scene()
    s = score_arrangement(gt, gt, graph="listed")
    assert s.optimized.typed.f1 == 1.0 and s.initial is None and s.size is None
    assert s.mean_iou == pytest.approx(1.0)


def test_mean_iou_is_undefined_against_an_empty_truth():
    """Nothing to overlap is not a perfect overlap: NaN (None in JSON), whatever was
    predicted."""
    from pipeline.model import Arrangement

    empty = Arrangement((), _stack_scene().supports)
    s = score_arrangement(_stack_scene(), empty, graph="listed")
    assert s.n_gt == 0 and np.isnan(s.mean_iou)
    assert s.to_json()["mean_iou"] is None


def test_initial_graph_from_geometry():
    pytest.importorskip("pipeline.contacts")
    gt = _stack_scene()
    pred = _prediction(gt)
    init = initial_arrangement(pred)
    np.testing.assert_allclose(init.sizes[:, 2], gt.sizes[:, 2] * 0.6)
    s = score_arrangement(pred, gt, graph="union")
    # observed boxes float 0.1-0.12 m above the ground and above g0's top: farther than
    # the initial graph's 2 cm, so nothing touches initially
    assert s.initial.typed.n_pred == 0 and s.initial.typed.recall == 0.0
    # the truth's geometry adds no pair that is not listed (g1 on g0, g0 and g2 on ground)
    assert {(a, b) for a, b, _ in contact_graph(gt)} == {(a, b) for a, b, _ in
                                                         contact_graph(gt, "listed")}
    assert s.optimized.untyped.f1 == 1.0


@pytest.mark.parametrize(("gap", "expected"), [(0.0199, True), (0.0201, False)])
def test_initial_graph_counts_pairs_within_two_centimetres(gap, expected):
    # a box hovering `gap` above another (yawed, so the faces are not aligned) and `gap`
    # above the ground elsewhere: both pairs are in the initial graph iff gap <= 2 cm
    lower = box("a", (0, 0, 0.25), (1.0, 0.8, 0.5))
    upper = box("b", (0.1, 0, 0.5 + gap + 0.2), (0.4, 0.4, 0.4), yaw=0.3)
    apart = box("c", (3.0, 0, 0.15 + gap), (0.3, 0.3, 0.3))
    edges = initial_graph(Arrangement((lower, upper, apart), (ground(),)))
    assert (("a", "b", "touch") in edges) is expected
    assert (("c", "ground", "touch") in edges) is expected
    assert ("a", "ground", "touch") in edges  # resting exactly
    assert not any("c" in e[:2] and "a" in e[:2] for e in edges)


def test_iou_of_a_box_with_itself_is_one_for_rotations_the_reader_admits():
    """A rotation written with a few decimals (orthonormal to 1e-6, as arrangement_io
    accepts) used to give IoU 0 of a box with itself: its edges lie in the other's faces."""
    from scipy.spatial.transform import Rotation

    from eval.metrics import pairwise_iou
    from pipeline.constants import ROTATION_TOL

    c, s = np.array([[0.1, -0.2, 0.5]]), np.array([[0.4, 0.3, 0.2]])
    checked = 0
    for k in range(50):
        for decimals in (7, 8, 10):
            R = np.round(Rotation.random(random_state=k).as_matrix(), decimals)
            if np.abs(R.T @ R - np.eye(3)).max() > ROTATION_TOL:
                continue
            checked += 1
            assert pairwise_iou(c, R[None], s, c, R[None], s)[0, 0] == pytest.approx(1.0, abs=1e-9)
            moved = c + np.array([[0.2, 0.0, 0.0]]) @ R.T  # half a box along its own x
            assert pairwise_iou(c, R[None], s, moved, R[None], s)[0, 0] == \
                pytest.approx(1 / 3, abs=1e-6)
    assert checked > 100
