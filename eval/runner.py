"""Run a suite's independent tasks serially, on local processes, or on a Dask cluster.

One job: execute a list of :class:`Task` and keep one JSON record per task.

* **One code path.**  Tasks go to a :class:`concurrent.futures.Executor`: an inline one
  (``workers=1``), a spawn-based :class:`~concurrent.futures.ProcessPoolExecutor`
  (``workers=N``), or a ``dask.distributed`` client's executor (``dask="tcp://host:port"``).
  The calling process collects results and writes every file, so Dask workers need no
  shared disk, only the code.
* **Deterministic.**  A task is called as ``fn(rng=rng, **kwargs)`` with ``rng`` seeded from
  ``(suite seed, task id)`` only (:func:`task_rng`), so the results do not depend on the
  number of workers or on the order tasks finish in.
* **Failures are data.**  A task that raises is recorded with its error and traceback;
  the others go on.
* **Resumable.**  Each record is written atomically to ``out/tasks/<task-id>.json`` as soon
  as the task ends; a rerun loads the records already there (same function, arguments and
  seed) instead of running those tasks again.  Failed tasks are run again.  The code
  itself is not part of that key: after changing a task's code, use a fresh folder.

Record files hold no timings, so the same tasks and seed give byte-identical records;
timings go to ``out/timing.json``.
"""

from __future__ import annotations

import concurrent.futures as cf
import hashlib
import json
import logging
import re
import time
import traceback
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pipeline import atomic
from pipeline.progress import Progress

log = logging.getLogger(__name__)

_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,199}$")


@dataclass(frozen=True)
class Task:
    """One independent unit of a suite.

    Attributes
    ----------
    id : str
        Unique within the suite; letters, digits, ``.``, ``_``, ``-`` (it names the file).
    fn : callable
        A module-level (picklable) function called as ``fn(rng=Generator, **kwargs)`` and
        returning a JSON-serialisable dict (numpy scalars and arrays are converted).
    kwargs : mapping
        Picklable keyword arguments.
    cost : float
        A rough relative running time.  Parallel runs start the costliest tasks first
        (longest processing time first: a long task started last keeps one worker busy
        while the others idle); results, records and their order do not depend on it.
    where : mapping
        Keyword arguments that say where the task works, not what it computes (an
        output folder): passed to ``fn`` but not part of :func:`fingerprint`, so a
        folder moved elsewhere still resumes.
    """

    id: str
    fn: Callable[..., Mapping[str, Any]]
    kwargs: Mapping[str, Any] = field(default_factory=dict)
    cost: float = 1.0
    where: Mapping[str, Any] = field(default_factory=dict)

    def arguments(self) -> dict:
        """Everything ``fn`` is called with besides ``rng``."""
        return {**self.kwargs, **self.where}


@dataclass(frozen=True)
class TaskRecord:
    """What became of one task: ``status`` is ``"ok"`` (with ``result``) or ``"failed"``
    (with ``error`` and ``traceback``); ``resumed`` when loaded from an earlier run."""

    id: str
    status: str
    result: dict | None = None
    error: str | None = None
    traceback: str | None = None
    seconds: float = 0.0
    resumed: bool = False

    @property
    def ok(self) -> bool:
        return self.status == "ok"


@dataclass(frozen=True)
class RunSummary:
    """All records in task order, with counts and the wall time of this run."""

    records: tuple[TaskRecord, ...]
    backend: str
    wall_seconds: float

    @property
    def n_ok(self) -> int:
        return sum(r.ok for r in self.records)

    @property
    def n_failed(self) -> int:
        return sum(not r.ok for r in self.records)

    @property
    def n_resumed(self) -> int:
        return sum(r.resumed for r in self.records)

    @property
    def results(self) -> dict[str, dict]:
        """Task id -> result, for the tasks that succeeded."""
        return {r.id: r.result for r in self.records if r.ok}

    @property
    def failures(self) -> dict[str, str]:
        """Task id -> error line, for the tasks that failed."""
        return {r.id: r.error or "" for r in self.records if not r.ok}


