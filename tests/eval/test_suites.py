"""The paper's suites (table1, perturb, density, viewpoint, complexity): quick runs write
their tables and plots through ``unseen eval``, parallel runs equal serial ones, and the
perturbation/density helpers obey their closed-form definitions."""

from __future__ import annotations

import argparse
import csv
import io
import json
from pathlib import Path

import numpy as np
import pytest

from eval.cli import main
from pipeline.model import Arrangement, box, ground

pytest.importorskip("mujoco")


def _rows(path: Path) -> list[dict]:
    return list(csv.DictReader(path.open()))


def _eval(suite: str, out: Path, *extra: str) -> int:
    return main(["eval", suite, "--out", str(out), *extra])


# ------------------------------------------------------------------------- table1
@pytest.fixture(scope="module")
def table1_serial(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("table1_serial")
    assert _eval("table1", out, "--quick", "--n", "1") == 0
    return out


def test_table1_quick(table1_serial: Path) -> None:
    out = table1_serial
    for name in ("table1.md", "table1.csv", "scenes.csv", "table1.png", "command.json"):
        assert (out / name).stat().st_size > 0
    rows = {r["scenes"]: r for r in _rows(out / "table1.csv")}
    assert {"stack", "all, single view", "all, 3 views fused", "paper: Synthetic",
            "paper: Kinfu"} <= set(rows)
    assert rows["paper: Synthetic"]["optimized F1"] == "87.2"
    scenes = _rows(out / "scenes.csv")
    assert [(s["family"], s["seed"], s["views"]) for s in scenes] == [
        ("stack", "1000", "1"), ("stack", "1000", "3")]
    # the family row and the total row of one family are the same scenes: same figures
    assert rows["stack"]["optimized F1"] == rows["all, single view"]["optimized F1"]
    # the table's F1 is the F1 of the task record's edge counts
    rec = json.loads((out / "tasks" / "stack-1000-v1.json").read_text())["result"]
    c = rec["optimized"]["typed"]
    f1 = 2 * c["tp"] / (c["n_pred"] + c["n_gt"]) if c["n_pred"] + c["n_gt"] else 0.0
    assert rows["stack"]["optimized F1"] == f"{100 * f1:.1f}"
    assert rec["n_gt"] >= 2 and rec["family"] == "stack"
    assert json.loads((out / "command.json").read_text())["suite"] == "table1"
    # a stack in front of the camera hides none of its boxes: nothing is missed for want
    # of points, and the reachable F1 is 100
    unseen = {r["scenes"]: r for r in _rows(out / "table1_unseen.csv")}
    assert unseen["stack"]["unseen parts"] == "0" and rec["unseen"] == []
    assert unseen["stack"]["missed at unseen parts"] == "0"
    assert unseen["stack"]["F1 if only those were missed"] == "100.0"
    assert unseen["stack"]["optimized F1"] == rows["stack"]["optimized F1"]
    # the geometry columns are the record's pooled sums: every stack box is seen
    assert rec["n_seen"] == rec["n_gt"] and rec["n_matched_seen"] <= rec["n_seen"]
    assert rows["stack"]["matched share (%)"] == f"{100 * rec['n_matched_seen'] / rec['n_seen']:.1f}"
    assert rows["stack"]["IoU (matched)"] == f"{rec['iou_sum'] / rec['n_matched']:.3f}"
    assert rows["stack"]["side error"] == f"{rec['side_abs'] / rec['side_len']:.3f}"
    lo, hi = (float(x) for x in rows["all, single view"]["F1 95% interval"].split("-"))
    assert lo <= float(rows["all, single view"]["optimized F1"]) <= hi
    assert int(unseen["stack"]["true contacts"]) == c["n_gt"]
    assert int(unseen["stack"]["missed"]) == c["n_gt"] - c["tp"]


def test_unseen_parts_are_those_with_fewer_points_than_an_instance_needs(tmp_path: Path) -> None:
    from eval.suites._scenes import missed_at, unseen_parts
    from pipeline.segment import MIN_INSTANCE_POINTS
    from simulate.scan import write_ply

    gt = Arrangement(tuple(box(f"b{k}", (k, 0, 0.5), (0.5, 0.5, 1.0)) for k in range(4)),
                     (ground(),))
    # instance k + 1 is cuboid b{k}: b0 just enough points, b1 one short, b2 none, b3 many
    counts = {1: MIN_INSTANCE_POINTS, 2: MIN_INSTANCE_POINTS - 1, 4: 500}
    inst = np.concatenate([np.full(n, i, np.uint16) for i, n in counts.items()]
                          + [np.zeros(7, np.uint16)])  # and points of no cuboid
    pts = np.random.default_rng(0).random((len(inst), 3))
    write_ply(tmp_path / "points.ply", pts, instance=inst)
    assert unseen_parts(tmp_path, gt) == ["b1", "b2"]
    fn = [("b0", "b1", "touch"), ("b2", "ground", "touch"), ("b0", "b3", "fixed")]
    assert missed_at(fn, ["b1", "b2"]) == 2 and missed_at(fn, []) == 0


def test_table1_parallel_equals_serial(table1_serial: Path, tmp_path: Path) -> None:
    assert _eval("table1", tmp_path, "--quick", "--n", "1", "--workers", "2") == 0
    timing = json.loads((tmp_path / "timing.json").read_text())
    assert timing["backend"] == "2 processes" and timing["n_resumed"] == 0
    for name in ("stack-1000-v1.json", "stack-1000-v3.json"):
        assert (tmp_path / "tasks" / name).read_bytes() == \
            (table1_serial / "tasks" / name).read_bytes()
    for name in ("table1.csv", "scenes.csv"):
        assert (tmp_path / name).read_bytes() == (table1_serial / name).read_bytes()


# ------------------------------------------------------------------------- perturb
def _two_boxes(gap: float = 0.0) -> Arrangement:
    return Arrangement((box("a", (0, 0, 0.25), (0.5, 0.4, 0.5)),
                        box("b", (0, 0, 0.75 + gap), (0.3, 0.3, 0.5), yaw=0.3)), (ground(),))


@pytest.mark.parametrize("angle", [0.0, 5.0, 15.0])
def test_perturb_definition(angle: float) -> None:
    from eval.suites import perturb

    arr = _two_boxes(gap=0.06)
    rng = np.random.default_rng(7)
    for _ in range(5):
        p, _, forced = perturb.perturb(arr, rng, angle)
        assert not forced
        rel = p.sizes / arr.sizes
        assert np.all(rel >= 0.95 - 1e-12) and np.all(rel <= 1.05 + 1e-12)
        np.testing.assert_array_equal(p.centers, arr.centers)   # about their centres
        # each cuboid turned by exactly `angle`: trace(R_new R_old^T) = 1 + 2 cos(angle)
        dR = p.rotations @ arr.rotations.transpose(0, 2, 1)
        cos = (np.trace(dR, axis1=1, axis2=2) - 1) / 2
        np.testing.assert_allclose(cos, np.cos(np.deg2rad(angle)), atol=1e-12)
        np.testing.assert_allclose(dR @ dR.transpose(0, 2, 1), np.broadcast_to(np.eye(3), dR.shape),
                                   atol=1e-12)
        # the separate pair stays non-intersecting
        assert perturb._pairs_sep(p.centers, p.rotations, p.sizes)[0] >= -perturb.OVERLAP_TOL
        assert all(c.observed is None for c in p.cuboids) and p.contacts == ()


def test_perturb_yaw_keeps_the_vertical() -> None:
    from eval.suites import perturb

    arr = _two_boxes(gap=0.06)
    p, _, forced = perturb.perturb(arr, np.random.default_rng(3), 10.0, axis="yaw")
    assert not forced
    dR = p.rotations @ arr.rotations.transpose(0, 2, 1)
    np.testing.assert_allclose(dR[:, :, 2], np.broadcast_to([0.0, 0.0, 1.0], (2, 3)), atol=1e-12)
    np.testing.assert_allclose(np.abs(np.arctan2(dR[:, 1, 0], dR[:, 0, 0])), np.deg2rad(10.0),
                               atol=1e-12)


def test_perturb_face_to_face_is_forced_but_least_overlapping() -> None:
    from eval.suites import perturb

    arr = _two_boxes()          # b sits on a: at 15 degrees every draw intersects
    p, discarded, forced = perturb.perturb(arr, np.random.default_rng(1), 15.0)
    assert forced and discarded == perturb.MAX_TRIES
    q, _, forced0 = perturb.perturb(arr, np.random.default_rng(1), 0.0)
    assert not forced0          # no rotation: touching faces stay touching, sizes only
    assert perturb._pairs_sep(q.centers, q.rotations, q.sizes)[0] >= -perturb.OVERLAP_TOL


def test_perturb_axes_are_random() -> None:
    from eval.suites.perturb import random_rotations

    R = random_rotations(np.random.default_rng(0), 400, 10.0)
    w = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], 1)
    axes = w / np.linalg.norm(w, axis=1, keepdims=True)
    # uniform on the sphere: mean ~ 0, second moment ~ I/3 (not only yaw)
    assert np.all(np.abs(axes.mean(axis=0)) < 0.1)
    np.testing.assert_allclose(axes.T @ axes / len(axes), np.eye(3) / 3, atol=0.06)


