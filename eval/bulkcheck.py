"""Check many arrangement files at once: inputs, parallel checks, table, JUnit report.

One job: the library behind ``unseen check A.json B.json DIR ...``.

* **Inputs** (:func:`expand_inputs`).  A file named on the command line is always a case
  (a bad one becomes an *error* case).  A folder is walked recursively (sorted, hidden
  names and symlinked folders skipped) for ``*.json`` files; one of those is a case when
  it declares ``"format": "unseen.arrangement"`` or cannot be parsed as JSON at all (a
  truncated or corrupted file is an error, never silently dropped).  Valid JSON of
  another or no format (``manifest.json``, ``command.json``, ``timing.json``, a suite's
  ``tasks/*.json``) is *skipped* and the skips are counted.  A file reached twice is
  checked once.
* **Checks** (:func:`check_file`, :func:`iter_checks`).  Each case is one record, the
  object ``unseen check --json`` prints for one file, with the engines' ``wall_time``
  left out (the only key that varies between runs), or ``{"arrangement", "error"}``.
  Failures are data: a file that cannot be read, validated or simulated is an error
  record, and the other cases go on.  Cases run in this process (``workers=1``) or on
  spawned processes; records come back in any order and are reported in input order,
  so the JSON lines and the JUnit report are byte-identical for any worker count.
* **Reports** (:func:`table`, :func:`disagreements`, :func:`junit_xml`).  Pure functions
  of the records.  The JUnit report carries no ``time`` attributes, for the same reason.

Outcomes (:func:`outcome`): ``stable`` (every engine asked says stable), ``unstable``
(every engine says unstable), ``disagree`` (verdicts differ; only with several engines)
and ``error``.  A case *fails* unless it is ``stable``.

Top-level imports are the standard library only: ``unseen check --help`` stays instant.
"""

from __future__ import annotations

import concurrent.futures as cf
import json
import os
import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

#: Format tag that makes a JSON file found in a folder an arrangement.
ARRANGEMENT_FORMAT = "unseen.arrangement"
#: The engines of ``--engine all``, in report order.
ALL_ENGINES = ("analytic", "mujoco", "pybullet")
#: Bodies named per engine in a one-line message before "+k more".
MAX_BODIES_NAMED = 3
OUTCOMES = ("stable", "unstable", "disagree", "error")


# ---------------------------------------------------------------------- one arrangement
@dataclass(frozen=True)
class CheckOptions:
    """How to check: the options of ``unseen check`` (picklable, sent to workers).

    Attributes
    ----------
    engines : tuple of str
        Checks to run, a subset of :data:`ALL_ENGINES` in that order.
    mu : float or None
        Friction coefficient; None: the file's ``meta.mu``, else the default 0.7.
    threshold : float or None
        Analytic energy threshold (None: the default).
    backend, side_friction : analytic solver options (see ``pipeline.stability``)
    welds : str
        How engines realise ``fixed`` contacts (``exact`` or ``constraint``).
    budget : float
        Wall seconds each engine may take to settle one scene.
    """

    engines: tuple[str, ...] = ("analytic",)
    mu: float | None = None
    threshold: float | None = None
    backend: str = "auto"
    side_friction: bool = False
    welds: str = "exact"
    budget: float = 300.0


def file_mu(arr, flag_mu: float | None,  # noqa: ANN001 - an Arrangement
            where: str | os.PathLike | None = None) -> float:
    """The friction coefficient to use: ``--mu`` when given, else the file's ``meta.mu``
    (what ``unseen run --mu`` recorded), else the default 0.7.  ``where``: the file, named
    in the error."""
    import math

    from pipeline.constants import DEFAULT_MU, MU_RANGE
    from pipeline.errors import InputError

    if flag_mu is not None:
        return flag_mu
    mu = arr.meta.get("mu", DEFAULT_MU)
    if isinstance(mu, bool) or not isinstance(mu, (int, float)) or not math.isfinite(mu) \
            or not MU_RANGE[0] <= mu <= MU_RANGE[1]:
        raise InputError(f"{f'{where}: ' if where is not None else ''}meta.mu: must be a "
                         f"friction coefficient in [{MU_RANGE[0]:g}, "
                         f"{MU_RANGE[1]:g}], got {mu!r}; fix the file or pass --mu")
    return float(mu)


