"""The ``reach`` prior: an unheld body reaches back over what carries it, as far as the
lever balance demands (closed form), through space no view saw."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.model import Arrangement, Cuboid, ground
from pipeline.priors.gate import TILT_DEG
from pipeline.priors.reach import Params, stands_on
from tests.pipeline.priors_util import run

TAN = np.tan(np.radians(TILT_DEG))
BLOCK = Cuboid("block", (0.0, -0.10, 0.40), np.eye(3), (0.40, 0.40, 0.80), object="block")
EDGE = 0.10  # the block's edge towards the camera (+y)
T = 0.04  # the plank's thickness
W = 0.24  # the plank's width (x)


def _plank(y0: float, y1: float = 0.40) -> Cuboid:
    return Cuboid("plank", (0.0, (y0 + y1) / 2, 0.80 + T / 2), np.eye(3), (W, y1 - y0, T),
                  object="plank")


WEIGHT = Cuboid("weight", (0.0, 0.32, 0.84 + 0.09), np.eye(3), (W, 0.16, 0.18), object="weight")


def test_a_plank_stands_exactly_while_its_centre_of_mass_is_inside_the_margin():
    # alone: its centre of mass is its centre, T/2 above its bottom
    margin = T / 2 * TAN
    for inside in (margin + 1e-3, margin - 1e-3):
        y1 = 0.40
        y0 = 2 * (EDGE - inside) - y1  # centre at EDGE - inside
        assert stands_on(_plank(y0, y1), [], [BLOCK]) == (inside > margin)


def _balanced_y0() -> float:
    """The plank's far end where plank and weight balance at the tilted margin, from
    the lever equation m_p (y0 + y1) / 2 + m_w y_w = (m_p + m_w) (EDGE - margin), with
    m_p = rho W T (y1 - y0), solved for y0 (a quadratic)."""
    y1, yw = 0.40, WEIGHT.center[1]
    mw = float(np.prod(WEIGHT.size))  # same density for both
    zc_guess = 0.84  # centre-of-mass height for the margin, refined below
    for _ in range(20):
        c = EDGE - (zc_guess - 0.80) * TAN
        # W T (y1 - y0) (y0 + y1) / 2 + mw yw = (W T (y1 - y0) + mw) c
        a = W * T
        # a (y1^2 - y0^2) / 2 + mw yw - a (y1 - y0) c - mw c = 0
        # -a/2 y0^2 + a c y0 + (a y1^2 / 2 + mw yw - a y1 c - mw c) = 0
        roots = np.roots([-a / 2, a * c, a * y1 ** 2 / 2 + mw * yw - a * y1 * c - mw * c])
        y0 = float(min(r.real for r in roots if r.real < y1))
        mp = a * (y1 - y0)
        zc_guess = (mp * (0.80 + T / 2) + mw * WEIGHT.center[2]) / (mp + mw)
    return y0


def test_a_counterweighted_plank_reaches_back_as_far_as_the_lever_balance_needs():
    stub = _plank(0.38)  # only its near end was seen
    arr = Arrangement((BLOCK, stub, WEIGHT), (ground(),))
    assert not stands_on(stub, [WEIGHT], [BLOCK])
    out, report = run("reach", arr, unheld=("plank", "weight"))
    (edit,) = [e for e in report.edits if e.prior == "reach"]
    assert edit.accepted and edit.boxes == ("plank",)
    got = out.cuboid("plank")
    y0 = float(got.center[1] - got.size[1] / 2)
    want = _balanced_y0()
    # the first step past the balance point: no further, no shorter
    assert want - Params().step <= y0 < want
    assert stands_on(got, [WEIGHT], [BLOCK])
    assert got.size[0] == W and got.size[2] == T and got.center[1] + got.size[1] / 2 == 0.40


def test_nothing_to_reach_nothing_held_or_switched_off():
    stub = _plank(0.38)
    arr = Arrangement((BLOCK, stub, WEIGHT), (ground(),))
    # not asked: the search held everything
    out, report = run("reach", arr)
    assert out is arr and report.edits == []
    # nothing under it in any direction: no proposal (a post is the posts prior's job)
    high = BLOCK.with_(center=np.array([0.0, -0.10, 0.30]), size=np.array([0.4, 0.4, 0.6]))
    out, report = run("reach", Arrangement((high, stub, WEIGHT), (ground(),)),
                      unheld=("plank",))
    assert out.cuboid("plank") is stub and report.edits == []


@pytest.mark.parametrize("free", [True, False])
def test_the_reach_goes_only_through_space_no_view_saw(free):
    """A camera high above the plank's seen end looks down over the weight onto the block:
    with the space behind the stub seen empty (no plank there) the reach is refused; with
    the plank there its volume is hidden under its top, and the reach is taken."""
    from pipeline.camera import Intrinsics, look_at
    from pipeline.evidence import DepthView
    from tests.pipeline.test_imagine import _depth_of_boxes

    stub = _plank(0.38)
    arr = Arrangement((BLOCK, stub, WEIGHT), (ground(),))
    intr = Intrinsics.kinect_v1()
    pose = look_at((0.0, 1.2, 2.0), (0.0, -0.2, 0.8))
    scene = [BLOCK, stub, WEIGHT] if free else [BLOCK, _plank(-0.8), WEIGHT]
    views = [DepthView(_depth_of_boxes(scene, pose, intr), intr, pose)]
    out, report = run("reach", arr, views=views, unheld=("plank",))
    (edit,) = [e for e in report.edits if e.prior == "reach"]
    assert edit.accepted == (not free)
    if free:
        assert "seen" in edit.why_not and out.cuboid("plank") is stub
