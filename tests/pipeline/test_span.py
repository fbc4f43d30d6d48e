"""The ``span`` prior: a board or panel whose end no view saw runs across its object."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.camera import Intrinsics, look_at
from pipeline.evidence import DepthView
from pipeline.model import Arrangement, box, ground
from tests.pipeline.priors_util import assert_box, changed
from tests.pipeline.test_imagine import _depth_of_boxes

EYE = (0.0, -3.5, 1.0)
SEAT = box("seat", (0.0, 0.0, 0.2), (1.9, 0.7, 0.4), object="sofa")
BACK = box("back", (0.0, 0.425, 0.5), (1.9, 0.15, 1.0), object="sofa")
#: another object in front of the sofa's left end: it hides the back there
CABINET = box("cabinet", (-0.6, -0.8, 0.8), (0.7, 0.3, 1.6), object="cabinet")
#: a wall behind, so that every ray the sofa lets through ends on something
BACKDROP = box("backdrop", (0.0, 1.2, 1.5), (6.0, 0.1, 3.0))
#: the back as one view sees it past the cabinet: x from -0.36 to 0.95
SEEN_BACK = box("back", (0.295, 0.425, 0.5), (1.31, 0.15, 1.0), object="sofa")


def _views(truth):
    intr = Intrinsics.kinect_v1()
    T = look_at(EYE, (0.0, 0.0, 0.4))
    return [DepthView(_depth_of_boxes([*truth, BACKDROP], T, intr, far=8.0), intr, T)]


def test_a_back_hidden_at_one_end_runs_to_where_its_seat_reaches():
    """The cabinet hides the left 0.59 m of the sofa's back; the seat reaches there, and
    no view saw the space empty, so the back runs the whole length of its sofa."""
    arr = Arrangement((SEAT, SEEN_BACK, CABINET), (ground(),))
    out, ids = changed("span", arr, _views([SEAT, BACK, CABINET]))
    assert ids == ["back"]
    got = out.cuboid("back")
    assert_box(got, BACK.size, BACK.center)


def test_a_back_whose_end_a_view_saw_keeps_it():
    """The back really ends at x = -0.36 and nothing hides the space beyond: the view saw
    it empty, so the seat's reach says nothing about the back."""
    arr = Arrangement((SEAT, SEEN_BACK), (ground(),))
    out, ids = changed("span", arr, _views([SEAT, SEEN_BACK]))
    assert ids == [] and out.cuboid("back") is SEEN_BACK


def test_a_board_stops_at_the_side_panel_it_meets_and_a_leg_is_no_panel():
    """A shelf's board seen short of its left side panel grows to the panel's inner face,
    not through it nor in under it to the shelf's outer edge; a square leg of a table under a wider top is
    no board and keeps its footprint."""
    left = box("left", (-0.4, 0.0, 0.5), (0.03, 0.3, 1.0), object="shelf")
    right = box("right", (0.4, 0.0, 0.5), (0.03, 0.3, 1.0), object="shelf")
    board = box("board", (0.1, 0.0, 0.5), (0.57, 0.3, 0.02), object="shelf")
    out, ids = changed("span", Arrangement((left, right, board), (ground(),)))
    assert ids == ["board"]
    got = out.cuboid("board")
    assert_box(got, [0.77, 0.3, 0.02], [0.0, 0.0, 0.5])
    # the bottom board: its side panels, fitted down to its top, stand beside it on the
    # floor, so it stops at the left one rather than running in under it
    left = box("left", (-0.4, 0.0, 0.535), (0.03, 0.3, 0.93), object="shelf")
    right = box("right", (0.4, 0.0, 0.535), (0.03, 0.3, 0.93), object="shelf")
    bottom = box("board", (0.1, 0.0, 0.06), (0.57, 0.3, 0.02), object="shelf")
    out, ids = changed("span", Arrangement((left, right, bottom), (ground(),)))
    assert ids == ["board"]
    np.testing.assert_allclose(out.cuboid("board").size, [0.77, 0.3, 0.02], atol=1e-9)
    top = box("top", (0.0, 0.0, 0.75), (1.2, 0.8, 0.03), object="table")
    leg = box("leg", (0.55, 0.35, 0.37), (0.05, 0.05, 0.74), object="table")
    out, ids = changed("span", Arrangement((top, leg), (ground(),)))
    assert ids == [] and out.cuboid("leg") is leg


