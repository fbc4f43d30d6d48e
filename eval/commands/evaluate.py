"""``unseen eval SUITE --out DIR``: run an experiment suite (the paper's tables)."""

from __future__ import annotations

import argparse
import json
import platform
import shlex
import sys
from pathlib import Path

from eval.run_checks import check_seed
from pipeline.outdir import out_arg

EPILOG = """\
Suites live in eval/suites/<suite>.py.  Each writes Markdown and CSV tables and plots
under --out, one JSON record per scene under --out/tasks (a rerun resumes from them),
and command.json with the exact command, package versions and seed.
--workers N runs scenes on N local processes (one thread each: OMP_NUM_THREADS and the
BLAS thread counts default to 1), --dask tcp://HOST:PORT on a running Dask cluster; the
numbers do not depend on either.  Exit 0; 1 when the suite's answer is
"no" (the regression suite got worse) or when any task failed (the line says how many
and gives the first error; tracebacks are in --out/tasks); 2 on bad input.
The held-out pool (single views of all ten families from seeds nobody developed on):
  unseen eval pool --out results/pool --first-seed 100000 --n 20 --workers 2"""

#: The most scenes per family (``--n``) a suite is asked for.
MAX_N = 100_000
#: Packages whose versions command.json records (distribution names; first one installed wins).
VERSIONED = {"unseen": ("unseen",), "numpy": ("numpy",), "scipy": ("scipy",),
             "mujoco": ("mujoco",), "pybullet": ("pybullet",), "open3d": ("open3d", "open3d-cpu"),
             "trimesh": ("trimesh",), "qpsolvers": ("qpsolvers",), "shapely": ("shapely",),
             "dask": ("dask",), "distributed": ("distributed",)}


def available_suites() -> list[str]:
    """Names of the suite modules in ``eval/suites`` (without importing them)."""
    import pkgutil

    import eval.suites

    return sorted(m.name for m in pkgutil.iter_modules(eval.suites.__path__)
                  if not m.name.startswith("_"))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    suites = ", ".join(available_suites()) or "(none yet)"
    parser.add_argument("suite", help=f"one of: {suites}")
    parser.add_argument("--out", type=out_arg, required=True, help="output folder (created)")
    parser.add_argument("--seed", type=int, default=0, help="suite seed (default 0)")
    parser.add_argument("--n", type=int, default=None,
                        help="number of scenes/runs (default: the suite's own)")
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--workers", type=int, default=1, help="local worker processes (default 1)")
    group.add_argument("--dask", default=None, metavar="ADDRESS",
                       help="run on an existing Dask cluster, e.g. tcp://10.0.0.5:8786")
    parser.add_argument("--quick", action="store_true", help="a small, fast version (CI)")
    abl = parser.add_argument_group("ablation suite only")
    abl.add_argument("--pool-n", type=int, default=None, metavar="N",
                     help="held-out scenes per family (default 20; --n is the development "
                          "scenes per family, default 4)")
    reg = parser.add_argument_group("regression suite only")
    reg.add_argument("--only", nargs="+", default=None, metavar="CASE",
                     help="check only these cases (names in eval/suites/regression.py)")
    reg.add_argument("--expected", type=Path, default=None, metavar="FILE",
                     help="expectation file (default: eval/suites/regression_expected.json)")
    reg.add_argument("--update", action="store_true",
                     help="rewrite the expectation file with the measured figures (exit 0)")
    real = parser.add_argument_group("real suite only")
    real.add_argument("--data", type=Path, default=None, metavar="DIR",
                      help="the real scans (default: ../shared/data/real beside the checkout)")
    pool = parser.add_argument_group("pool and ablation suites only")
    pool.add_argument("--first-seed", type=int, default=None, metavar="S",
                      help="held-out pool: scene seeds S .. S+n-1 of every family (--n per "
                           "family for pool, --pool-n for ablation; default 20); required, "
                           "100000 or more, a fresh range for each round of work")
    parser.add_argument("--compare", type=Path, default=None, metavar="DIR",
                        help="pool and real suites: also compare, scene by scene, with an "
                             "earlier run of the same scenes (its --out): compare.md (pool: a "
                             "paired interval of the change in F1 per family; real: the scans "
                             "that changed and the labelled pairs they gained or lost)")