def test_perturb_quick(tmp_path: Path) -> None:
    assert _eval("perturb", tmp_path, "--quick", "--n", "1") == 0
    rows = _rows(tmp_path / "perturb.csv")
    ours = [r for r in rows if not r["family"].startswith("paper")]
    assert [(r["family"], r["axis"], r["rotation (deg)"], r["runs"]) for r in ours] == [
        ("chair", "random", "0", "1"), ("chair", "random", "15", "1")]
    assert {r["family"] for r in rows} >= {"paper: chair_01", "paper: chair_02"}
    assert (tmp_path / "perturb.png").stat().st_size > 0
    for r in ours:
        assert 0.0 <= float(r["optimized F1"]) <= 100.0


# ------------------------------------------------------------------------- density
def test_density_scaling_is_exact() -> None:
    from eval.suites.density import _scaled

    arr = _two_boxes()
    s = _scaled(arr, {"b"}, 5.0)
    np.testing.assert_allclose(s.masses, arr.masses * np.array([1.0, 5.0]), rtol=1e-12)
    np.testing.assert_array_equal(s.sizes, arr.sizes)


def test_density_quick(tmp_path: Path) -> None:
    assert _eval("density", tmp_path, "--quick", "--n", "1") == 0
    rows = _rows(tmp_path / "density.csv")
    assert [(r["family"], r["factor"], r["draws"]) for r in rows] == [("stack", "5x", "1")]
    rec = json.loads(next((tmp_path / "tasks").glob("*.json")).read_text())["result"]
    (d,) = rec["draws"]
    k = rec["n_gt"]
    assert 1 <= len(d["changed"]) <= max(1, int(0.2 * k)) and d["factor"] == 5.0
    assert rows[0]["graph survives %"] == ("100" if d["survives"] else "0")
    assert (tmp_path / "density.png").stat().st_size > 0


