"""``unseen eval real --out DIR [--data DIR]``: the real scans against our own labels.

Every annotation in ``eval/real/annotations`` names a scan in the real data folder
(default ``../shared/data/real`` beside the checkout, or ``--data``).  Each scan goes
through the whole pipeline with no flags, as ``unseen run SCAN`` would run it, its result
is settled in MuJoCo and PyBullet, and its support graph is scored against the labels
(:mod:`eval.real`: objects matched through ``meta.camera_pose``, unsure pairs
do-not-care).

Outputs under ``--out``: ``real.md`` / ``.csv`` (one row per scan and one per group:
box scenes and cluttered rooms, micro-averaged), ``real.json`` (every figure, the pairs
missed and wrongly added per scan), ``scans/<name>/`` (the run's outputs: arrangement,
``overlay.png``, ``report.md``), ``tasks/`` (resumable).  ``--quick``: the first box scan.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ENGINES = ("mujoco", "pybullet")
COLUMNS = ["scan", "group", "objects", "found", "predicted objects", "support P", "support R",
           "support F1", "F1, every contact", "glue", "glue between objects", "stands: analytic", "stands: MuJoCo",
           "stands: PyBullet"]


def real_task(rng, name: str, scan: str, out: str, seed: int = 0) -> dict:  # noqa: ANN001
    """Run one real scan as ``unseen run`` does, write its outputs to ``out/scans/name``,
    score it against its annotation; a JSON-ready record."""
    from eval.real import ANNOTATIONS, load_annotation, score
    from eval.run_full import check_engines, write_full_outputs
    from pipeline.outdir import output_folder
    from pipeline.run import RunConfig, run_scan

    ann = load_annotation(ANNOTATIONS / f"{name}.json")
    config = RunConfig(seed=seed)
    result = run_scan(scan, config)
    arr = result.arrangement
    engines = check_engines(arr, config.imagine.mu)
    with output_folder(Path(out) / "scans" / name, command="run") as tmp:
        write_full_outputs(tmp, result.scan, result.initial, result, result.initial_report,
                           engines, f"unseen run {Path(scan).name}", seed)
    s = score(arr, _input_points(result), ann)
    return {"name": name, "group": ann.group, **s.to_json(),
            "stable": bool(result.report.stable),
            "stands_in": {e: bool(engines[e]["stable"]) for e in ENGINES}}


def _input_points(result):  # noqa: ANN001, ANN202
    """The scan's points back in the input frame and units (the labels' frame)."""
    s = float(result.arrangement.meta.get("input_scale", 1.0) or 1.0)
    return result.scan.points / s


def group_figures(recs: list[dict]) -> dict:
    """Micro-averaged support P/R/F1, objects found, glue, stand fractions of ``recs``."""
    from eval.real import prf

    tp, fp, fn = (sum(r[k] for r in recs) for k in ("tp", "fp", "fn"))
    p, r, f = prf(tp, fp, fn)
    f_all = prf(*(sum(x["all_contacts"][k] for x in recs) for k in ("tp", "fp", "fn")))[2]
    n = max(len(recs), 1)
    return {"scans": len(recs), "objects": sum(x["objects"] for x in recs),
            "found": sum(x["found"] for x in recs),
            "predicted_objects": sum(x["predicted_objects"] for x in recs),
            "tp": tp, "fp": fp, "fn": fn, "precision": p, "recall": r, "f1": f,
            "f1_all_contacts": f_all,
            "glue": sum(x["glue"] for x in recs),
            "glue_between_objects": sum(x["glue_between_objects"] for x in recs),
            "stands_analytic": sum(bool(x["stable"]) for x in recs) / n,
            **{f"stands_{e}": sum(bool(x["stands_in"][e]) for x in recs) / n for e in ENGINES}}


def _row(name: str, group: str, f: dict) -> list:
    from eval.suites._common import pct

    return [name, group, f["objects"], f["found"], f["predicted_objects"], pct(f["precision"]),
            pct(f["recall"]), pct(f["f1"]), pct(f["f1_all_contacts"]), f["glue"], f["glue_between_objects"],
            pct(f["stands_analytic"], 0), pct(f["stands_mujoco"], 0),
            pct(f["stands_pybullet"], 0)]


def run(args: argparse.Namespace) -> int:
    from eval.real import DEFAULT_DATA, annotations
    from eval.runner import Task
    from eval.suites._common import failures_markdown, run_suite_tasks, write_table
    from eval.suites.pool import _json_safe
    from pipeline import atomic
    from pipeline.errors import InputError

    data = Path(getattr(args, "data", None) or DEFAULT_DATA)
    if not data.is_dir():
        raise InputError(f"--data {data}: no real data folder there; give the folder that "
                         "holds osd_stacked_boxes/, shao_kinect_boxes/, ... (../shared/data/real)")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    anns = annotations()
    missing = [a.scan for a in anns if not (data / a.scan).exists()]
    if missing:
        raise InputError(f"--data {data}: scans named by the annotations are missing: "
                         f"{', '.join(missing)}")
    if getattr(args, "quick", False):
        anns = [a for a in anns if a.group == "boxes"][:1]
    if getattr(args, "n", None) is not None:
        anns = anns[:args.n]
    tasks = [Task(a.name, real_task, {"name": a.name, "scan": str(data / a.scan),
                                      "out": str(out.resolve()), "seed": int(args.seed)},
                  cost=3.0 if a.group == "rooms" else 1.0) for a in anns]
    summary = run_suite_tasks(args, tasks, "real")
    recs = [summary.results[a.name] for a in anns if a.name in summary.results]
    rows, figs = [], {}
    for r in recs:
        f = group_figures([r])
        rows.append(_row(r["name"], r["group"], f))
    for group in ("boxes", "rooms"):
        g = [r for r in recs if r["group"] == group]
        if g:
            figs[group] = group_figures(g)
            rows.append(_row(f"**all {group}**", group, figs[group]))
    note = ("Support graph of each real scan (run with no flags, as `unseen run SCAN`) against "
            "our labels in eval/real/annotations: unordered pairs of objects, floor and walls "
            "joined by a fixed contact or a touch that carries load in the statics' solution "
            "(F1, every contact: all listed contacts instead); relations labelled with "
            "confidence below 0.5 are do-not-care.  "
            "Objects: labelled; found: of them covered by a matched predicted object "
            "(eval/real: at least 30% of their points).  Glue: fixed contacts between "
            "different predicted objects or with the floor or a wall; between objects: of "
            "them joining two different labelled objects.  Group rows are micro-averaged. "
            "Stands: the result in the analytic check and settled in each engine.\n"
            + failures_markdown(summary))
    md = write_table(out, "real", COLUMNS, rows, title="Real scans against our labels",
                     note=note)
    record = {"data": str(data), "groups": figs,
              "scans": {r["name"]: r for r in recs}}
    atomic.write_text(out / "real.json", json.dumps(_json_safe(record), indent=1) + "\n")
    stream = getattr(args, "stream", None) or sys.stdout
    stream.write(md)
    if getattr(args, "compare", None) is not None:
        stream.write("\n" + compare(out, Path(args.compare), recs))
    else:
        from eval.suites._common import clear_comparison

        clear_comparison(out)
    return 0


COMPARE_COLUMNS = ["scan", "group", "support F1 before", "support F1 after", "found",
                   "glue", "stands (analytic / MuJoCo / PyBullet)", "pairs gained",
                   "pairs lost"]


def read_real(folder: Path) -> dict:
    """The per-scan records of an earlier ``unseen eval real`` run in ``folder`` (its
    ``real.json``; :func:`eval.suites._common.read_earlier`).

    Raises
    ------
    pipeline.errors.InputError
        No readable ``real.json`` there, or a scan record without a field the comparison
        reads.
    """
    from eval.suites._common import read_earlier
    from pipeline.errors import InputError

    scans = read_earlier(folder, "real.json", "real", ("scans",))["scans"]
    if not isinstance(scans, dict):
        raise InputError(f"--compare {folder}: no readable real.json there; give the --out "
                         f"of an earlier 'unseen eval real' run")
    need = ("group", "tp", "fp", "fn", "found", "objects", "predicted_objects", "glue",
            "glue_between_objects", "stable", "stands_in", "missed_pairs", "false_pairs",
            "all_contacts")
    for name, rec in scans.items():
        gone = [k for k in need if not isinstance(rec, dict) or k not in rec]
        if gone:
            raise InputError(f"--compare {folder}: real.json's scan {name!r} lacks "
                             f"{', '.join(gone)}; give the --out of a run of this version")
    return scans


def compare(out: Path, folder: Path, recs: list[dict]) -> str:
    """These scans against the same scans of an earlier run (``folder``): one row per scan
    whose score, objects found, glue or standing changed (support F1 before and after, the
    labelled pairs it now gets right and those it no longer does) and one per group
    (micro-averaged).  Writes ``compare.md`` / ``.csv`` / ``.json``; returns the Markdown."""
    from eval.suites._common import pct, write_table
    from eval.suites.pool import _json_safe
    from pipeline import atomic

    before = read_real(folder)

    def stands(r: dict) -> str:
        return " / ".join(str(int(bool(x))) for x in
                          (r["stable"], *(r["stands_in"][e] for e in ENGINES)))

    def cell(ps: list, sign: str) -> str:
        return ", ".join(f"{sign}{x}-{y}" for x, y in ps)

    def only_in(r: dict, other: dict, key: str) -> list:
        """The pairs under ``key`` that ``r`` lists and ``other`` does not, sorted."""
        return sorted({tuple(p) for p in r[key]} - {tuple(p) for p in other[key]})

    same = ("tp", "fp", "fn", "found", "glue", "stable", "stands_in")
    rows, changed = [], []
    pairs = [(before[r["name"]], r) for r in recs if r["name"] in before]
    for a, b in pairs:
        if all(a[k] == b[k] for k in same):
            continue
        fa, fb = group_figures([a])["f1"], group_figures([b])["f1"]
        lost, gained = only_in(b, a, "missed_pairs"), only_in(a, b, "missed_pairs")
        wrong, fixed = only_in(b, a, "false_pairs"), only_in(a, b, "false_pairs")
        rows.append([b["name"], b["group"], pct(fa), pct(fb), f"{a['found']} -> {b['found']}",
                     f"{a['glue']} -> {b['glue']}", f"{stands(a)} -> {stands(b)}",
                     "; ".join(x for x in (cell(gained, ""), cell(fixed, "not ")) if x),
                     "; ".join(x for x in (cell(lost, ""), cell(wrong, "added ")) if x)])
        changed.append(b["name"])
    figs = {}
    for group in ("boxes", "rooms"):
        ps = [(a, b) for a, b in pairs if b["group"] == group]
        if ps:
            fa, fb = (group_figures([p[k] for p in ps]) for k in (0, 1))
            figs[group] = {"scans": len(ps), "f1_before": fa["f1"], "f1_after": fb["f1"],
                           "found_before": fa["found"], "found_after": fb["found"],
                           "glue_before": fa["glue"], "glue_after": fb["glue"]}
            rows.append([f"**all {group}**", group, pct(fa["f1"]), pct(fb["f1"]),
                         f"{fa['found']} -> {fb['found']}", f"{fa['glue']} -> {fb['glue']}",
                         f"{pct(fa['stands_analytic'], 0)} / {pct(fa['stands_mujoco'], 0)} / "
                         f"{pct(fa['stands_pybullet'], 0)} -> {pct(fb['stands_analytic'], 0)} / "
                         f"{pct(fb['stands_mujoco'], 0)} / {pct(fb['stands_pybullet'], 0)} %", "",
                         ""])
    left = sorted(r["name"] for r in recs if r["name"] not in before)
    note = (f"Before: the run in {folder}; after: this run ({out}).  One row per scan whose "
            f"support score, objects found, glue or verdicts changed ({len(changed)} of "
            f"{len(pairs)}); stands: 1 / 0 in the analytic check, MuJoCo, PyBullet.  Pairs "
            f"gained: labelled pairs now found, or wrong pairs no longer added ('not'); "
            f"pairs lost: labelled pairs no longer found, or wrong pairs now added ('added')."
            + (f"  Not in the earlier run, left out: {', '.join(left)}." if left else ""))
    md = write_table(out, "compare", COMPARE_COLUMNS, rows, title=f"Against {folder}",
                     note=note)
    atomic.write_text(out / "compare.json", json.dumps(_json_safe(
        {"before": str(folder), "after": str(out), "changed": changed, "groups": figs,
         "left_out": left}), indent=1) + "\n")
    return md
