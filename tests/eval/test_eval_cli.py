"""``unseen eval``: dispatch to a suite, command.json, bad input; the suites' shared helpers."""

from __future__ import annotations

import csv
import json
import sys
import types

import numpy as np
import pytest

from eval.cli import main
from eval.commands import evaluate
from eval.runner import Task
from eval.suites import _common


def _noisy_task(rng: np.random.Generator, k: int) -> dict:
    return {"k": k, "optimized": {"typed": {"tp": k, "n_pred": k + 1, "n_gt": 3}},
            "u": float(rng.random())}


def _fake_suite_run(args) -> int:
    tasks = [Task(f"s{k}", _noisy_task, {"k": k}) for k in range(args.n or 3)]
    summary = _common.run_suite_tasks(args, tasks, "fake")
    agg = _common.aggregate_prf(summary.results.values())
    _common.write_table(args.out, "table", ["F1", "n"], [[100 * agg["f1"], agg["n"]]],
                        title="fake")
    return 0 if not args.quick else 1


def _threads_task(rng: np.random.Generator) -> dict:
    import os

    return {name: os.environ.get(name) for name in evaluate.THREAD_VARS}


def _threads_suite_run(args) -> int:
    tasks = [Task(f"t{k}", _threads_task) for k in range(2)]
    summary = _common.run_suite_tasks(args, tasks, "threads")
    (args.out / "seen.json").write_text(json.dumps(summary.results))
    return 0


@pytest.fixture
def fake_suite(monkeypatch):
    mod = types.ModuleType("eval.suites.fake")
    mod.run = _fake_suite_run
    monkeypatch.setitem(sys.modules, "eval.suites.fake", mod)
    real = evaluate.available_suites
    monkeypatch.setattr(evaluate, "available_suites", lambda: sorted([*real(), "fake"]))
    return mod


def test_eval_runs_suite_and_records_command(fake_suite, tmp_path):
    out = tmp_path / "res"
    assert main(["eval", "fake", "--out", str(out), "--seed", "4", "--n", "3"]) == 0
    cmd = json.loads((out / "command.json").read_text())
    assert cmd["command"] == f"unseen eval fake --out {out} --seed 4 --n 3 --workers 1"
    assert cmd["seed"] == 4 and cmd["suite"] == "fake"
    for pkg in ("unseen", "numpy", "mujoco", "pybullet", "open3d"):
        assert pkg in cmd["versions"]
    assert cmd["versions"]["numpy"] == np.__version__
    # micro F1 over tp 0+1+2 = 3, predicted 1+2+3 = 6, true 9: P 1/2, R 1/3 -> F1 0.4
    assert "| 40 | 3 |" in (out / "table.md").read_text()
    rows = list(csv.reader((out / "table.csv").open()))
    assert rows[0] == ["F1", "n"] and float(rows[1][0]) == pytest.approx(40.0)
    assert sorted(p.name for p in (out / "tasks").iterdir()) == ["s0.json", "s1.json", "s2.json"]
    # the suite's exit code is the command's
    assert main(["eval", "fake", "--out", str(out), "--quick"]) == 1


def test_eval_pins_one_thread_per_worker_unless_set(fake_suite, monkeypatch, tmp_path):
    """Suites scale by processes: each worker runs one OpenMP/BLAS thread; a user's own
    setting wins."""
    fake_suite.run = _threads_suite_run
    for name in evaluate.THREAD_VARS:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "3")
    out = tmp_path / "thr"
    assert main(["eval", "fake", "--out", str(out), "--workers", "2"]) == 0
    want = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "3"}
    seen = json.loads((out / "seen.json").read_text())
    assert seen == {"t0": want, "t1": want}  # as the spawned worker processes saw them
    assert json.loads((out / "command.json").read_text())["threads"] == want


