"""Image edits (``simulate.edit`` with ``edit_plan``, ``raycast``, ``compare_images``;
``unseen edit``): what moves with what, what is refused, which pixels are deleted, what
stays untouched, and the command end to end."""

from __future__ import annotations

import json
import os
import re

import numpy as np
import pytest

from pipeline.camera import Intrinsics, look_at
from pipeline.model import Arrangement, Contact, Cuboid, box, ground

os.environ.setdefault("MUJOCO_GL", "egl")

INTR = Intrinsics(320, 240, 262.5, 262.5, 159.5, 119.5)
T_CAM = look_at(np.array([1.0, -2.6, 1.6]), np.array([0.3, 0.0, 0.5]))


def table_scene() -> Arrangement:
    """A table (top + 4 legs, fused) with a box on it, and a crate on the floor beside it."""
    top = box("t", (0, 0, 0.72), (1.2, 0.6, 0.04), object="table0")
    legs = [box(f"l{k}", (sx * 0.55, sy * 0.25, 0.35), (0.05, 0.05, 0.70), object="table0")
            for k, (sx, sy) in enumerate([(-1, -1), (-1, 1), (1, -1), (1, 1)])]
    item = box("b", (0.2, 0.0, 0.84), (0.25, 0.25, 0.2), object="box0")
    crate = box("c", (1.2, 0.0, 0.2), (0.4, 0.7, 0.4), object="crate")
    contacts = tuple(Contact("t", f"l{k}", "fixed") for k in range(4))
    return Arrangement((top, *legs, item, crate), (ground(),), contacts,
                       meta={"camera_pose": T_CAM.tolist(), "intrinsics": INTR.to_json(),
                             "mu": 0.7, "input_frame": "camera"})


def leaning_scene() -> Arrangement:
    """A plank leaning at 60 degrees on a cabinet's side (held by it, not resting on it)."""
    th = np.radians(60.0)
    d = np.array([-np.cos(th), 0.0, np.sin(th)])
    y = np.array([0.0, 1.0, 0.0])
    R = np.stack([d, y, np.cross(d, y)], axis=1)
    size = np.array([1.0, 0.3, 0.02])
    plank = Cuboid("p", np.zeros(3), R, size, object="plank")
    c = plank.corners()
    plank = plank.with_(center=np.array([-c[:, 0].min(), 0.0, -c[:, 2].min()]))
    cabinet = box("k", (-0.25, 0.0, 0.6), (0.5, 1.0, 1.2), object="cabinet")
    return Arrangement((cabinet, plank), (ground(),))


def bridge_scene() -> Arrangement:
    """A beam resting on two pillars."""
    return Arrangement((box("p1", (0, 0, 0.25), (0.2, 0.2, 0.5), object="pillar1"),
                        box("p2", (0.8, 0, 0.25), (0.2, 0.2, 0.5), object="pillar2"),
                        box("bm", (0.4, 0, 0.55), (1.0, 0.2, 0.1), object="beam")), (ground(),))


# ---------------------------------------------------------------------- what moves
def test_moving_the_table_carries_the_box_not_the_other_way():
    from simulate.edit_plan import carried_set

    arr = table_scene()
    assert carried_set(arr, "table0") == (["table0", "box0"], None)
    assert carried_set(arr, "box0") == (["box0"], None)
    assert carried_set(arr, "crate") == (["crate"], None)


def test_plan_moves_every_cuboid_of_the_group_by_the_offset():
    from simulate.edit_plan import Operation, plan_edit

    arr = table_scene()
    plan = plan_edit(arr, [Operation("move", "table0", -0.3, 0.1)])
    assert plan.ok, plan.refusal
    assert set(plan.moved) == {"t", "l0", "l1", "l2", "l3", "b"}
    for i, off in plan.moved.items():
        assert np.allclose(off, [-0.3, 0.1, 0.0])
        assert np.allclose(plan.after.cuboid(i).center, arr.cuboid(i).center + off)
    assert np.allclose(plan.after.cuboid("c").center, arr.cuboid("c").center)
    assert plan.groups[0].objects == ("table0", "box0")


def test_a_leaning_plank_is_not_carried_and_a_move_that_drops_it_is_refused():
    from pipeline.stability import check_stability
    from simulate.edit_plan import Operation, carried_set, plan_edit

    arr = leaning_scene()
    assert check_stability(arr).stable  # it stands because the cabinet holds it
    assert carried_set(arr, "cabinet") == (["cabinet"], None)
    plan = plan_edit(arr, [Operation("move", "cabinet", -0.4, 0.0)])
    assert plan.refusal == ("cannot move cabinet by (-0.400, +0.000) m: plank would no longer "
                            "stand once cabinet moves")