# ------------------------------------------------------------------------- viewpoint
def test_viewpoint_quick(tmp_path: Path) -> None:
    from eval.suites import viewpoint

    assert _eval("viewpoint", tmp_path, "--quick", "--n", "1") == 0
    rows = _rows(tmp_path / "viewpoint.csv")
    assert [float(r["azimuth (deg)"]) for r in rows] == [0.0, 120.0, 240.0]
    assert len(rows) == viewpoint.QUICK_VIEWS
    for p in sorted((tmp_path / "tasks").glob("*.json")):
        rec = json.loads(p.read_text())["result"]
        # FN at hidden cuboids are a subset of the FN, and hidden ids are true cuboids
        assert rec["fn_hidden"] <= len(rec["false_negatives"])
        assert len(rec["hidden"]) <= rec["n_gt"]
    summary = _rows(tmp_path / "viewpoint_summary.csv")
    assert summary[0]["views"] == "3"
    f1s = [float(r["optimized F1"]) for r in rows]
    assert float(summary[0]["min F1"]) == pytest.approx(min(f1s), abs=0.051)
    assert float(summary[0]["max F1"]) == pytest.approx(max(f1s), abs=0.051)


# ------------------------------------------------------------------------- complexity
def test_complexity_quick(tmp_path: Path) -> None:
    stream = io.StringIO()
    from eval.suites import complexity

    args = argparse.Namespace(out=tmp_path, seed=0, n=1, workers=1, dask=None, quick=True,
                              stream=stream)
    assert complexity.run(args) == 0
    rows = {r["scenes"]: r for r in _rows(tmp_path / "complexity.csv")}
    assert float(rows["stack 6"]["proxies"]) == 6.0        # a 6-box stack has 6 proxies
    # every box of a stack touches something, and a stack's contacts form a connected graph
    assert float(rows["stack 6"]["min val."]) >= 1
    assert float(rows["stack 6"]["contacts"]) >= 6
    assert float(rows["paper: Fig. 13"]["proxies"]) == 18
    assert float(rows["stack 6"]["seconds"]) > 0
    assert "Table 3" in stream.getvalue()