def task_rng(seed: int, task_id: str) -> np.random.Generator:
    """The generator of one task: a function of the suite seed and the task id only."""
    digest = hashlib.sha256(task_id.encode("utf-8")).digest()
    words = np.frombuffer(digest[:16], dtype="<u4").tolist()
    return np.random.default_rng(np.random.SeedSequence([int(seed), *words]))


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, Mapping):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    return obj


def fingerprint(task: Task, seed: int) -> str:
    """A short hash of what a task computes: its function, arguments and the suite seed."""
    name = f"{getattr(task.fn, '__module__', '?')}.{getattr(task.fn, '__qualname__', repr(task.fn))}"
    text = json.dumps([name, _jsonable(dict(task.kwargs)), int(seed)], sort_keys=True, default=repr)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def execute(fn: Callable[..., Mapping[str, Any]], kwargs: Mapping[str, Any], task_id: str,
            seed: int) -> dict:
    """Run one task (in whatever process it lands) and return its record as a dict.

    Never raises for a failing task: the error is part of the record.
    """
    t0 = time.perf_counter()
    try:
        result = fn(rng=task_rng(seed, task_id), **dict(kwargs))
        if not isinstance(result, Mapping):
            raise TypeError(f"task returned {type(result).__name__}, expected a dict")
        result = _jsonable(result)
        json.dumps(result)  # fail here, inside the task, if it cannot be written
        rec = {"id": task_id, "status": "ok", "result": result}
    except Exception as exc:  # noqa: BLE001 - a failing task is a recorded outcome
        rec = {"id": task_id, "status": "failed",
               "error": f"{type(exc).__name__}: {exc}".splitlines()[0][:500],
               "traceback": traceback.format_exc()}
    rec["seconds"] = time.perf_counter() - t0
    return rec


class _InlineExecutor(cf.Executor):
    """Runs each task at submission, in this process (``workers=1``)."""

    def submit(self, fn, /, *args, **kwargs):  # noqa: ANN001 - Executor signature
        fut: cf.Future = cf.Future()
        try:
            fut.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # noqa: BLE001 - delivered through the future
            fut.set_exception(exc)
        return fut


def _task_path(out: Path, task_id: str) -> Path:
    return out / "tasks" / f"{task_id}.json"


def _load_done(path: Path, fp: str) -> TaskRecord | None:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if data.get("status") != "ok" or data.get("fingerprint") != fp:
        return None
    return TaskRecord(data["id"], "ok", data.get("result"), resumed=True)


def _write(path: Path, rec: dict, fp: str) -> None:
    body = {"id": rec["id"], "fingerprint": fp, "status": rec["status"]}
    if rec["status"] == "ok":
        body["result"] = rec["result"]
    else:
        body["error"] = rec["error"]
        body["traceback"] = rec["traceback"]
    atomic.write_text(path, json.dumps(body, indent=1, sort_keys=False) + "\n")