def check_arrangement(arr, opts: CheckOptions,  # noqa: ANN001 - an Arrangement
                      progress: Callable[[str], None] | None = None,
                      where: str | os.PathLike | None = None) -> dict:
    """Run every check of ``opts`` on ``arr`` (read from the file ``where``, named in
    errors).

    Returns
    -------
    dict
        ``{"engines": {name: result.to_json()}, "agree": bool}``, engines in the order
        of ``opts.engines``; ``agree`` when every verdict is the same.

    Raises
    ------
    InputError
        A bad ``meta.mu``, or a scene an engine cannot simulate within ``opts.budget``.
    """
    mu = file_mu(arr, opts.mu, where)
    results: dict[str, dict] = {}
    for engine in opts.engines:
        if engine == "analytic":
            from pipeline.stability import check_stability

            res = check_stability(arr, mu=mu, threshold=opts.threshold, backend=opts.backend,
                                  side_friction=opts.side_friction)
        else:
            from simulate.engines import settle

            res = settle(arr, engine, mu=mu, welds=opts.welds, budget=opts.budget,
                         progress=progress)
        results[engine] = res.to_json()
    return {"engines": results, "agree": len({r["stable"] for r in results.values()}) == 1}


def _error_line(exc: BaseException, path: str) -> str:
    text = " ".join(str(exc).split())
    for prefix in (f"{path}: ", f"{Path(path)}: "):
        if text.startswith(prefix):  # the case is named by its file already
            text = text[len(prefix):]
            break
    return text


def check_file(path: str, opts: CheckOptions) -> dict:
    """Read and check one file; never raises for a bad file (a worker function).

    Returns
    -------
    dict
        ``{"arrangement": path, "engines": ..., "agree": ...}`` as ``unseen check --json``
        prints it, without the engines' ``wall_time``; or ``{"arrangement": path,
        "error": "one line"}`` when the file cannot be read, validated or simulated.
    """
    from pipeline.errors import InputError

    try:
        from pipeline.arrangement_io import read_arrangement

        arr = read_arrangement(path)
        res = check_arrangement(arr, opts, where=path)
    except InputError as exc:
        return {"arrangement": path, "error": _error_line(exc, path)}
    except OSError as exc:
        return {"arrangement": path, "error": f"cannot read: {exc.strerror or exc}"}
    except Exception as exc:  # noqa: BLE001 - one broken case must not stop the others
        return {"arrangement": path,
                "error": f"internal error: {type(exc).__name__}: {_error_line(exc, path)}"}
    for r in res["engines"].values():
        r.pop("wall_time", None)
    return {"arrangement": path, **res}


def _worker_init() -> None:
    """A spawned worker: no progress lines, numerical libraries on one thread (inherited
    from the parent's environment, set again here in case it was not)."""
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(name, "1")


def iter_checks(paths: Sequence[str], opts: CheckOptions, workers: int = 1
                ) -> Iterator[tuple[int, dict]]:
    """Check ``paths``, yielding ``(index, record)`` as each case finishes.

    ``workers=1`` checks in this process, in order; more start that many spawned
    processes (at most one per case) and yield in finishing order.  A worker that dies
    (a crash inside an engine) makes its case an error record.
    """
    if workers < 1:
        raise ValueError(f"workers: expected >= 1, got {workers}")
    if workers == 1 or len(paths) <= 1:
        for i, p in enumerate(paths):
            yield i, check_file(p, opts)
        return
    import multiprocessing

    ctx = multiprocessing.get_context("spawn")
    ex = cf.ProcessPoolExecutor(max_workers=min(workers, len(paths)), mp_context=ctx,
                                initializer=_worker_init)
    try:
        futures = {ex.submit(check_file, p, opts): i for i, p in enumerate(paths)}
        for fut in cf.as_completed(futures):
            i = futures[fut]
            try:
                rec = fut.result()
            except Exception as exc:  # noqa: BLE001 - the worker process itself failed
                rec = {"arrangement": paths[i],
                       "error": f"the worker process failed: {type(exc).__name__}: "
                                f"{' '.join(str(exc).split())}"}
            yield i, rec
    finally:
        ex.shutdown(wait=True, cancel_futures=True)


