"""Regression on your own scans: record what the pipeline makes of them, verify it later.

One job: keep a small, text expectation of the pipeline's answer for every scan in a
folder, and say per scan and per figure whether a later run dropped below it.

**The folder** (``DIR``).  Each direct child of ``DIR`` that ``unseen run`` takes is one
scan, named by its file or folder name (:func:`discover`): a ``.ply`` / ``.pcd`` / ``.npz``
point cloud, a scene directory (``scene.json`` + ``scan/``, whose ``scene.json`` is the
ground truth), an RGB-D folder (``color.png``, ``depth.png``, ``intrinsics.json``), a
multi-view folder (``view0/depth.png`` ...) or a folder holding one cloud.  Hidden
names and the expectation file are ignored; anything else is listed once as skipped,
never an error.  Each scan is run with ``unseen run``'s defaults (seed 0, search budget
10 s); nothing in ``DIR`` is modified except the expectation file that ``record`` writes.

**The expectation file** is one file, ``DIR/unseen-regress.json`` (:data:`RECORD_NAME`):
one file to commit and review, written in one atomic rename, that scan discovery never
mistakes for a scan, and from which ``verify`` can tell a scan that disappeared from one
that was never recorded.  It holds no timings and no absolute paths; keys come in a
fixed order, each box, support and contact on one line, so a re-record diffs line by
line.  Per scan (:func:`measure`)::

    "boxes":    [{"id", "object", "center", "size", "rotation"}]   metres, 0.1 mm
    "supports": [{"id", "point", "normal"}]
    "contacts": [[a, b, "touch" | "fixed"]]      the contact graph, supports included
                                                 (listed contacts and touching pairs,
                                                 as eval.metrics.contact_graph "union")
    "verdicts": {"analytic": bool, "mujoco": bool, "pybullet": bool}  (engines asked)
    "fixed":    fixed contacts between different objects or with a support (glue; the
                joins inside one object are the object's own and show in the graph)
    "truth":    {"f1", "size"} against scene.json, for a scene directory only
    "error":    instead of all the above, when the pipeline refused the scan

and once for all scans, ``run`` (seed, budget, engines: what ``verify`` reruns with) and
``tolerances`` (the defaults of ``verify``; its flags override them).

**The figures** ``verify`` compares (:func:`compare`), each with its tolerance:

``f1``
    Typed contact-graph F1.  With a ground truth: F1 against the truth, now vs recorded;
    a drop is ``now < recorded - tol``.  Without: F1 of the new graph against the
    recorded graph (recorded: 1), boxes matched by 3D IoU with Hungarian assignment as
    :func:`eval.metrics.match_cuboids` does (IoU at least
    :data:`eval.metrics.MIN_MATCH_IOU`), supports by plane; a drop is ``now < 1 - tol``.
``size``
    Relative side error of the matched boxes, ``sum |s - s_ref| / sum s_ref`` over their
    sides (the paper's equation 5 ``e_i`` weighted by side length), against the truth
    (now vs recorded) or against the recorded sizes (recorded: 0); a drop is
    ``now > recorded + tol``.
``moved``
    Without a ground truth: the largest distance between a matched box's centre and its
    recorded centre (metres; recorded 0); a drop is ``now > tol``.  With a truth it is
    shown but not judged (the truth F1 and size say whether a change is worse).
``stands:<engine>``
    The verdict of the analytic statics and of each engine recorded.  ``--stands
    recorded`` (default): a recorded "stands" that no longer stands is a drop;
    ``required``: anything that does not stand now is a drop; ``ignore``: shown only.
``agree``
    With two or more verdicts: do they agree?  Judged as ``stands``.
``fixed``
    Glue contacts; a drop is ``now > recorded + tol``.

A tolerance of ``None`` (``off`` on the command line) shows the figure without judging
it.  A scan that fails to run, or a recorded scan gone from ``DIR``, is an *error* (a
JUnit ``<error>``), never dropped silently; a scan recorded as refused that is refused
again is *skipped*, so is a scan in ``DIR`` that was never recorded.

**Reports** (:mod:`eval.regress_report`: ``markdown_report``, ``junit_xml``): one row per scan per figure
(recorded, now, tolerance, verdict) and a list of what changed (boxes added, removed,
moved or resized; contacts gained, lost or retyped; verdicts); JUnit has one testcase per
scan whose failure message names the figure and its numbers (``f1 0.62 < 1.00 -
0.05``).  Neither holds a timing: the same scans and results give the same bytes.

Caveat: the search has a time budget.  On a much slower or busier machine a large scene
may get a different (worse) answer than when it was recorded; keep regression scans
small, or record on the machine that verifies.
"""

from __future__ import annotations

import json
import logging
import math
import re
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pipeline.errors import InputError

