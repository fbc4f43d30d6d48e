"""``unseen eval regression``: a fixed set of seeded scenes against stored figures.

Each case of :data:`CASES` (one single-view Kinect-noised scene) goes through the whole
pipeline and its result is settled in MuJoCo.  Per case four figures are compared with
``regression_expected.json`` (next to this file):

``f1``
    typed optimized contact-graph F1 in [0, 1]; worse when lower than stored by more
    than :data:`F1_TOL`.
``stands``
    1 when the result stands in MuJoCo; worse when it no longer does.
``agree``
    1 when the analytic verdict and MuJoCo's agree; worse when they no longer do.
``fixed``
    number of ``fixed`` contacts in the result between different objects or with a
    support (glue; the joins between parts of one object are the object's own and
    scored by the F1); worse when it grows by more than :data:`FIXED_TOL` (the search
    should explain the scene with as few glued contacts as possible).

Exit 1 with one line per regression on the stream when anything got worse, 0 otherwise.
Outputs under ``--out``: ``regression.md`` / ``.csv`` (measured vs stored per case),
``regression.json`` (the measured figures, in the expectation file's format),
``tasks/``.

``unseen eval regression --out DIR [--only CASE ...] [--expected FILE] [--update]``
checks every case (or those named); the same options are available through this
module as ``python -m eval.suites.regression``.

``--update`` rewrites the expectation file with the measured figures (exit 0).
``--quick`` checks the first :data:`QUICK_CASES` cases, ``--n N`` the first N.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

#: (case name, family, scene seed, family options).  Since the generator was widened
#: the camera films wall_shelf-1000 with almost no floor in the picture and the pipeline
#: stops ("no ground plane found", issue 20 item 4): its figures are 0 until that is
#: fixed, and wall_shelf-1003 guards the wall-shelf code meanwhile.
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
#: ``--quick`` runs the first this many cases (``--n N``: the first N).
QUICK_CASES = 3


def figures(rec: dict) -> dict:
    """The four compared figures of a :func:`eval.suites._scenes.scene_task` result."""
    from eval.suites._scenes import f1_of

    return {"f1": round(f1_of(rec, "optimized.typed"), 6), "stands": int(rec["stands"]),
            "agree": int(bool(rec["stable"]) == bool(rec["stands"])),
            "fixed": int(rec.get("n_glue", rec["n_fixed"]))}


def compare(actual: dict[str, dict], expected: dict[str, dict]) -> list[str]:
    """Regression lines (empty: nothing got worse); see the module docstring."""
    from eval.suites._common import regressions

    lines = regressions({k: {"f1": v["f1"], "stands": v["stands"], "agree": v["agree"]}
                         for k, v in actual.items()},
                        {k: {n: v[n] for n in ("f1", "stands", "agree") if n in v}
                         for k, v in expected.items()},
                        higher_better=("f1", "stands", "agree"), tol=F1_TOL)
    lines += regressions({k: {"fixed": v["fixed"]} for k, v in actual.items()},
                         {k: {"fixed": v["fixed"]} for k, v in expected.items() if "fixed" in v},
                         lower_better=("fixed",), tol=FIXED_TOL + 1e-9)
    return sorted(set(lines))


def load_expected(path: Path) -> dict[str, dict]:
    """``{case: {figure: value}}`` from an expectation file."""
    from pipeline.errors import InputError

    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
        return {k: dict(v) for k, v in data["cases"].items()}
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise InputError(f"--expected {path}: not a regression expectation file ({exc}); "
                         "write one with --update") from None


def run(args: argparse.Namespace) -> int:
    from eval.runner import Task
    from eval.suites._common import failures_markdown, run_suite_tasks, write_table
    from eval.suites._scenes import scene_task
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
    expected = {} if update and not path.exists() else load_expected(path)
    if not update:
        expected = {k: v for k, v in expected.items() if k in {c[0] for c in cases}}
    tasks = [Task(name, scene_task, {"family": fam, "seed": seed, "options": opts,
                                     "engine": ENGINE})
             for name, fam, seed, opts in cases]
    summary = run_suite_tasks(args, tasks, "regression")
    actual = {name: figures(rec) for name, rec in summary.results.items()}
    stream = getattr(args, "stream", None) or sys.stdout

    rows = []
    for name, *_ in cases:
        a, e = actual.get(name, {}), expected.get(name, {})
        rows.append([name] + [x for f in ("f1", "stands", "agree", "fixed")
                              for x in (a.get(f, "-"), e.get(f, "-"))])
    body = {"tolerance": {"f1": F1_TOL, "fixed": FIXED_TOL}, "engine": ENGINE,
            "cases": {k: actual[k] for k in names if k in actual}}
    atomic.write_text(out / "regression.json", json.dumps(body, indent=1) + "\n")
    if update:
        merged = dict(load_expected(path)) if path.exists() else {}
        merged.update(actual)
        body["cases"] = {k: merged[k] for k in names if k in merged}
        atomic.write_text(path, json.dumps(body, indent=1) + "\n")
        lines: list[str] = []
        verdict = f"expectations written to {path}"
    else:
        lines = compare(actual, expected)
        verdict = ("REGRESSED:\n" + "\n".join(f"- {ln}" for ln in lines)) if lines else \
            "no regression"
    note = (f"Measured vs stored ({path.name}); f1: typed optimized contact F1 (slack "
            f"{F1_TOL:g}), stands: the result stands in {ENGINE}, agree: analytic verdict == "
            f"{ENGINE}, fixed: fixed contacts between different objects or with a support "
            f"(may not grow by more than {FIXED_TOL}).\n\n"
            f"{verdict}\n" + failures_markdown(summary))
    md = write_table(out, "regression", ["case", "f1", "stored f1", "stands", "stored stands",
                                         "agree", "stored agree", "fixed", "stored fixed"],
                     rows, title="Regression suite", note=note, floatfmt=".4g")
    stream.write(md)
    return 1 if lines else 0


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
