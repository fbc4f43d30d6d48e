"""``unseen eval regression``: our own scans, verified as ``unseen regress verify`` does.

The suite is one folder of scans of the kind :mod:`eval.regress` verifies.  Each case of
:data:`CASES` (one single-view Kinect-noised scene of a family and seed) is synthesized
into ``--out/scans/<case>/`` (a scene directory with its ground truth), run through the
whole pipeline, settled in MuJoCo, and compared with ``regression_expected.json`` (next
to this file), an expectation file in :mod:`eval.regress`'s format holding per case the
boxes, the contact graph, the verdicts, the fixed count and the figures against the
truth.  The file's tolerances (:data:`TOLERANCES`) judge:

``f1``
    typed optimized contact-graph F1 against the truth; worse when lower than recorded
    by more than :data:`F1_TOL`.
``stands:mujoco``
    the result stands in MuJoCo; worse when it no longer does.  ``stands:analytic``
    likewise for the analytic statics.
``agree``
    the analytic verdict and MuJoCo's agree; worse when they no longer do.
``fixed``
    number of ``fixed`` contacts in the result between different objects or with a
    support (glue; the joins between parts of one object are the object's own and
    scored by the F1); worse when it grows by more than :data:`FIXED_TOL`.

The size error against the truth and the change of every box against the record are
shown, not judged (``size`` and ``moved`` tolerances off): the truth F1 is the suite's
measure, and the list of changes says what moved.

Exit 1 when anything got worse or a case failed to run (how many, and the first error,
on stderr), 0 otherwise.  Outputs under ``--out``: ``regression.md`` / ``.csv`` (measured
vs recorded per case), ``regress.md`` (every figure and what changed) and
``regression.xml`` (JUnit), ``regression.json`` (the measured record, in the
expectation file's format), ``scans/`` (the cases' scene directories with a copy of the
expectation file: ``unseen regress verify --out/scans`` reruns them) and ``tasks/``.
With ``--dask`` the scene directories are written where the workers run (the figures
come back either way).

``unseen eval regression --out DIR [--only CASE ...] [--expected FILE] [--update]``
checks every case (or those named); the same options are available through this
module as ``python -m eval.suites.regression``.

``--update`` rewrites the expectation file with the measured records (exit 0; 1 when a
case failed to run, which is then recorded as refused).  ``--quick`` checks the first
:data:`QUICK_CASES` cases, ``--n N`` the first N.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from eval.regress import Tolerances

#: (case name, family, scene seed, family options).  wall_shelf-1000 is filmed with little
#: floor in the picture (issue 20 item 4); wall_shelf-1003 guards the wall-shelf code too.
CASES = (("stack-1000", "stack", 1000, {}),
         ("table-1000", "table", 1000, {}),
         ("chair-1000", "chair", 1000, {}),
         ("wall_shelf-1000", "wall_shelf", 1000, {}),
         ("wall_shelf-1003", "wall_shelf", 1003, {}),
         ("counterweight-1000", "counterweight", 1000, {}),
         ("desk-1000", "desk", 1000, {}))
EXPECTED = Path(__file__).with_name("regression_expected.json")
#: Slack on the typed F1 (a fraction): search ties may move one edge in a large scene.
F1_TOL = 0.02
#: Slack on the number of fixed contacts.
FIXED_TOL = 0
ENGINE = "mujoco"
#: The tolerances ``--update`` writes into the expectation file (and the suite judges by).
TOLERANCES = Tolerances(f1=F1_TOL, size=None, move=None, fixed=FIXED_TOL, stands="recorded")
#: ``--quick`` runs the first this many cases (``--n N``: the first N).
QUICK_CASES = 3


def case_task(rng, family: str, seed: int, folder: str, options: dict | None = None,  # noqa: ANN001
              engines: tuple | list = (ENGINE,)) -> dict:
    """One case (an :class:`eval.runner.Task` function): synthesize its scene directory
    into ``folder`` and return its :func:`eval.regress.measure` record."""
    from eval import regress
    from eval.suites._scenes import BUDGET, make_scene

    del rng  # the scene is a function of its seed; the pipeline is seeded by its config
    make_scene(family, seed, Path(folder), **(options or {}))
    return regress.measure(folder, list(engines), BUDGET)


def figures(entry: dict) -> dict:
    """The suite's four figures of a record (``{}`` for a refused scan)."""
    if "error" in entry:
        return {}
    v = entry["verdicts"]
    return {"f1": entry.get("truth", {}).get("f1"), "stands": int(bool(v.get(ENGINE))),
            "agree": int(bool(v.get("analytic")) == bool(v.get(ENGINE))),
            "fixed": int(entry["fixed"])}