#: The expectation file ``record`` writes into DIR.
RECORD_NAME = "unseen-regress.json"
FORMAT = "unseen.regress"
VERSION = 1
#: Point-cloud files ``unseen run`` takes.
CLOUD_SUFFIXES = (".ply", ".pcd", ".npz")
#: Engines ``--engine`` may ask for besides the analytic statics (always recorded).
ENGINES = ("mujoco", "pybullet")
#: ``--stands`` modes.
STANDS_MODES = ("recorded", "required", "ignore")
#: Search budget (seconds) and seed of every run: ``unseen run``'s defaults.
BUDGET = 10.0
SEED = 0
#: Decimals kept for lengths in metres (0.1 mm) and for rotations and figures.
LENGTH_DECIMALS = 4
ROTATION_DECIMALS = 5
FIGURE_DECIMALS = 6
#: Changes smaller than this (metres) are not listed in the diff.
DIFF_MIN_LENGTH = 0.002


# ============================================================================ tolerances
@dataclass(frozen=True)
class Tolerances:
    """How far each figure may drop before ``verify`` fails (None: shown, not judged).

    Attributes
    ----------
    f1 : float or None
        Allowed drop of the typed contact-graph F1 (a fraction in [0, 1]).
    size : float or None
        Allowed rise of the relative side error (a fraction).
    move : float or None
        Allowed centre displacement of a matched box, metres (scans without a truth).
    fixed : int or None
        Allowed rise of the number of glue contacts.
    stands : {"recorded", "required", "ignore"}
    """

    f1: float | None = 0.05
    size: float | None = 0.05
    move: float | None = 0.05
    fixed: int | None = 0
    stands: str = "recorded"

    def __post_init__(self) -> None:
        for name in ("f1", "size", "move"):
            v = getattr(self, name)
            if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v)
                                      and v >= 0):
                raise InputError(f"tolerance {name}: expected a number >= 0 or off, got {v!r}")
        if self.fixed is not None and not (isinstance(self.fixed, int) and self.fixed >= 0):
            raise InputError(f"tolerance fixed: expected an integer >= 0 or off, "
                             f"got {self.fixed!r}")
        if self.stands not in STANDS_MODES:
            raise InputError(f"tolerance stands: expected one of {', '.join(STANDS_MODES)}, "
                             f"got {self.stands!r}")

    def to_json(self) -> dict:
        return {"f1": self.f1, "size": self.size, "move": self.move, "fixed": self.fixed,
                "stands": self.stands}

    @classmethod
    def from_json(cls, data: Any, where: str = "tolerances") -> Tolerances:
        if not isinstance(data, Mapping):
            raise InputError(f"{where}: expected an object")
        unknown = set(data) - {"f1", "size", "move", "fixed", "stands"}
        if unknown:
            raise InputError(f"{where}: unknown key(s) {', '.join(sorted(unknown))}")
        d = cls()
        try:
            return cls(**{k: data.get(k, getattr(d, k)) for k in ("f1", "size", "move", "fixed",
                                                                  "stands")})
        except InputError as exc:
            raise InputError(f"{where}: {exc}") from None


def parse_tolerance(text: str, flag: str, integer: bool = False) -> float | int | None:
    """A command-line tolerance: a number >= 0 (an integer for ``integer``) or ``off``."""
    if text.strip().lower() in ("off", "none"):
        return None
    try:
        v: float | int = int(text) if integer else float(text)
    except ValueError:
        raise InputError(f"{flag} {text!r}: expected {'an integer' if integer else 'a number'}"
                         " >= 0, or off") from None
    if not math.isfinite(v) or v < 0:
        raise InputError(f"{flag} {text}: expected a value >= 0, or off")
    return v


# ============================================================================ discovery
@dataclass(frozen=True)
class Scan:
    """One scan of DIR: ``name`` (file or folder name), ``path``, ``kind`` (``cloud``,
    ``scene``, ``rgbd``, ``views``) and whether it carries a ground truth (``scene.json``)."""

    name: str
    path: Path
    kind: str

    @property
    def has_truth(self) -> bool:
        return self.kind == "scene"


def scan_kind(path: Path) -> str | None:
    """What ``unseen run`` would read at ``path`` (None: nothing it takes).

    Mirrors :func:`pipeline.scan_io.load_scan`: a cloud file; a folder whose ``scan/``
    (or itself) holds ``depth.png``, ``view0/depth.png`` or a ``.ply`` / ``.pcd``."""
    if path.is_file():
        return "cloud" if path.suffix.lower() in CLOUD_SUFFIXES else None
    if not path.is_dir():
        return None
    folder = path / "scan" if (path / "scan").is_dir() else path
    truth = (path / "scene.json").is_file()
    if (folder / "depth.png").is_file():
        return "scene" if truth else "rgbd"
    if (folder / "view0" / "depth.png").is_file():
        return "scene" if truth else "views"
    if not (folder / "color.png").exists() and (any(folder.glob("*.ply"))
                                                 or any(folder.glob("*.pcd"))):
        return "scene" if truth else "cloud"
    return None