# ------------------------------------------------------------------------- pool
def test_pool_tasks_cover_every_family_over_the_seed_range() -> None:
    from eval.suites import pool

    tasks = pool.build_tasks(100_000, 20)
    assert len(tasks) == 200 and len({t.id for t in tasks}) == 200
    assert {t.kwargs["family"] for t in tasks} == set(pool.FAMILIES) and len(pool.FAMILIES) == 10
    assert {t.kwargs["seed"] for t in tasks} == set(range(100_000, 100_020))
    assert all(t.kwargs["views"] == 1 and "config" not in t.kwargs for t in tasks)
    cfg = {"disable": ["symmetry"]}
    assert all(t.kwargs["config"] == cfg for t in pool.build_tasks(100_000, 1, config=cfg))
    # the pool never reaches down into development (1000 + 100 s + i) or test seeds
    from pipeline.errors import InputError

    with pytest.raises(InputError, match="at least 100000"):
        pool.build_tasks(99_999, 1)


@pytest.mark.parametrize(("argv", "msg"), [
    (["pool"], "--first-seed S is required"),
    (["pool", "--first-seed", "1000"], "--first-seed: must be at least 100000"),
    (["table1", "--first-seed", "100000"], "--first-seed: only for the pool and ablation suites"),
])
def test_pool_seed_range_errors_exit_2(tmp_path: Path, capsys, argv, msg) -> None:
    out = tmp_path / "p"
    assert main(["eval", argv[0], "--out", str(out), *argv[1:]]) == 2
    err = capsys.readouterr().err.strip()
    assert msg in err and "\n" not in err and not out.exists()