def test_a_beam_on_two_pillars_cannot_go_with_one():
    from simulate.edit_plan import Operation, carried_set, plan_edit

    arr = bridge_scene()
    group, conflict = carried_set(arr, "pillar1")
    assert group == ["pillar1", "beam"]
    assert conflict == "beam rests on pillar1 and on pillar2: it cannot go with pillar1 alone"
    assert not plan_edit(arr, [Operation("move", "pillar1", -0.5, 0)]).ok


# ---------------------------------------------------------------------- refusals
@pytest.mark.parametrize("op, expected", [
    (("move", "table0", 0.5, 0.0), r"^cannot move table0 by \(\+0\.500, \+0\.000\) m: table0 "
                                   r"would enter crate by 7\.5 cm$"),
    (("move", "box0", 1.0, 0.0), r"^cannot move box0 by \(\+1\.000, \+0\.000\) m: nothing "
                                 r"under box0 at its new place \(its bottom would hang "
                                 r"74\.0 cm above the floor\)$"),
    (("move", "sofa", 0.1, 0.0), r"^unknown object 'sofa'; objects: table0, box0, crate$"),
    (("remove", "box0", 0, 0), None),
    (("move", "box0", 0.2, 0.0), None),   # still on the table
])
def test_refusals_are_one_line(op, expected):
    from simulate.edit_plan import Operation, plan_edit

    plan = plan_edit(table_scene(), [Operation(*op)])
    if expected is None:
        assert plan.ok, plan.refusal
    else:
        assert plan.refusal is not None and "\n" not in plan.refusal
        assert re.match(expected, plan.refusal), plan.refusal


def test_glue_to_the_floor_travels_with_the_object():
    from simulate.edit_plan import Operation, plan_edit

    arr = table_scene()
    arr = arr.with_(contacts=arr.contacts + (Contact("c", "ground", "fixed"),))
    plan = plan_edit(arr, [Operation("move", "crate", 0.0, -0.5)])
    assert plan.ok, plan.refusal
    assert ("c", "ground", "fixed") in {(c.a, c.b, c.type) for c in plan.after.contacts}


def test_removing_the_table_takes_its_box():
    from simulate.edit_plan import Operation, plan_edit

    plan = plan_edit(table_scene(), [Operation("remove", "table0")])
    assert plan.ok
    assert set(plan.removed) == {"t", "l0", "l1", "l2", "l3", "b"}
    assert plan.after.ids == ("c",)


# ---------------------------------------------------------------------- ray casting, metrics
def test_cast_boxes_hits_the_near_face_at_the_right_depth():
    from simulate.raycast import cast_boxes

    C, R, S = np.array([[0.0, 0, 5]]), np.eye(3)[None], np.array([[4.0, 2, 2]])
    dirs = np.array([[0.0, 0, 1], [0.3, 0, 1], [0.0, 0, -1]])
    t, k, f = cast_boxes(np.zeros(3), dirs, C, R, S)
    assert t[0] == pytest.approx(4.0) and k[0] == 0 and f[0] == 4  # -z face
    assert t[1] == pytest.approx(4.0) and f[1] == 4
    assert np.isinf(t[2]) and k[2] == -1


def test_ssim_and_psnr_closed_forms():
    from simulate.compare_images import psnr, ssim

    a = np.full((20, 20, 3), 100, np.uint8)
    b = np.full((20, 20, 3), 120, np.uint8)
    c1 = (0.01 * 255) ** 2
    assert ssim(a, b) == pytest.approx((2 * 100 * 120 + c1) / (100 ** 2 + 120 ** 2 + c1))
    assert psnr(a, b) == pytest.approx(10 * np.log10(255 ** 2 / 400))
    assert ssim(a, a) == pytest.approx(1.0) and psnr(a, a) == np.inf


# ---------------------------------------------------------------------- pixels
@pytest.fixture(scope="module")
def rendered():
    from simulate.scan import render
    from simulate.view import View

    arr = table_scene()
    frame = render(arr, INTR, T_CAM)
    return arr, frame, View(frame.color, frame.depth.astype(float), INTR, T_CAM)


