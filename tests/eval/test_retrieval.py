"""``unseen models make`` and ``unseen retrieve``: end to end, the right kind on generated
furniture, bad input exits 2 with one line; the suite's object matching."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from eval.cli import main
from pipeline.arrangement_io import read_arrangement, write_arrangement


@pytest.fixture(scope="module")
def models(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("m") / "models"
    assert main(["models", "make", "--out", str(out), "--n-per-kind", "4", "--seed", "5"]) == 0
    return out


@pytest.fixture(scope="module")
def furniture():
    """Ground truth of a table scene and a chair scene (no engines, no scan)."""
    from synth_scenes.families import make_chair, make_desk, make_table

    return {"table": make_table(np.random.default_rng(11), n_items=1),
            "chair": make_chair(np.random.default_rng(12)),
            "desk": make_desk(np.random.default_rng(13))}


def test_models_make_writes_an_index(models: Path) -> None:
    index = json.loads((models / "index.json").read_text())
    kinds = {e["kind"] for e in index["models"]}
    assert kinds == {"table", "chair", "shelf", "desk", "sofa", "monitor"}   # no plain boxes
    assert (models / "manifest.json").is_file()


def test_retrieval_picks_the_right_kind_on_generated_furniture(models: Path, furniture) -> None:
    from pipeline.retrieve import RetrieveConfig, load_repository, object_groups, retrieve_object

    repo = load_repository(models)
    for kind, arr in furniture.items():
        groups = object_groups(arr)
        name = f"{kind}0"
        r = retrieve_object(name, groups[name], repo, config=RetrieveConfig())
        assert r.best.kind == kind, (kind, r.best.kind, r.best.score)
        assert r.best.score > 1.5


def _run_folder(tmp: Path, arr) -> Path:
    folder = tmp / "res"
    folder.mkdir()
    write_arrangement(arr, folder / "arrangement.json")
    # the initial structure: the chair without its back
    back = max(arr.cuboids, key=lambda c: c.center[2])
    write_arrangement(arr.with_(cuboids=tuple(c for c in arr.cuboids if c.id != back.id),
                                contacts=()), folder / "initial.json")
    return folder


def test_retrieve_end_to_end(models: Path, furniture, tmp_path: Path, capsys) -> None:
    import trimesh

    res = _run_folder(tmp_path, furniture["chair"])
    out = tmp_path / "out"
    assert main(["retrieve", str(res), "--models", str(models), "--out", str(out), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["format"] == "unseen.retrieval" and data["structure"] == "imagined"
    (obj,) = [o for o in data["objects"] if o["object"] == "chair0"]
    assert obj["kind"] == "chair" and obj["runner_up"] is not None
    T = np.array(obj["transform"])
    assert T.shape == (4, 4) and np.allclose(T[3], [0, 0, 0, 1])
    for name in ("retrieved.glb", "retrieval.json", "retrieval.png", "report.md", "manifest.json"):
        assert (out / name).is_file(), name
    assert (out / "retrieval.png").stat().st_size < 150_000
    scene = trimesh.load(out / "retrieved.glb")
    assert "chair0" in scene.graph.nodes
    # the placed model in the file (y up) spans the chair's height along y
    arr = read_arrangement(res / "arrangement.json")
    top = max(c.corners()[:, 2].max() for c in arr.cuboids if c.object == "chair0")
    T, geom = scene.graph["chair0"]
    ys = trimesh.transform_points(scene.geometry[geom].vertices, T)[:, 1]
    assert ys.max() == pytest.approx(top, abs=0.02) and ys.min() == pytest.approx(0.0, abs=0.02)
    # the initial structure (no back) and a keyword search
    out2 = tmp_path / "out2"
    assert main(["retrieve", str(res), "--models", str(models), "--out", str(out2),
                 "--structure", "initial", "--kinds", "chair,table"]) == 0
    data2 = json.loads((out2 / "retrieval.json").read_text())
    assert data2["structure"] == "initial"
    assert {o["kind"] for o in data2["objects"]} <= {"chair", "table"}
    # the paper's score alone: no stretch cost, kinds compared by the score
    out3 = tmp_path / "out3"
    assert main(["retrieve", str(res), "--models", str(models), "--out", str(out3),
                 "--stretch-cost", "0"]) == 0
    data3 = json.loads((out3 / "retrieval.json").read_text())
    assert data["stretch_cost"] == 0.5 and data3["stretch_cost"] == 0.0
    assert "| stretch | kind score |" in (out3 / "report.md").read_text()
    (obj3,) = [o for o in data3["objects"] if o["object"] == "chair0"]
    assert obj3["kind_score"] == obj3["score"] and obj["kind_score"] == pytest.approx(
        obj["score"] - 0.5 * obj["stretch"], abs=1e-5)


@pytest.mark.parametrize("args, needle", [
    (["retrieve", "{tmp}/none", "--models", "{models}", "--out", "{tmp}/o"], "no such file"),
    (["retrieve", "{res}", "--models", "{tmp}/none", "--out", "{tmp}/o"], "not a folder"),
    (["retrieve", "{res}/arrangement.json", "--models", "{models}", "--out", "{tmp}/o",
      "--structure", "initial"], "initial.json"),
    (["retrieve", "{res}", "--models", "{models}", "--out", "{tmp}/o", "--kinds", "bed"],
     "--kinds"),
    (["retrieve", "{res}", "--models", "{models}", "--out", "{tmp}/o", "--scan", "{tmp}/none"],
     "--scan"),
    (["retrieve", "{tmp}", "--models", "{models}", "--out", "{tmp}/o"], "arrangement.json"),
    (["retrieve", "{res}", "--models", "{models}", "--out", "{tmp}/o", "--stretch-cost", "-1"],
     "--stretch-cost"),
    (["retrieve", "{res}", "--models", "{models}", "--out", "{tmp}/o", "--stretch-cost", "nan"],
     "--stretch-cost"),
    (["models", "make", "--out", "{tmp}/o", "--kinds", "bed"], "--kinds"),
    (["models", "make", "--out", "{tmp}/o", "--n-per-kind", "0"], "--n-per-kind"),
])
def test_bad_input_exits_2_with_one_line(args, needle: str, models: Path, furniture,
                                         tmp_path: Path, capsys) -> None:
    res = _run_folder(tmp_path, furniture["chair"])
    argv = [a.format(tmp=tmp_path, models=models, res=res) for a in args]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_suite_matches_objects_by_volume_iou(furniture) -> None:
    from eval.suites.retrieval import match_objects

    gt = furniture["table"]
    # the prediction: the table without one leg, renamed, and a stray box
    from pipeline.model import box

    cubs = [c.with_(object="thing") for c in gt.cuboids if c.object == "table0"][:-1]
    pred = gt.with_(cuboids=(*cubs, box("x", (9, 9, 0.1), (0.2, 0.2, 0.2), object="stray")),
                    contacts=())
    m = match_objects(gt, pred, np.random.default_rng(0), ["table0"])
    assert m["table0"][0] == "thing" and m["table0"][1] > 0.8


@pytest.mark.slow
def test_synth_run_retrieve_with_scan(models: Path, tmp_path: Path) -> None:
    scene, res, out = tmp_path / "scene", tmp_path / "res", tmp_path / "out"
    assert main(["synth", "chair", "--out", str(scene), "--seed", "3"]) == 0
    assert main(["run", str(scene), "--out", str(res)]) == 0
    assert main(["retrieve", str(res), "--models", str(models), "--scan", str(scene),
                 "--out", str(out)]) == 0
    data = json.loads((out / "retrieval.json").read_text())
    (obj,) = [o for o in data["objects"] if o["object"] == "chair0"]
    assert obj["kind"] == "chair" and obj["points"] > 100 and "icp" in obj


@pytest.mark.slow
def test_suite_quick(tmp_path: Path) -> None:
    assert main(["eval", "retrieval", "--out", str(tmp_path / "s"), "--quick"]) == 0
    assert (tmp_path / "s" / "retrieval.md").is_file()


def test_a_scan_of_another_camera_is_refused(models: Path, tmp_path: Path, capsys) -> None:
    # --scan must be the frame the result came from: a frame whose focal length is not
    # the one the result recorded would be put into the result's world at the wrong place
    scene, res = tmp_path / "scene", tmp_path / "res"
    assert main(["synth", "stack", "--out", str(scene), "--seed", "3"]) == 0
    assert main(["run", str(scene), "--out", str(res), "--stage", "initial"]) == 0
    capsys.readouterr()
    data = json.loads((res / "arrangement.json").read_text())
    fx = data["meta"]["intrinsics"]["fx"]
    data["meta"]["intrinsics"]["fx"] = fx + 5.0
    (res / "arrangement.json").write_text(json.dumps(data))
    assert main(["retrieve", str(res), "--models", str(models), "--scan", str(scene),
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert f"made from a frame with fx {fx + 5.0:g} but --scan {scene} has fx {fx:g}" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "o").exists()
    data["meta"]["intrinsics"]["fx"] = fx  # the frame it came from passes
    (res / "arrangement.json").write_text(json.dumps(data))
    assert main(["retrieve", str(res), "--models", str(models), "--scan", str(scene),
                 "--out", str(tmp_path / "o"), "--no-icp"]) == 0