def discover(folder: str | Path, record_name: str = RECORD_NAME
             ) -> tuple[list[Scan], list[str]]:
    """The scans of ``folder`` (sorted by name) and the names skipped (not a scan).

    Raises
    ------
    InputError
        ``folder`` is missing or not a folder.
    """
    folder = Path(folder)
    if not folder.exists():
        raise InputError(f"{folder}: no such folder")
    if not folder.is_dir():
        raise InputError(f"{folder}: not a folder (give the folder that holds your scans)")
    scans, skipped = [], []
    for p in sorted(folder.iterdir(), key=lambda q: q.name):
        if p.name.startswith(".") or p.name == record_name:
            continue
        kind = scan_kind(p)
        if kind is None:
            skipped.append(p.name)
        else:
            scans.append(Scan(p.name, p, kind))
    return scans, skipped


# ============================================================================ measuring
def _r(x: Any, decimals: int) -> Any:
    """Rounded plain floats (-0.0 becomes 0.0) of a number or nested array."""
    import numpy as np

    a = np.round(np.asarray(x, dtype=float), decimals) + 0.0
    return a.tolist()


def glue_count(arr) -> int:  # noqa: ANN001 - an Arrangement
    """``fixed`` contacts between different objects, or with a support."""
    objects = {c.id: c.object for c in arr.cuboids}
    return int(sum(c.type == "fixed" and (objects.get(c.a) is None
                                          or objects.get(c.a) != objects.get(c.b))
                   for c in arr.contacts))


def entry_of(arr, verdicts: Mapping[str, bool], truth: Mapping[str, Any] | None = None
             ) -> dict:  # noqa: ANN001
    """The record of one result (see the module docstring), rounded for a text file."""
    from eval.metrics import contact_graph

    boxes = []
    for c in arr.cuboids:
        b: dict[str, Any] = {"id": c.id}
        if c.object is not None:
            b["object"] = c.object
        b.update(center=_r(c.center, LENGTH_DECIMALS), size=_r(c.size, LENGTH_DECIMALS),
                 rotation=_r(c.rotation, ROTATION_DECIMALS))
        boxes.append(b)
    out: dict[str, Any] = {"verdicts": {k: bool(verdicts[k]) for k in verdicts},
                           "fixed": glue_count(arr)}
    if truth is not None:
        out["truth"] = dict(truth)
    out["boxes"] = boxes
    out["supports"] = [{"id": s.id, "point": _r(s.point, LENGTH_DECIMALS),
                        "normal": _r(s.normal, ROTATION_DECIMALS)} for s in arr.supports]
    out["contacts"] = [list(e) for e in sorted(contact_graph(arr, "union"))]
    return out


def measure(path: str | Path, engines: Sequence[str] = (), budget: float = BUDGET,
            seed: int = SEED) -> dict:
    """Run the pipeline on one scan and return its record (module docstring).

    Parameters
    ----------
    path : anything ``unseen run`` takes; a folder with ``scene.json`` is scored against it
    engines : engines to settle the result in (``mujoco``, ``pybullet``) besides statics
    budget : search budget, seconds
    seed : the run's seed

    Raises
    ------
    InputError
        The pipeline refused the scan (no ground plane, unreadable file, ...).
    """
    from pipeline.arrangement_io import read_arrangement
    from pipeline.priors import ImagineConfig
    from pipeline.run import RunConfig, run_scan

    path = Path(path)
    config = RunConfig(seed=int(seed), imagine=ImagineConfig.from_dict({"budget": float(budget)}))
    result = run_scan(path, config)
    arr = result.arrangement
    verdicts = {"analytic": bool(result.report.stable)}
    if engines:
        from simulate.engines import settle

        for engine in engines:
            verdicts[engine] = bool(settle(arr, engine, mu=config.imagine.mu).stable)
    truth = None
    if path.is_dir() and (path / "scene.json").is_file():
        from eval.metrics import score_arrangement

        s = score_arrangement(arr, read_arrangement(path / "scene.json"), initial=result.initial)
        side = s.side_error
        truth = {"f1": round(float(s.optimized.typed.f1), FIGURE_DECIMALS),
                 "size": None if side != side else round(float(side), FIGURE_DECIMALS)}
    return entry_of(arr, verdicts, truth)


def measure_task(rng, path: str, engines: Sequence[str] = (), budget: float = BUDGET,  # noqa: ANN001
                 seed: int = SEED) -> dict:
    """:func:`measure` as an :class:`eval.runner.Task` function (``rng`` unused: the run
    is seeded by ``seed``)."""
    del rng
    return measure(path, engines, budget, seed)