def test_the_mask_covers_the_object_pixels_and_little_else(rendered):
    import cv2

    from simulate.edit import EditParams, hole_mask
    from simulate.raycast import inside_boxes, pixel_rays

    arr, frame, view = rendered
    params = EditParams(margin=0.03, dilate_px=3)
    crate = arr.cuboid("c")
    mask = hole_mask(view, [crate], params)
    k = arr.index["c"] + 1
    mine = frame.instance == k
    assert mine.sum() > 500
    assert mask[mine].all()  # every pixel of the crate is deleted
    # and nothing else but pixels within the margin of it, dilated by the given pixels
    H, W = frame.depth.shape
    v, u = np.mgrid[0:H, 0:W]
    o, d = pixel_rays(view, u.ravel(), v.ravel())
    near = inside_boxes(o + d * frame.depth.reshape(-1, 1).astype(float), [crate], 0.03)
    allowed = (near.reshape(H, W) | mine).astype(np.uint8)
    allowed = cv2.dilate(allowed, np.ones((7, 7), np.uint8)).astype(bool)
    assert not (mask & ~allowed).any()
    assert not mask[frame.instance == arr.index["b"] + 1].any()  # the box on the table stays


def test_after_equals_before_far_from_the_edit_and_matches_the_truth_near_it(rendered):
    import cv2

    from simulate.compare_images import psnr
    from simulate.edit import EditParams, edit_image
    from simulate.edit_plan import Operation, plan_edit
    from simulate.scan import render

    arr, frame, view = rendered
    plan = plan_edit(arr, [Operation("move", "table0", -0.3, 0.0)])
    assert plan.ok
    out = edit_image(view, plan, EditParams(shadow=False))
    touched = out.hole | (out.alpha > 0) | (out.shadow > 0) | out.old_region | out.new_region
    far = ~cv2.dilate(touched.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    assert far.sum() > 0.3 * far.size
    assert np.array_equal(out.after[far], out.before[far])
    truth = render(plan.after, INTR, T_CAM).color
    region = out.old_region | out.new_region
    assert psnr(out.after, truth, region) > psnr(out.before, truth, region) + 6.0
    # with a shadow, only pixels near the moved group darken
    shadowed = edit_image(view, plan, EditParams(shadow=True))
    assert (shadowed.shadow > 0).any()
    assert np.all(shadowed.after.astype(int) <= out.after.astype(int) + 1)


def test_a_retrieved_model_is_drawn_where_its_box_would_be(rendered, tmp_path):
    import trimesh

    from simulate.edit import EditParams, edit_image, read_retrieved
    from simulate.edit_plan import Operation, plan_edit

    arr, frame, view = rendered
    crate = arr.cuboid("c")
    trimesh.creation.box(extents=crate.size).export(tmp_path / "crate.obj")
    T = np.eye(4)
    T[:3, 3] = crate.center
    (tmp_path / "retrieval.json").write_text(json.dumps({
        "format": "unseen.retrieval", "models": str(tmp_path),
        "objects": [{"object": "crate", "model": "crate.obj", "transform": T.tolist()},
                    {"object": "not-here", "model": "x.obj", "transform": T.tolist()}]}))
    meshes = read_retrieved(tmp_path, arr)
    assert set(meshes) == {"crate"}
    plan = plan_edit(arr, [Operation("move", "crate", 0.0, -0.4)])
    params = EditParams(shadow=False)
    as_box = edit_image(view, plan, params)
    as_model = edit_image(view, plan, params, meshes=meshes)
    a, b = as_box.alpha > 0.5, as_model.alpha > 0.5
    assert a.sum() > 500 and (a & b).sum() / (a | b).sum() > 0.97


# ---------------------------------------------------------------------- the command
@pytest.fixture(scope="module")
def scene_and_result(tmp_path_factory):
    from pipeline.arrangement_io import write_arrangement
    from simulate.scan import scan_arrangement, write_scan

    root = tmp_path_factory.mktemp("edit")
    arr = table_scene()
    scan = scan_arrangement(arr, np.random.default_rng(0), poses=[T_CAM], noise="none",
                            intrinsics=INTR)
    write_scan(scan, root / "scene" / "scan")
    write_arrangement(arr, root / "scene" / "scene.json")
    write_arrangement(arr, root / "result" / "arrangement.json")
    return root


def test_command_writes_the_edit(scene_and_result, capsys):
    from eval.cli import main

    root = scene_and_result
    out = root / "out"
    assert main(["edit", str(root / "scene"), str(root / "result"), "--move", "table0", "-0.3",
                 "0", "--out", str(out)]) == 0
    line = capsys.readouterr().out
    assert "carrying box0" in line
    for name in ("before.png", "after.png", "compare.png", "mask.png", "edit.json",
                 "edited.json", "report.md", "manifest.json"):
        assert (out / name).is_file(), name
    rec = json.loads((out / "edit.json").read_text())
    assert rec["operations"][0]["carried"] == ["box0"]
    assert rec["operations"][0]["transform"][0][3] == pytest.approx(-0.3)
    assert set(rec["moved"]) == {"t", "l0", "l1", "l2", "l3", "b"}
    assert main(["check", str(out / "edited.json")]) == 0


@pytest.mark.parametrize("argv, message", [
    (["--move", "sofa", "0.1", "0"], "unknown object 'sofa'; objects: table0, box0, crate"),
    (["--move", "table0", "0.5", "0"], "table0 would enter crate by 7.5 cm"),
    (["--move", "box0", "1", "0"], "nothing under box0 at its new place"),
    (["--move", "box0", "x", "0"], "DX and DY must be numbers"),
    (["--move", "box0", "0", "-0.0"], "--move box0 0 -0.0: moves nothing"),
    ([], "nothing to do"),
    (["--remove", "box0", "--fill", "patchmatch"], "invalid choice"),
])
def test_bad_input_exit_2_one_line(scene_and_result, capsys, argv, message):
    from eval.cli import main

    root = scene_and_result
    out = root / "never"
    try:
        code = main(["edit", str(root / "scene"), str(root / "result"), *argv, "--out", str(out)])
    except SystemExit as exc:  # argparse's own errors (one line: eval.cli.OneLineParser)
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2
    assert message in err and err.count("\n") == 1, err
    assert not out.exists()


def test_no_camera_or_no_image_exit_2(scene_and_result, capsys, tmp_path):
    from eval.cli import main
    from pipeline.arrangement_io import write_arrangement
    from simulate.scan import write_ply

    root = scene_and_result
    write_arrangement(table_scene().with_(meta={}), tmp_path / "nopose.json")
    assert main(["edit", str(root / "scene"), str(tmp_path / "nopose.json"), "--remove", "box0",
                 "--out", str(tmp_path / "o1")]) == 2
    assert "meta.camera_pose" in capsys.readouterr().err
    write_ply(tmp_path / "cloud.ply", np.random.default_rng(0).random((500, 3)))
    assert main(["edit", str(tmp_path / "cloud.ply"), str(root / "result"), "--remove", "box0",
                 "--out", str(tmp_path / "o2")]) == 2
    assert "no colour image" in capsys.readouterr().err


def test_a_result_of_another_camera_is_refused(scene_and_result, capsys, tmp_path):
    # the result's recorded intrinsics must be the scan's: a result whose frame had
    # another focal length is the run of another scan (same image size or not)
    import json as _json

    from eval.cli import main

    root = scene_and_result
    data = _json.loads((root / "result" / "arrangement.json").read_text())
    fx = data["meta"]["intrinsics"]["fx"]
    data["meta"]["intrinsics"]["fx"] = fx + 5.0
    other = tmp_path / "other.json"
    other.write_text(_json.dumps(data))
    assert main(["edit", str(root / "scene"), str(other), "--remove", "box0",
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert f"made from a frame with fx {fx + 5.0:g} but SCAN has fx {fx:g}" in err
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_edits_suite_quick(tmp_path):
    import argparse

    from eval.suites import edits

    args = argparse.Namespace(out=tmp_path, seed=0, n=1, workers=1, dask=None, quick=True)
    assert edits.run(args) == 0
    rec = json.loads((tmp_path / "tasks" / "demo-table.json").read_text())
    res = rec.get("result", rec)
    assert res["object"] == "table0" and "box0" in res["carried_ours"]
    s = res["scores"]
    assert s["ours"]["psnr_in"] > s["unedited (baseline)"]["psnr_in"]


@pytest.mark.parametrize("flag, value, needle", [
    ("--depth-scale", "1e300", "--depth-scale: must be a positive number of raw units"),
    ("--depth-scale", "0", "--depth-scale: must be a positive number of raw units"),
    ("--intrinsics", "1,2,3", "4 finite numbers"),
])
def test_frame_flags_are_checked_as_run_checks_them(scene_and_result, capsys, tmp_path,
                                                     flag, value, needle):
    from eval.cli import main

    root = scene_and_result
    assert main(["edit", str(root / "scene"), str(root / "result"), "--remove", "box0",
                 "--out", str(tmp_path / "o"), f"{flag}={value}"]) == 2
    err = capsys.readouterr().err
    assert needle in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


def test_a_negative_number_in_e_notation_is_a_value_not_an_option(scene_and_result, capsys,
                                                                    tmp_path):
    # argparse alone reads -1e300 as an option ("--move: expected 3 arguments"); our
    # parser passes it on, and edit's own check refuses the distance
    from eval.cli import main

    root = scene_and_result
    assert main(["edit", str(root / "scene"), str(root / "result"), "--move", "box0", "0",
                 "-1e300", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "DX and DY must be finite metres" in err and len(err.strip().splitlines()) == 1
