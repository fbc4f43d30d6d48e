"""The suite runner: serial, local processes and Dask give identical records; failures and resume."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from eval.runner import Task, load_records, run_tasks, task_rng


def draw(rng: np.random.Generator, n: int, scale: float = 1.0) -> dict:
    """A task whose result depends only on its own generator and arguments."""
    x = rng.normal(size=n) * scale
    return {"n": n, "sum": float(x.sum()), "first": x[:3], "max": np.float64(x.max())}


def flaky(rng: np.random.Generator, n: int, fail: bool = False) -> dict:
    if fail:
        raise RuntimeError(f"task {n} broke on purpose")
    return {"n": n, "u": float(rng.random())}


def counted(rng: np.random.Generator, n: int, log: str, interrupt: bool = False) -> dict:
    with open(log, "a", encoding="utf-8") as fh:
        fh.write(f"{n}\n")
    if interrupt:
        raise KeyboardInterrupt
    return {"n": n, "u": float(rng.random())}


def timed(rng: np.random.Generator, n: int, log: str) -> dict:
    """Log this task's start (a monotonic clock shared by the workers of one machine)."""
    import time

    with open(log, "a", encoding="utf-8") as fh:
        fh.write(f"{n} {time.monotonic()}\n")
    time.sleep(0.3)
    return {"n": n}


def not_a_dict(rng: np.random.Generator) -> list:
    return [1, 2]


def not_json(rng: np.random.Generator) -> dict:
    return {"x": object()}


def _tasks(k: int = 6) -> list[Task]:
    return [Task(f"scene-{i:02d}", draw, {"n": 5 + i, "scale": 0.5 * (i + 1)}) for i in range(k)]


def _files(out: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted((out / "tasks").glob("*.json"))}


def test_task_rng_depends_on_seed_and_id_only():
    a = task_rng(3, "x").random(4)
    np.testing.assert_array_equal(a, task_rng(3, "x").random(4))
    assert not np.array_equal(a, task_rng(4, "x").random(4))
    assert not np.array_equal(a, task_rng(3, "y").random(4))


def test_serial_two_processes_and_dask_identical(tmp_path):
    distributed = pytest.importorskip("distributed")
    serial = run_tasks(_tasks(), tmp_path / "serial", seed=11, progress=False)
    procs = run_tasks(_tasks(), tmp_path / "procs", seed=11, workers=2, progress=False)
    assert serial.backend == "serial" and procs.backend == "2 processes"
    assert serial.n_ok == 6 and serial.n_failed == 0
    # independent truth: the task run by hand with the documented generator
    first = draw(task_rng(11, "scene-00"), n=5, scale=0.5)
    assert serial.results["scene-00"]["sum"] == first["sum"]
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        dask = run_tasks(_tasks(), tmp_path / "dask", seed=11, dask=cluster.scheduler_address,
                         progress=False)
    assert dask.backend.startswith("dask")
    assert serial.results == procs.results == dask.results
    assert [r.id for r in dask.records] == [t.id for t in _tasks()]
    # the record files themselves are byte-identical
    assert _files(tmp_path / "serial") == _files(tmp_path / "procs") == _files(tmp_path / "dask")
    other = run_tasks(_tasks(), tmp_path / "seed12", seed=12, progress=False)
    assert other.results["scene-00"] != serial.results["scene-00"]


def test_failing_task_recorded_others_finish(tmp_path):
    tasks = [Task(f"t{i}", flaky, {"n": i, "fail": i == 2}) for i in range(5)]
    for workers in (1, 2):
        out = tmp_path / f"w{workers}"
        s = run_tasks(tasks, out, seed=0, workers=workers, progress=False)
        assert s.n_ok == 4 and s.n_failed == 1
        assert s.failures == {"t2": "RuntimeError: task 2 broke on purpose"}
        rec = json.loads((out / "tasks" / "t2.json").read_text())
        assert rec["status"] == "failed" and "broke on purpose" in rec["traceback"]
        assert sorted(load_records(out)) == [f"t{i}" for i in range(5)]
        timing = json.loads((out / "timing.json").read_text())
        assert timing["n_failed"] == 1 and timing["n_ok"] == 4


