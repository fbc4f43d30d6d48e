"""``unseen eval ablation``: what each prior buys, on the development seeds and a held-out pool.

Runs Table 1's single views with every prior on, then again with each prior switched off
in turn (:class:`pipeline.priors.ImagineConfig`), on two sets of scenes:

* **development**: Table 1's seeds (:func:`eval.suites._scenes.scene_seed`, ``--n`` per
  family, default 4) of the ten families, the scenes the priors were written against;
* **held-out pool**: ``--pool-n`` scenes per family (default 20) from seeds
  ``--first-seed`` + i (required, 100000 or more: :mod:`eval.suites.pool`), which no test
  or development run uses.  Use a fresh ``--first-seed`` for each round of work.

A prior that made no accepted edit in a scene's full run changes nothing there when it
is switched off (its proposals have no other effect), so only the scenes where it acted
are run again.  Per prior the table gives, on each set, the change in typed F1 (points,
micro-averaged; on the pool with a paired bootstrap 95 % interval over scenes), in the
mean IoU of the matched boxes and in the size error when it is off, and the number of
scenes where it acted.  A negative change means the prior pays.

Outputs under ``--out``: ``ablation.md`` / ``.csv``, ``ablation.png`` (the change in F1
per prior), ``scenes.csv`` (every run), ``tasks/`` (resumable).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

#: Held-out scenes per family by default; ``--quick`` pools start at this seed.
POOL_N = 20
QUICK_POOL_SEED = 100000
DEV_N = 4
FAMILIES = ("stack", "table", "chair", "shelf", "desk", "sofa", "counterweight", "bridge",
            "wall_shelf", "room")
QUICK_FAMILIES = ("stack", "table")
COST = {"room": 4.0, "shelf": 2.5}


def _scene_tasks(sets: dict[str, list[tuple[str, int]]], config: dict | None, tag: str,
                 only: dict[str, set[str]] | None = None) -> list:
    from eval.runner import Task
    from eval.suites._scenes import scene_task

    tasks = []
    for which, scenes in sets.items():
        for fam, seed in scenes:
            sid = f"{which}-{fam}-{seed}"
            if only is not None and sid not in only.get(tag, set()):
                continue
            kw = {"family": fam, "seed": seed, "views": 1}
            if config:
                kw["config"] = config
            tasks.append(Task(f"{tag}-{sid}", scene_task, kw, cost=COST.get(fam, 1.0)))
    return tasks


def scene_sets(args: argparse.Namespace) -> dict[str, list[tuple[str, int]]]:
    """``{"dev": [(family, seed)], "pool": [...]}``."""
    from eval.suites._scenes import scene_seed

    quick = bool(getattr(args, "quick", False))
    fams = QUICK_FAMILIES if quick else FAMILIES
    n_dev = 1 if quick else (args.n or DEV_N)
    n_pool = 2 if quick else int(getattr(args, "pool_n", None) or POOL_N)
    first = getattr(args, "first_seed", None)
    first = QUICK_POOL_SEED if first is None and quick else int(first)
    return {"dev": [(f, scene_seed(args.seed, i)) for f in fams for i in range(n_dev)],
            "pool": [(f, first + i) for f in fams for i in range(n_pool)]}


def _f1(recs: list[dict]) -> float:
    tp = sum(int(r["optimized"]["typed"]["tp"]) for r in recs)
    n = sum(int(r["optimized"]["typed"]["n_pred"]) + int(r["optimized"]["typed"]["n_gt"])
            for r in recs)
    return 2 * tp / n if n else float("nan")


def _mean(recs: list[dict], key: str) -> float:
    vals = []
    for r in recs:
        v = r
        for k in key.split("."):
            v = v.get(k) if isinstance(v, dict) else None
        if isinstance(v, (int, float)) and v == v:
            vals.append(float(v))
    return float(np.mean(vals)) if vals else float("nan")


def run(args: argparse.Namespace) -> int:
    from eval.suites._common import paired_bootstrap, plot_bars, run_suite_tasks, write_table
    from pipeline.priors import PRIORS

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    sets = scene_sets(args)
    full_tasks = _scene_tasks(sets, None, "full")
    summary = run_suite_tasks(args, full_tasks, "ablation: all priors on")
    full = {t.id.removeprefix("full-"): summary.results[t.id] for t in full_tasks
            if t.id in summary.results}
    acted: dict[str, set[str]] = {}
    for sid, rec in full.items():
        for name, (ok, _rej) in rec.get("priors", {}).items():
            if ok:
                acted.setdefault(f"off-{name}", set()).add(sid)
    off_tasks = []
    for prior in PRIORS:
        off_tasks += _scene_tasks(sets, {"disable": [prior.name]}, f"off-{prior.name}",
                                  only=acted)
    summary2 = run_suite_tasks(args, off_tasks, "ablation: one prior off")
    failed = summary.n_failed + summary2.n_failed
    rng = np.random.default_rng(args.seed)
    rows, bars, scene_rows = [], {}, []
    for prior in PRIORS:
        tag = f"off-{prior.name}"
        row = [prior.name, prior.stage]
        for which in ("dev", "pool"):
            ids = [f"{which}-{f}-{s}" for f, s in sets[which] if f"{which}-{f}-{s}" in full]
            base = [full[i] for i in ids]
            off = [summary2.results.get(f"{tag}-{i}", full[i]) if i in acted.get(tag, ())
                   else full[i] for i in ids]
            d = 100 * (_f1(off) - _f1(base)) if base else float("nan")
            cell = f"{d:+.1f}"
            if which == "pool" and base:
                lo, hi = paired_bootstrap(base, off, rng)
                cell += f" [{100 * lo:+.1f}, {100 * hi:+.1f}]"
            diou = _mean(off, "mean_iou") - _mean(base, "mean_iou")
            dsize = _mean(off, "size.mean_opt") - _mean(base, "size.mean_opt")
            row += [cell, f"{diou:+.3f}", f"{dsize:+.3f}",
                    f"{len(acted.get(tag, set()) & set(ids))}/{len(ids)}"]
            bars.setdefault(prior.name, {})[which] = d
        rows.append(row)
        for sid in sorted(acted.get(tag, ())):
            r = summary2.results.get(f"{tag}-{sid}")
            if r is not None:
                scene_rows.append([tag, sid, f"{100 * _f1([full[sid]]):.1f}",
                                   f"{100 * _f1([r]):.1f}"])
    base_rows = []
    for which in ("dev", "pool"):
        recs = [full[f"{which}-{f}-{s}"] for f, s in sets[which] if f"{which}-{f}-{s}" in full]
        base_rows.append(f"{which}: {len(recs)} scenes, typed F1 {100 * _f1(recs):.1f}, mean "
                         f"IoU {_mean(recs, 'mean_iou'):.3f}")
    pool_seeds = sorted({s for _, s in sets["pool"]})
    note = ("Change when the prior is switched off (points of typed F1; IoU and size error "
            "of matched boxes), development seeds and the held-out pool (seeds "
            f"{pool_seeds[0]}-{pool_seeds[-1]}, each family); [95 % paired bootstrap "
            "interval over scenes].  Negative F1 change / negative IoU change / positive "
            "size-error change: the prior pays.  'acted': scenes where it made an "
            f"accepted edit.  All priors on: {'; '.join(base_rows)}.  {failed} runs "
            "failed.\n")
    md = write_table(out, "ablation",
                     ["prior", "stage", "dev dF1", "dev dIoU", "dev dsize", "dev acted",
                      "pool dF1 [95 %]", "pool dIoU", "pool dsize", "pool acted"],
                     rows, title="Ablation: each prior switched off", note=note)
    write_table(out, "scenes", ["run", "scene", "F1 all on", "F1 off"], scene_rows)
    plot_bars(out / "ablation.png", bars, ylabel="typed F1 change when off (points)",
              title="What each prior buys (negative: it pays)")
    (getattr(args, "stream", None) or sys.stdout).write(md)
    return 1 if failed else 0