def _task_id(k: int, name: str) -> str:
    safe = re.sub(r"[^A-Za-z0-9._-]", "_", name)[:150]
    return f"{k:04d}-{safe}"


def measure_scans(scans: Sequence[Scan], engines: Sequence[str] = (), *, budget: float = BUDGET,
                  seed: int = SEED, workers: int = 1, label: str = "regress",
                  progress: bool | None = None) -> dict[str, dict]:
    """Measure every scan (in parallel with ``workers``): name -> record, or
    ``{"error": "<one line>"}`` for a scan that failed to run."""
    from eval.runner import Task, run_tasks

    tasks = [Task(_task_id(k, s.name), measure_task,
                  {"path": str(s.path), "engines": list(engines), "budget": float(budget),
                   "seed": int(seed)}) for k, s in enumerate(scans)]
    runner_log = logging.getLogger("eval.runner")  # a failed scan is reported here, once
    level = runner_log.level
    runner_log.setLevel(logging.ERROR)
    try:
        with tempfile.TemporaryDirectory(prefix="unseen-regress-") as tmp:
            summary = run_tasks(tasks, tmp, seed=0, workers=workers, label=label,
                                progress=progress)
    finally:
        runner_log.setLevel(level)
    out = {}
    for s, rec in zip(scans, summary.records, strict=True):
        if rec.ok:
            out[s.name] = dict(rec.result)
            continue
        line = error_line(rec.error)  # named by the scan, not by where DIR lies (no paths)
        for where in sorted({str(s.path.resolve()), str(s.path.absolute()), str(s.path)},
                            key=len, reverse=True):
            line = line.replace(where, s.name)
        out[s.name] = {"error": line}
    return out


def error_line(error: str | None) -> str:
    """A failed task's error line (the runner's ``Type: message``), without the type when
    it is an ``InputError`` (the pipeline refused the scan and says why)."""
    text = (error or "failed").strip()
    return text.split(": ", 1)[1] if text.startswith("InputError: ") else text


# ============================================================================ the file
@dataclass(frozen=True)
class Record:
    """An expectation file: ``scans`` (name -> record), the ``engines``, ``budget`` and
    ``seed`` to rerun with, and the default ``tolerances``."""

    scans: dict[str, dict]
    engines: tuple[str, ...] = ()
    budget: float = BUDGET
    seed: int = SEED
    tolerances: Tolerances = field(default_factory=Tolerances)

    def to_json(self) -> dict:
        return {"format": FORMAT, "version": VERSION,
                "run": {"seed": self.seed, "budget": self.budget, "engines": list(self.engines)},
                "tolerances": self.tolerances.to_json(),
                "scans": {k: self.scans[k] for k in sorted(self.scans)}}


def _compact(obj: Any, indent: int = 0) -> str:
    """JSON with containers that hold no object (and objects that hold only numbers,
    strings and such lists) on one line; everything else one key per line."""
    one = json.dumps(obj, allow_nan=False, separators=(", ", ": "))
    if not isinstance(obj, (dict, list)) or _flat(obj):
        return one
    pad, inner = " " * indent, " " * (indent + 1)
    if isinstance(obj, list):
        if not obj:
            return "[]"
        return "[\n" + ",\n".join(inner + _compact(v, indent + 1) for v in obj) + "\n" + pad + "]"
    if not obj:
        return "{}"
    return ("{\n" + ",\n".join(f"{inner}{json.dumps(k)}: {_compact(v, indent + 1)}"
                              for k, v in obj.items()) + "\n" + pad + "}")


def _flat(obj: dict | list) -> bool:
    """A leaf, written on one line: a list of scalars, or an object whose values are
    scalars or (nested) lists of scalars (a box with its rotation matrix)."""
    def plain(v: Any) -> bool:
        return not isinstance(v, (dict, list)) or (
            isinstance(v, list) and all(plain(x) for x in v))

    if isinstance(obj, list):
        return all(not isinstance(v, (dict, list)) for v in obj)
    return all(plain(v) for v in obj.values())


def dumps(record: Record) -> str:
    """The expectation file's text (stable, one box / contact per line)."""
    return _compact(record.to_json()) + "\n"


def write_record(record: Record, path: str | Path) -> None:
    """Write ``record`` to ``path`` atomically."""
    from pipeline import atomic

    atomic.write_text(path, dumps(record))