def package_versions() -> dict[str, str | None]:
    """Installed versions of the packages that shape the numbers (None when absent)."""
    from importlib.metadata import PackageNotFoundError, version

    out: dict[str, str | None] = {}
    for name, dists in VERSIONED.items():
        out[name] = None
        for dist in dists:
            try:
                out[name] = version(dist)
                break
            except PackageNotFoundError:
                continue
    return out


def canonical_command(args: argparse.Namespace) -> list[str]:
    """The command line that reproduces this run, every option spelled out."""
    cmd = ["unseen", "eval", args.suite, "--out", str(args.out), "--seed", str(args.seed)]
    if args.n is not None:
        cmd += ["--n", str(args.n)]
    cmd += ["--dask", args.dask] if args.dask else ["--workers", str(args.workers)]
    if args.quick:
        cmd.append("--quick")
    for name in ("pool_n",):
        if getattr(args, name, None) is not None:
            cmd += ["--" + name.replace("_", "-"), str(getattr(args, name))]
    if getattr(args, "only", None):
        cmd += ["--only", *args.only]
    if getattr(args, "expected", None) is not None:
        cmd += ["--expected", str(args.expected)]
    if getattr(args, "update", False):
        cmd.append("--update")
    if getattr(args, "first_seed", None) is not None:
        cmd += ["--first-seed", str(args.first_seed)]
    if getattr(args, "data", None) is not None:
        cmd += ["--data", str(args.data)]
    if getattr(args, "compare", None) is not None:
        cmd += ["--compare", str(args.compare)]
    return cmd


#: Thread pools the numerical libraries start (OpenMP for Open3D, BLAS for numpy/scipy).
#: Suites scale by processes (``--workers``), one thread each: on two cores two workers of
#: two threads each slowed every scene by a quarter (``table1``: 1.48x instead of 1.75x).
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def pin_threads() -> dict[str, str]:
    """One thread per process unless the user set the variable; called before numpy or
    Open3D are imported, and inherited by spawned workers.  Returns the settings."""
    import os

    for name in THREAD_VARS:
        os.environ.setdefault(name, "1")
    return {name: os.environ[name] for name in THREAD_VARS}


