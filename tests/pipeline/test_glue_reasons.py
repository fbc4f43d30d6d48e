"""report.md's reasons for glue (pipeline.stability.glue_reasons): per fixed joint between
different objects, what falls without it, checked against the closed-form tipping point
of a box overhanging its support."""

from __future__ import annotations

from pipeline.model import Arrangement, Contact, box, ground
from pipeline.stability import glue_reasons


def _overhang(shift: float, fixed: bool = True) -> Arrangement:
    """A 0.4 m plank on a 0.2 m wide block, its centre ``shift`` beyond the block's centre.

    The plank tips when its centre of mass passes the block's edge: shift > 0.1 m."""
    block = box("block", (0.0, 0.0, 0.25), (0.2, 0.3, 0.5), object="block")
    plank = box("plank", (shift, 0.0, 0.55), (0.4, 0.3, 0.1), object="plank")
    t = "fixed" if fixed else "touch"
    return Arrangement((block, plank), (ground(),),
                       (Contact("block", "ground", "touch"), Contact("block", "plank", t)))


def test_a_glue_joint_that_holds_an_overhang_names_what_would_fall():
    (c, falls, margin), = glue_reasons(_overhang(0.13))  # 3 cm past the tipping point
    assert c.key == ("block", "plank") and falls == ["plank"]


def test_a_glue_joint_nothing_needs_is_reported_as_spare():
    (c, falls, margin), = glue_reasons(_overhang(0.0))
    assert falls == [] and margin is True
    # 1 mm inside the tipping point it stands, but not with gravity tilted by 2 degrees,
    # which moves the plank's weight (0.05 m above the block) by 0.05 tan 2 deg = 1.7 mm
    (_, falls, margin), = glue_reasons(_overhang(0.099))
    assert falls == [] and margin is False


def test_joints_inside_one_object_are_not_glue():
    arr = _overhang(0.13)
    one = arr.with_(cuboids=tuple(c.with_(object="bench") for c in arr.cuboids))
    assert glue_reasons(one) == []
