"""Closing contact gaps (pipeline.snap): what the statics counts as touching touches."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.contacts import find_contacts
from pipeline.model import Arrangement, Contact, box, ground
from pipeline.snap import close_gaps
from pipeline.stability import check_stability


def deck_on_pillars(sunk: float) -> Arrangement:
    """A 1.6 m deck on two 15 cm pillars 1 m apart, overhanging 0.6 m past pillar a, with
    a 10 cm box on the overhang; pillar a reaches ``sunk`` metres into the floor (the
    contact tolerance for a 15 cm box is 3 mm: up to that it counts as standing on it)."""
    return Arrangement((
        box("pillar_a", (0, 0, 0.17 - sunk / 2), (0.15, 0.15, 0.34 + sunk)),
        box("pillar_b", (0, 1.0, 0.17), (0.15, 0.15, 0.34)),
        box("deck", (0, 0.2, 0.365), (0.25, 1.6, 0.05)),
        box("cargo", (0, -0.53, 0.44), (0.1, 0.1, 0.1))), (ground(),))


def test_gaps_within_the_tolerance_are_closed_exactly():
    arr = Arrangement((
        box("low", (0, 0, 0.099), (0.2, 0.2, 0.202)),  # 2 mm into the floor, top at 0.2
        box("up", (0, 0, 0.2 + 0.0005 + 0.1), (0.2, 0.2, 0.2)),  # 0.5 mm above "low"
        box("side", (0.2 + 0.001, 0, 0.1), (0.2, 0.2, 0.2)),  # 1 mm beside "low"
        box("glued", (0.0, 0.0, 0.4005 + 0.0002 + 0.05), (0.1, 0.1, 0.1))),  # fused to "up"
        (ground(),), (Contact("up", "glued", "fixed"),))
    before = find_contacts(arr)
    out, worst = close_gaps(arr)
    after = find_contacts(out)
    assert worst == pytest.approx(0.002)
    assert set(after.pairs) == set(before.pairs) and not after.penetrations
    gaps = dict(zip(after.pairs, after.gap, strict=True))
    for pair in [("low", "up"), ("low", "side"), ("low", "ground"), ("up", "ground"),
                 ("side", "ground")]:
        if pair in gaps:
            assert abs(gaps[pair]) < 1e-9, pair
    # a gap inside one rigid body (the engines load one body) is left as it was
    was = dict(zip(before.pairs, before.gap, strict=True))[("up", "glued")]
    assert was == pytest.approx(0.0002) and gaps[("up", "glued")] == pytest.approx(was, abs=1e-9)
    # sub-tolerance moves only
    assert np.abs(out.centers - arr.centers).max() < 0.002
    assert np.abs(out.sizes - arr.sizes).max() < 0.004


def test_nothing_to_close_returns_the_input_itself():
    arr = deck_on_pillars(0.0)
    out, worst = close_gaps(arr)
    assert out is arr and worst == 0.0


@pytest.mark.parametrize("engine", ["mujoco", "pybullet"])
def test_a_pillar_sunk_into_the_floor_tilts_the_deck_until_the_gap_is_closed(engine):
    """Engine round trip: statics counts a pillar 2.8 mm into the floor as standing on it
    (stable), both engines push it out, which tilts the deck about the other pillar and
    lifts the box on the overhang by 4.6-6.1 mm (> 2 % of its 10 cm); closed, it stands."""
    from simulate.engines import settle

    arr = deck_on_pillars(0.0028)
    assert check_stability(arr).stable
    moved = settle(arr, engine)
    assert not moved.stable
    cargo = {b.id: b for b in moved.bodies}["cargo"]
    assert cargo.translation > 0.004 and cargo.rotation_deg > 0.1
    closed, worst = close_gaps(arr)
    assert worst == pytest.approx(0.0028)
    assert check_stability(closed).stable
    assert settle(closed, engine).stable


def _row_of_three(step: float) -> Arrangement:
    """Three 20 cm crates in a row on the floor, the last ``step`` metres taller; one
    crate rests across the first two, another on the third, its end ``step`` over the
    second (the two supports' fitted heights differ by the noise of two fits)."""
    return Arrangement((
        box("l0", (0.2, 0, 0.1), (0.4, 0.3, 0.2)),
        box("l1", (0.6, 0, 0.1), (0.4, 0.3, 0.2)),
        box("l2", (1.0, 0, (0.2 + step) / 2), (0.4, 0.3, 0.2 + step)),
        box("u0", (0.4, 0, 0.3), (0.4, 0.3, 0.2)),
        box("u1", (0.85, 0, 0.3 + step), (0.4, 0.3, 0.2))), (ground(),))


def test_close_pair_levels_a_row_so_the_upper_box_meets_both_supports():
    # raising l1's top alone would drive it into u0, which it carries with l0; the
    # smallest change that keeps every contact brings the three tops to one level
    from pipeline.snap import close_pair

    arr = _row_of_three(0.0045)
    before = find_contacts(arr)
    assert ("l1", "u1") not in before.lookup()
    out = close_pair(arr, arr.index["u1"], arr.index["l1"], np.array([0.0, 0.0, 1.0]),
                     0.0045, 0.0045)
    assert out is not None
    after = find_contacts(out)
    assert set(after.lookup()) == set(before.lookup()) | {("l1", "u1")}
    assert not after.penetrations
    tops = [out.cuboid(k).center[2] + out.cuboid(k).size[2] / 2 for k in ("l0", "l1", "l2")]
    assert max(tops) - min(tops) < 1e-9  # one level
    for k in ("u0", "u1"):  # each upper box sits on that level
        c = out.cuboid(k)
        assert c.center[2] - c.size[2] / 2 == pytest.approx(tops[0], abs=1e-9)
    for a, b in zip(arr.cuboids, out.cuboids, strict=True):  # nothing moved far
        assert np.abs(a.center - b.center).max() <= 0.0045
        assert np.abs(a.size - b.size).max() <= 0.0045 * 2
    assert check_stability(out).stable
    # a gap larger than the change allowed is left alone
    assert close_pair(arr, arr.index["u1"], arr.index["l1"], np.array([0.0, 0.0, 1.0]),
                      0.0045, 0.001) is None
