"""``unseen regress record|verify DIR``: regression on your own scans (:mod:`eval.regress`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

EPILOG = """\
DIR holds your scans: each direct child that 'unseen run' takes is one scan, named by its
file or folder name (a .ply/.pcd/.npz cloud, a scene directory with scene.json + scan/,
an RGB-D folder with color.png, depth.png, intrinsics.json, a multi-view folder).  Other
files are listed as skipped.  Every scan runs with unseen run's defaults (seed 0, budget
10 s); the scans are never modified.

record DIR [--engine analytic|mujoco|pybullet|all] [--workers N] [--update]
  writes DIR/unseen-regress.json (commit it): per scan the boxes (id, object, centre,
  size, rotation), the contact graph with supports, the verdicts (analytic statics and
  the engines asked), the number of fixed contacts between different objects or with a
  support, and for a scene directory its F1 and size error against scene.json.  Text,
  stable order, no timings, no absolute paths.  An existing file is kept unless --update.

verify DIR [--f1-tol 0.05] [--size-tol 0.05] [--move-tol 0.05] [--fixed-tol 0]
           [--stands recorded|required|ignore] [--report FILE.md] [--junit FILE.xml]
  reruns every recorded scan (same engines) and compares, per scan:
    f1      typed contact-graph F1: vs the truth when the scan has one (drop: now <
            recorded - tol), else vs the recorded graph, boxes matched by 3D IoU +
            Hungarian (drop: now < 1 - tol)
    size    relative side error sum|s - s_ref| / sum s_ref of the matched boxes, vs the
            truth or the recorded sizes (drop: now > recorded + tol)
    moved   largest centre shift of a matched box, metres (scans without a truth)
    stands:ENGINE, agree   a recorded "stands" that no longer stands is a drop
            (--stands required: anything not standing; ignore: shown only)
    fixed   fixed contacts (drop: now > recorded + tol)
  Defaults come from the file's "tolerances"; a flag overrides them, 'off' shows a figure
  without judging it.  The Markdown report (stdout without --report) has one row per scan
  per figure and what changed (boxes added/removed/moved/resized, contacts gained/lost/
  retyped); --junit writes one testcase per scan, a failure naming figure and numbers.
  A scan that fails to run, or a recorded scan gone from DIR, is an error; a new scan
  is skipped until recorded.

exit codes: 0 nothing dropped; 1 a figure dropped or a scan failed (stderr says how many
and names each scan with its first problem); 2 bad input (DIR missing, no expectation
file, an existing one without --update, a bad tolerance).

  unseen regress record my_scans --engine mujoco
  unseen regress verify my_scans --junit regress.xml --report regress.md"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="action", required=True, metavar="ACTION",
                           help="record: store what the pipeline makes of DIR's scans; "
                                "verify: rerun them and compare")
    raw = argparse.RawDescriptionHelpFormatter
    rec = sub.add_parser("record", help="store the expected results next to the scans",
                         description="Run every scan of DIR and write DIR/unseen-regress.json.",
                         formatter_class=raw, epilog="example:\n  unseen regress record "
                         "my_scans --engine mujoco\n\n'unseen regress --help': what is "
                         "recorded and compared.")
    rec.add_argument("dir", metavar="DIR", help="folder of scans")
    rec.add_argument("--engine", default=None,
                     choices=["analytic", "mujoco", "pybullet", "all"],
                     help="verdicts to record besides the analytic statics (default: analytic "
                          "only, or with --update those of the record it replaces; all: "
                          "MuJoCo and PyBullet)")
    rec.add_argument("--workers", type=int, default=1, help="local worker processes (default 1)")
    rec.add_argument("--update", "--force", action="store_true",
                     help="record again over an existing expectation file (its tolerances "
                          "are kept)")
    rec.add_argument("--expected", type=Path, default=None, metavar="FILE",
                     help="the expectation file (default DIR/unseen-regress.json)")
    ver = sub.add_parser("verify", help="rerun the scans and compare with the record",
                         description="Rerun every recorded scan of DIR and compare; exit 1 "
                                     "on a drop beyond the tolerances or a failed scan.",
                         formatter_class=raw, epilog="example:\n  unseen regress verify "
                         "my_scans --junit regress.xml --report regress.md\n\n'unseen "
                         "regress --help': the figures, tolerances and exit codes.")
    ver.add_argument("dir", metavar="DIR", help="folder of scans with unseen-regress.json")
    ver.add_argument("--f1-tol", default=None, metavar="X",
                     help="allowed drop of the typed contact F1 (file default: 0.05; off)")
    ver.add_argument("--size-tol", default=None, metavar="X",
                     help="allowed rise of the relative side error (default 0.05; off)")
    ver.add_argument("--move-tol", default=None, metavar="M",
                     help="allowed centre shift of a box, metres (default 0.05; off)")
    ver.add_argument("--fixed-tol", default=None, metavar="N",
                     help="allowed rise of the fixed contacts (default 0; off)")
    ver.add_argument("--stands", default=None, choices=["recorded", "required", "ignore"],
                     help="recorded (default): a recorded 'stands' must still stand; "
                          "required: every verdict must say stands; ignore")
    ver.add_argument("--report", type=Path, default=None, metavar="FILE.md",
                     help="write the Markdown report here (default: print it)")
    ver.add_argument("--junit", type=Path, default=None, metavar="FILE.xml",
                     help="write a JUnit XML report here")
    ver.add_argument("--workers", type=int, default=1, help="local worker processes (default 1)")
    ver.add_argument("--expected", type=Path, default=None, metavar="FILE",
                     help="the expectation file (default DIR/unseen-regress.json)")


def _say(line: str) -> None:
    print(f"unseen regress: {line}", file=sys.stderr)