# ---------------------------------------------------------------------------- inputs
@dataclass(frozen=True)
class Inputs:
    """The cases of a bulk check: ``files`` in input order; ``skipped`` JSON files found
    in folders that are not arrangements."""

    files: tuple[str, ...]
    skipped: tuple[str, ...]


def _walk_json(folder: Path) -> list[Path]:
    """``*.json`` under ``folder``, sorted by path components; hidden names (``.x``,
    temporary files of atomic writes) and symlinked folders are not entered."""
    found = []
    for root, dirs, files in os.walk(folder, followlinks=False):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        found += [Path(root) / f for f in files
                  if f.lower().endswith(".json") and not f.startswith(".")]
    return sorted(found, key=lambda p: p.relative_to(folder).parts)


def _is_case(path: Path) -> bool:
    """Whether a JSON file found in a folder is checked: it declares the arrangement
    format, or it cannot be parsed (then it is an error case rather than a silent skip)."""
    from pipeline.errors import InputError
    from pipeline.safe_read import load_json

    try:
        data = load_json(path)
    except InputError:
        return True
    return isinstance(data, dict) and data.get("format") == ARRANGEMENT_FORMAT


def expand_inputs(paths: Sequence[str | os.PathLike]) -> Inputs:
    """The cases named by command-line paths (see the module docstring).

    Raises
    ------
    InputError
        A path that does not exist.
    """
    from pipeline.errors import InputError

    files: list[str] = []
    skipped: list[str] = []
    seen: set[str] = set()

    def add(p: Path) -> None:
        key = os.path.realpath(p)
        if key not in seen:
            seen.add(key)
            files.append(str(p))

    for raw in paths:
        p = Path(raw)
        if str(raw) == "":
            raise InputError("an empty path was given; name arrangement files or folders")
        if not (p.exists() or p.is_symlink()):
            raise InputError(f"{p}: no such file or folder")
        if p.is_dir():
            for f in _walk_json(p):
                if _is_case(f):
                    add(f)
                else:
                    skipped.append(str(f))
        else:
            add(p)
    return Inputs(tuple(files), tuple(skipped))


# ---------------------------------------------------------------------------- outcomes
def outcome(rec: dict) -> str:
    """``stable``, ``unstable``, ``disagree`` or ``error`` (see the module docstring)."""
    if "error" in rec:
        return "error"
    verdicts = {r["stable"] for r in rec["engines"].values()}
    if len(verdicts) > 1:
        return "disagree"
    return "stable" if verdicts == {True} else "unstable"


def counts(records: Sequence[dict]) -> dict[str, int]:
    """Number of cases per outcome, in :data:`OUTCOMES` order."""
    out = dict.fromkeys(OUTCOMES, 0)
    for r in records:
        out[outcome(r)] += 1
    return out


def summary_line(records: Sequence[dict]) -> str:
    """``N checked: S stable, U unstable, D disagree, E errors``."""
    c = counts(records)
    return (f"{len(records)} checked: {c['stable']} stable, {c['unstable']} unstable, "
            f"{c['disagree']} disagree, {c['error']} errors")


def _num(x: float) -> str:
    return f"{x:.3g}"