def run_tasks(tasks: Iterable[Task], out: str | Path, *, seed: int = 0, workers: int = 1,
              dask: str | None = None, label: str = "tasks",
              progress: bool | None = None) -> RunSummary:
    """Run ``tasks``, writing ``out/tasks/<id>.json`` per task, and return every record.

    Parameters
    ----------
    tasks : iterable of Task
    out : output folder (created)
    seed : suite seed; each task's generator is :func:`task_rng` ``(seed, task.id)``
    workers : local processes (1 = in this process)
    dask : address of a running Dask scheduler (``tcp://host:port``); overrides ``workers``
    label : progress bar label
    progress : draw a progress bar on stderr (default: when stderr is a terminal)

    Returns
    -------
    RunSummary
        Records in the order of ``tasks``.  A ``KeyboardInterrupt`` stops the run; the
        records written so far are kept and a rerun resumes from them.
    """
    tasks = list(tasks)
    seen: set[str] = set()
    for t in tasks:
        if not _ID.match(t.id):
            raise ValueError(f"task id {t.id!r}: use letters, digits, '.', '_' or '-'")
        if t.id in seen:
            raise ValueError(f"task id {t.id!r} appears twice")
        seen.add(t.id)
    if workers < 1:
        raise ValueError(f"workers: expected >= 1, got {workers}")
    out = Path(out)
    (out / "tasks").mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    prints = {t.id: fingerprint(t, seed) for t in tasks}
    records: dict[str, TaskRecord] = {}
    for t in tasks:
        done = _load_done(_task_path(out, t.id), prints[t.id])
        if done is not None:
            records[t.id] = done
    pending = [t for t in tasks if t.id not in records]

    client = None
    if dask:
        from distributed import Client

        client = Client(dask, timeout="10s")
        executor: cf.Executor = client.get_executor(pure=False)
        backend = f"dask {dask}"
    elif workers > 1 and len(pending) > 1:
        import multiprocessing

        executor = cf.ProcessPoolExecutor(max_workers=min(workers, len(pending)),
                                          mp_context=multiprocessing.get_context("spawn"))
        backend = f"{workers} processes"
    else:
        executor = _InlineExecutor()
        backend = "serial"
    bar = Progress(len(tasks), label, enabled=progress)
    bar.count = len(records)
    futures: dict[cf.Future, Task] = {}
    try:
        with bar:
            if isinstance(executor, _InlineExecutor):
                # submit lazily so the bar moves and an interrupt keeps what is written
                for t in pending:
                    _collect(executor.submit(execute, t.fn, t.arguments(), t.id, seed),
                             t, out, prints, records, bar)
            else:
                order = sorted(pending, key=lambda t: -t.cost)  # stable: ties in task order
                futures = {executor.submit(execute, t.fn, t.arguments(), t.id, seed): t
                           for t in order}
                for fut in cf.as_completed(futures):
                    _collect(fut, futures[fut], out, prints, records, bar)
    finally:
        for fut in futures:
            fut.cancel()
        if isinstance(executor, cf.ProcessPoolExecutor):
            executor.shutdown(wait=True, cancel_futures=True)
        else:
            executor.shutdown(wait=True)
        if client is not None:
            client.close()
    wall = time.perf_counter() - t0
    summary = RunSummary(tuple(records[t.id] for t in tasks), backend, wall)
    timing = {"backend": backend, "wall_seconds": wall, "n_tasks": len(tasks),
              "n_ok": summary.n_ok, "n_failed": summary.n_failed,
              "n_resumed": summary.n_resumed,
              "task_seconds": {r.id: r.seconds for r in summary.records if not r.resumed}}
    atomic.write_text(out / "timing.json", json.dumps(timing, indent=1) + "\n")
    return summary


def _collect(fut: cf.Future, task: Task, out: Path, prints: dict[str, str],
             records: dict[str, TaskRecord], bar: Progress) -> None:
    try:
        rec = fut.result()
    except Exception as exc:  # noqa: BLE001 - the worker itself died or could not unpickle
        rec = {"id": task.id, "status": "failed",
               "error": f"{type(exc).__name__}: {exc}".splitlines()[0][:500],
               "traceback": "".join(traceback.format_exception(exc)), "seconds": 0.0}
    _write(_task_path(out, task.id), rec, prints[task.id])
    records[task.id] = TaskRecord(rec["id"], rec["status"], rec.get("result"), rec.get("error"),
                                  rec.get("traceback"), float(rec.get("seconds", 0.0)))
    if rec["status"] != "ok":
        log.warning("task %s failed: %s", task.id, rec["error"])
    bar.update(note=task.id)


def failure_line(summaries: Iterable[RunSummary]) -> str | None:
    """One line for the runs' failed tasks (how many, and the first error), or None.

    A suite, dataset or bulk run with a failed task prints this on stderr and exits 1: a
    table of the tasks that did succeed must not pass for the whole answer.
    """
    summaries = list(summaries)
    failed = [r for s in summaries for r in s.records if not r.ok]
    if not failed:
        return None
    total = sum(len(s.records) for s in summaries)
    first = failed[0]
    return (f"{len(failed)} of {total} tasks failed; first: {first.id}: {first.error} "
            f"(its traceback is in tasks/{first.id}.json)")


def load_records(out: str | Path) -> dict[str, dict]:
    """Every task record under ``out/tasks`` (id -> the JSON object), sorted by id."""
    folder = Path(out) / "tasks"
    recs = {}
    for p in sorted(folder.glob("*.json")):
        try:
            data = json.loads(p.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        recs[data.get("id", p.stem)] = data
    return recs