def test_pool_quick(tmp_path: Path) -> None:
    assert _eval("pool", tmp_path, "--quick", "--first-seed", "100007") == 0
    # rerun (it resumes from its records) without --compare: a comparison an earlier run
    # wrote no longer describes the folder and goes
    (tmp_path / "compare.md").write_text("an earlier run's comparison")
    assert _eval("pool", tmp_path, "--quick", "--first-seed", "100007") == 0
    assert not (tmp_path / "compare.md").exists()
    cmd = json.loads((tmp_path / "command.json").read_text())
    assert cmd["command"].endswith("--quick --first-seed 100007") and cmd["first_seed"] == 100007
    rec = json.loads((tmp_path / "pool.json").read_text())
    assert (rec["first_seed"], rec["last_seed"], rec["n_per_family"]) == (100007, 100007, 1)
    assert "seeds 100007-100007" in (tmp_path / "pool.md").read_text()
    rows = {r["family"]: r for r in _rows(tmp_path / "pool.csv")}
    assert list(rows) == ["stack", "chair", "all"]
    scenes = _rows(tmp_path / "scenes.csv")
    assert [(s["family"], s["seed"]) for s in scenes] == [("stack", "100007"), ("chair", "100007")]
    tasks = {p.stem: json.loads(p.read_text())["result"] for p in (tmp_path / "tasks").iterdir()}
    assert set(tasks) == {"stack-100007", "chair-100007"}
    for fam, r in tasks.items():
        fam = fam.split("-")[0]
        c = r["optimized"]["typed"]
        f1 = 2 * c["tp"] / (c["n_pred"] + c["n_gt"])
        fig = rec["figures"][fam]
        assert fig["f1"] == pytest.approx(f1) and rows[fam]["typed F1"] == f"{100 * f1:.1f}"
        # one scene: every bootstrap resample is that scene
        assert fig["f1_lo"] == pytest.approx(f1) and fig["f1_hi"] == pytest.approx(f1)
        best = c["n_gt"] - r["fn_unseen"]
        assert fig["bound"] == pytest.approx(2 * best / (best + c["n_gt"]))
        assert fig["matched_share"] == pytest.approx(r["n_matched_seen"] / r["n_seen"])
        assert set(r["stands_in"]) == {"mujoco", "pybullet"}
        assert fig["stands_mujoco"] == float(r["stands_in"]["mujoco"])
    f_all = rec["figures"]["all"]
    assert f_all["scenes"] == 2 and f_all["f1_lo"] <= f_all["f1"] <= f_all["f1_hi"]
    assert (tmp_path / "pool.png").stat().st_size > 0


def _scene_record(tp: int, n: int, iou: float) -> dict:
    """A pool scene's result with ``tp`` of ``n`` predicted and ``n`` true contacts right
    and every one of its 2 boxes matched at ``iou``."""
    return {"optimized": {"typed": {"tp": tp, "n_pred": n, "n_gt": n}}, "n_gt": 2,
            "n_matched": 2, "n_seen": 2, "n_matched_seen": 2, "iou_sum": 2 * iou,
            "side_abs": 0.0, "side_len": 1.0}


def test_pool_compare_pairs_the_same_scenes_and_bounds_the_change(tmp_path: Path) -> None:
    """``--compare``: each scene against its own earlier record.  Every stack scene gains
    one of 4 contacts (F1 0.75 -> 1.0 in each, so every resample of the paired bootstrap
    gains exactly 25 points), chairs do not change (an interval of exactly 0), a scene
    the earlier run lacks is left out and named, and a failed earlier record is not
    compared."""
    from eval.suites import pool

    tasks = pool.build_tasks(100_000, 3, families=("stack", "chair"))
    before, after = tmp_path / "before", tmp_path / "after"
    (before / "tasks").mkdir(parents=True)
    after.mkdir()
    results = {}
    for t in tasks:
        fam = t.kwargs["family"]
        results[t.id] = _scene_record(4 if fam == "stack" else 2, 4, 0.7)
        if t.id == "chair-100002":
            continue  # not in the earlier run
        old = {"id": t.id, "fingerprint": "x", "status": "ok",
               "result": _scene_record(3 if fam == "stack" else 2, 4, 0.5)}
        if t.id == "chair-100001":
            old = {"id": t.id, "fingerprint": "x", "status": "error", "error": "boom"}
        (before / "tasks" / f"{t.id}.json").write_text(json.dumps(old))
    md = pool.compare(after, before, tasks, results)
    rec = json.loads((after / "compare.json").read_text())
    stack, chair, every = (rec["figures"][k] for k in ("stack", "chair", "all"))
    assert stack["scenes"] == 3 and (stack["up"], stack["down"]) == (3, 0)
    assert stack["f1_before"] == pytest.approx(0.75) and stack["f1_after"] == pytest.approx(1.0)
    assert stack["change_lo"] == pytest.approx(0.25) and stack["change_hi"] == pytest.approx(0.25)
    assert stack["iou_before"] == pytest.approx(0.5) and stack["iou_after"] == pytest.approx(0.7)
    assert chair["scenes"] == 1 and chair["change"] == 0.0
    assert (chair["change_lo"], chair["change_hi"]) == (0.0, 0.0)
    assert every["scenes"] == 4 and every["f1_before"] == pytest.approx(11 / 16)
    assert every["change_lo"] <= every["change"] <= every["change_hi"]
    assert rec["left_out"] == ["chair-100001", "chair-100002"]
    rows = {r["family"]: r for r in _rows(after / "compare.csv")}
    assert rows["stack"]["change"] == "+25.0" and rows["stack"]["change 95% interval"] == "+25.0 to +25.0"
    assert "2 scenes of this run have no record there" in md


