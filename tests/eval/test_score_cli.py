"""``unseen score``: JSON and table output on a hand-checked example, exit 2 on bad input."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from eval.cli import main
from pipeline.arrangement_io import write_arrangement
from pipeline.model import Arrangement, Contact, ObservedBox, box, ground


def _truth() -> Arrangement:
    cubes = (box("g0", (0, 0, 0.25), (1.0, 0.8, 0.5)),
             box("g1", (0.1, 0, 0.7), (0.6, 0.6, 0.4)),
             box("g2", (2.0, 0, 0.3), (0.4, 0.4, 0.6), yaw=0.4))
    return Arrangement(cubes, (ground(),), (Contact("g0", "ground"), Contact("g1", "g0", "fixed"),
                                             Contact("g2", "ground")))


def _prediction(gt: Arrangement) -> Arrangement:
    # shuffled order, ids unrelated to the truth, the fused contact predicted as touch;
    # every box was observed at half its height
    order = [2, 0, 1]
    cubes = []
    for k, i in enumerate(order):
        c = gt.cuboids[i]
        obs = ObservedBox(c.center + np.array([0, 0, c.size[2] / 4]), c.size * [1, 1, 0.5])
        cubes.append(c.with_(id=f"p{k}", observed=obs))
    contacts = (Contact("p1", "ground"), Contact("p2", "p1", "touch"), Contact("p0", "ground"))
    return Arrangement(tuple(cubes), (ground(),), contacts)


@pytest.fixture
def files(tmp_path):
    gt = _truth()
    scene = tmp_path / "scene"
    write_arrangement(gt, scene / "scene.json")
    write_arrangement(_prediction(gt), tmp_path / "pred.json")
    return tmp_path / "pred.json", scene


def test_score_json_hand_checked(files, capsys):
    pred, scene = files
    before = pred.read_bytes()
    assert main(["score", str(pred), str(scene), "--json", "--graph", "listed"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["truth"].endswith("scene.json")
    opt = out["optimized"]
    # 3 true edges, 3 predicted; the fixed one predicted as touch: typed 2/3, untyped 3/3
    assert (opt["typed"]["tp"], opt["typed"]["n_pred"], opt["typed"]["n_gt"]) == (2, 3, 3)
    assert opt["typed"]["f1"] == pytest.approx(2 / 3)
    assert opt["untyped"]["f1"] == 1.0
    assert opt["false_negatives"] == [["g0", "g1", "fixed"]]
    assert {c["pred"]: c["gt"] for c in out["cuboids"]} == {"p0": "g2", "p1": "g0", "p2": "g1"}
    assert all(c["iou"] == pytest.approx(1.0) for c in out["cuboids"])
    # half-height observed boxes: IoU 0.5 and relative z error 0.5 -> 0 (eq. 6 = 0.5)
    assert all(c["iou_initial"] == pytest.approx(0.5) for c in out["cuboids"])
    assert out["size"]["error"] == pytest.approx(0.5)
    assert out["size"]["n_changed"] == 3
    assert pred.read_bytes() == before  # inputs never modified


def test_score_table_and_arrangement_file_as_truth(files, capsys):
    pred, scene = files
    result = pred.parent / "result"
    result.mkdir()
    (result / "arrangement.json").write_bytes(pred.read_bytes())
    assert main(["score", str(result), str(scene / "scene.json"), "--graph", "listed",
                 "--per-cuboid"]) == 0
    text = capsys.readouterr().out
    assert "matched 3 of 3 true cuboids" in text
    assert f"prediction: {result / 'arrangement.json'}" in text
    assert "optimized typed" in text and "66.7%" in text
    assert "- g0 - g1 fixed  (true, missed)" in text
    assert "p0 -> g2" in text


@pytest.mark.parametrize("case", ["missing_pred", "dir_without_scene", "bad_json", "bad_iou",
                                  "empty_result_dir"])
def test_score_bad_input_exits_2_with_one_line(files, capsys, tmp_path, case):
    pred, scene = files
    argv = ["score", str(pred), str(scene)]
    if case == "missing_pred":
        argv[1] = str(tmp_path / "nope.json")
    elif case == "dir_without_scene":
        (tmp_path / "empty").mkdir()
        argv[2] = str(tmp_path / "empty")
    elif case == "empty_result_dir":
        (tmp_path / "res").mkdir()
        argv[1] = str(tmp_path / "res")
    elif case == "bad_json":
        (tmp_path / "broken.json").write_text("{not json")
        argv[1] = str(tmp_path / "broken.json")
    else:
        argv += ["--min-iou", "2"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("unseen score: error:") and "\n" not in err
    assert "Traceback" not in err


def test_score_console_entry_point(files):
    pred, scene = files
    proc = subprocess.run([sys.executable, "-m", "eval.cli", "score", str(pred), str(scene),
                           "--json"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["n_gt"] == 3