def _moved(bodies: list[dict]) -> list[str]:
    """Engine bodies that moved, largest translation first: ``top 0.21 m 44 deg``."""
    moved = sorted((b for b in bodies if not b["stable"]),
                   key=lambda b: (-b["translation"], -b["rotation_deg"], b["id"]))
    return [f"{b['id']} {_num(b['translation'])} m {_num(b['rotation_deg'])} deg" for b in moved]


def _residuals(bodies: list[dict]) -> list[str]:
    """Analytic bodies that would move, largest residual force first."""
    bad = sorted((b for b in bodies if not b["stable"]),
                 key=lambda b: (-b["residual_force"], -b["residual_torque"], b["id"]))
    return [f"{b['id']} F {_num(b['residual_force'])} N T {_num(b['residual_torque'])} N m"
            for b in bad]


def _short(items: list[str], n: int = MAX_BODIES_NAMED) -> str:
    more = f" +{len(items) - n} more" if len(items) > n else ""
    return ", ".join(items[:n]) + more


def _bodies_of(name: str, res: dict) -> list[str]:
    return _residuals(res["bodies"]) if name == "analytic" else _moved(res["bodies"])


def _unstable_why(name: str, res: dict) -> str:
    """One engine's unstable verdict in a few words: the bodies, or its status."""
    items = _bodies_of(name, res)
    if items:
        return _short(items)
    return f"status {res.get('status', '?')}"


def failure_message(rec: dict) -> str:
    """One line saying why a case fails ("" when it does not)."""
    kind = outcome(rec)
    if kind == "error":
        return rec["error"]
    if kind == "stable":
        return ""
    engines = rec["engines"]
    bad = "; ".join(f"{n} {_unstable_why(n, r)}" for n, r in engines.items() if not r["stable"])
    if kind == "unstable":
        return f"unstable: {bad}"
    verdicts = ", ".join(f"{n} {'stable' if r['stable'] else 'unstable'}"
                         for n, r in engines.items())
    return f"engines disagree ({verdicts}): {bad}"


def engine_lines(rec: dict) -> list[str]:
    """Per engine of a checked case: its verdict and the bodies that moved (engines) or
    would move (analytic residuals), by how much."""
    lines = []
    for name, res in rec["engines"].items():
        verdict = "stable" if res["stable"] else "UNSTABLE"
        if name == "analytic":
            items = _residuals(res["bodies"])
            detail = f"E {_num(res['energy'])} (threshold {res['threshold']:.0e})"
            if items:
                detail += "; would move: " + ", ".join(items)
            elif res["bodies"]:
                worst = max(res["bodies"], key=lambda b: (b["residual_force"], b["id"]))
                detail += (f"; largest residual: {worst['id']} F "
                           f"{_num(worst['residual_force'])} N T "
                           f"{_num(worst['residual_torque'])} N m")
            for p in res.get("penetrations", []):
                detail += f"; interpenetration {p['a']} / {p['b']} by {_num(p['depth'])} m"
        else:
            items = _moved(res["bodies"])
            if items:
                detail = "moved: " + ", ".join(items)
            elif res["bodies"]:
                top = max(res["bodies"], key=lambda b: (b["translation"], b["id"]))
                detail = (f"nothing moved (largest: {top['id']} {_num(top['translation'])} m "
                          f"{_num(top['rotation_deg'])} deg)")
            else:
                detail = "no bodies"
            if res.get("status", "ok") != "ok":
                detail += f"; status {res['status']}"
        lines.append(f"{name:<9} {verdict:<9} {detail}")
    return lines


