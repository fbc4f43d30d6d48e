"""Our labels of the real scans (eval/real) and the scorer of ``unseen eval real``."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from eval.real import (
    ANNOTATIONS,
    DEFAULT_DATA,
    AnnotationError,
    annotations,
    load_annotation,
    score,
)
from pipeline.model import Arrangement, Contact, box, ground

ROT = np.eye(3).tolist()


def _write(tmp_path, objects, relations, name="scan__x_pcd"):
    p = tmp_path / f"{name}.json"
    p.write_text(json.dumps({"scan": "folder/x.pcd", "group": "boxes", "objects": objects,
                             "relations": relations}))
    return p


def _obj(id, center, size):
    return {"id": id, "what": id, "why": "test",
            "box": {"center": list(center), "size": list(size), "rotation": ROT}}


def _stack_labels(tmp_path, relations):
    objs = [_obj("low", (0, 0, 0.2), (0.5, 0.5, 0.42)), _obj("top", (0, 0, 0.55), (0.3, 0.3, 0.3))]
    return load_annotation(_write(tmp_path, objs, relations))


def _points():
    """Visible points of the two boxes (their tops and fronts), in the input frame."""
    rng = np.random.default_rng(0)
    low = np.column_stack([rng.uniform(-0.24, 0.24, 400), np.full(400, -0.24),
                           rng.uniform(0.01, 0.39, 400)])
    top = np.column_stack([rng.uniform(-0.14, 0.14, 200), np.full(200, -0.14),
                           rng.uniform(0.41, 0.69, 200)])
    return np.vstack([low, top])


def _result(contacts, shift=(0.0, 0.0, 0.0), objects=("A", "B")):
    """A result in a world frame ``shift`` away from the input frame (meta.camera_pose)."""
    T = np.eye(4)
    T[:3, 3] = shift
    s = np.asarray(shift)
    a = box("b0", s + (0, 0, 0.2), (0.5, 0.5, 0.4), object=objects[0])
    b = box("b1", s + (0, 0, 0.55), (0.3, 0.3, 0.3), object=objects[1])
    return Arrangement((a, b), (ground(),), tuple(Contact(*c) for c in contacts),
                       meta={"camera_pose": T.tolist(), "input_scale": 1.0})


def test_a_result_that_matches_the_labels_scores_one(tmp_path):
    ann = _stack_labels(tmp_path, [{"a": "top", "b": "low", "type": "on", "confidence": 0.9},
                                   {"a": "low", "b": "floor", "type": "on", "confidence": 0.9}])
    res = _result([("b0", "b1", "touch"), ("b0", "ground", "touch")], shift=(2.0, -1.0, 0.0))
    s = score(res, _points(), ann)
    assert (s.tp, s.fp, s.fn, s.found, s.glue) == (2, 0, 0, 2, 0)
    assert s.f1 == 1.0 and s.match == {"A": "low", "B": "top"}


def test_missed_added_and_do_not_care_pairs(tmp_path):
    ann = _stack_labels(tmp_path, [{"a": "top", "b": "low", "type": "on", "confidence": 0.9},
                                   {"a": "low", "b": "floor", "type": "on", "confidence": 0.9},
                                   {"a": "top", "b": "wall", "type": "leans", "confidence": 0.3}])
    # top glued to a wall (unsure in the labels: do-not-care), low-floor missed,
    # top on the floor (false)
    res = _result([("b0", "b1", "fixed"), ("b1", "wall:0", "fixed"), ("b1", "ground", "touch")])
    s = score(res, _points(), ann, contacts="all")
    assert (s.tp, s.fp, s.fn) == (1, 1, 1)
    assert s.missed_pairs == [frozenset({"low", "floor"})]
    assert s.false_pairs == [frozenset({"top", "floor"})]
    assert s.glue == 2 and s.glue_between_objects == 1


def test_parts_of_one_labelled_object_count_once_and_never_as_glue(tmp_path):
    ann = _stack_labels(tmp_path, [{"a": "low", "b": "floor", "type": "on", "confidence": 0.9}])
    objs = [_obj("both", (0, 0, 0.35), (0.5, 0.5, 0.72))]
    ann = load_annotation(_write(tmp_path, objs, [
        {"a": "both", "b": "floor", "type": "on", "confidence": 0.9}], name="one"))
    res = _result([("b0", "b1", "fixed"), ("b0", "ground", "touch")])
    s = score(res, _points(), ann)
    assert (s.tp, s.fp, s.fn, s.glue_between_objects) == (1, 0, 0, 0)
    assert s.predicted_objects == 2 and s.matched_objects == 2 and s.found == 1


def test_the_support_graph_keeps_only_contacts_that_carry_load(tmp_path):
    from pipeline.model import Support

    ann = _stack_labels(tmp_path, [{"a": "top", "b": "low", "type": "on", "confidence": 0.9},
                                   {"a": "low", "b": "floor", "type": "on", "confidence": 0.9}])
    # the stack stands on the floor with its back flush against a wall it does not need
    wall = Support("wall:0", np.array([0.0, 0.25, 0.0]), np.array([0.0, -1.0, 0.0]))
    res = _result([("b0", "b1", "touch"), ("b0", "ground", "touch"), ("b0", "wall:0", "touch")])
    res = res.with_(supports=res.supports + (wall,))
    support, every = score(res, _points(), ann), score(res, _points(), ann, contacts="all")
    assert (support.tp, support.fp, support.fn) == (2, 0, 0)
    assert (every.tp, every.fp, every.fn) == (2, 1, 0)
    assert every.false_pairs == [frozenset({"low", "wall"})]


@pytest.mark.parametrize("bad, words", [
    ({"box": {"center": [0, 0, 0], "size": [1, 1, 1], "rotation": [[1, 0, 0], [0, 1, 0],
                                                                   [0, 0, -1]]}},
     "rotation"),
    ({"box": {"center": [0, 0], "size": [1, 1, 1], "rotation": ROT}}, "center"),
    ({"box": {"center": [0, 0, 0], "size": [1, 0, 1], "rotation": ROT}}, "positive"),
])
def test_a_malformed_label_names_its_file_and_field(tmp_path, bad, words):
    o = {"id": "x", **bad}
    p = _write(tmp_path, [o], [])
    with pytest.raises(AnnotationError, match=words) as err:
        load_annotation(p)
    assert str(p) in str(err.value)


def test_a_relation_to_an_unknown_object_is_refused(tmp_path):
    p = _write(tmp_path, [_obj("a", (0, 0, 0), (1, 1, 1))],
               [{"a": "a", "b": "ghost", "type": "on", "confidence": 1}])
    with pytest.raises(AnnotationError, match="ghost"):
        load_annotation(p)


def test_every_shipped_label_file_follows_the_format():
    anns = annotations()
    assert len(anns) >= 10 and {a.group for a in anns} <= {"boxes", "rooms"}
    for a in anns:
        assert a.objects and a.relations, a.name
        assert a.name == a.scan.replace("/", "__", 1).replace("/", "_").replace(".", "_"), a.name


@pytest.mark.skipif(not DEFAULT_DATA.is_dir(),
                    reason=f"the real scans are not beside this checkout ({DEFAULT_DATA})")
def test_every_labelled_object_holds_visible_points_of_its_scan():
    from pipeline.run import load

    for a in annotations():
        scan = load(DEFAULT_DATA / a.scan)
        counts = np.bincount(a.labels(scan.points) + 1, minlength=len(a.objects) + 1)[1:]
        assert counts.min() >= 100, (a.name, dict(zip([o.id for o in a.objects], counts)))
    assert ANNOTATIONS.is_dir()


def test_eval_real_without_the_data_says_where_to_point_it(tmp_path, capsys):
    from eval.cli import main

    rc = main(["eval", "real", "--out", str(tmp_path / "out"), "--data",
               str(tmp_path / "nowhere")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "--data" in err[0] and "Traceback" not in err[0]


def _real_record(name, group, tp, fp, fn, missed=(), false=(), glue=0, stands=True):
    """An ``unseen eval real`` scan record with the counts and pairs given."""
    return {"name": name, "group": group, "objects": 3, "found": 3, "predicted_objects": 3,
            "matched_objects": 3, "tp": tp, "fp": fp, "fn": fn, "glue": glue,
            "glue_between_objects": 0, "false_pairs": [list(p) for p in false],
            "missed_pairs": [list(p) for p in missed], "match": {},
            "all_contacts": {"tp": tp, "fp": fp, "fn": fn}, "stable": stands,
            "stands_in": {"mujoco": stands, "pybullet": stands}}


def test_eval_real_compare_names_the_scans_and_pairs_that_changed(tmp_path):
    """``unseen eval real --compare``: a scan whose score did not change has no row; one
    that found a labelled pair it missed and stopped adding a wrong one shows both, and
    one that lost a pair shows that; group rows are micro-averaged before and after; a
    scan the earlier run lacks is left out and named."""
    from eval.suites import real

    before = {"a": _real_record("a", "boxes", 2, 0, 0),
              "b": _real_record("b", "boxes", 1, 1, 1, missed=[("box", "floor")],
                                false=[("box", "wall")]),
              "c": _real_record("c", "rooms", 2, 0, 0)}
    (tmp_path / "before").mkdir()
    (tmp_path / "before" / "real.json").write_text(json.dumps({"scans": before}))
    after = [_real_record("a", "boxes", 2, 0, 0),
             _real_record("b", "boxes", 2, 0, 0),
             _real_record("c", "rooms", 1, 0, 1, missed=[("lamp", "stand")], stands=False),
             _real_record("d", "rooms", 1, 0, 0)]
    out = tmp_path / "after"
    out.mkdir()
    md = real.compare(out, tmp_path / "before", after)
    rec = json.loads((out / "compare.json").read_text())
    assert rec["changed"] == ["b", "c"] and rec["left_out"] == ["d"]
    rows = {r["scan"]: r for r in csv.DictReader((out / "compare.csv").open())}
    assert set(rows) == {"b", "c", "**all boxes**", "**all rooms**"}
    assert (rows["b"]["support F1 before"], rows["b"]["support F1 after"]) == ("50.0", "100.0")
    assert rows["b"]["pairs gained"] == "box-floor; not box-wall" and rows["b"]["pairs lost"] == ""
    assert rows["c"]["pairs lost"] == "lamp-stand" and rows["c"]["stands (analytic / MuJoCo / PyBullet)"] == "1 / 1 / 1 -> 0 / 0 / 0"
    boxes = rec["groups"]["boxes"]
    assert boxes["f1_before"] == pytest.approx(2 * 3 / (2 * 3 + 1 + 1)) and boxes["f1_after"] == 1.0
    assert rec["groups"]["rooms"]["scans"] == 1  # d is left out
    assert "Not in the earlier run, left out: d." in md


def test_eval_real_compare_refuses_a_folder_without_real_json(tmp_path, capsys):
    from eval.cli import main

    (tmp_path / "prev").mkdir()
    out = tmp_path / "out"
    assert main(["eval", "real", "--out", str(out), "--compare", str(tmp_path / "prev")]) == 2
    err = capsys.readouterr().err.strip()
    assert "no readable real.json there" in err and "\n" not in err and not out.exists()
    (tmp_path / "prev" / "real.json").write_text(json.dumps({"scans": {"x": {"group": "boxes"}}}))
    assert main(["eval", "real", "--out", str(out), "--compare", str(tmp_path / "prev")]) == 2
    err = capsys.readouterr().err.strip()
    assert "real.json's scan 'x' lacks tp, fp, fn" in err and "\n" not in err