def run(args: argparse.Namespace) -> int:
    threads = pin_threads()
    import importlib

    from pipeline import atomic
    from pipeline.errors import InputError

    suites = available_suites()
    if args.suite not in suites:
        raise InputError(f"unknown suite {args.suite!r}; available: {', '.join(suites) or 'none'}")
    if args.workers < 1:
        raise InputError(f"--workers: must be at least 1, got {args.workers}")
    if args.n is not None and not 1 <= args.n <= MAX_N:
        raise InputError(f"--n: must be from 1 to {MAX_N}, got {args.n}")
    check_seed(args.seed)
    if getattr(args, "first_seed", None) is not None:
        check_seed(args.first_seed, "--first-seed")
    used = [f"--{n}" for n in ("only", "expected", "update") if getattr(args, n, None)]
    if used and args.suite != "regression":
        raise InputError(f"{', '.join(used)}: only for the regression suite, not {args.suite!r}")
    used = [f"--{n.replace('_', '-')}" for n in ("pool_n",)
            if getattr(args, n, None) is not None]
    if used and args.suite != "ablation":
        raise InputError(f"{', '.join(used)}: only for the ablation suite, not {args.suite!r}")
    if getattr(args, "pool_n", None) is not None and args.pool_n < 1:
        raise InputError(f"--pool-n: must be at least 1, got {args.pool_n}")
    if getattr(args, "first_seed", None) is not None and args.suite not in ("pool", "ablation"):
        raise InputError(f"--first-seed: only for the pool and ablation suites, not "
                         f"{args.suite!r}")
    if getattr(args, "compare", None) is not None and args.suite not in ("pool", "real"):
        raise InputError(f"--compare: only for the pool and real suites, not {args.suite!r}")
    if args.suite in ("pool", "ablation") and not args.quick:
        from eval.suites.pool import seed_range

        n = (args.n or 1) if args.suite == "pool" else (args.pool_n or 1)
        seed_range(getattr(args, "first_seed", None), n)  # one line before any work
    if getattr(args, "compare", None) is not None and args.suite == "pool":
        from eval.suites.pool import DEFAULT_N, FAMILIES, QUICK_FAMILIES, check_compare

        n = args.n if args.n is not None else (1 if args.quick else DEFAULT_N)
        check_compare(args.compare, args.out, getattr(args, "first_seed", None), n,
                      QUICK_FAMILIES if args.quick else FAMILIES)
    elif getattr(args, "compare", None) is not None:
        from eval.suites._common import check_not_out
        from eval.suites.real import read_real

        check_not_out(args.compare, args.out)
        read_real(args.compare)
    from pipeline.outdir import check_results_folder

    def same_suite(path: Path) -> bool:
        try:
            return json.loads(path.read_text("utf-8")).get("suite") == args.suite
        except (OSError, ValueError, AttributeError):
            return False

    check_results_folder(args.out, marker="command.json", what=f"unseen eval {args.suite}",
                         same=same_suite,
                         inputs=[getattr(args, "data", None), getattr(args, "compare", None)])
    if args.dask:
        check_dask(args.dask)
    created = not args.out.exists()
    args.out.mkdir(parents=True, exist_ok=True)
    cmd = canonical_command(args)
    record = {"command": shlex.join(cmd), "argv": cmd, "suite": args.suite, "seed": args.seed,
              "n": args.n, "first_seed": getattr(args, "first_seed", None), "quick": bool(args.quick), "workers": args.workers, "dask": args.dask,
              "versions": package_versions(), "python": sys.version.split()[0], "threads": threads,
              "platform": platform.platform()}
    record_path = args.out / "command.json"
    previous = record_path.read_bytes() if record_path.is_file() else None
    atomic.write_text(record_path, json.dumps(record, indent=1) + "\n")
    module = importlib.import_module(f"eval.suites.{args.suite}")
    args.task_summaries = []
    try:
        rc = int(module.run(args) or 0)
    except InputError:
        # the suite refused its input: leave --out as it was
        if previous is None:
            record_path.unlink(missing_ok=True)
        else:
            atomic.write_bytes(record_path, previous)
        if created and not any(args.out.iterdir()):
            args.out.rmdir()
        raise
    from eval.runner import failure_line

    line = failure_line(args.task_summaries)
    if line is not None:
        print(f"unseen eval {args.suite}: {line}", file=sys.stderr)
        rc = max(rc, 1)
    return rc


#: Seconds to wait for a Dask scheduler to answer before giving up.
DASK_CONNECT_TIMEOUT = 3.0


def check_dask(address: str) -> None:
    """``--dask``: a ``tcp://HOST:PORT`` (or ``tls://``) address where something answers.

    Checked with one TCP connection of :data:`DASK_CONNECT_TIMEOUT` seconds, so a wrong
    address is one line in seconds rather than Dask's 30 s timeout and a traceback.
    """
    import re
    import socket

    from pipeline.errors import InputError

    m = re.fullmatch(r"(tcp|tls)://(\[[0-9a-fA-F:.]+\]|[A-Za-z0-9_.-]+):(\d{1,5})", address)
    if not m or not 0 < int(m.group(3)) < 65536:
        raise InputError(f"--dask {address!r}: expected a scheduler address tcp://HOST:PORT "
                         "(e.g. tcp://10.0.0.5:8786)")
    host, port = m.group(2).strip("[]"), int(m.group(3))
    try:
        with socket.create_connection((host, port), timeout=DASK_CONNECT_TIMEOUT):
            pass
    except OSError as exc:
        why = "timed out" if isinstance(exc, TimeoutError) else (exc.strerror or str(exc))
        raise InputError(f"--dask {address}: no scheduler answers there ({why} within "
                         f"{DASK_CONNECT_TIMEOUT:g} s); start one with 'dask scheduler' or "
                         "use --workers N") from None