def read_record(path: str | Path, record_with: str | None = None) -> Record:
    """Read and check an expectation file (``record_with``: the command that writes one,
    named where there is none; default ``unseen regress record DIR``).

    Raises
    ------
    InputError
        Missing file, not JSON, or not an ``unseen.regress`` file of a known version.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no expectation file; write one with "
                         f"{record_with or f'unseen regress record {path.parent}'}")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: not a readable JSON file ({exc})") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise InputError(f"{path}: not an expectation file (format must be {FORMAT!r}); "
                         f"write one with {record_with or 'unseen regress record'}")
    if data.get("version") != VERSION:
        raise InputError(f"{path}: version {data.get('version')!r} is not supported "
                         f"(expected {VERSION}); record again with --update")
    run = data.get("run", {})
    scans = data.get("scans")
    if not isinstance(run, dict) or not isinstance(scans, dict):
        raise InputError(f"{path}: 'run' and 'scans' must be objects")
    engines = tuple(run.get("engines", ()))
    bad = [e for e in engines if e not in ENGINES]
    if bad:
        raise InputError(f"{path}: run.engines: unknown engine(s) {', '.join(map(str, bad))}")
    for name, entry in scans.items():
        _check_entry(entry, f"{path}: scans[{name!r}]")
    try:
        budget, seed = float(run.get("budget", BUDGET)), int(run.get("seed", SEED))
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{path}: run.budget and run.seed must be numbers") from None
    from eval.run_checks import BUDGET_RANGE, SEED_MAX

    if not (math.isfinite(budget) and BUDGET_RANGE[0] <= budget <= BUDGET_RANGE[1]):
        raise InputError(f"{path}: run.budget: seconds in [{BUDGET_RANGE[0]:g}, "
                         f"{BUDGET_RANGE[1]:g}], got {budget}")
    if not 0 <= seed <= SEED_MAX:
        raise InputError(f"{path}: run.seed: an integer from 0 to {SEED_MAX}, got {seed}")
    return Record({k: dict(v) for k, v in scans.items()}, engines, budget, seed,
                  Tolerances.from_json(data.get("tolerances", {}), f"{path}: tolerances"))


def _check_entry(entry: Any, where: str) -> None:
    if not isinstance(entry, dict):
        raise InputError(f"{where}: expected an object")
    if "error" in entry:
        return
    for key, kind in (("boxes", list), ("supports", list), ("contacts", list),
                      ("verdicts", dict), ("fixed", int)):
        if not isinstance(entry.get(key), kind):
            raise InputError(f"{where}.{key}: missing or not a {kind.__name__}")
    for k, b in enumerate(entry["boxes"]):
        if not (isinstance(b, dict) and {"id", "center", "size", "rotation"} <= set(b)):
            raise InputError(f"{where}.boxes[{k}]: needs id, center, size, rotation")
        for key, shape in (("center", (3,)), ("size", (3,)), ("rotation", (3, 3))):
            _finite_array(b[key], shape, f"{where}.boxes[{k}].{key}",
                          positive=key == "size")
    for k, sup in enumerate(entry["supports"]):
        if not (isinstance(sup, dict) and {"id", "point", "normal"} <= set(sup)):
            raise InputError(f"{where}.supports[{k}]: needs id, point, normal")
        for key in ("point", "normal"):
            _finite_array(sup[key], (3,), f"{where}.supports[{k}].{key}")
    for k, c in enumerate(entry["contacts"]):
        if not (isinstance(c, list) and len(c) == 3 and all(isinstance(x, str) for x in c)):
            raise InputError(f"{where}.contacts[{k}]: expected [a, b, type]")
    for engine, verdict in entry["verdicts"].items():
        if engine not in ("analytic", *ENGINES) or not isinstance(verdict, bool):
            raise InputError(f"{where}.verdicts: {engine!r}: expected one of analytic, "
                             f"{', '.join(ENGINES)} with true or false")
    truth = entry.get("truth")
    if truth is not None:
        if not isinstance(truth, dict):
            raise InputError(f"{where}.truth: expected an object")
        for key, value in truth.items():
            if value is not None and (isinstance(value, bool)
                                      or not isinstance(value, (int, float))
                                      or not math.isfinite(value)):
                raise InputError(f"{where}.truth.{key}: expected a finite number, got {value!r}")


def _finite_array(value: Any, shape: tuple[int, ...], where: str, positive: bool = False
                  ) -> None:
    """InputError unless ``value`` is a list of finite numbers of ``shape`` (each > 0
    when ``positive``)."""
    import numpy as np

    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        a = None
    if (a is None or a.shape != shape or not np.all(np.isfinite(a))
            or (positive and np.any(a <= 0))):
        what = "positive " if positive else ""
        raise InputError(f"{where}: expected {' x '.join(map(str, shape))} finite {what}numbers")


# ============================================================================ comparing
@dataclass(frozen=True)
class Figure:
    """One compared figure of one scan.

    ``verdict`` is ``pass``, ``drop`` or ``info`` (not judged); ``versus`` says what the
    figure is measured against (``truth``, ``record`` or ``""``); ``message`` is the one
    line a failure shows (``f1 0.62 < 1.00 - 0.05``)."""

    name: str
    recorded: Any
    now: Any
    tolerance: Any
    verdict: str
    versus: str = ""
    message: str = ""


@dataclass(frozen=True)
class ScanResult:
    """The outcome for one scan: ``status`` ``pass``, ``drop``, ``error`` or ``skipped``."""

    name: str
    status: str
    figures: tuple[Figure, ...] = ()
    changes: tuple[str, ...] = ()
    message: str = ""

    @property
    def drops(self) -> list[Figure]:
        return [f for f in self.figures if f.verdict == "drop"]


@dataclass(frozen=True)
class Verification:
    """Every scan's :class:`ScanResult` (sorted by name) and the tolerances used."""

    scans: tuple[ScanResult, ...]
    tolerances: Tolerances
    skipped_files: tuple[str, ...] = ()

    def count(self, status: str) -> int:
        return sum(s.status == status for s in self.scans)

    @property
    def ok(self) -> bool:
        return not any(s.status in ("drop", "error") for s in self.scans)

    @property
    def problems(self) -> list[str]:
        """``name: message`` of every dropped or failed scan, in name order."""
        return [f"{s.name}: {s.message}" for s in self.scans if s.status in ("drop", "error")]

    def summary(self) -> str:
        n = len(self.scans)
        return (f"{n} scan{'s' if n != 1 else ''}: {self.count('pass')} passed, "
                f"{self.count('drop')} dropped, {self.count('error')} failed, "
                f"{self.count('skipped')} skipped")


