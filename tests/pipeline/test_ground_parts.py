"""Parts of a grounded object that hang from it by glue stand on the floor instead."""

import numpy as np

from pipeline.extend import candidate_edges
from pipeline.model import Arrangement, Contact, ObservedBox, box, ground
from pipeline.search import finalize
from tests.pipeline.priors_util import changed


def ground_parts(final, initial, edges):
    """The ``ground_parts`` prior alone on the searched ``final``: (arrangement, ids of
    the parts it extended)."""
    return changed("ground_parts", final, None, initial=initial, edges=edges)


def _seen(c):
    return c.with_(observed=ObservedBox(c.center, c.size))


def _sofa(arm_top_seen: float):
    """A sofa's back on the floor and an arm beside it seen as its top ``arm_top_seen``
    metres thick (the camera behind the sofa), glued to the back."""
    back = _seen(box("back", (0.0, 0.0, 0.45), (0.2, 2.0, 0.9), object="sofa"))
    top = 0.6
    arm = _seen(box("arm", (0.4, 0.9, top - arm_top_seen / 2), (0.6, 0.2, arm_top_seen),
                    object="sofa"))
    initial = Arrangement((back, arm), (ground(),))
    final = finalize(initial, [Contact("arm", "back", "fixed")])
    return initial, final


def test_an_arm_seen_only_at_its_top_stands_on_the_floor():
    initial, final = _sofa(0.02)
    assert final.stability.stable  # glued, it stands as it is: the search would keep it
    out, done = ground_parts(final, initial, candidate_edges(initial))
    assert done == ["arm"]
    arm = out.cuboid("arm")
    np.testing.assert_allclose(arm.center[2] - arm.size[2] / 2, 0.0, atol=1e-9)
    np.testing.assert_allclose(arm.center[2] + arm.size[2] / 2, 0.6, atol=1e-9)
    keys = {(c.a, c.b, c.type) for c in out.contacts}
    assert ("arm", "ground", "touch") in keys or ("ground", "arm", "touch") in keys
    assert out.stability.stable


def test_a_part_seen_over_most_of_its_drop_keeps_hanging():
    # 0.3 m of the arm seen, 0.3 m hidden below it: not more than 1.5x what was seen
    initial, final = _sofa(0.3)
    out, done = ground_parts(final, initial, candidate_edges(initial))
    assert done == [] and out is final


def test_a_board_between_two_sides_is_not_grounded():
    sides = [_seen(box(f"side{i}", (x, 0.0, 0.5), (0.02, 0.3, 1.0), object="shelf"))
             for i, x in enumerate((-0.4, 0.4))]
    board = _seen(box("board", (0.0, 0.0, 0.5), (0.78, 0.3, 0.02), object="shelf"))
    initial = Arrangement((*sides, board), (ground(),))
    final = finalize(initial, [Contact("board", "side0", "fixed"),
                               Contact("board", "side1", "fixed")])
    out, done = ground_parts(final, initial, candidate_edges(initial))
    assert done == [] and out is final


def test_a_leg_seen_at_its_top_stands_while_three_others_hold_the_table():
    top = _seen(box("top", (0.0, 0.0, 0.72), (1.0, 0.6, 0.04), object="table"))
    legs = [_seen(box(f"leg{i}", (x, y, 0.35), (0.05, 0.05, 0.7), object="table"))
            for i, (x, y) in enumerate(((-0.45, -0.25), (0.45, -0.25), (-0.45, 0.25)))]
    # the fourth seen over its top 0.2 m only: it hangs from the top, glued
    stub = _seen(box("leg3", (0.45, 0.25, 0.6), (0.05, 0.05, 0.2), object="table"))
    initial = Arrangement((top, *legs, stub), (ground(),))
    fixed = [Contact(k, "top", "fixed") for k in ("leg0", "leg1", "leg2", "leg3")]
    final = finalize(initial, fixed)
    assert final.stability.stable
    out, done = ground_parts(final, initial, candidate_edges(initial))
    assert done == ["leg3"]
    leg = out.cuboid("leg3")
    np.testing.assert_allclose([leg.center[2] - leg.size[2] / 2, leg.center[2] + leg.size[2] / 2],
                               [0.0, 0.7], atol=1e-9)
    assert ("ground", "leg3") in {tuple(sorted((c.a, c.b))) for c in out.contacts}
    assert out.stability.stable
