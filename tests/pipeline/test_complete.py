"""Structure-guided completion (pipeline.complete): matching, ground-edge alignment, ICP,
transfer."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.complete import (
    CompleteConfig,
    Matching,
    align,
    box_affine,
    edge_alignments,
    icp_refine,
    parts_of,
    refine_matching,
    score_alignments,
    spectral_match,
    surface_distance,
    transfer,
    upright_transform,
)
from pipeline.model import box

#: An object of five distinct parts, none a copy of another (no symmetry to confuse a
#: test of the exact permutation): a desk-like top on a panel and a drawer block, a
#: monitor and a box.
PARTS = [("top", (0.0, 0.0, 0.74), (1.4, 0.7, 0.04)),
         ("panel", (-0.68, 0.0, 0.36), (0.03, 0.7, 0.72)),
         ("drawer", (0.5, 0.02, 0.36), (0.4, 0.6, 0.72)),
         ("monitor", (-0.2, 0.2, 0.98), (0.55, 0.06, 0.44)),
         ("box", (0.4, -0.1, 0.82), (0.2, 0.15, 0.12))]


def object_cuboids(scale=(1.0, 1.0, 1.0), yaw: float = 0.0, shift=(0.0, 0.0, 0.0),
                   noise: float = 0.0, rng=None, order=None):
    """The object's cuboids scaled per world axis, turned by ``yaw``, moved, with
    relative size noise, in ``order``."""
    rng = rng or np.random.default_rng(0)
    T = upright_transform(yaw, shift)
    out = []
    for name, c, s in PARTS:
        c = np.asarray(c) * scale
        s = np.asarray(s) * scale * (1 + noise * rng.uniform(-1, 1, 3))
        out.append(box(name, T[:3, :3] @ c + T[:3, 3], s, yaw=yaw, object="desk0"))
    order = range(len(out)) if order is None else order
    return [out[k] for k in order]


def surface_points(cuboids, spacing: float = 0.02) -> np.ndarray:
    """Points on the boxes' faces (visible or not), a grid per face."""
    pts = []
    for c in cuboids:
        h = c.size / 2
        for ax in range(3):
            u, v = [a for a in range(3) if a != ax]
            gu, gv = np.meshgrid(np.arange(-h[u], h[u] + 1e-9, spacing),
                                 np.arange(-h[v], h[v] + 1e-9, spacing))
            for sign in (-1, 1):
                loc = np.zeros((gu.size, 3))
                loc[:, u], loc[:, v], loc[:, ax] = gu.ravel(), gv.ravel(), sign * h[ax]
                pts.append(c.center + loc @ c.rotation.T)
    return np.concatenate(pts)


# ----------------------------------------------------------------------------- matching
def test_spectral_match_recovers_a_permutation_under_size_noise():
    perm = [3, 0, 4, 2, 1]  # partial part k is template part perm[k]
    a = parts_of(object_cuboids())
    b = parts_of(object_cuboids(yaw=1.1, shift=(2.0, -1.0, 0.0), noise=0.05,
                                rng=np.random.default_rng(4), order=perm))
    m = spectral_match(a, b)
    assert len(m.pairs) == len(PARTS)
    assert {(i, j) for i, j in m.pairs} == {(perm[j], j) for j in range(len(perm))}
    assert all(0.0 < c <= 1.0 for c in m.confidence)


def test_spectral_match_survives_other_proportions():
    """A wider, taller object of the same kind: each part still finds its partner."""
    a = parts_of(object_cuboids())
    b = parts_of(object_cuboids(scale=(1.3, 1.1, 1.05), yaw=-0.4))
    m = spectral_match(a, b)
    assert sorted(m.pairs) == [(k, k) for k in range(len(PARTS))]


def test_impossible_pairs_are_pruned():
    """The paper's rule: heights more than 5 cm and lengths more than 10 cm apart."""
    a = parts_of([box("tall", (0, 0, 0.5), (1.0, 1.0, 1.0))])
    b = parts_of([box("small", (0, 0, 0.05), (0.1, 0.1, 0.1))])
    m = spectral_match(a, b)
    assert m.pairs == () and m.candidates == 0 and m.pruned == 1
    # one criterion within its tolerance keeps the pair (height 1.0 vs 1.04)
    c = parts_of([box("thin", (0, 0, 0.52), (0.1, 0.1, 1.04))])
    m2 = spectral_match(a, c)
    assert m2.candidates == 1 and m2.pruned == 0
    # with tighter tolerances nothing is left
    m3 = spectral_match(a, c, CompleteConfig(height_tol=0.01, length_tol=0.01))
    assert m3.pairs == () and m3.pruned == 1