def _arrangement(entry: Mapping):  # noqa: ANN202 - an Arrangement
    """Boxes and supports of a record (no objects: matching is by overlap alone)."""
    from pipeline.model import Arrangement, Cuboid, Support

    cuboids = tuple(Cuboid(b["id"], b["center"], _orthonormal(b["rotation"]), b["size"])
                    for b in entry["boxes"])
    supports = tuple(Support(s["id"], s["point"], s["normal"]) for s in entry["supports"])
    return Arrangement(cuboids, supports)


def _orthonormal(rotation: Any):  # noqa: ANN202 - (3, 3) float
    """The rotation nearest a rounded one (polar decomposition ``U V^T``).

    A record keeps rotations to :data:`ROTATION_DECIMALS`; the exact box intersection of
    :func:`eval.metrics.pairwise_iou` clips edges with a 1e-12 tolerance and calls two
    copies of one slightly skewed box disjoint, so the matrix is made orthonormal again."""
    import numpy as np

    u, _, vt = np.linalg.svd(np.asarray(rotation, dtype=float))
    r = u @ vt
    return r if np.linalg.det(r) > 0 else u @ np.diag([1.0, 1.0, -1.0]) @ vt


def _yes(v: bool) -> str:
    return "yes" if v else "no"


def compare(now: Mapping, recorded: Mapping, tol: Tolerances) -> tuple[list[Figure], list[str]]:
    """The figures of one scan (module docstring) and the list of what changed.

    Parameters
    ----------
    now, recorded : records of :func:`measure` (neither an error record)
    tol : the tolerances
    """
    import numpy as np

    from eval.metrics import compare_graphs, match_cuboids, match_supports

    a_now, a_rec = _arrangement(now), _arrangement(recorded)
    match = match_cuboids(a_now, a_rec, use_instances=False)
    mapping = {**match.pred_to_gt, **match_supports(a_now, a_rec)}
    graph = compare_graphs([tuple(e) for e in now["contacts"]],
                           [tuple(e) for e in recorded["contacts"]], mapping)
    f1_graph = round(float(graph.typed.f1), FIGURE_DECIMALS)
    # matched boxes: displacement and relative side error against the record
    dist = np.zeros(0)
    side_abs = side_len = 0.0
    if match.pairs:
        from eval.metrics import relative_size_errors

        ip = np.array([a_now.index[p] for p, _ in match.pairs], dtype=np.intp)
        ir = np.array([a_rec.index[r] for _, r in match.pairs], dtype=np.intp)
        dist = np.linalg.norm(a_now.centers[ip] - a_rec.centers[ir], axis=1)
        e = relative_size_errors(a_now.sizes[ip], a_now.rotations[ip], a_rec.sizes[ir],
                                 a_rec.rotations[ir])
        side_abs = float((e * a_rec.sizes[ir]).sum())
        side_len = float(a_rec.sizes[ir].sum())
    size_rec = round(side_abs / side_len, FIGURE_DECIMALS) if side_len > 0 else 0.0
    moved = round(float(dist.max()), LENGTH_DECIMALS) if len(dist) else 0.0
    moved_id = match.pairs[int(np.argmax(dist))][1] if len(dist) else ""

    figures: list[Figure] = []
    truth_now, truth_rec = now.get("truth"), recorded.get("truth")
    has_truth = truth_now is not None and truth_rec is not None
    # f1
    if has_truth:
        figures.append(_higher("f1", truth_rec.get("f1"), truth_now.get("f1"), tol.f1, "truth"))
        figures.append(Figure("f1 (record)", 1.0, f1_graph, None, "info", "record"))
    else:
        figures.append(_higher("f1", 1.0, f1_graph, tol.f1, "record"))
    # size
    if has_truth:
        figures.append(_lower("size", truth_rec.get("size"), truth_now.get("size"), tol.size,
                              "truth"))
        figures.append(Figure("size (record)", 0.0, size_rec, None, "info", "record"))
    else:
        figures.append(_lower("size", 0.0, size_rec, tol.size, "record"))
    # moved
    where = f" ({moved_id})" if moved_id and moved > 0 else ""
    if has_truth or tol.move is None:
        figures.append(Figure("moved", 0.0, moved, None if has_truth else tol.move, "info",
                              "record"))
    else:
        drop = moved > tol.move + 1e-12
        figures.append(Figure("moved", 0.0, moved, tol.move, "drop" if drop else "pass",
                              "record", f"moved {moved:.3f} m > {tol.move:g} m{where}"
                              if drop else ""))
    # verdicts
    v_now, v_rec = now["verdicts"], recorded["verdicts"]
    for engine in v_rec:
        rec_v, now_v = bool(v_rec[engine]), v_now.get(engine)
        figures.append(_verdict(f"stands:{engine}", rec_v, now_v, tol.stands))
    if len(v_rec) >= 2:
        rec_agree = len({bool(v) for v in v_rec.values()}) == 1
        now_agree = (all(k in v_now for k in v_rec)
                     and len({bool(v_now[k]) for k in v_rec}) == 1)
        fig = _verdict("agree", rec_agree, now_agree, tol.stands)
        if fig.verdict == "drop":
            said = ", ".join(f"{k} {_yes(bool(v_now.get(k)))}" for k in v_rec)
            fig = Figure(fig.name, fig.recorded, fig.now, fig.tolerance, fig.verdict, "",
                         f"{fig.message}: {said}")
        figures.append(fig)
    # fixed
    f_rec, f_now = int(recorded["fixed"]), int(now["fixed"])
    if tol.fixed is None:
        figures.append(Figure("fixed", f_rec, f_now, None, "info"))
    else:
        drop = f_now > f_rec + tol.fixed
        figures.append(Figure("fixed", f_rec, f_now, tol.fixed, "drop" if drop else "pass", "",
                              f"fixed {f_now} > {f_rec} + {tol.fixed}" if drop else ""))
    return figures, _changes(now, recorded, a_now, a_rec, match, mapping, dist)


