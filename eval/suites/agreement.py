"""``unseen eval agreement``: analytic statics vs MuJoCo vs PyBullet on random arrangements.

For each of ``--n`` (default 500) arrangements of
:func:`synth_scenes.random_arrangements.random_arrangement` (seeded per task from
``--seed``) it records three verdicts: analytic (:func:`pipeline.stability.check_stability`),
MuJoCo and PyBullet (:func:`simulate.engines.settle`).  Outputs under ``--out``:

``agreement.md`` / ``agreement.csv``
    Per engine pair: the confusion matrix (stable/unstable) and the agreement, counted
    separately outside and inside the *near-threshold band*.
``agreement_by_kind.md`` / ``.csv``
    The same agreement per arrangement family.
``cases.csv``
    One row per arrangement: kind, margin, energy, the three verdicts, in the band or not.
``agreement.png``
    Agreement outside the band, per family and engine pair.
``arrangements/<task>.json``
    Every arrangement of the study as an ``arrangement.json`` whose ``meta`` holds the
    suite's ``verdicts``, ``energy`` and ``near_threshold``: ``unseen check
    OUT/arrangements --engine all --junit report.xml`` checks them all again (a few KB
    each, about 1 MB for 500).
``disagreements/<task>.json``
    The same file for every arrangement on which any two verdicts differ, ready for
    ``unseen check OUT/disagreements --engine all``.

The band: an arrangement is *near the threshold* when its closed-form tipping angle
(``meta["margin"]``, signed, radians: how far the part that can tip must turn before it
topples, or how far a leaning plank is above its ladder limit) satisfies
``|margin| < MARGIN_BAND`` (0.02 rad = 1.15 degrees), or when its analytic energy is
within a decade of the threshold, ``|log10(E / threshold)| < ENERGY_DECADES``.  Inside
the band a verdict is at the mercy of contact softness and of the transient of releasing
a stack from rest (measured: the engines' ladder limit sits 0.5-0.9 degrees above the
rigid-body one; a 0.75 m tower with a 1.7 degree margin topples in both engines) and of
the friction cone's linearisation, so it is reported, not scored.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

#: Default number of arrangements.
DEFAULT_N = 500
#: Size of the quick (CI) run.
QUICK_N = 24
#: Half-width of the margin band, radians of tipping angle (1.15 degrees).
MARGIN_BAND = 0.02
#: Half-width of the energy band, in decades around the threshold.
ENERGY_DECADES = 1.0
PAIRS = (("analytic", "mujoco"), ("analytic", "pybullet"), ("mujoco", "pybullet"))
VERDICTS = ("analytic", "mujoco", "pybullet")


def agreement_task(rng: np.random.Generator, index: int) -> dict:
    """Draw one arrangement and judge it three ways (a :class:`eval.runner.Task` function)."""
    from pipeline.arrangement_io import arrangement_to_dict
    from pipeline.stability import check_stability
    from simulate.engines import settle
    from synth_scenes.random_arrangements import random_arrangement

    arr = random_arrangement(rng)
    a = check_stability(arr)
    rec: dict = {"index": index, "kind": arr.meta["kind"], "margin": arr.meta.get("margin"),
                 "n_cuboids": len(arr.cuboids),
                 "analytic": {"stable": bool(a.stable), "energy": float(a.energy),
                              "threshold": float(a.threshold), "status": a.status,
                              "unstable": a.unstable_ids}}
    for engine in ("mujoco", "pybullet"):
        r = settle(arr, engine)
        rec[engine] = {"stable": bool(r.stable), "status": r.status,
                       "unstable": [b.id for b in r.bodies if not b.stable],
                       "max_translation": max(b.translation for b in r.bodies),
                       "max_rotation_deg": max(b.rotation_deg for b in r.bodies)}
    rec["near"] = near_threshold(rec)
    rec["arrangement"] = arrangement_to_dict(arr)  # every case is saved (arrangements/)
    return rec


def _redraw(seed: int, task_id: str) -> dict:
    """The arrangement of a task whose record predates saving it: the same draw again
    (:func:`agreement_task` draws it first from the task's generator)."""
    from eval.runner import task_rng
    from pipeline.arrangement_io import arrangement_to_dict
    from synth_scenes.random_arrangements import random_arrangement

    return arrangement_to_dict(random_arrangement(task_rng(seed, task_id)))


def _write_if_changed(path: Path, text: str) -> None:
    """Write atomically unless the file already holds ``text`` (a resumed run)."""
    from pipeline import atomic

    try:
        if path.read_text(encoding="utf-8") == text:
            return
    except (OSError, ValueError):
        pass
    atomic.write_text(path, text)


def near_threshold(rec: dict) -> bool:
    """Whether a case lies in the near-threshold band (see the module docstring)."""
    margin = rec.get("margin")
    if margin is not None and abs(margin) < MARGIN_BAND:
        return True
    e, thr = rec["analytic"]["energy"], rec["analytic"]["threshold"]
    return bool(abs(np.log10(max(e, 1e-300) / thr)) < ENERGY_DECADES)


def confusion(records: list[dict], a: str, b: str) -> dict[str, int]:
    """Counts of (a, b) verdict pairs: ``ss`` (both stable), ``su``, ``us``, ``uu``."""
    out = {"ss": 0, "su": 0, "us": 0, "uu": 0}
    for r in records:
        out[("s" if r[a]["stable"] else "u") + ("s" if r[b]["stable"] else "u")] += 1
    return out


def _rate(c: dict[str, int]) -> float:
    n = sum(c.values())
    return (c["ss"] + c["uu"]) / n if n else float("nan")


def summarize(records: list[dict]) -> dict:
    """Agreement per engine pair outside and inside the band (JSON-ready)."""
    outside = [r for r in records if not r["near"]]
    inside = [r for r in records if r["near"]]
    out = {"n": len(records), "n_outside": len(outside), "n_band": len(inside), "pairs": {}}
    for a, b in PAIRS:
        co, ci = confusion(outside, a, b), confusion(inside, a, b)
        out["pairs"][f"{a}-{b}"] = {"outside": co, "band": ci, "agree_outside": _rate(co),
                                    "agree_band": _rate(ci)}
    return out


def plot_agreement(path: Path, records: list[dict], bars: dict[str, dict[str, float]],
                   n_outside: int) -> None:
    """Two panels: agreement outside the band per family, and the fraction of cases each
    check calls stable against the closed-form tipping margin (a step at 0 is ideal)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pipeline import atomic

    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(12.0, 4.4))
    kinds = list(bars)
    width = 0.8 / len(PAIRS)
    for j, (a, b) in enumerate(PAIRS):
        vals = [bars[k].get(f"{a}-{b}", np.nan) for k in kinds]
        ax0.bar(np.arange(len(kinds)) + (j - 1) * width, vals, width, label=f"{a}-{b}")
    low = np.nanmin([90.0] + [v for g in bars.values() for v in g.values()])
    ax0.set_ylim(low - 1, 100.5)
    ax0.set_xticks(np.arange(len(kinds)), kinds, rotation=30)
    ax0.set_ylabel("agreement outside the band (%)")
    ax0.set_title(f"Verdicts agree ({n_outside} cases outside the band)")
    ax0.legend(loc="lower left", fontsize=8)
    ax0.grid(True, axis="y", alpha=0.3)

    with_margin = [r for r in records if r.get("margin") is not None]
    deg = np.degrees([r["margin"] for r in with_margin]) if with_margin else np.zeros(0)
    edges = np.arange(-10.0, 10.5, 1.0)
    centers = 0.5 * (edges[1:] + edges[:-1])
    idx = np.digitize(np.clip(deg, edges[0], edges[-1] - 1e-9), edges) - 1
    for v, marker in zip(VERDICTS, ("o", "s", "^"), strict=True):
        st = np.array([r[v]["stable"] for r in with_margin], dtype=float)
        frac = np.array([st[idx == i].mean() if np.any(idx == i) else np.nan
                         for i in range(len(centers))])
        ax1.plot(centers, 100 * frac, marker=marker, label=v)
    band = np.degrees(MARGIN_BAND)
    ax1.axvspan(-band, band, color="0.85", label="band")
    ax1.set_xlabel("closed-form tipping margin (degrees; |x| > 10 in the end bins)")
    ax1.set_ylabel("called stable (%)")
    ax1.set_title(f"Verdict against margin ({len(with_margin)} cases with a closed form)")
    ax1.legend(loc="lower right", fontsize=8)
    ax1.grid(True, alpha=0.3)
    fig.tight_layout()
    with atomic.atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, metadata={"Software": None})
    plt.close(fig)


def run(args: argparse.Namespace) -> int:
    """Run the study and write its tables, plot and disagreements under ``args.out``."""
    import json

    from eval.runner import Task
    from eval.suites._common import pct, run_suite_tasks, write_table
    from pipeline import atomic

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    n = args.n if getattr(args, "n", None) is not None else (
        QUICK_N if getattr(args, "quick", False) else DEFAULT_N)
    tasks = [Task(f"arr{i:04d}", agreement_task, {"index": i}) for i in range(n)]
    summary = run_suite_tasks(args, tasks, "agreement")
    results = summary.results
    records = [results[t.id] | {"id": t.id} for t in tasks if t.id in results]

    # every case as an arrangement.json (meta: the verdicts), disagreements also apart
    for r in records:
        data = dict(r.get("arrangement") or _redraw(args.seed, r["id"]))
        data["meta"] = {**data.get("meta", {}),
                        "verdicts": {v: r[v]["stable"] for v in VERDICTS},
                        "energy": r["analytic"]["energy"], "near_threshold": r["near"]}
        text = json.dumps(data, indent=1) + "\n"
        folders = ["arrangements"] + (["disagreements"]
                                      if len({r[v]["stable"] for v in VERDICTS}) > 1 else [])
        for folder in folders:
            _write_if_changed(out / folder / f"{r['id']}.json", text)

    s = summarize(records)
    rows = []
    for name, p in s["pairs"].items():
        co = p["outside"]
        rows.append([name, s["n_outside"], pct(p["agree_outside"], 2), co["ss"], co["su"],
                     co["us"], co["uu"], s["n_band"], pct(p["agree_band"], 1)])
    note = (f"{s['n']} arrangements (seed {args.seed}); {s['n_band']} in the near-threshold "
            f"band (tipping angle |margin| < {MARGIN_BAND} rad, or |log10(E/threshold)| < "
            f"{ENERGY_DECADES:g}), scored separately.  ss/su/us/uu: stable/unstable by the "
            "first and the second verdict, outside the band.  Failed tasks: "
            f"{summary.n_failed}.")
    md = write_table(out, "agreement",
                     ["pair", "n outside", "agree outside %", "ss", "su", "us", "uu",
                      "n band", "agree band %"], rows,
                     title="Analytic vs MuJoCo vs PyBullet stability verdicts", note=note)

    kinds = sorted({r["kind"] for r in records})
    krows, bars = [], {}
    for k in kinds:
        rs = [r for r in records if r["kind"] == k]
        sk = summarize(rs)
        stable_frac = np.mean([r["analytic"]["stable"] for r in rs])
        krows.append([k, sk["n"], sk["n_band"], pct(float(stable_frac), 0)]
                     + [pct(sk["pairs"][f"{a}-{b}"]["agree_outside"], 1) for a, b in PAIRS])
        bars[k] = {f"{a}-{b}": 100 * sk["pairs"][f"{a}-{b}"]["agree_outside"]
                   for a, b in PAIRS if sk["n_outside"]}
    write_table(out, "agreement_by_kind",
                ["kind", "n", "n band", "analytic stable %"]
                + [f"{a}-{b} agree outside %" for a, b in PAIRS], krows,
                title="Agreement outside the band, per family")
    case_rows = [[r["id"], r["kind"], r["margin"], r["analytic"]["energy"],
                  int(r["analytic"]["stable"]), int(r["mujoco"]["stable"]),
                  int(r["pybullet"]["stable"]), int(r["near"])] for r in records]
    write_table(out, "cases", ["id", "kind", "margin", "energy", "analytic", "mujoco",
                               "pybullet", "near"], case_rows, floatfmt=".4g")
    plot_agreement(out / "agreement.png", records, bars, s["n_outside"])
    atomic.write_text(out / "summary.json", json.dumps(s, indent=1) + "\n")
    # the table goes to the caller's stream (the terminal for `unseen eval`)
    stream = getattr(args, "stream", None) or sys.stdout
    stream.write(md)
    return 0