def test_a_part_without_partner_stays_unmatched():
    a = parts_of(object_cuboids())
    # a wardrobe-sized block: 1.2 m high and 1.6 m long, like no part of the desk
    b = parts_of(object_cuboids() + [box("block", (0.0, 0.9, 0.6), (1.6, 0.5, 1.2))])
    m = spectral_match(a, b)
    assert sorted(m.pairs) == [(k, k) for k in range(len(PARTS))]
    assert m.pruned >= len(PARTS)  # the block against every part


# ---------------------------------------------------------------------------- alignment
def test_ground_edge_alignment_recovers_a_rigid_transform_exactly():
    yaw, shift = 2.3, (1.7, -0.6, 0.25)  # 0.25: the partial scan's floor is higher
    T_true = upright_transform(yaw, shift)
    tc = object_cuboids()
    pc = object_cuboids(yaw=yaw, shift=shift)
    a, b = parts_of(tc), parts_of(pc)
    m = Matching(tuple((k, k) for k in range(len(PARTS))), (1.0,) * len(PARTS), 5, 0)
    Ts = edge_alignments(a, b, m.pairs, dz=0.25)
    assert Ts.shape == (32 * len(PARTS), 4, 4)
    assert min(np.abs(T - T_true).max() for T in Ts) < 1e-12
    tp, pp = surface_points(tc), surface_points(pc)
    scores = score_alignments(Ts, tp, pp, cap=0.1)
    best = Ts[int(np.argmin(scores))]
    assert np.abs(best - T_true).max() < 1e-9
    for pairs in ("matched", "all"):
        T, info = align(a, b, m, tp, pp, 0.25, CompleteConfig(icp_iterations=0, edge_pairs=pairs))
        assert np.abs(T - T_true).max() < 1e-9
        assert 0 < info["candidates"] <= (len(Ts) if pairs == "matched" else 32 * len(PARTS) ** 2)


def test_every_pair_of_parts_aligns_without_a_matching():
    """No spectral pair (a partial view the matching cannot read): the paper's candidates
    are gone and the centroids are put on each other unturned; candidates from every pair
    of parts still hold the exact pose."""
    yaw, shift = 2.3, (1.7, -0.6, 0.0)
    T_true = upright_transform(yaw, shift)
    tc, pc = object_cuboids(), object_cuboids(yaw=yaw, shift=shift)
    a, b = parts_of(tc), parts_of(pc)
    tp, pp = surface_points(tc), surface_points(pc)
    none = Matching((), (), 0, 0)
    T, info = align(a, b, none, tp, pp, 0.0, CompleteConfig(icp_iterations=0))
    assert np.abs(T - T_true).max() < 1e-9
    T, _ = align(a, b, none, tp, pp, 0.0, CompleteConfig(icp_iterations=0, edge_pairs="matched"))
    assert np.allclose(T[:3, :3], np.eye(3)) and np.abs(T - T_true).max() > 1.0


class SeenEmpty:
    """Depth views reduced to what :func:`align` asks: space seen empty, one box."""

    def __init__(self, lo, hi):
        self.lo, self.hi = np.asarray(lo), np.asarray(hi)

    def free_mask(self, points):
        return np.all((points >= self.lo) & (points <= self.hi), axis=1)


def test_space_seen_empty_turns_a_template_that_fits_the_seen_points_both_ways():
    """Only the desk top's upper face is seen: the template fits it turned by 0 and by a
    half turn alike.  Where the scan saw empty space under one end of the top, the pose
    that puts the drawer block there loses, whichever end it is."""
    tc = object_cuboids()
    a = b = parts_of(tc)
    tp = surface_points(tc)
    top = tc[0]
    pp = surface_points([top])
    pp = pp[pp[:, 2] > top.center[2] + top.size[2] / 2 - 1e-9]  # the upper face only
    m = Matching(((0, 0),), (1.0,), 1, 0)
    cfg = CompleteConfig(icp_iterations=0)
    for empty_x, yaw in (((-0.65, -0.3), 0.0), ((0.3, 0.65), np.pi)):
        views = SeenEmpty((empty_x[0], -0.3, 0.05), (empty_x[1], 0.3, 0.7))
        T, _ = align(a, b, m, tp, pp, 0.0, cfg, views=views)
        assert np.abs(T - upright_transform(yaw, (0.0, 0.0, 0.0))).max() < 1e-9


def test_icp_improves_a_perturbed_alignment():
    yaw, shift = 0.7, (0.4, 0.9, 0.0)
    T_true = upright_transform(yaw, shift)
    tc = object_cuboids()
    tp = surface_points(tc, 0.01)
    pp = surface_points(object_cuboids(yaw=yaw, shift=shift), 0.02)
    pp = pp[pp[:, 1] < np.median(pp[:, 1])]  # a partial view: half of it
    T0 = upright_transform(yaw + np.radians(3.0), (shift[0] + 0.03, shift[1] - 0.02, 0.0))
    T, info = icp_refine(T0, tp, pp, CompleteConfig(icp_distance=0.1))

    def err(M):
        return float(np.abs(M - T_true)[:3].max())

    assert err(T) < 0.2 * err(T0) and err(T) < 5e-3
    assert info["fitness"] >= info["fitness_before"]
    assert info["rmse"] < info["rmse_before"]
    assert abs(T[2, 3]) < 1e-12 and np.allclose(T[2, :3], [0, 0, 1])  # stays upright