def _higher(name: str, rec: float | None, now: float | None, tol: float | None,
            versus: str) -> Figure:
    """A figure that drops when it falls more than ``tol`` below the record."""
    if tol is None or rec is None:
        return Figure(name, rec, now, tol, "info", versus)
    if now is None or now < rec - tol - 1e-12:
        shown = "none" if now is None else f"{now:.2f}"
        return Figure(name, rec, now, tol, "drop", versus,
                      f"{name} {shown} < {rec:.2f} - {tol:g} (vs {versus})")
    return Figure(name, rec, now, tol, "pass", versus)


def _lower(name: str, rec: float | None, now: float | None, tol: float | None,
           versus: str) -> Figure:
    """A figure that drops when it rises more than ``tol`` above the record."""
    if tol is None or rec is None:
        return Figure(name, rec, now, tol, "info", versus)
    if now is None or now > rec + tol + 1e-12:
        shown = "none" if now is None else f"{now:.3f}"
        return Figure(name, rec, now, tol, "drop", versus,
                      f"{name} {shown} > {rec:.3f} + {tol:g} (vs {versus})")
    return Figure(name, rec, now, tol, "pass", versus)


def _verdict(name: str, rec: bool, now: bool | None, mode: str) -> Figure:
    """A yes/no figure judged by the ``--stands`` mode."""
    tol = mode
    if mode == "ignore":
        return Figure(name, rec, now, tol, "info")
    if now is None:
        return Figure(name, rec, now, tol, "drop", "", f"{name} not measured (recorded "
                                                       f"{_yes(rec)})")
    if not now and (rec or mode == "required"):
        why = "required" if mode == "required" and not rec else f"recorded {_yes(rec)}"
        return Figure(name, rec, now, tol, "drop", "", f"{name} no ({why})")
    return Figure(name, rec, now, tol, "pass")


def _num(v: float) -> str:
    """Three decimals, without a minus sign on zero."""
    return f"{v:.3f}".replace("-0.000", "0.000")


def _box_text(b: Mapping) -> str:
    return (f"{' x '.join(_num(v) for v in b['size'])} m at "
            f"({', '.join(_num(v) for v in b['center'])})")