def test_resume_skips_done_tasks_and_reruns_failed_or_changed(tmp_path):
    log = tmp_path / "calls.txt"
    out = tmp_path / "out"

    def tasks(interrupt_at: int | None, n_extra: int = 0) -> list[Task]:
        return [Task(f"t{i}", counted, {"n": i + n_extra * (i == 3), "log": str(log),
                                        "interrupt": i == interrupt_at}) for i in range(5)]

    # an interrupt at t2 stops the run; t0, t1 are written, t3, t4 never ran
    with pytest.raises(KeyboardInterrupt):
        run_tasks(tasks(2), out, seed=5, progress=False)
    assert sorted(load_records(out)) == ["t0", "t1"]
    assert log.read_text().split() == ["0", "1", "2"]
    before = _files(out)

    s = run_tasks(tasks(None), out, seed=5, progress=False)
    assert s.n_ok == 5 and s.n_resumed == 2
    assert log.read_text().split() == ["0", "1", "2", "2", "3", "4"]
    assert {k: v for k, v in _files(out).items() if k in before} == before
    # a full rerun runs nothing
    s = run_tasks(tasks(None), out, seed=5, progress=False)
    assert s.n_resumed == 5 and len(log.read_text().split()) == 6
    # changed arguments for t3 -> only t3 runs again; a different seed -> everything
    run_tasks(tasks(None, n_extra=10), out, seed=5, progress=False)
    assert log.read_text().split()[6:] == ["13"]
    s = run_tasks(tasks(None), out, seed=6, progress=False)
    assert s.n_resumed == 0 and len(log.read_text().split()) == 12
    # the same tasks in a fresh folder give the same results as the resumed run
    fresh = run_tasks(tasks(None), tmp_path / "fresh", seed=6, progress=False)
    assert fresh.results == s.results


def test_bad_task_ids_rejected(tmp_path):
    with pytest.raises(ValueError, match="twice"):
        run_tasks([Task("a", draw, {"n": 1}), Task("a", draw, {"n": 2})], tmp_path)
    with pytest.raises(ValueError, match="letters"):
        run_tasks([Task("../evil", draw, {"n": 1})], tmp_path)


def test_results_must_be_json_dicts(tmp_path):
    s = run_tasks([Task("a", not_a_dict), Task("b", not_json), Task("c", draw, {"n": 2})],
                  tmp_path, progress=False)
    assert s.failures["a"] == "TypeError: task returned list, expected a dict"
    assert s.failures["b"].startswith("TypeError: Object of type object")
    assert s.n_ok == 1 and s.results["c"]["n"] == 2
    # numpy values were converted to plain JSON
    assert isinstance(s.results["c"]["first"], list) and isinstance(s.results["c"]["max"], float)


def test_parallel_runs_start_the_costliest_tasks_first(tmp_path):
    # longest processing time first: of six tasks on two workers the two marked costliest
    # start before the rest; records (and their order) are as without costs
    log = tmp_path / "starts.log"
    costs = [1.0, 1.0, 1.0, 5.0, 1.0, 3.0]
    tasks = [Task(f"t{i}", timed, {"n": i, "log": str(log)}, cost=c)
             for i, c in enumerate(costs)]
    summary = run_tasks(tasks, tmp_path / "out", workers=2, progress=False)
    assert [r.id for r in summary.records] == [t.id for t in tasks] and summary.n_ok == 6
    starts = dict(line.split() for line in log.read_text().splitlines())
    first_two = sorted(starts, key=lambda k: float(starts[k]))[:2]
    assert sorted(first_two) == ["3", "5"]
    # the serial path keeps the task order (nothing to balance)
    log.unlink()
    run_tasks(tasks, tmp_path / "serial", progress=False)
    assert [line.split()[0] for line in log.read_text().splitlines()] == [str(i) for i in range(6)]