def test_pool_compare_refuses_another_pool_in_one_line(tmp_path: Path, capsys) -> None:
    """``--compare`` needs an earlier pool of the same seeds and families: a folder without
    ``pool.json``, another seed range, the run's own ``--out`` and another suite are one
    line each, exit 2, before any work."""
    prev = tmp_path / "prev"
    prev.mkdir()
    out = tmp_path / "out"

    def refused(*argv: str) -> str:
        existed = out.exists()
        assert main(["eval", *argv]) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and out.exists() == existed
        assert not out.exists() or not any(out.iterdir())  # nothing written
        return err

    base = ["pool", "--out", str(out), "--quick", "--first-seed", "100007"]
    assert "no readable pool.json there" in refused(*base, "--compare", str(prev))
    (prev / "pool.json").write_text(json.dumps(
        {"first_seed": 100000, "last_seed": 100000, "families": ["stack", "chair"]}))
    err = refused(*base, "--compare", str(prev))
    assert "that pool is seeds 100000-100000" in err and "this one 100007-100007" in err
    assert "only for the pool and real suites" in refused("table1", "--out", str(out), "--quick",
                                                "--compare", str(prev))
    out.mkdir()
    assert "is the --out of this run" in refused(*base, "--compare", str(out))


def test_paired_bootstrap_of_identical_runs_is_zero() -> None:
    from eval.suites._common import paired_bootstrap

    recs = [_scene_record(k, 5, 0.5) for k in range(6)]
    assert paired_bootstrap(recs, recs, np.random.default_rng(0)) == (0.0, 0.0)


def test_a_scan_the_pipeline_refuses_scores_every_contact_missed(monkeypatch) -> None:
    from eval.suites import _scenes
    from pipeline.errors import InputError

    def refuse(*args, **kwargs):
        raise InputError("no ground plane found (test)")

    monkeypatch.setattr(_scenes, "run_dir", refuse)
    rec = _scenes.scene_task(np.random.default_rng(0), "stack", 1, engines=["mujoco"])
    n = rec["n_gt_contacts"]
    assert rec["pipeline_error"] == "no ground plane found (test)"
    for graph in ("optimized", "initial"):
        assert rec[graph]["typed"] == {"tp": 0, "n_pred": 0, "n_gt": n}
    assert rec["n_matched_seen"] == 0 and rec["n_seen"] == rec["n_gt"] - len(rec["unseen"])
    assert rec["stable"] is False and rec["stands_in"] == {"mujoco": False}
    from eval.suites.pool import figures

    assert figures([rec])["refused"] == 1 and figures([rec])["f1"] == 0.0
