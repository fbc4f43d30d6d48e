"""``unseen check``: is an arrangement stable?  Analytic statics and/or the two engines.

One file: a per-body table (or one JSON object).  Several files or folders: a bulk
check (:mod:`eval.bulkcheck`), one row (or JSON line) per file, and a JUnit report.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from eval.bulkcheck import file_mu  # noqa: F401  (re-exported: export.py uses it)

EPILOG = """exit codes: 0 every engine asked says stable, 1 any says unstable, 2 bad input
(or a scene an engine cannot simulate, or not within --engine-budget: one line says why).

many files: unseen check A.json B.json DIR ... [--workers N] [--json] [--junit FILE]
  A folder is searched recursively for *.json arrangements ("format": "unseen.arrangement";
  a file that is not valid JSON is an error case; other JSON such as manifest.json or a
  suite's tasks/*.json is skipped and counted).  Prints one row per file and a summary
  (--json: one JSON line per file, the one-file object, or "error" for a bad file), always
  in input order.  --engine all adds every case where the verdicts differ, with the bodies
  that moved.  --junit FILE: JUnit XML, one test case per file (failure: unstable or
  disagreeing checks; error: a bad file).  Exit 0 when every file is stable in every
  check, 1 when any is unstable, disagrees or is a bad file (stderr says how many, and
  the first bad file or else the first failure), 2 for bad usage (a path that does not
  exist, no arrangement found, a bad option).  Bulk mode is chosen by several paths, a
  folder, or --junit; --workers N checks on N processes (the output does not change).

engines: analytic = rigid-block static equilibrium (pipeline.stability);
mujoco / pybullet = settle the exported scene from rest and measure motion;
all = the three side by side (agree = all verdicts equal)."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("arrangement", type=Path, nargs="+", metavar="ARRANGEMENT",
                   help="arrangement.json to check; several files or folders: a bulk check")
    p.add_argument("--engine", default="analytic",
                   choices=["analytic", "mujoco", "pybullet", "all"],
                   help="which check to run (default: analytic)")
    p.add_argument("--mu", type=float, default=None,
                   help="friction coefficient (default: the file's meta.mu, which unseen run "
                        "records, else 0.7)")
    p.add_argument("--engine-budget", type=float, default=300.0, metavar="SECONDS",
                   help="wall time each engine may take to settle the scene (default 300); a "
                        "scene that would need longer is refused early with the estimate")
    p.add_argument("--threshold", type=float, default=None,
                   help="analytic energy threshold (default 1e-5, see pipeline/constants.py)")
    p.add_argument("--backend", default="auto", choices=["auto", "nnls", "qp"],
                   help="analytic solver backend (default auto)")
    p.add_argument("--side-friction", action="store_true",
                   help="plain statics: allow friction on vertical face contacts (the trap)")
    p.add_argument("--welds", default="exact", choices=["exact", "constraint"],
                   help="how engines realise fixed contacts (default: one rigid body)")
    p.add_argument("--json", action="store_true",
                   help="print one JSON object (bulk: one JSON line per file)")
    p.add_argument("--workers", type=int, default=1, metavar="N",
                   help="bulk: check files on N local processes (default 1)")
    p.add_argument("--junit", type=Path, default=None, metavar="FILE",
                   help="bulk: write a JUnit XML report, one test case per file")


def check_mu(mu: float | None) -> None:
    import math

    from pipeline.constants import MU_RANGE
    from pipeline.errors import InputError

    if mu is not None and not (math.isfinite(mu) and MU_RANGE[0] <= mu <= MU_RANGE[1]):
        raise InputError(f"--mu: must be a friction coefficient in [{MU_RANGE[0]:g}, "
                         f"{MU_RANGE[1]:g}], got {mu}")


def run(args: argparse.Namespace) -> int:
    import math

    from pipeline.errors import InputError

    check_mu(args.mu)
    if args.threshold is not None and not (math.isfinite(args.threshold) and args.threshold > 0):
        raise InputError(f"--threshold: must be a finite positive energy (default 1e-5), got "
                         f"{args.threshold}")
    if not (math.isfinite(args.engine_budget) and args.engine_budget > 0):
        raise InputError(f"--engine-budget: must be a positive number of seconds, got "
                         f"{args.engine_budget}")
    if args.workers < 1:
        raise InputError(f"--workers: must be at least 1, got {args.workers}")
    from eval.bulkcheck import ALL_ENGINES, CheckOptions

    opts = CheckOptions(engines=ALL_ENGINES if args.engine == "all" else (args.engine,),
                        mu=args.mu, threshold=args.threshold, backend=args.backend,
                        side_friction=args.side_friction, welds=args.welds,
                        budget=args.engine_budget)
    paths = args.arrangement
    if len(paths) > 1 or paths[0].is_dir() or args.junit is not None:
        return _run_bulk(args, opts)
    return _run_one(args, opts)


def _run_one(args: argparse.Namespace, opts) -> int:  # noqa: ANN001 - a CheckOptions
    """One file: the per-body table or one JSON object; a bad file is exit 2."""
    from eval.bulkcheck import check_arrangement
    from pipeline.arrangement_io import read_arrangement

    path = args.arrangement[0]
    arr = read_arrangement(path)
    res = check_arrangement(arr, opts, progress=_progress_line, where=path)
    results, agree = res["engines"], res["agree"]
    if args.json:
        print(json.dumps({"arrangement": str(path), "engines": results,
                          "agree": agree}, indent=1))
    else:
        _print_table(arr, results, agree, sys.stdout)
    return 0 if all(r["stable"] for r in results.values()) else 1


