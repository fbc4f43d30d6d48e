"""``unseen eval pool --out DIR --first-seed S [--n 20]``: the held-out pool.

Single Kinect-noised views of every scene family (:data:`FAMILIES`, ten), scene seeds
``S .. S + n - 1`` for each family (``--n``, default 20: 200 scenes), drawn from a range no
test or development run uses: development suites use ``1000 + 100 * --seed + i`` and tests
small seeds, so the pool starts at :data:`POOL_SEED_MIN`.  ``--first-seed`` is required:
each round of work takes a fresh range, and the range is written into every output, so
that a change is kept or reverted on scenes nobody tuned it to.

Per family and overall: typed contact F1 (micro over the scenes' edges) with its 95%
percentile bootstrap interval (:func:`eval.suites._common.bootstrap_f1`), the F1 a result
reaches when it is right about everything the scan saw (only the contacts at unseen parts
missed, as ``table1_unseen``) and the share of that bound reached, the geometry of the
matched boxes (matched share, IoU, side error), and the fractions of results that stand
in the analytic check, MuJoCo and PyBullet.

Outputs under ``--out``: ``pool.md`` / ``.csv`` (the table), ``pool.json`` (the seed
range and every figure of the table, machine-readable), ``scenes.csv`` (one row per
scene), ``pool.png`` (F1 and bound per family), ``tasks/`` (one record per scene;
resumable).  ``--quick``: stack and chair, one scene each.

``--compare DIR`` (the ``--out`` of an earlier pool of the same seeds, run by other code)
also writes ``compare.md`` / ``.csv`` / ``.json``: per family the typed F1 before and
after with a paired bootstrap interval of the change, the matched IoU, and the scenes
that went up or down, so a change is kept or reverted on its effect on these scenes.
A rerun into a finished ``--out`` only reads its records, so the comparison of two
finished runs takes seconds.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

#: The ten scene families of the pool.
FAMILIES = ("stack", "table", "chair", "shelf", "desk", "sofa", "counterweight", "bridge",
            "wall_shelf", "room")
QUICK_FAMILIES = ("stack", "chair")
#: Scenes per family.
DEFAULT_N = 20
#: Smallest pool seed: development suites use 1000 + 100 * seed + i, tests small seeds.
POOL_SEED_MIN = 100_000
#: Engines every result is settled in.
ENGINES = ("mujoco", "pybullet")
#: Rough relative scene times (rooms and shelves hold many cuboids): costliest start first.
COST = {"room": 4.0, "shelf": 2.5}

COLUMNS = ["family", "#scenes", "typed F1", "F1 95% interval", "F1 if right about all seen",
           "share of that reached (%)", "matched share (%)", "IoU (matched)", "side error",
           "stands: analytic", "stands: MuJoCo", "stands: PyBullet", "scans refused"]


def seed_range(first_seed: int, n: int) -> tuple[int, int]:
    """First and last scene seed of a pool (inclusive), checked.

    Raises
    ------
    pipeline.errors.InputError
        ``first_seed`` missing or below :data:`POOL_SEED_MIN`.
    """
    from pipeline.errors import InputError

    if first_seed is None:
        raise InputError(f"pool: --first-seed S is required (a range no earlier round used, "
                         f"{POOL_SEED_MIN} or more)")
    if first_seed < POOL_SEED_MIN:
        raise InputError(f"--first-seed: must be at least {POOL_SEED_MIN} (smaller seeds are "
                         f"development and test scenes), got {first_seed}")
    return int(first_seed), int(first_seed) + int(n) - 1


def build_tasks(first_seed: int, n: int, families=FAMILIES, config: dict | None = None) -> list:
    """One :class:`eval.runner.Task` per (family, seed): a single view through
    :func:`eval.suites._scenes.scene_task`, settled in :data:`ENGINES`.  ``config``
    (inference overrides) goes to every scene; task ids are ``<family>-<seed>``."""
    from eval.runner import Task
    from eval.suites._scenes import scene_task

    lo, hi = seed_range(first_seed, n)
    extra = {"config": config} if config else {}
    return [Task(f"{fam}-{seed}", scene_task,
                 {"family": fam, "seed": seed, "views": 1, "engines": list(ENGINES), **extra},
                 cost=COST.get(fam, 1.0))
            for fam in families for seed in range(lo, hi + 1)]


def figures(recs: list[dict]) -> dict:
    """The pool's figures of a group of :func:`eval.suites._scenes.scene_task` records
    (fractions in [0, 1]; NaN where undefined)."""
    from eval.suites._common import aggregate_prf, bootstrap_f1, geometry, seen_bound

    nan = float("nan")
    f1 = aggregate_prf(recs, "optimized.typed")["f1"]
    bound = seen_bound(recs)
    lo, hi = bootstrap_f1(recs)
    out = {"scenes": len(recs), "f1": f1, "f1_lo": lo, "f1_hi": hi, "bound": bound,
           "bound_share": f1 / bound if bound > 0 else nan, **geometry(recs)}
    out["stands_analytic"] = (sum(bool(r.get("stable")) for r in recs) / len(recs)
                              if recs else nan)
    for e in ENGINES:
        got = [bool(r["stands_in"][e]) for r in recs if e in r.get("stands_in", {})]
        out[f"stands_{e}"] = sum(got) / len(got) if got else nan
    out["refused"] = sum(1 for r in recs if "pipeline_error" in r)
    return out


def table_row(name: str, f: dict) -> list:
    """A row of :data:`COLUMNS` from :func:`figures`."""
    from eval.suites._common import dec, interval_cell, pct

    return [name, f["scenes"], pct(f["f1"]), interval_cell((f["f1_lo"], f["f1_hi"])),
            pct(f["bound"]), pct(f["bound_share"]), pct(f["matched_share"]), dec(f["iou"]),
            dec(f["side_error"]), pct(f["stands_analytic"], 0), pct(f["stands_mujoco"], 0),
            pct(f["stands_pybullet"], 0), f["refused"]]


def run(args: argparse.Namespace) -> int:
    """Run the pool and write its tables under ``args.out``."""
    from eval.suites._common import (
        BOOTSTRAP_RESAMPLES,
        BOOTSTRAP_SEED,
        geometry_cells,
        geometry_note,
        pct,
        plot_bars,
        run_suite_tasks,
        write_table,
    )
    from eval.suites._scenes import f1_of, failure_note
    from pipeline import atomic

    quick = bool(getattr(args, "quick", False))
    n = args.n if getattr(args, "n", None) is not None else (1 if quick else DEFAULT_N)
    families = QUICK_FAMILIES if quick else FAMILIES
    first = getattr(args, "first_seed", None)
    lo, hi = seed_range(first, n)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tasks = build_tasks(lo, n, families)
    summary = run_suite_tasks(args, tasks, "pool")
    results = summary.results
    groups: dict[str, list[dict]] = {}
    for t in tasks:
        if t.id in results:
            groups.setdefault(t.kwargs["family"], []).append(results[t.id])
    everything = [r for recs in groups.values() for r in recs]
    figs = {fam: figures(recs) for fam, recs in groups.items()}
    figs["all"] = figures(everything)
    rows = [table_row(name, f) for name, f in figs.items()]
    from pipeline.segment import MIN_INSTANCE_POINTS

    note = (f"Held-out pool: scene seeds {lo}-{hi} of each family, one Kinect-noised view "
            f"each.  Typed contact F1 in percent, micro-averaged over a row's edges; 95% "
            f"interval: percentile bootstrap over the row's scenes ({BOOTSTRAP_RESAMPLES} "
            f"resamples, generator seed {BOOTSTRAP_SEED}).  F1 if right about all seen: the "
            f"F1 of a result that misses only the true contacts at parts the scan saw too "
            f"little of (fewer than {MIN_INSTANCE_POINTS} points) and adds none; share: F1 "
            f"over that bound.  {geometry_note()}  Stands: fractions of results standing in "
            f"the analytic check and settled in each engine.  Scans refused: scenes the "
            f"pipeline gave up on (e.g. no ground plane found), scored as an empty result "
            f"(every true contact missed).  {summary.n_ok} scenes ok, "
            f"{summary.n_failed} failed.\n" + failure_note(summary))
    md = write_table(out, "pool", COLUMNS, rows,
                     title=f"Held-out pool (seeds {lo}-{hi})", note=note)
    record = {"first_seed": lo, "last_seed": hi, "n_per_family": n,
              "families": list(families), "scenes_ok": summary.n_ok,
              "scenes_failed": summary.n_failed, "bootstrap_resamples": BOOTSTRAP_RESAMPLES,
              "bootstrap_seed": BOOTSTRAP_SEED, "figures": figs}
    atomic.write_text(out / "pool.json", json.dumps(_json_safe(record), indent=1) + "\n")
    scene_rows = [[t.id, t.kwargs["family"], t.kwargs["seed"], results[t.id]["n_gt"],
                   len(results[t.id].get("unseen", [])), pct(f1_of(results[t.id])),
                   *geometry_cells([results[t.id]]), int(bool(results[t.id]["stable"])),
                   *[int(bool(results[t.id].get("stands_in", {}).get(e))) for e in ENGINES]]
                  for t in tasks if t.id in results]
    write_table(out, "scenes", ["task", "family", "seed", "gt cuboids", "unseen parts",
                                "typed F1", "matched share (%)", "IoU (matched)", "side error",
                                "stable", *ENGINES], scene_rows)
    plot_bars(out / "pool.png",
              {fam: {"typed F1": 100 * f["f1"], "right about all seen": 100 * f["bound"]}
               for fam, f in figs.items()},
              ylabel="typed contact F1 (%)", title=f"Held-out pool, seeds {lo}-{hi}",
              ylim=(0, 105))
    stream = getattr(args, "stream", None) or sys.stdout
    stream.write(md)
    if getattr(args, "compare", None) is not None:
        stream.write("\n" + compare(out, Path(args.compare), tasks, results))
    else:
        from eval.suites._common import clear_comparison

        clear_comparison(out)
    return 0


COMPARE_COLUMNS = ["family", "scenes compared", "typed F1 before", "typed F1 after",
                   "change", "change 95% interval", "IoU before", "IoU after", "scenes up",
                   "scenes down"]


def read_pool(folder: Path) -> dict:
    """The seed range and families of an earlier pool run in ``folder`` (its
    ``pool.json``; :func:`eval.suites._common.read_earlier`)."""
    from eval.suites._common import read_earlier

    keys = ("first_seed", "last_seed", "families")
    record = read_earlier(folder, "pool.json", "pool", keys)
    return {k: record[k] for k in keys}


def check_compare(folder: Path, out: Path, first_seed: int, n: int, families) -> None:
    """``--compare``: an earlier pool of the same seed range and families, not ``--out``
    itself (one line, before any work)."""
    from eval.suites._common import check_not_out
    from pipeline.errors import InputError

    check_not_out(folder, out)
    prev = read_pool(folder)
    lo, hi = seed_range(first_seed, n)
    if (prev["first_seed"], prev["last_seed"]) != (lo, hi) or list(prev["families"]) != list(families):
        raise InputError(f"--compare {folder}: that pool is seeds {prev['first_seed']}-"
                         f"{prev['last_seed']} of {len(prev['families'])} families, this one "
                         f"{lo}-{hi} of {len(families)}; compare runs of the same scenes")


def compare(out: Path, folder: Path, tasks: list, results: dict) -> str:
    """This pool's scenes against the same scenes of an earlier run (``folder``): per
    family and overall, typed F1 before and after with a paired bootstrap interval of the
    change (the same scenes resampled for both), mean IoU of the matched boxes, and how
    many scenes went up or down.  Writes ``compare.md`` / ``.csv`` / ``.json``; returns
    the Markdown."""
    import numpy as np

    from eval.runner import load_records
    from eval.suites._common import (
        BOOTSTRAP_RESAMPLES,
        BOOTSTRAP_SEED,
        aggregate_prf,
        dec,
        geometry,
        paired_bootstrap,
        pct,
        write_table,
    )
    from eval.suites._scenes import f1_of
    from pipeline import atomic

    before = {i: r["result"] for i, r in load_records(folder).items()
              if r.get("status") == "ok" and isinstance(r.get("result"), dict)
              and not np.isnan(f1_of(r["result"]))}  # a record without typed counts: left out
    pairs: dict[str, list[tuple[dict, dict]]] = {}
    for t in tasks:
        if t.id in results and t.id in before:
            pairs.setdefault(t.kwargs["family"], []).append((before[t.id], results[t.id]))
    pairs["all"] = [p for fam in list(pairs) for p in pairs[fam]]
    rows, figs = [], {}
    for fam, ps in pairs.items():
        if not ps:
            continue
        a, b = [p[0] for p in ps], [p[1] for p in ps]
        fa, fb = aggregate_prf(a)["f1"], aggregate_prf(b)["f1"]
        lo, hi = paired_bootstrap(a, b, np.random.default_rng(BOOTSTRAP_SEED))
        per_scene = [(f1_of(x), f1_of(y)) for x, y in ps]
        up = sum(fy > fx + 1e-9 for fx, fy in per_scene)
        down = sum(fy < fx - 1e-9 for fx, fy in per_scene)
        ia, ib = geometry(a)["iou"], geometry(b)["iou"]
        figs[fam] = {"scenes": len(ps), "f1_before": fa, "f1_after": fb, "change": fb - fa,
                     "change_lo": lo, "change_hi": hi, "iou_before": ia, "iou_after": ib,
                     "up": up, "down": down}
        rows.append([fam, len(ps), pct(fa), pct(fb), f"{100 * (fb - fa):+.1f}",
                     f"{100 * lo:+.1f} to {100 * hi:+.1f}", dec(ia), dec(ib), up, down])
    missing = sorted(t.id for t in tasks if t.id in results and t.id not in before)
    note = (f"Before: the pool in {folder}; after: this run ({out}).  Change: typed F1 after "
            f"minus before, in points; its 95% interval: paired percentile bootstrap over the "
            f"scenes ({BOOTSTRAP_RESAMPLES} resamples of the same scenes for both, generator "
            f"seed {BOOTSTRAP_SEED}).  An interval that holds 0 is no evidence either way.  "
            f"Scenes up / down: scenes whose typed F1 rose / fell."
            + (f"  {len(missing)} scenes of this run have no record there and are left "
               f"out." if missing else ""))
    md = write_table(out, "compare", COMPARE_COLUMNS, rows,
                     title=f"Against {folder}", note=note)
    atomic.write_text(out / "compare.json", json.dumps(_json_safe(
        {"before": str(folder), "after": str(out), "figures": figs, "left_out": missing}),
        indent=1) + "\n")
    return md


def _json_safe(obj):  # noqa: ANN001, ANN202
    """NaN -> None, recursively (JSON has no NaN)."""
    if isinstance(obj, dict):
        return {k: _json_safe(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_json_safe(v) for v in obj]
    if isinstance(obj, float) and obj != obj:
        return None
    return obj
