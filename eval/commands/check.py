"""``unseen check``: is an arrangement stable?  Analytic statics and/or the two engines."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

EPILOG = """exit codes: 0 every engine asked says stable, 1 any says unstable, 2 bad input.

engines: analytic = rigid-block static equilibrium (pipeline.stability);
mujoco / pybullet = settle the exported scene from rest and measure motion;
all = the three side by side (agree = all verdicts equal)."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("arrangement", type=Path, help="arrangement.json to check")
    p.add_argument("--engine", default="analytic",
                   choices=["analytic", "mujoco", "pybullet", "all"],
                   help="which check to run (default: analytic)")
    p.add_argument("--mu", type=float, default=0.7, help="friction coefficient (default 0.7)")
    p.add_argument("--threshold", type=float, default=None,
                   help="analytic energy threshold (default 1e-5, see pipeline/constants.py)")
    p.add_argument("--backend", default="auto", choices=["auto", "nnls", "qp"],
                   help="analytic solver backend (default auto)")
    p.add_argument("--side-friction", action="store_true",
                   help="plain statics: allow friction on vertical face contacts (the trap)")
    p.add_argument("--welds", default="exact", choices=["exact", "constraint"],
                   help="how engines realise fixed contacts (default: one rigid body)")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def run(args: argparse.Namespace) -> int:
    from pipeline.arrangement_io import read_arrangement
    from pipeline.errors import InputError

    if not (args.mu >= 0):
        raise InputError(f"--mu: must be a non-negative number, got {args.mu}")
    arr = read_arrangement(args.arrangement)
    engines = ["analytic", "mujoco", "pybullet"] if args.engine == "all" else [args.engine]
    results: dict[str, dict] = {}
    for engine in engines:
        if engine == "analytic":
            from pipeline.stability import check_stability

            res = check_stability(arr, mu=args.mu, threshold=args.threshold,
                                  backend=args.backend, side_friction=args.side_friction)
        else:
            from simulate.engines import settle

            res = settle(arr, engine, mu=args.mu, welds=args.welds)
        results[engine] = res.to_json()
    verdicts = [r["stable"] for r in results.values()]
    agree = len(set(verdicts)) == 1
    if args.json:
        print(json.dumps({"arrangement": str(args.arrangement), "engines": results,
                          "agree": agree}, indent=1))
    else:
        _print_table(arr, results, agree, sys.stdout)
    return 0 if all(verdicts) else 1


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
