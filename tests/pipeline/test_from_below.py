"""The ``from_below`` prior: a load that leans on a wall while resting on furniture is
carried by the furniture's hidden side instead (pipeline/priors/from_below.py)."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.contacts import find_contacts, pair_tolerance
from pipeline.model import Arrangement, Contact, ObservedBox, Support, box, ground
from pipeline.stability import check_stability
from tests.pipeline.priors_util import accepted, run

WALL_Y = 0.5  # the wall's plane; its normal points back into the room (-y)


def _scene(seen_back: float) -> Arrangement:
    """A night stand 0.3 m deep (y -0.05..0.25, top 0.7 m) in front of a wall at y = 0.5,
    and a lamp on it that reaches back to the wall (y 0.15..0.5) with its centre of mass
    beyond the stand's back face; the sensor saw the lamp up to ``seen_back``."""
    stand = box("stand", (0.0, 0.1, 0.35), (0.5, 0.3, 0.7))
    lamp = box("lamp", (0.0, 0.325, 0.95), (0.2, 0.35, 0.5))
    seen = np.array([0.0, (0.15 + seen_back) / 2, 0.95])
    lamp = lamp.with_(observed=ObservedBox(seen, (0.2, seen_back - 0.15, 0.5)))
    wall = Support("wall:0", (0.0, WALL_Y, 0.0), (0.0, -1.0, 0.0))
    return Arrangement(cuboids=(stand, lamp), supports=(ground(), wall))


def _wall_load(arr: Arrangement) -> float:
    """The lamp-wall contact's load over the largest load (the statics' solution)."""
    cs = find_contacts(arr)
    res = check_stability(arr, mu=0.7, contacts=cs)
    assert res.stable
    return float(res.contact_load[cs.lookup()[("lamp", "wall:0")]] / res.contact_load.max())


def _stands_without_wall(arr: Arrangement) -> bool:
    alone = arr.with_(supports=(ground(),), contacts=(), stability=None)
    return check_stability(alone, mu=0.7, tilt_deg=2.0).stable


def test_a_lamp_leaning_on_the_wall_from_a_night_stand_is_carried_by_the_stand():
    arr = _scene(seen_back=0.45)
    # before: the lamp's centre (y 0.325) is past the stand's back (0.25): it leans
    assert _wall_load(arr) > 0.01
    assert not _stands_without_wall(arr)

    out, report = run("from_below", arr, mu=0.7)

    assert [e.boxes for e in accepted(report, "from_below")] == [("stand",)]
    stand = out.cuboids[out.index["stand"]]
    y = stand.corners()[:, 1]
    # under as much of the lamp as was seen (to y 0.45), short of the wall
    np.testing.assert_allclose([y.min(), y.max()], [-0.05, 0.45], atol=1e-9)
    np.testing.assert_allclose(stand.size[[0, 2]], [0.5, 0.7], atol=1e-12)  # nothing else
    assert out.cuboids[out.index["lamp"]] == arr.cuboids[arr.index["lamp"]]
    # after: the wall carries nothing, and the lamp stands with the wall taken away
    assert _wall_load(out) < 1e-9
    assert _stands_without_wall(out)


def test_a_lean_the_sensor_did_not_see_past_the_stand_is_left_alone():
    # the lamp was seen only up to 5 mm past the stand's back (min_push is 10 mm): the
    # part over the gap is the search's guess, not evidence of a load there
    arr = _scene(seen_back=0.255)
    out, report = run("from_below", arr, mu=0.7)
    assert not report.edits
    assert out.cuboids == arr.cuboids


def test_a_box_in_the_way_behind_the_stand_stops_the_push():
    arr = _scene(seen_back=0.45)
    crate = box("crate", (0.2, 0.4, 0.3), (0.1, 0.15, 0.6))  # under the gap, on the floor
    arr = arr.with_(cuboids=arr.cuboids + (crate,))
    out, report = run("from_below", arr, mu=0.7)
    assert [e.accepted for e in report.edits] == [False]
    assert report.edits[0].why_not == "crate into stand by 100.0 mm"
    assert out.cuboids == arr.cuboids


# --- propped: a load resting on furniture is not also stood on the floor by a column ---