def _check_junit_path(path: Path) -> None:
    """``--junit FILE`` must be writable before any work (one line, exit 2)."""
    import os

    from pipeline.errors import InputError

    if str(path).strip() == "":
        raise InputError("--junit: empty path; give the report file, e.g. --junit check.xml")
    if path.is_dir():
        raise InputError(f"--junit {path}: is a folder; give the report file to write")
    parent = path.absolute().parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"--junit {path}: cannot write there ({parent} is not a writable "
                         "folder)")


def _run_bulk(args: argparse.Namespace, opts) -> int:  # noqa: ANN001 - a CheckOptions
    """Many files: one row or JSON line each, in input order; JUnit; exit 0 or 1."""
    from eval.bulkcheck import (
        disagreements,
        expand_inputs,
        failure_message,
        iter_checks,
        json_line,
        junit_xml,
        outcome,
        summary_line,
        table,
    )
    from eval.commands.evaluate import pin_threads
    from pipeline.errors import InputError

    if args.junit is not None:
        _check_junit_path(args.junit)
    pin_threads()  # one thread per process, here and in the workers (before numpy)
    inputs = expand_inputs(args.arrangement)
    skipped = (f"{len(inputs.skipped)} JSON file(s) that are not arrangements (no "
               f"\"format\": \"unseen.arrangement\"), e.g. {inputs.skipped[0]}"
               if inputs.skipped else "")
    if not inputs.files:
        raise InputError("no arrangement files found in " + ", ".join(map(str, args.arrangement))
                         + " (folders are searched for *.json with \"format\": "
                           "\"unseen.arrangement\")" + (f"; skipped {skipped}" if skipped else ""))
    if skipped:
        print(f"unseen check: skipped {skipped}", file=sys.stderr)
    from pipeline.progress import Progress

    n = len(inputs.files)
    records: list[dict | None] = [None] * n
    shown = 0
    with Progress(n, "checking") as bar:
        for i, rec in iter_checks(inputs.files, opts, workers=args.workers):
            records[i] = rec
            bar.update(note=Path(rec["arrangement"]).name)
            while args.json and shown < n and records[shown] is not None:
                print(json_line(records[shown]), flush=True)  # streamed, in input order
                shown += 1
    done: list[dict] = [r for r in records if r is not None]
    if not args.json:
        sys.stdout.write(table(done, opts.engines))
        print()
        print(summary_line(done))
        if len(opts.engines) > 1:
            print()
            sys.stdout.write(disagreements(done, opts.engines))
    if args.junit is not None:
        from pipeline import atomic

        atomic.write_bytes(args.junit, junit_xml(done, opts.engines))
    failed = [r for r in done if outcome(r) != "stable"]
    if not failed:
        return 0
    errors = [r for r in failed if outcome(r) == "error"]
    first, what = (errors[0], "first error") if errors else (failed[0], "first failure")
    print(f"unseen check: {len(failed)} of {n} failed ({summary_line(done)}); {what}: "
          f"{first['arrangement']}: {failure_message(first)}", file=sys.stderr)
    return 1


def _progress_line(text: str) -> None:
    """A progress line of a long settling run, on stderr whether or not it is a terminal."""
    print(f"unseen check: {text}", file=sys.stderr, flush=True)


def _print_table(arr, results: dict[str, dict], agree: bool, out) -> None:
    ids = list(arr.ids)
    header = ["body"]
    per_engine = {}
    for name, res in results.items():
        per_engine[name] = {b["id"]: b for b in res["bodies"]}
        if name == "analytic":
            header += ["analytic", "resid F [N]", "resid T [N m]"]
        else:
            header += [name, "move [m]", "turn [deg]"]
    rows = []
    for cid in ids:
        row = [cid]
        for name in results:
            b = per_engine[name].get(cid)
            if b is None:
                row += ["-", "-", "-"]
            elif name == "analytic":
                verdict = "anchored" if b.get("anchored") else ("ok" if b["stable"] else "MOVES")
                row += [verdict, f"{b['residual_force']:.3g}", f"{b['residual_torque']:.3g}"]
            else:
                row += ["ok" if b["stable"] else "MOVES", f"{b['translation']:.3g}",
                        f"{b['rotation_deg']:.3g}"]
        rows.append(row)
    widths = [max(len(str(r[i])) for r in rows + [header]) for i in range(len(header))]
    fmt = "  ".join(f"{{:<{w}}}" for w in widths)
    print(fmt.format(*header), file=out)
    for r in rows:
        print(fmt.format(*r), file=out)
    print(file=out)
    for name, res in results.items():
        extra = ""
        if name == "analytic":
            extra = f"  E = {res['energy']:.3g} (threshold {res['threshold']:.0e})"
            for p in res.get("penetrations", []):
                extra += f"\n  interpenetration: {p['a']} / {p['b']} by {p['depth']:.3g} m"
        print(f"{name}: {'STABLE' if res['stable'] else 'UNSTABLE'}{extra}", file=out)
    if len(results) > 1:
        print(f"engines agree: {'yes' if agree else 'NO'}", file=out)