def test_eval_unknown_suite_lists_suites(fake_suite, tmp_path, capsys):
    assert main(["eval", "nosuch", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip()
    assert "unknown suite 'nosuch'" in err and "fake" in err and "\n" not in err
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("extra", [["--workers", "0"], ["--n", "0"], ["--seed", "-1"],
                                   ["--update"], ["--only", "stack-1000"]])
def test_eval_bad_options_exit_2(fake_suite, tmp_path, capsys, extra):
    assert main(["eval", "fake", "--out", str(tmp_path / "x"), *extra]) == 2
    assert capsys.readouterr().err.startswith("unseen eval: error:")


def test_eval_regression_unknown_case_exit_2(tmp_path, capsys):
    assert main(["eval", "regression", "--out", str(tmp_path / "r"), "--only", "nosuch"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--only: unknown case(s) nosuch" in err and "stack-1000" in err and "\n" not in err


def test_eval_regression_update_through_the_cli(tmp_path, capsys):
    exp = tmp_path / "expected.json"
    out = tmp_path / "r"
    assert main(["eval", "regression", "--out", str(out), "--only", "stack-1000",
                 "--expected", str(exp), "--update"]) == 0
    data = json.loads(exp.read_text())
    assert set(data["scans"]) == {"stack-1000"}
    cmd = json.loads((out / "command.json").read_text())["command"]
    assert cmd.endswith(f"--only stack-1000 --expected {exp} --update")
    # checked against what it just wrote: no regression; a flipped figure: exit 1
    assert main(["eval", "regression", "--out", str(out), "--only", "stack-1000",
                 "--expected", str(exp)]) == 0
    data["scans"]["stack-1000"]["fixed"] = -1
    exp.write_text(json.dumps(data))
    assert main(["eval", "regression", "--out", str(out), "--only", "stack-1000",
                 "--expected", str(exp)]) == 1
    captured = capsys.readouterr()
    assert "REGRESSED:\n- stack-1000: fixed 0 > -1 + 0" in captured.out


def test_workers_and_dask_are_exclusive(tmp_path):
    with pytest.raises(SystemExit) as exc:
        main(["eval", "fake", "--out", str(tmp_path), "--workers", "2", "--dask", "tcp://x:1"])
    assert exc.value.code == 2


def test_common_markdown_csv_and_aggregation(tmp_path):
    md = _common.write_table(tmp_path, "t", ["family", "P / R", "F1"],
                             [["stack", "96.2 / 84.7", 87.21], ["a|b", None, float("nan")]],
                             title="Table 1", note="micro-averaged", floatfmt=".1f")
    assert md.splitlines()[:4] == ["## Table 1", "", "| family | P / R | F1 |", "|---|---|---|"]
    assert "| stack | 96.2 / 84.7 | 87.2 |" in md and "| a\\|b |  | - |" in md
    assert (tmp_path / "t.md").read_text() == md
    rows = list(csv.reader((tmp_path / "t.csv").open()))
    assert rows[1] == ["stack", "96.2 / 84.7", "87.21"] and rows[2][0] == "a|b"
    with pytest.raises(ValueError, match="columns"):
        _common.markdown_table(["a"], [[1, 2]])
    recs = [{"optimized": {"typed": {"tp": 2, "n_pred": 2, "n_gt": 4}}},
            {"optimized": {"typed": {"tp": 1, "n_pred": 3, "n_gt": 1}}}, {"failed": True}]
    agg = _common.aggregate_prf(recs)
    # micro: tp 3, pred 5, true 5 -> 0.6; macro: F1 2/3 and 0.5
    assert agg["n"] == 2 and agg["f1"] == pytest.approx(0.6)
    assert agg["macro_f1"] == pytest.approx((2 / 3 + 0.5) / 2)
    assert _common.pr_cell(agg) == "60.0 / 60.0"
    groups = _common.group_records({"stack-0": {"a": 1}, "table-0": {"a": 2}, "stack-1": {"a": 3}},
                                   lambda tid, r: tid.split("-")[0])
    assert list(groups) == ["stack", "table"] and len(groups["stack"]) == 2


def test_common_score_record_and_plots(tmp_path):
    from pipeline.model import Arrangement, Contact, box, ground

    gt = Arrangement((box("a", (0, 0, 0.5), (1, 1, 1)), box("b", (0, 0, 1.5), (1, 1, 1))),
                     (ground(),), (Contact("a", "ground"), Contact("a", "b", "fixed")))
    pred = gt.with_(contacts=(Contact("a", "ground"), Contact("a", "b")))
    rec = _common.score_record(pred, gt, graph="listed")
    assert rec["optimized"]["typed"] == {"tp": 1, "n_pred": 2, "n_gt": 2}
    assert rec["optimized"]["untyped"] == {"tp": 2, "n_pred": 2, "n_gt": 2}
    assert rec["valence"]["gt"]["contacts"] == 2 and rec["valence"]["gt"]["max_valence"] == 2
    json.dumps(rec)
    _common.plot_series(tmp_path / "p.png", {"ours": ([1, 2, 4], [0.1, 0.2, 0.5])},
                        xlabel="boxes", ylabel="s", logy=True)
    _common.plot_bars(tmp_path / "b.png", {"stack": {"initial": 30, "optimized": 95}},
                      ylabel="F1")
    first = (tmp_path / "p.png").read_bytes()
    assert first[:8] == b"\x89PNG\r\n\x1a\n" and (tmp_path / "b.png").stat().st_size > 1000
    _common.plot_series(tmp_path / "p.png", {"ours": ([1, 2, 4], [0.1, 0.2, 0.5])},
                        xlabel="boxes", ylabel="s", logy=True)
    assert (tmp_path / "p.png").read_bytes() == first


def test_common_regressions_and_failures():
    from eval.runner import RunSummary, TaskRecord

    expected = {"stack-0": {"f1": 0.95, "fixed": 2, "agree": 1.0}, "room-0": {"f1": 0.9}}
    same = {"stack-0": {"f1": 0.95, "fixed": 2, "agree": 1.0}, "room-0": {"f1": 0.91}}
    kw = {"higher_better": ["f1", "agree"], "lower_better": ["fixed"]}
    assert _common.regressions(same, expected, **kw) == []
    worse = {"stack-0": {"f1": 0.94, "fixed": 3, "agree": 1.0}}
    lines = _common.regressions(worse, expected, **kw)
    assert lines == ["stack-0: f1 0.94 < stored 0.95", "stack-0: fixed 3 > stored 2",
                     "room-0: missing (expected {'f1': 0.9})"]
    # a two-sided figure must match
    assert _common.regressions({"a": {"n": 3}}, {"a": {"n": 4}}) == ["a: n 3 != stored 4"]
    ok = RunSummary((TaskRecord("a", "ok", {}),), "serial", 0.0)
    assert _common.failures_markdown(ok) == ""
    bad = RunSummary((TaskRecord("a", "ok", {}), TaskRecord("b", "failed", error="E: x")),
                     "serial", 0.0)
    assert "- `b`: E: x" in _common.failures_markdown(bad)


def _rec(tp, n_pred, n_gt, init=None, *, seen=None, matched=None, iou=None, side=None):
    """A score_record-like result: edge counts and, optionally, geometry sums."""
    r = {"optimized": {"typed": {"tp": tp, "n_pred": n_pred, "n_gt": n_gt},
                       "untyped": {"tp": n_gt, "n_pred": n_gt, "n_gt": n_gt}}}
    if init:
        r["initial"] = {"typed": dict(zip(("tp", "n_pred", "n_gt"), init, strict=True))}
    if seen is not None:
        r.update(n_seen=seen, n_matched_seen=matched, n_matched=len(iou), n_gt=seen,
                 iou_sum=float(sum(iou)), side_abs=side[0], side_len=side[1])
    return r


def test_common_pr_f1_rows():
    groups = {"stack": [_rec(4, 4, 5, (1, 2, 5), seen=4, matched=3, iou=[0.9, 0.8, 0.7],
                             side=(0.3, 3.0)),
                        _rec(3, 4, 3, (0, 0, 3), seen=2, matched=2, iou=[0.6, 0.5],
                             side=(0.1, 2.0))],
              "chair": [_rec(2, 2, 2, seen=4, matched=2, iou=[0.1, 0.2], side=(1.0, 5.0))]}
    rows = _common.pr_f1_rows(groups)
    assert len(rows[0]) == len(_common.PR_F1_COLUMNS)
    assert _common.PR_F1_COLUMNS[-4:] == ["untyped F1", "matched share (%)", "IoU (matched)",
                                          "side error"]
    # stack: optimized tp 7, pred 8, true 8 -> 87.5 / 87.5; initial tp 1, pred 2, true 8;
    # matched 5 of 6 seen parts, IoU (0.9 + 0.8 + 0.7 + 0.6 + 0.5) / 5, side 0.4 / 5.0
    lo, hi = _common.bootstrap_f1(groups["stack"])
    assert rows[0] == ["stack", 2, "50.0 / 12.5", "20.0", "87.5 / 87.5", "87.5",
                       f"{100 * lo:.1f}-{100 * hi:.1f}", "100.0", "83.3", "0.700", "0.080"]
    assert rows[1][:4] == ["chair", 1, "-", "-"] and rows[1][5] == "100.0"
    assert rows[1][6] == "100.0-100.0"  # one perfect scene: every resample is perfect
    # all: optimized tp 9, pred 10, true 10; matched 7 of 10; IoU 3.8 / 7; side 1.4 / 10
    assert rows[2][0] == "all" and rows[2][4] == "90.0 / 90.0"
    assert rows[2][8:] == ["70.0", f"{3.8 / 7:.3f}", "0.140"]


def test_common_geometry_pools_sums_and_falls_back_to_all_parts():
    recs = [_rec(1, 1, 1, seen=4, matched=3, iou=[1.0, 0.5, 0.0], side=(1.0, 4.0)),
            _rec(1, 1, 1, seen=1, matched=1, iou=[0.5], side=(0.0, 1.0))]
    g = _common.geometry(recs)
    assert g == {"matched_share": 4 / 5, "iou": 2.0 / 4, "side_error": 1.0 / 5.0}
    # without the seen counts, the share is of all true parts
    old = {"n_gt": 4, "n_matched": 2}
    assert _common.geometry([old])["matched_share"] == 0.5
    empty = _common.geometry([])
    assert all(v != v for v in empty.values())
    assert _common.geometry_cells([]) == ["-", "-", "-"]


def test_bootstrap_interval_contains_the_f1_is_repeatable_and_shrinks_with_more_scenes():
    rng = np.random.default_rng(7)
    recs = []
    for _ in range(20):
        n_gt = int(rng.integers(3, 12))
        tp = int(rng.integers(0, n_gt + 1))
        recs.append(_rec(tp, tp + int(rng.integers(0, 3)), n_gt))
    f1 = _common.aggregate_prf(recs)["f1"]
    lo, hi = _common.bootstrap_f1(recs)
    assert 0.0 <= lo < f1 < hi <= 1.0
    assert _common.bootstrap_f1(recs) == (lo, hi)  # fixed seed: the same interval
    assert _common.bootstrap_f1(recs[::-1]) == (lo, hi)  # in any order
    assert _common.bootstrap_f1(recs, seed=1) != (lo, hi)
    lo4, hi4 = _common.bootstrap_f1(recs * 4)  # the same scenes, four times as many
    assert lo < lo4 < f1 < hi4 < hi
    assert (hi4 - lo4) < 0.6 * (hi - lo)  # about 1 / sqrt(4) as wide
    lo90, hi90 = _common.bootstrap_f1(recs, level=0.9)
    assert lo < lo90 and hi90 < hi
    assert _common.interval_cell((lo, hi)) == f"{100 * lo:.1f}-{100 * hi:.1f}"
    nan = _common.bootstrap_f1([{"n_gt": 1}])
    assert nan[0] != nan[0] and _common.interval_cell(nan) == "-"


def test_score_record_counts_seen_and_matched_parts():
    from pipeline.model import Arrangement, Contact, box, ground

    gt = Arrangement((box("a", (0, 0, 0.5), (1, 1, 1)), box("b", (0, 0, 1.5), (1, 1, 1)),
                      box("c", (3, 0, 0.5), (1, 1, 1))), (ground(),),
                     (Contact("a", "ground"), Contact("a", "b"), Contact("c", "ground")))
    # a matched, b shifted off its part (IoU 0.05: unmatched), c not predicted (unseen)
    pred = Arrangement((gt.cuboids[0], box("b", (0, 0.9, 1.5), (1, 1, 1))), (ground(),),
                       (Contact("a", "ground"), Contact("a", "b")))
    rec = _common.score_record(pred, gt, graph="listed", unseen=["c"])
    assert rec["n_seen"] == 2 and rec["n_matched_seen"] == 1 and rec["n_matched"] == 1
    assert rec["iou_sum"] == pytest.approx(1.0) and rec["side_abs"] == pytest.approx(0.0)
    assert rec["unseen"] == ["c"] and rec["fn_unseen"] == 1
    assert rec["optimized"]["typed"] == {"tp": 1, "n_pred": 2, "n_gt": 3}


def test_pipeline_config_is_checked_and_switches_priors_off():
    from eval.suites import _scenes
    from pipeline.priors import BY_NAME

    assert _scenes.run_config(1.0, None).imagine.disabled == frozenset()
    cfg = _scenes.run_config(1.0, {"disable": ["symmetry", "deepen"]}).imagine
    assert cfg.disabled == {"mirror", "copies", "deepen"} and cfg.budget == 1.0
    tuned = _scenes.run_config(2.0, {"params": {"close_gaps": {"gap": 0.03}}}).imagine
    assert tuned.params_of(BY_NAME["close_gaps"]).gap == 0.03
    assert tuned.params_of(BY_NAME["deepen"]) == BY_NAME["deepen"].params
    for bad, msg in (({"enable": []}, "unknown keys"), ({"disable": ["rows2"]}, "unknown prior"),
                     ({"params": {"deepen": {"nope": 1}}}, "params of prior deepen")):
        with pytest.raises(ValueError, match=msg):
            _scenes.run_config(1.0, _scenes.check_config(bad))
    with pytest.raises(ValueError, match="unknown keys"):  # before any scene is made
        _scenes.scene_task(np.random.default_rng(0), "stack", 1, config={"x": 1})
