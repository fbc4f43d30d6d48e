"""The ``between`` prior: loads lying between an object's sides rest on a hidden part of it."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.boxops import z_range
from pipeline.camera import Intrinsics, look_at
from pipeline.contacts import find_contacts
from pipeline.evidence import DepthView, Evidence
from pipeline.imagine import imagine
from pipeline.model import Arrangement, box, ground
from pipeline.priors import ImagineConfig, between
from tests.pipeline.priors_util import accepted, assert_box, changed, run
from tests.pipeline.test_imagine import _depth_of_boxes

P = between.Params()
SEAT = 0.42  # the cushions' bottom
DEPTH = 0.6  # the cushions' extent front to back (y from -0.3 to 0.3)


def _xyz(name, x0, x1, y0, y1, z0, z1, obj):
    return box(name, ((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2),
               (x1 - x0, y1 - y0, z1 - z0), object=obj)


def _sofa(inner_a=-0.65, arm_b_y=(-0.3, 0.3), arm_y=(-0.3, 0.3), back=True, arms=2,
          arm_z=(0.0, 0.60)):
    """Two arms (x) and a back (y > 0.3) of ``sofa``, three board-thick cushions of their
    own lying between the arms 0.42 m up, nothing under them."""
    parts = [_xyz("armA", -0.80, inner_a, *arm_y, *arm_z, "sofa")]
    if arms == 2:
        parts.append(_xyz("armB", 0.65, 0.80, *arm_b_y, *arm_z, "sofa"))
    if back:
        parts.append(_xyz("back", -0.65, 0.65, 0.30, 0.45, 0.0, 0.90, "sofa"))
    cushions = [_xyz(f"c{i}", x0, x1, -0.3, 0.3, SEAT, SEAT + 0.02, f"cushion{i}")
                for i, (x0, x1) in enumerate(((-0.65, -0.22), (-0.22, 0.22), (0.22, 0.65)))]
    return Arrangement(tuple(parts + cushions), (ground(),))


def _view(arr, eye, target=(0.0, 0.0, 0.3)):
    intr = Intrinsics.kinect_v1()
    T = look_at(eye, target)
    return [DepthView(_depth_of_boxes(list(arr.cuboids), T, intr), intr, T)]


def _assert_carries(arr, part):
    """Nothing in ``arr`` interpenetrates, and ``part`` touches the three cushions, both
    arms and the floor."""
    contacts = find_contacts(arr)
    assert not contacts.penetrations
    pairs = {frozenset((contacts.names[a], contacts.names[b]))
             for a, b in zip(contacts.a, contacts.b)}
    for k in ("c0", "c1", "c2", "armA", "armB", "ground"):
        assert frozenset((k, part)) in pairs, k


def test_cushions_between_a_sofas_arms_rest_on_one_hidden_part_of_it():
    arr = _sofa()
    out, ids = changed("between", arr)
    assert ids == ["sofa_under"]
    under = out.cuboid("sofa_under")
    # from arm to arm, as deep as the arms, from the floor up to the cushions
    assert_box(under, (1.30, DEPTH, SEAT), (0.0, 0.0, SEAT / 2))
    assert under.object == "sofa" and under.extra["hallucinated"]
    _assert_carries(out, "sofa_under")


def test_the_hidden_part_stops_at_the_back_that_runs_between_the_arms():
    # the arms run the whole depth, back included: the part under the cushions is cut
    # at the back's front face (the back lies at one end, not under the loads' middle)
    out, ids = changed("between", _sofa(arm_y=(-0.3, 0.45), arm_b_y=(-0.3, 0.45)))
    assert ids == ["sofa_under"]
    assert_box(out.cuboid("sofa_under"), (1.30, DEPTH, SEAT), (0.0, 0.0, SEAT / 2))


def test_space_under_the_cushions_a_view_saw_empty_gets_no_part():
    arr = _sofa()
    # from the side, above the arm: the arm and the cushions' tops hide the space under
    # them, and the part is kept
    hidden = _view(arr, (-2.5, 0.0, 1.2))
    out, report = run("between", arr, hidden)
    assert [e.boxes for e in accepted(report, "between")] == [("sofa_under",)]
    # from the front, low: the view saw under the cushions through to the back
    seen = _view(arr, (0.0, -2.5, 0.25), (0.0, 0.0, 0.25))
    out, report = run("between", arr, seen)
    assert not accepted(report, "between")
    (why,) = [e.why_not for e in report.edits if e.prior == "between"]
    assert why.startswith("sofa_under: ") and why.endswith("of its added volume seen empty")
    assert "sofa_under" not in {c.id for c in out.cuboids}


@pytest.mark.parametrize("into, kept", [(P.side_tol - 0.001, True),
                                        (P.side_tol + 0.001, False)])
def test_a_side_reaching_into_the_load_by_more_than_the_fit_noise_flanks_nothing(into, kept):
    # the arm reaches into the first cushion's extent: within the fit's noise it is still
    # beside it; further, it is no side of it (the other two still lie between the arms)
    out, report = run("between", _sofa(inner_a=-0.65 + into))
    (edit,) = accepted(report, "between")
    loads = edit.reason.split(" between ")[0]
    assert loads == ("c0, c1, c2" if kept else "c1, c2")
    under = out.cuboid("sofa_under")  # from the arm's inner face
    assert under.center[0] - under.size[0] / 2 == pytest.approx(-0.65 + into)


@pytest.mark.parametrize("share, kept", [(P.cover_min + 0.01, True),
                                         (P.cover_min - 0.01, False)])
def test_a_side_must_cover_the_load_front_to_back(share, kept):
    half = share * DEPTH / 2
    out, ids = changed("between", _sofa(arm_b_y=(-half, half), back=False))
    assert (ids == ["sofa_under"]) is kept
    if kept:  # over the depth both arms cover
        assert out.cuboid("sofa_under").size[1] == pytest.approx(2 * half)


@pytest.mark.parametrize("above, kept", [(P.side_tol - 0.001, True),
                                         (P.side_tol + 0.001, False)])
def test_sides_must_be_beside_the_load_not_above_it(above, kept):
    # arms seen only by their tops (their lower ends hidden) may start just above the
    # cushions' top within the fit's noise; parts higher up (the brackets of a board
    # above) are no sides of it
    low = SEAT + 0.02 + above
    out, ids = changed("between", _sofa(arm_z=(low, low + 0.15), back=False))
    assert (ids == ["sofa_under"]) is kept
    if kept:
        assert_box(out.cuboid("sofa_under"), (1.30, DEPTH, SEAT), (0.0, 0.0, SEAT / 2))


def test_a_load_with_one_side_or_a_box_under_it_gets_nothing():
    assert changed("between", _sofa(arms=1))[1] == []
    arr = _sofa()
    stool = _xyz("stool", -0.2, 0.2, -0.2, 0.2, 0.0, SEAT, "stool")  # under c1
    low = Arrangement(arr.cuboids + (stool,), arr.supports)
    # c1 rests on the stool; c0 and c2 still lie between the arms, but the part under
    # them would enter the stool under their middle
    out, ids = changed("between", low)
    assert ids == []
    # loads lower than min_height over the floor are left to stand on it
    flat = Arrangement(tuple(c.with_(center=c.center - np.array([0, 0, SEAT - 0.5 * P.min_height]))
                             if c.object.startswith("cushion") else c for c in arr.cuboids),
                       arr.supports)
    assert changed("between", flat)[1] == []


def test_the_whole_pipeline_stands_the_cushions_on_the_hidden_part_not_on_columns():
    arr = _sofa()
    views = _view(arr, (-2.5, 0.0, 1.2))
    res = imagine(arr, Evidence(tuple(views)))
    final = res.arrangement
    assert final.stability is not None and final.stability.stable
    pairs = {frozenset((c.a, c.b)): c.type for c in final.contacts}
    for k in ("c0", "c1", "c2"):
        assert pairs.get(frozenset((k, "sofa_under"))) == "touch", k
        assert frozenset((k, "ground")) not in pairs, k  # no column down to the floor
    assert pairs.get(frozenset(("sofa_under", "ground"))) == "touch"
    # the part is the sofa's: fixed to its arms
    assert pairs.get(frozenset(("armA", "sofa_under"))) == "fixed"
    # switched off, each cushion stands on a column of its own
    off = imagine(arr, Evidence(tuple(views)), ImagineConfig(disabled=frozenset({"between"})))
    grounded = {k for k in ("c0", "c1", "c2")
                if any({c.a, c.b} == {k, "ground"} for c in off.arrangement.contacts)}
    assert grounded == {"c0", "c1", "c2"}


@pytest.mark.parametrize("lift, top, grows", [(0.0, SEAT - 0.07, True), (0.02, SEAT - 0.07, True),
                                             (0.04, SEAT - 0.07, False), (0.0, SEAT, True)])
def test_a_part_of_the_sofa_seen_in_part_between_its_arms_is_the_one_under_the_cushions(
        lift, top, grows):
    # the seat seen only by a strip of its top between the cushions (under their bottom
    # or up to it), taken down to the floor as a thin panel: it grows under the cushions
    # from arm to arm instead of a hidden part beside it.  A panel not standing on the
    # floor (more than side_tol up) is a board the arms hold.  (A seat filling that space
    # already, as in _seated, is left as it is: the fill test below.)
    arr = _sofa()
    strip = _xyz("seat", -0.60, 0.60, 0.10, 0.13, lift, top, "sofa")
    out, ids = changed("between", Arrangement(arr.cuboids + (strip,), arr.supports))
    if not grows:
        assert ids == [] and out.cuboid("seat") == strip
        return
    seat = out.cuboid("seat")
    # the box the hidden part would be (from arm to arm, as deep as the arms, from the
    # floor), holding the strip: up to the cushions when the strip reaches them, else
    # up to the strip's top (what was seen of it), the cushions reaching down to it
    assert_box(seat, (1.30, DEPTH, top), (0.0, 0.0, top / 2))
    if top < SEAT:
        assert ids == ["seat", "c0", "c1", "c2"]
        for k in ("c0", "c1", "c2"):
            c, c0 = out.cuboid(k), arr.cuboid(k)
            np.testing.assert_allclose(c.size, c0.size + [0.0, 0.0, SEAT - top], atol=1e-9)
            np.testing.assert_allclose(c.center, c0.center - [0.0, 0.0, (SEAT - top) / 2],
                                       atol=1e-9)
    else:
        assert ids == ["seat"]
    assert seat.object == "sofa" and "hallucinated" not in seat.extra
    assert [c.id for c in out.cuboids if c.id.startswith("sofa_under")] == []
    _assert_carries(out, "seat")
    # the rule's ablation: the strip is in the way, and no hidden part is added
    out, ids = changed("between", Arrangement(arr.cuboids + (strip,), arr.supports),
                       params={"between": {"seen_part": False}})
    assert ids == []


def test_a_seat_seen_whole_under_the_cushions_but_short_of_them_carries_them_from_below():
    # the seat's top seen 7 cm under the cushions, from arm to arm and front to back: it
    # stays as seen, and the cushions (seen by their tops) reach down to it
    arr = _sofa()
    seat = _xyz("seat", -0.65, 0.65, -0.3, 0.3, 0.0, SEAT - 0.07, "sofa")
    out, ids = changed("between", Arrangement(arr.cuboids + (seat,), arr.supports))
    assert ids == ["seat", "c0", "c1", "c2"]
    assert_box(out.cuboid("seat"), seat.size, seat.center)  # the edit leaves it as seen
    for k in ("c0", "c1", "c2"):
        assert z_range(out.cuboid(k)) == pytest.approx((SEAT - 0.07, SEAT + 0.02))
    _assert_carries(out, "seat")


def test_two_parts_seen_under_the_cushions_are_not_merged_into_one():
    # two strips: neither is the one part; the hidden part stops at their near faces
    arr = _sofa()
    strips = (_xyz("s1", -0.60, -0.05, 0.10, 0.13, 0.0, SEAT - 0.07, "sofa"),
              _xyz("s2", 0.05, 0.60, 0.10, 0.13, 0.0, SEAT - 0.07, "sofa"))
    out, ids = changed("between", Arrangement(arr.cuboids + strips, arr.supports))
    assert ids == ["sofa_under"]
    assert_box(out.cuboid("sofa_under"), (1.30, 0.40, SEAT), (0.0, -0.10, SEAT / 2))
    assert out.cuboid("s1") == strips[0] and out.cuboid("s2") == strips[1]


def test_the_hidden_part_takes_a_free_id():
    arr = _sofa()
    clash = _xyz("sofa_under", 2.0, 2.2, 2.0, 2.2, 0.0, 0.2, "stool")  # far away
    out, ids = changed("between", Arrangement(arr.cuboids + (clash,), arr.supports))
    assert ids == ["sofa_under1"] and out.cuboid("sofa_under") == clash


def _seated(gaps=(0.0, 0.0), back_in=False, leaning=False, under_obj="sofa"):
    """A sofa's two arms (x from -0.8 to -0.65 and 0.65 to 0.8, y from -0.3 to 0.3), its
    seat under them and a back behind them (y from 0.3; with ``back_in`` between them,
    from y = 0.15), and a row of three cushions on the seat, each fitted from its front
    face 0.2 m deep (y from -0.3 to -0.1), ``gaps`` between them along the row; with
    ``leaning``, a back cushion seen above the seat behind them (y from 0.0 to 0.1, its
    lower end hidden behind them)."""
    arms = [_xyz("armA", -0.80, -0.65, -0.3, 0.3, 0.0, 0.60, "sofa"),
            _xyz("armB", 0.65, 0.80, -0.3, 0.3, 0.0, 0.60, "sofa")]
    back = _xyz("back", -0.65, 0.65, 0.15 if back_in else 0.3, 0.45, 0.0, 0.90, "sofa")
    seat = _xyz("seat", -0.65, 0.65, -0.3, 0.15 if back_in else 0.3, 0.0, SEAT, under_obj)
    g0, g1 = gaps
    xs = ((-0.65, -0.22 - g0 / 2), (-0.22 + g0 / 2, 0.22 - g1 / 2), (0.22 + g1 / 2, 0.65))
    cushions = [_xyz(f"c{i}", x0, x1, -0.3, -0.1, SEAT, SEAT + 0.12, f"cushion{i}")
                for i, (x0, x1) in enumerate(xs)]
    extra = [_xyz("lean", -0.6, 0.6, 0.0, 0.1, SEAT + 0.12, 0.80, "cushion9")] if leaning else []
    return Arrangement(tuple(arms + [back, seat] + cushions + extra), (ground(),))


def test_a_row_filling_the_width_between_the_arms_goes_back_as_deep_as_the_arms():
    """Cushions seen by their front faces, filling the width between the arms of the
    sofa whose seat carries them, go back as far as both arms reach; with the back
    between the arms, to its front face; with a cushion standing behind them, above the
    space they would fill, to its front face; nothing else changes."""
    out, ids = changed("between", _seated())
    assert ids == ["c0", "c1", "c2"]
    for c, x in zip(("c0", "c1", "c2"), ((-0.65, -0.22), (-0.22, 0.22), (0.22, 0.65))):
        assert_box(out.cuboid(c), (x[1] - x[0], DEPTH, 0.12),
                   ((x[0] + x[1]) / 2, 0.0, SEAT + 0.06))
    assert not find_contacts(out).penetrations
    out, ids = changed("between", _seated(), params={"between": {"fill": False}})
    assert ids == []  # the rule's ablation
    out, ids = changed("between", _seated(back_in=True))
    assert ids == ["c0", "c1", "c2"]
    assert out.cuboid("c1").size[1] == pytest.approx(0.45)  # y from -0.3 to 0.15
    out, ids = changed("between", _seated(leaning=True))
    assert ids == ["c0", "c1", "c2"]
    assert out.cuboid("c1").size[1] == pytest.approx(0.3)  # y from -0.3 to 0.0


def test_a_row_that_does_not_fill_the_width_or_rests_on_another_object_stays():
    # gaps along the row: up to twice side_tol in all is the fit's noise, more is a gap
    for gaps, fills in (((0.029, 0.03), True), ((0.031, 0.031), False)):
        out, ids = changed("between", _seated(gaps=gaps))
        assert (ids == ["c0", "c1", "c2"]) is fills, gaps
    # carried by a box of another object between the arms (a crate), not by the sofa
    out, ids = changed("between", _seated(under_obj="crate"))
    assert ids == []