# ----------------------------------------------------------------------------- transfer
def test_parts_transfer_carries_each_part_into_its_partner_box():
    """A template of other proportions: rigid transfer misses the partial boxes, the parts
    transfer lands every point on its partner box's surface."""
    tc = object_cuboids()
    pc = object_cuboids(scale=(1.3, 1.1, 1.05), yaw=0.5, shift=(1.0, 0.0, 0.0))
    a, b = parts_of(tc), parts_of(pc)
    m = spectral_match(a, b)
    assert sorted(m.pairs) == [(k, k) for k in range(len(PARTS))]
    T = upright_transform(0.5, (1.0, 0.0, 0.0))
    tp = surface_points(tc)
    rigid = transfer(tp, a, b, m, T, "rigid")
    parts = transfer(tp, a, b, m, T, "parts")
    assert np.allclose(rigid, tp @ T[:3, :3].T + T[:3, 3])
    assert surface_distance(parts, b).max() < 1e-9
    assert surface_distance(rigid, b).mean() > 0.02


def test_config_is_validated():
    with pytest.raises(ValueError, match="height_tol"):
        CompleteConfig(height_tol=0.0)
    with pytest.raises(ValueError, match="transfer"):
        CompleteConfig(transfer="morph")


def table(width: float, depth: float, height: float, yaw: float = 0.0, shift=(0.0, 0.0)):
    """A top on four legs (a symmetric object: distances cannot tell its mirror image)."""
    T = upright_transform(yaw, (*shift, 0.0))
    legs = [((sx * (width / 2 - 0.04), sy * (depth / 2 - 0.04), (height - 0.04) / 2),
             (0.05, 0.05, height - 0.04)) for sx in (-1, 1) for sy in (-1, 1)]
    out = []
    for k, (c, s_) in enumerate([((0, 0, height - 0.02), (width, depth, 0.04)), *legs]):
        out.append(box(f"p{k}", T[:3, :3] @ np.asarray(c, float) + T[:3, 3], s_, yaw=yaw,
                       object="table0"))
    return out


def test_aligned_matching_tells_left_legs_from_right():
    """Spectral matching pairs legs by distances alone (a mirror image scores the same);
    once aligned, each template leg finds the partial leg in the same corner, also for a
    table of other proportions."""
    a = parts_of(table(1.2, 0.7, 0.75))
    b = parts_of(table(1.5, 0.8, 0.7, yaw=0.8, shift=(2.0, 1.0)))
    T = upright_transform(0.8, (2.0, 1.0, 0.0))
    m = refine_matching(a, b, T)
    assert sorted(m.pairs) == [(k, k) for k in range(5)]
    # a wrong spectral pair whose parts are both taken is not added
    wrong = Matching(((1, 4),), (1.0,), 1, 0)
    assert sorted(refine_matching(a, b, T, spectral=wrong).pairs) == [(k, k) for k in range(5)]


def test_box_affine_maps_a_scaled_object_onto_the_other():
    tc = object_cuboids()
    pc = object_cuboids(scale=(1.3, 1.1, 1.05), yaw=0.5, shift=(1.0, -2.0, 0.0))
    a, b = parts_of(tc), parts_of(pc)
    A = box_affine(a, b, upright_transform(0.5, (1.0, -2.0, 0.0)))
    for c_t, c_p in zip(tc, pc, strict=True):
        assert np.allclose(A[:3, :3] @ c_t.center + A[:3, 3], c_p.center, atol=1e-9)
    # a scale outside [0.5, 2] is not trusted: the rigid transform comes back
    big = parts_of(object_cuboids(scale=(3.0, 1.0, 1.0)))
    assert np.allclose(box_affine(a, big, np.eye(4)), np.eye(4))


def test_level_offset_uses_floors_or_lowest_points():
    on_floor = parts_of(table(1.0, 0.6, 0.7))
    raised = parts_of([box("b", (0, 0, 0.25), (0.3, 0.2, 0.1))])  # bottom 0.2 above z = 0
    from pipeline.complete import level_offset

    # both stand on floors found 3 cm apart: the floors decide
    assert level_offset(on_floor, on_floor, 0.0, 0.03) == pytest.approx(0.03)
    assert level_offset(on_floor, raised, 0.0, 0.0) == pytest.approx(0.2)  # on a box