def _propped(seen_bottom: float, stand_y: float = 0.25) -> Arrangement:
    """A night stand (y -0.05..``stand_y``, top 0.7 m) carrying a lamp's base (y 0.1..0.25,
    z 0.7..1.0), to which the lamp's shade (y 0.25..0.35) is fixed; the search stood the
    shade on the floor (z 0..1.2) though the sensor saw it only from ``seen_bottom`` up."""
    stand = box("stand", (0.0, (stand_y - 0.05) / 2, 0.35), (0.5, stand_y + 0.05, 0.7))
    base = box("base", (0.0, 0.175, 0.85), (0.2, 0.15, 0.3))
    shade = box("shade", (0.0, 0.3, 0.6), (0.2, 0.1, 1.2))
    shade = shade.with_(observed=ObservedBox((0.0, 0.3, (seen_bottom + 1.2) / 2),
                                             (0.2, 0.1, 1.2 - seen_bottom)))
    return Arrangement(cuboids=(stand, base, shade), supports=(ground(),),
                       contacts=(Contact("base", "shade", "fixed"),))


def _floor_load(arr: Arrangement, who: str) -> float:
    """The ``who``-floor contact's load over the largest load (0 when they do not touch)."""
    cs = find_contacts(arr.with_(stability=None))
    res = check_stability(arr, mu=0.7, contacts=cs)
    assert res.stable
    k = cs.lookup().get(("ground", who))
    return 0.0 if k is None else float(res.contact_load[k] / res.contact_load.max())


def test_a_lamp_propped_on_the_floor_by_its_unseen_shade_rests_on_the_stand():
    arr = _propped(seen_bottom=0.9)
    assert _floor_load(arr, "shade") > 0.01  # before: the column carries the lamp

    out, report = run("from_below", arr, mu=0.7)

    assert [sorted(e.boxes) for e in accepted(report, "from_below")] == [["shade", "stand"]]
    stand = out.cuboids[out.index["stand"]]
    y = stand.corners()[:, 1]
    # pushed back under the shade as far as it was seen (y 0.35), nothing else changed
    np.testing.assert_allclose([y.min(), y.max()], [-0.05, 0.35], atol=1e-9)
    np.testing.assert_allclose(stand.size[[0, 2]], [0.5, 0.7], atol=1e-12)
    shade = out.cuboids[out.index["shade"]]
    z = shade.corners()[:, 2]
    np.testing.assert_allclose([z.min(), z.max()], [0.9, 1.2], atol=1e-9)  # as seen
    assert _floor_load(out, "shade") == 0.0
    # the lamp stands on the stand alone, with gravity tilted by the gate's margin
    assert check_stability(out.with_(stability=None), mu=0.7, tilt_deg=2.0).stable


@pytest.mark.parametrize("seen_bottom, glued", [
    # seen from 0.5 m up, 0.2 m under the stand's top (more than rest_gap, 0.04 m): the
    # sensor saw the part reach below the level the lamp rests at; it is a leg
    (0.5, False),
    # glued to the floor (a joint the search needed, or the user's): not an unseen prop
    (0.9, True),
])
def test_a_leg_or_a_column_glued_to_the_floor_stays(seen_bottom, glued):
    arr = _propped(seen_bottom=seen_bottom)
    if glued:
        arr = arr.with_(contacts=arr.contacts + (Contact("shade", "ground", "fixed"),))
    out, report = run("from_below", arr, mu=0.7)
    assert not report.edits
    assert out.cuboids == arr.cuboids


def test_a_push_stops_short_of_a_box_in_the_way():
    # a crate beside the shade, behind the stand, leaves room for 4 cm of push (y up to
    # 0.29): the lamp's centre of mass (y 0.225) over its base on the stand needs no more
    arr = _propped(seen_bottom=0.9)
    crate = box("crate", (0.25, 0.34, 0.3), (0.2, 0.1, 0.6))  # x 0.15..0.35, y 0.29..0.39
    arr = arr.with_(cuboids=arr.cuboids + (crate,))
    out, report = run("from_below", arr, mu=0.7)
    assert [e.accepted for e in report.edits] == [True]
    y = out.cuboids[out.index["stand"]].corners()[:, 1]
    tol = pair_tolerance(arr.cuboids[0].size, crate.size)  # how far a touch may reach in
    assert 0.29 - 1e-3 <= y.max() <= 0.29 + tol + 1e-3
    assert out.cuboids[out.index["crate"]] == crate
    assert _floor_load(out, "shade") == 0.0
