"""``unseen check``: is an arrangement stable?  Analytic statics and/or the two engines."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

EPILOG = """exit codes: 0 every engine asked says stable, 1 any says unstable, 2 bad input
(or a scene an engine cannot simulate, or not within --engine-budget: one line says why).

engines: analytic = rigid-block static equilibrium (pipeline.stability);
mujoco / pybullet = settle the exported scene from rest and measure motion;
all = the three side by side (agree = all verdicts equal)."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("arrangement", type=Path, help="arrangement.json to check")
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
    p.add_argument("--json", action="store_true", help="print one JSON object")


def file_mu(arr, flag_mu: float | None) -> float:
    """The friction coefficient to use: ``--mu`` when given, else the file's ``meta.mu``
    (what ``unseen run --mu`` recorded), else the default 0.7."""
    import math

    from pipeline.constants import DEFAULT_MU, MU_RANGE
    from pipeline.errors import InputError

    if flag_mu is not None:
        return flag_mu
    mu = arr.meta.get("mu", DEFAULT_MU)
    if isinstance(mu, bool) or not isinstance(mu, (int, float)) or not math.isfinite(mu) \
            or not MU_RANGE[0] <= mu <= MU_RANGE[1]:
        raise InputError(f"meta.mu: must be a friction coefficient in [{MU_RANGE[0]:g}, "
                         f"{MU_RANGE[1]:g}], got {mu!r}; fix the file or pass --mu")
    return float(mu)


def check_mu(mu: float | None) -> None:
    import math

    from pipeline.constants import MU_RANGE
    from pipeline.errors import InputError

    if mu is not None and not (math.isfinite(mu) and MU_RANGE[0] <= mu <= MU_RANGE[1]):
        raise InputError(f"--mu: must be a friction coefficient in [{MU_RANGE[0]:g}, "
                         f"{MU_RANGE[1]:g}], got {mu}")


def run(args: argparse.Namespace) -> int:
    import math

    from pipeline.arrangement_io import read_arrangement
    from pipeline.errors import InputError

    check_mu(args.mu)
    if args.threshold is not None and not (math.isfinite(args.threshold) and args.threshold > 0):
        raise InputError(f"--threshold: must be a finite positive energy (default 1e-5), got "
                         f"{args.threshold}")
    if not (math.isfinite(args.engine_budget) and args.engine_budget > 0):
        raise InputError(f"--engine-budget: must be a positive number of seconds, got "
                         f"{args.engine_budget}")
    arr = read_arrangement(args.arrangement)
    mu = file_mu(arr, args.mu)
    engines = ["analytic", "mujoco", "pybullet"] if args.engine == "all" else [args.engine]
    results: dict[str, dict] = {}
    for engine in engines:
        if engine == "analytic":
            from pipeline.stability import check_stability

            res = check_stability(arr, mu=mu, threshold=args.threshold,
                                  backend=args.backend, side_friction=args.side_friction)
        else:
            from simulate.engines import settle

            res = settle(arr, engine, mu=mu, welds=args.welds, budget=args.engine_budget,
                         progress=_progress_line)
        results[engine] = res.to_json()
    verdicts = [r["stable"] for r in results.values()]
    agree = len(set(verdicts)) == 1
    if args.json:
        print(json.dumps({"arrangement": str(args.arrangement), "engines": results,
                          "agree": agree}, indent=1))
    else:
        _print_table(arr, results, agree, sys.stdout)
    return 0 if all(verdicts) else 1


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