def _out_file(path: Path | None, flag: str, reads=()) -> None:
    """Refuse an output file that is a folder, lies under a non-folder, or is (or lies
    in) one of the inputs ``reads`` (the scans, the record): inputs are never written."""
    from pipeline.errors import InputError

    if path is None:
        return
    if path.is_dir():
        raise InputError(f"{flag} {path}: is a folder; give a file name")
    target = path.resolve()
    for src in reads:
        src = Path(src).resolve()
        if target == src or src in target.parents:
            raise InputError(f"{flag} {path}: is {'' if target == src else 'inside '}the input "
                             f"{src.name}, which is never written; give a file outside it")
    parent = path.parent if str(path.parent) else Path(".")
    if parent.exists() and not parent.is_dir():
        raise InputError(f"{flag} {path}: {parent} is not a folder")


def _check_common(args: argparse.Namespace) -> None:
    from pipeline.errors import InputError

    if args.workers < 1:
        raise InputError(f"--workers: must be at least 1, got {args.workers}")


def run(args: argparse.Namespace) -> int:
    from eval.commands.evaluate import pin_threads

    pin_threads()
    _check_common(args)
    return _record(args) if args.action == "record" else _verify(args)


def _record(args: argparse.Namespace) -> int:
    from eval import regress
    from pipeline.errors import InputError

    scans, skipped = regress.discover(args.dir)
    path = Path(args.expected) if args.expected else Path(args.dir) / regress.RECORD_NAME
    if path.exists() and not args.update:
        raise InputError(f"{path}: already recorded; unseen regress record {args.dir} --update "
                         "records again (verify compares with it)")
    if not scans:
        raise InputError(f"{args.dir}: no scans here (a .ply/.pcd/.npz cloud, a scene "
                         "directory or an RGB-D folder per child)")
    _out_file(path, "--expected", [sc.path for sc in scans])
    tolerances = regress.Tolerances()
    engines = ()
    if path.exists():
        try:
            old = regress.read_record(path)
            tolerances, engines = old.tolerances, tuple(old.engines)
        except InputError:
            pass  # a broken file is replaced whole
    if args.engine is not None:
        engines = {"analytic": (), "all": regress.ENGINES}.get(args.engine, (args.engine,))
    if skipped:
        _say(f"skipped (not a scan unseen run takes): {', '.join(skipped)}")
    entries = regress.measure_scans(scans, engines, workers=args.workers, label="regress record")
    record = regress.Record(entries, tuple(engines), regress.BUDGET, regress.SEED, tolerances)
    regress.write_record(record, path)
    failed = [(n, e["error"]) for n, e in entries.items() if "error" in e]
    n_truth = sum(s.has_truth for s in scans)
    print(f"recorded {len(scans)} scan{'s' if len(scans) != 1 else ''} ({n_truth} with a ground "
          f"truth; verdicts: {', '.join(['analytic', *engines])}) -> {path}")
    if failed:
        name, error = failed[0]
        _say(f"{len(failed)} of {len(scans)} scans failed to run (recorded as refused); first: "
             + (error if error.startswith(f"{name}:") else f"{name}: {error}"))
        return 1
    return 0


def tolerances_from_args(args: argparse.Namespace, base):  # noqa: ANN001, ANN201
    """The record's tolerances ``base`` with the flags that were given."""
    from dataclasses import replace

    from eval.regress import parse_tolerance

    changes = {}
    for flag, key, integer in (("f1_tol", "f1", False), ("size_tol", "size", False),
                               ("move_tol", "move", False), ("fixed_tol", "fixed", True)):
        text = getattr(args, flag, None)
        if text is not None:
            changes[key] = parse_tolerance(text, "--" + flag.replace("_", "-"), integer)
    if getattr(args, "stands", None) is not None:
        changes["stands"] = args.stands
    return replace(base, **changes)


def _verify(args: argparse.Namespace) -> int:
    from eval import regress
    from eval.regress_report import junit_xml, markdown_report
    from pipeline import atomic

    # every check before any work: tolerances, outputs, the folder, the record
    tolerances_from_args(args, regress.Tolerances())
    scans, skipped = regress.discover(args.dir)
    path = Path(args.expected) if args.expected else Path(args.dir) / regress.RECORD_NAME
    reads = [sc.path for sc in scans] + [path]
    _out_file(args.report, "--report", reads)
    _out_file(args.junit, "--junit", reads)
    record = regress.read_record(path)
    tol = tolerances_from_args(args, record.tolerances)
    found = {s.name for s in scans}
    run = [s for s in scans if s.name in record.scans]
    not_recorded = [s.name for s in scans if s.name not in record.scans]
    missing = sorted(n for n in record.scans if n not in found)
    if not_recorded:
        _say(f"not recorded, skipped: {', '.join(not_recorded)} (record --update adds them)")
    entries = regress.measure_scans(run, record.engines, budget=record.budget, seed=record.seed,
                                    workers=args.workers, label="regress verify")
    v = regress.verify_entries(entries, record, tol, not_recorded=not_recorded, missing=missing,
                               skipped_files=skipped)
    report = markdown_report(v)
    if args.report is not None:
        atomic.write_text(args.report, report)
    if args.junit is not None:
        atomic.write_text(args.junit, junit_xml(v))
    if args.report is None:
        sys.stdout.write(report)
    else:
        print(f"{v.summary()}: {'PASS' if v.ok else 'FAIL'}; report -> {args.report}")
    if not v.ok:
        problems = v.problems
        _say(f"{v.count('drop')} of {len(v.scans)} scans dropped, {v.count('error')} failed")
        for line in problems[:10]:
            print(f"  {line}", file=sys.stderr)
        if len(problems) > 10:
            print(f"  ... and {len(problems) - 10} more (see the report)", file=sys.stderr)
        return 1
    return 0