def run(args: argparse.Namespace) -> int:
    from eval import regress
    from eval.regress_report import junit_xml, markdown_report
    from eval.runner import Task
    from eval.suites._common import failures_markdown, run_suite_tasks, write_table
    from eval.suites._scenes import BUDGET
    from pipeline import atomic
    from pipeline.errors import InputError

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    only = list(getattr(args, "only", None) or [])
    names = [c[0] for c in CASES]
    bad = [o for o in only if o not in names]
    if bad:
        raise InputError(f"--only: unknown case(s) {', '.join(bad)}; cases: {', '.join(names)}")
    cases = [c for c in CASES if not only or c[0] in only]
    if getattr(args, "quick", False) and not only:
        cases = cases[:QUICK_CASES]
    if getattr(args, "n", None) is not None:
        cases = cases[:args.n]
    update = bool(getattr(args, "update", False))
    path = Path(getattr(args, "expected", None) or EXPECTED)
    record = None
    if not update or path.exists():
        hint = "unseen eval regression --update"
        try:
            record = regress.read_record(path, record_with=hint)
        except InputError as exc:
            if not update:
                why = str(exc)
                raise InputError(f"--expected {why}" + ("" if f"write one with {hint}" in why
                                                        else f"; write one with {hint}")) from None
    scans = out / "scans"
    tasks = [Task(name, case_task, {"family": fam, "seed": seed, "folder": str(scans / name),
                                    "options": opts, "engines": [ENGINE]})
             for name, fam, seed, opts in cases]
    summary = run_suite_tasks(args, tasks, "regression")
    entries = {r.id: dict(r.result) if r.ok else {"error": regress.error_line(r.error)}
               for r in summary.records}
    stream = getattr(args, "stream", None) or sys.stdout
    measured = regress.Record(entries, (ENGINE,), BUDGET, regress.SEED, TOLERANCES)
    atomic.write_text(out / "regression.json", regress.dumps(measured))

    v = None
    if update or record is None:
        merged = dict(record.scans) if record is not None else {}
        merged.update(entries)
        record = regress.Record({k: merged[k] for k in names if k in merged}, (ENGINE,), BUDGET,
                                regress.SEED, TOLERANCES)
        regress.write_record(record, path)
        verdict, failed = f"expectations written to {path}", 0
    else:
        run_names = [n for n in entries if n in record.scans]
        v = regress.verify_entries({n: entries[n] for n in run_names}, record,
                                   not_recorded=[n for n in entries if n not in record.scans])
        atomic.write_text(out / "regress.md", markdown_report(v, "Regression suite"))
        atomic.write_text(out / "regression.xml", junit_xml(v, "unseen eval regression"))
        problems = v.problems
        verdict = ("REGRESSED:\n" + "\n".join(f"- {p}" for p in problems)) if problems else \
            "no regression"
        failed = v.count("error")
    # scans/ as a folder of its own: the record of the cases run here beside their scans
    regress.write_record(replace(record, scans={k: v for k, v in record.scans.items()
                                                if k in entries}),
                         scans / regress.RECORD_NAME)

    rows = []
    stored = record.scans
    for name, *_ in cases:
        a, e = figures(entries.get(name, {"error": ""})), figures(stored.get(name, {"error": ""}))
        rows.append([name] + [x for f in ("f1", "stands", "agree", "fixed")
                              for x in (a.get(f, "-"), e.get(f, "-"))])
    note = (f"Measured vs recorded ({path.name}); f1: typed optimized contact F1 against the "
            f"truth (slack {F1_TOL:g}), stands: the result stands in {ENGINE}, agree: analytic "
            f"verdict == {ENGINE}, fixed: fixed contacts between different objects or with a "
            f"support (may not grow by more than {FIXED_TOL}).  Every figure and what changed: "
            f"regress.md.\n\n{verdict}\n" + failures_markdown(summary))
    md = write_table(out, "regression", ["case", "f1", "stored f1", "stands", "stored stands",
                                         "agree", "stored agree", "fixed", "stored fixed"],
                     rows, title="Regression suite", note=note, floatfmt=".4g")
    stream.write(md)
    n_failed = summary.n_failed
    if n_failed:
        first = next(r for r in summary.records if not r.ok)
        sys.stderr.write(f"regression: {n_failed} of {len(summary.records)} cases failed to run; "
                         f"first: {first.id}: {first.error}\n")
    if v is None:
        return 1 if n_failed else 0
    return 0 if v.ok and not failed else 1


def main(argv: list[str] | None = None) -> int:
    """``python -m eval.suites.regression``: the suite with its own options."""
    import os

    os.environ.setdefault("MUJOCO_GL", "egl")
    p = argparse.ArgumentParser(prog="python -m eval.suites.regression",
                                description="Regression suite with --only/--expected/--update.")
    p.add_argument("--out", type=Path, required=True, help="output folder (created)")
    p.add_argument("--only", nargs="+", default=None, metavar="CASE",
                   help="run only these cases: " + ", ".join(c[0] for c in CASES))
    p.add_argument("--expected", type=Path, default=None,
                   help=f"expectation file (default {EXPECTED.name} next to this module)")
    p.add_argument("--update", action="store_true", help="rewrite the expectations")
    p.add_argument("--workers", type=int, default=1, help="local worker processes")
    args = p.parse_args(argv)
    args.seed, args.n, args.dask, args.quick = 0, None, None, False
    from pipeline.errors import InputError

    try:
        return run(args)
    except InputError as exc:
        sys.stderr.write(f"eval.suites.regression: error: {exc}\n")
        return 2


if __name__ == "__main__":
    sys.exit(main())