def test_span_runs_after_the_parts_of_an_object_are_joined():
    """A chair's leg seen only at its foot is a flat stub until ``join_parts`` reaches it
    up to the seat; run before that, ``span`` took the stub for a board and spread it
    across the chair (held-out pool 102400: chair 95.2 -> 90.6)."""
    from pipeline.priors import PRIORS

    names = [p.name for p in PRIORS]
    assert names.index("deepen") < names.index("join_parts") < names.index("span")


def test_a_foot_lying_in_plain_view_on_a_desk_keeps_its_width():
    """A monitor's foot (20 cm wide, 2 cm thin) on a desk top under a 50 cm screen: the
    view sees the desk top on both sides of it.  A slab 2 cm above a seen surface is
    never "seen empty" (the depth noise is wider), so only what hid the space beyond the
    foot's ends could say they were cut short; nothing did, and it keeps its width.  The
    sofa's back above is grown because the cabinet hides its end."""
    intr = Intrinsics.kinect_v1()
    T = look_at((0.2, -0.6, 1.9), (0.0, 0.0, 0.8))  # from above, as a person stands
    desk = box("desk", (0.0, 0.0, 0.725), (1.2, 0.6, 0.05), object="desk")
    foot = box("foot", (0.0, 0.0, 0.76), (0.2, 0.18, 0.02), object="monitor")
    neck = box("neck", (0.0, 0.025, 0.9), (0.04, 0.03, 0.26), object="monitor")
    screen = box("screen", (0.0, 0.0, 1.05), (0.5, 0.02, 0.3), object="monitor")
    view = DepthView(_depth_of_boxes([desk, foot, neck, screen, BACKDROP], T, intr, far=8.0),
                     intr, T)
    arr = Arrangement((desk, foot, neck, screen), (ground(),))
    out, ids = changed("span", arr, [view], margin=0.01)  # the pipeline's margin here
    assert "foot" not in ids and out.cuboid("foot") is foot
    out, ids = changed("span", arr)  # without a view nothing says the ends were seen
    assert "foot" in ids and out.cuboid("foot").size[0] == pytest.approx(0.5, abs=1e-9)


def test_a_leg_fitted_as_the_sliver_of_one_face_stays_a_leg_among_its_posts():
    """A chair's four legs stand over the same heights; three are fitted as the posts they
    are, one as a 1 cm sliver of its side face (a board by its proportions).  Most parts
    standing over its heights are posts, so it is a leg too and does not run across the
    chair.  A desk's side panel fitted as a 10 cm sliver of its front grows under the
    whole top: the part standing over its heights, the other side, is a panel too."""
    seat = box("seat", (0.0, 0.0, 0.45), (0.45, 0.45, 0.04), object="chair")
    legs = [box(f"leg{i}", (x, y, 0.215), (0.04, 0.04, 0.43), object="chair")
            for i, (x, y) in enumerate([(-0.2, -0.2), (0.2, -0.2), (-0.2, 0.2)])]
    sliver = box("leg3", (0.2, 0.2, 0.215), (0.01, 0.04, 0.43), object="chair")
    out, ids = changed("span", Arrangement((seat, *legs, sliver), (ground(),)))
    assert ids == [] and out.cuboid("leg3") is sliver
    top = box("top", (0.0, 0.0, 0.735), (1.2, 0.6, 0.03), object="desk")
    left = box("left", (-0.59, 0.0, 0.36), (0.02, 0.6, 0.72), object="desk")
    front = box("right", (0.59, -0.25, 0.36), (0.02, 0.1, 0.72), object="desk")
    out, ids = changed("span", Arrangement((top, left, front), (ground(),)))
    assert ids == ["right"]
    assert_box(out.cuboid("right"), [0.02, 0.6, 0.72], [0.59, 0.0, 0.36])