# ---------------------------------------------------------------------------- reports
def table(records: Sequence[dict], engines: Sequence[str]) -> str:
    """One row per case: the file, each engine's verdict and what moved, agreement, error."""
    header = ["file"]
    for name in engines:
        header += [name, "worst residual" if name == "analytic" else "moved"]
    if len(engines) > 1:
        header.append("agree")
    header.append("error")
    rows = []
    for rec in records:
        row = [rec["arrangement"]]
        if "error" in rec:
            row += ["-", "-"] * len(engines) + (["-"] if len(engines) > 1 else [])
            row.append(rec["error"])
        else:
            for name in engines:
                res = rec["engines"][name]
                row += ["stable" if res["stable"] else "UNSTABLE",
                        "-" if res["stable"] else _unstable_why(name, res)]
            if len(engines) > 1:
                row.append("yes" if rec["agree"] else "NO")
            row.append("")
        rows.append(row)
    widths = [max(len(r[i]) for r in rows + [header]) for i in range(len(header))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in [header] + rows]
    return "\n".join(lines) + "\n"


def pair_agreement(records: Sequence[dict], engines: Sequence[str]) -> dict[str, tuple[int, int]]:
    """Per engine pair ``"a-b"``: (cases where the two verdicts are equal, cases checked)."""
    done = [r for r in records if "error" not in r]
    out = {}
    for i, a in enumerate(engines):
        for b in engines[i + 1:]:
            same = sum(r["engines"][a]["stable"] == r["engines"][b]["stable"] for r in done)
            out[f"{a}-{b}"] = (same, len(done))
    return out


def disagreements(records: Sequence[dict], engines: Sequence[str]) -> str:
    """The section printed after the table with several engines: pairwise agreement, then
    every case whose verdicts differ with each engine's bodies and motions."""
    pairs = pair_agreement(records, engines)
    text = "pairwise agreement: " + ", ".join(f"{k} {s}/{n}" for k, (s, n) in pairs.items())
    bad = [r for r in records if outcome(r) == "disagree"]
    lines = [text, f"disagreements ({len(bad)}):" if bad else "disagreements: none"]
    for rec in bad:
        lines.append(f"  {rec['arrangement']}")
        lines += [f"    {line}" for line in engine_lines(rec)]
    return "\n".join(lines) + "\n"


_XML_BAD = re.compile("[^\t\n\r\u0020-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


def _xml_text(s: str) -> str:
    """Text XML 1.0 can carry: control characters and lone surrogates (undecodable file
    names) become U+FFFD."""
    return _XML_BAD.sub("\ufffd", s)


def junit_xml(records: Sequence[dict], engines: Sequence[str]) -> bytes:
    """The JUnit XML report: one ``<testcase>`` per case, named by its file.

    A case *fails* (``<failure type="unstable|disagree">``) when an engine says unstable,
    and *errors* (``<error>``) when the file is bad; the failure's text lists each
    engine's verdict and bodies.  No ``time`` attributes: the report is a function of
    the records only.
    """
    import xml.etree.ElementTree as ET

    c = counts(records)
    suite = ET.Element("testsuite", {
        "name": "unseen check", "tests": str(len(records)),
        "failures": str(c["unstable"] + c["disagree"]), "errors": str(c["error"]),
        "skipped": "0"})
    props = ET.SubElement(suite, "properties")
    ET.SubElement(props, "property", {"name": "engines", "value": ",".join(engines)})
    for rec in records:
        case = ET.SubElement(suite, "testcase", {"classname": "unseen.check",
                                                 "name": _xml_text(rec["arrangement"])})
        kind = outcome(rec)
        if kind == "error":
            ET.SubElement(case, "error", {"message": _xml_text(rec["error"])})
        elif kind != "stable":
            fail = ET.SubElement(case, "failure", {"message": _xml_text(failure_message(rec)),
                                                   "type": kind})
            fail.text = _xml_text("\n".join(engine_lines(rec)))
    ET.indent(suite)
    return (b'<?xml version="1.0" encoding="utf-8"?>\n'
            + ET.tostring(suite, encoding="utf-8", xml_declaration=False) + b"\n")


def json_line(rec: dict) -> str:
    """One record as one compact JSON line (no newline)."""
    return json.dumps(rec, separators=(",", ":"))