def _changes(now: Mapping, recorded: Mapping, a_now, a_rec, match, mapping,  # noqa: ANN001
             dist) -> list[str]:  # noqa: ANN001
    """What changed from the record to now, in recorded names (new boxes: ``new:<id>``)."""
    import numpy as np

    lines: list[str] = []
    rec_boxes = {b["id"]: b for b in recorded["boxes"]}
    now_boxes = {b["id"]: b for b in now["boxes"]}
    for k, (p, r) in enumerate(match.pairs):
        name = r if p == r else f"{r} (now {p})"
        if dist[k] > DIFF_MIN_LENGTH:
            lines.append(f"box {name} moved {dist[k]:.3f} m")
        s_now = np.sort(np.asarray(now_boxes[p]["size"]))
        s_rec = np.sort(np.asarray(rec_boxes[r]["size"]))
        if np.abs(s_now - s_rec).max() > DIFF_MIN_LENGTH:
            lines.append(f"box {name} resized {' x '.join(f'{v:.3f}' for v in s_rec)} -> "
                         f"{' x '.join(f'{v:.3f}' for v in s_now)} m")
    for r in match.unmatched_gt:
        lines.append(f"box {r} removed (was {_box_text(rec_boxes[r])})")
    for p in match.unmatched_pred:
        lines.append(f"box new:{p} added ({_box_text(now_boxes[p])})")

    def name(node: str) -> str:
        return mapping.get(node, f"new:{node}")

    mapped = {}
    for a, b, t in now["contacts"]:
        x, y = sorted((name(a), name(b)))
        mapped[(x, y)] = t
    rec_edges = {tuple(sorted((a, b))): t for a, b, t in recorded["contacts"]}
    for pair in sorted(set(mapped) | set(rec_edges)):
        if pair in mapped and pair not in rec_edges:
            lines.append(f"contact gained: {pair[0]} - {pair[1]} {mapped[pair]}")
        elif pair in rec_edges and pair not in mapped:
            lines.append(f"contact lost: {pair[0]} - {pair[1]} {rec_edges[pair]}")
        elif mapped[pair] != rec_edges[pair]:
            lines.append(f"contact retyped: {pair[0]} - {pair[1]} {rec_edges[pair]} -> "
                         f"{mapped[pair]}")
    for engine, v in recorded["verdicts"].items():
        if engine in now["verdicts"] and bool(now["verdicts"][engine]) != bool(v):
            lines.append(f"{engine}: {'stands' if v else 'falls'} -> "
                         f"{'stands' if now['verdicts'][engine] else 'falls'}")
    if int(now["fixed"]) != int(recorded["fixed"]):
        lines.append(f"fixed contacts: {recorded['fixed']} -> {now['fixed']}")
    return lines


def verify_entries(now: Mapping[str, Mapping], record: Record, tol: Tolerances | None = None,
                   *, not_recorded: Iterable[str] = (), missing: Iterable[str] = (),
                   skipped_files: Iterable[str] = ()) -> Verification:
    """Compare measured records with ``record`` (module docstring).

    Parameters
    ----------
    now : scan name -> :func:`measure` record or ``{"error": ...}``, for the scans rerun
    record : the expectation file
    tol : tolerances (default: the record's)
    not_recorded : scans found but never recorded (skipped)
    missing : recorded scans no longer found (errors)
    skipped_files : names in DIR that are no scan (listed in the report)
    """
    tol = tol or record.tolerances
    results: list[ScanResult] = []
    for name in sorted(now):
        entry, rec = now[name], record.scans[name]
        if "error" in rec:
            if "error" in entry:
                results.append(ScanResult(name, "skipped", message=f"refused when recorded "
                                          f"and now: {entry['error']}"))
            else:
                results.append(ScanResult(name, "pass", message="runs now (refused when "
                                          "recorded: record it again with --update)"))
            continue
        if "error" in entry:
            results.append(ScanResult(name, "error", message=f"failed to run: {entry['error']}"))
            continue
        figures, changes = compare(entry, rec, tol)
        drops = [f for f in figures if f.verdict == "drop"]
        results.append(ScanResult(name, "drop" if drops else "pass", tuple(figures),
                                  tuple(changes), "; ".join(f.message for f in drops)))
    for name in missing:
        results.append(ScanResult(name, "error", message="recorded but not found in the folder "
                                  "(removed or renamed?)"))
    for name in not_recorded:
        results.append(ScanResult(name, "skipped", message="not recorded (unseen regress record "
                                  "--update adds it)"))
    results.sort(key=lambda s: s.name)
    return Verification(tuple(results), tol, tuple(skipped_files))


__all__ = ["RECORD_NAME", "Tolerances", "Scan", "discover", "measure", "measure_scans",
           "Record", "read_record", "write_record", "dumps", "compare", "verify_entries",
           "Verification", "ScanResult", "Figure"]
