"""Steps of :mod:`pipeline.imagine` around the search: glue relaxation, overlap repair,
and the depth views of a fused multi-view scan."""

from __future__ import annotations

import os

import numpy as np
import pytest

from pipeline.contacts import find_contacts
from pipeline.imagine import relax_fixed, repair_overlaps
from pipeline.model import Arrangement, Contact, ObservedBox, box, ground
from pipeline.stability import check_stability


def _observed(c):
    return c.with_(observed=ObservedBox(c.center, c.size))


def _contains(outer, inner_center, inner_size, tol=1e-6):
    lo = outer.rotation.T @ (inner_center - outer.center) - inner_size / 2
    hi = lo + inner_size
    return bool(np.all(lo >= -outer.size / 2 - tol) and np.all(hi <= outer.size / 2 + tol))


def test_a_glue_joint_from_a_shallow_looking_box_is_relaxed_to_touch():
    # the upper box, seen from the front only, looks 0.2 deep and hangs 3 cm over the
    # front edge of the box below: as fitted it needs a glue joint; with a box grown
    # where the fit was short of the truth it rests on its own
    lower = _observed(box("lo", (0, 0, 0.2), (0.4, 0.4, 0.4), object="o1"))
    upper = _observed(box("up", (0, -0.23, 0.5), (0.3, 0.2, 0.2), object="o2"))
    touching = Arrangement((lower, upper), (ground(),),
                           (Contact("lo", "ground"), Contact("lo", "up")))
    assert not check_stability(touching).stable  # COM at y = -0.23, the edge at -0.2
    glued = Arrangement((lower, upper), (ground(),),
                        (Contact("lo", "ground"), Contact("lo", "up", "fixed")))
    assert check_stability(glued).stable
    out, tried, relaxed = relax_fixed(glued)
    assert (tried, relaxed) == (1, 1)
    assert {c.key: c.type for c in out.contacts}[Contact("lo", "up").key] == "touch"
    assert check_stability(out, tilt_deg=2.0).stable
    for c in out.cuboids:  # every box kept its observed points; one grew to carry the other
        assert _contains(c, c.observed.center, c.observed.size)
    assert np.prod(out.sizes, axis=1).sum() > np.prod(glued.sizes, axis=1).sum() + 1e-4
    assert not find_contacts(out).penetrations


def test_a_needed_glue_joint_and_joints_within_an_object_stay():
    # a shelf board held only by a wall: nothing refinement may do makes it stand
    from pipeline.model import Support

    wall = Support("wall:0", (0, 0.5, 0), (0, -1, 0))
    board = _observed(box("board", (0, 0.35, 1.5), (0.6, 0.3, 0.03), object="shelf"))
    arr = Arrangement((board,), (ground(), wall), (Contact("board", "wall:0", "fixed"),))
    out, tried, relaxed = relax_fixed(arr)
    assert (tried, relaxed) == (1, 0) and out.contacts == arr.contacts
    # a table: top glued to its legs (one object) is not a candidate at all
    top = _observed(box("top", (0, 0, 0.72), (1.0, 0.6, 0.04), object="t"))
    legs = [_observed(box(f"l{i}", (x, y, 0.35), (0.05, 0.05, 0.7), object="t"))
            for i, (x, y) in enumerate([(-0.45, -0.25), (0.45, -0.25), (-0.45, 0.25),
                                        (0.45, 0.25)])]
    table = Arrangement((top, *legs), (ground(),),
                        tuple(Contact(f"l{i}", "top", "fixed") for i in range(4))
                        + tuple(Contact(f"l{i}", "ground") for i in range(4)))
    out, tried, relaxed = relax_fixed(table)
    assert (tried, relaxed) == (0, 0) and out is table


@pytest.mark.parametrize(("parts", "expected"), [((1, 2), 2), ((1, 1), 1), ((None, None), 1)])
def test_overlapping_slabs_merge_only_when_they_are_one_part(parts, expected):
    a = box("a", (0, 0, 0.3), (0.8, 0.3, 0.03), object="shelf")
    b = box("b", (0.38, 0, 0.5), (0.03, 0.3, 1.0), object="shelf")  # overlaps a's end
    cubs = []
    for c, p in zip((a, b), parts, strict=True):
        cubs.append(c.with_(extra={} if p is None else {"instance": p}))
    out, repaired = repair_overlaps(Arrangement(tuple(cubs), (ground(),)))
    assert repaired >= 1 and len(out.cuboids) == expected
    assert not find_contacts(out).penetrations


def test_a_multi_view_scene_folder_loads_fused_with_its_frames(tmp_path):
    if os.environ.get("MUJOCO_GL") not in ("egl", "osmesa"):
        pytest.skip("rendering needs MUJOCO_GL=egl or osmesa (make test sets it)")
    from pipeline.camera import transform
    from pipeline.errors import InputError
    from pipeline.imagine import views_from_scan
    from pipeline.scan_io import load_scan
    from synth_scenes.scene_dir import make_scene_dir

    made = make_scene_dir("stack", tmp_path / "s", seed=3, views=2, noise="none")
    scan = load_scan(made.path)
    assert len(scan.views) == 2 and scan.depth is None
    assert scan.n == sum(v.n for v in scan.views)
    np.testing.assert_array_equal(scan.points[: scan.views[0].n],
                                  transform(scan.views[0].T_world_cam, scan.views[0].points))
    assert set(scan.instance_objects.values()) == {c.object for c in made.truth.arrangement.cuboids}
    assert np.array_equal(np.unique(scan.instance[scan.instance > 0]),
                          np.arange(1, len(made.truth.arrangement.cuboids) + 1))
    arr = Arrangement((), (ground(),), meta={"camera_pose": np.eye(4).tolist()})
    views = views_from_scan(scan, arr)
    assert len(views) == 2
    np.testing.assert_array_equal(views[1].T_world_cam, scan.views[1].T_world_cam)
    (made.path / "scan" / "view1" / "camera_pose.json").unlink()
    with pytest.raises(InputError, match="view1: camera_pose.json missing"):
        load_scan(made.path)
