"""Shared helpers for the experiment suites: tasks, scores, aggregation, tables, plots.

A suite is mostly: build :class:`~eval.runner.Task` per scene, run them with
:func:`run_suite_tasks`, turn each task's :func:`score_record` into rows with
:func:`aggregate_prf` and :func:`group_records`, and write them with :func:`write_table`
and :func:`plot_series` / :func:`plot_bars`.  The paper's figures to print next to ours
are in :data:`PAPER_TABLE1`, :data:`PAPER_TABLE2` and :data:`PAPER_TABLE3`.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from pipeline import atomic

#: Table 1 of the paper: (initial P, R, F1, optimized P, R, F1) in percent, and #scenes.
PAPER_TABLE1: dict[str, dict[str, float]] = {
    "Synthetic": {"scenes": 12, "init_p": 42.1, "init_r": 26.7, "init_f1": 32.2,
                  "opt_p": 96.2, "opt_r": 84.7, "opt_f1": 87.2},
    "NYU2": {"scenes": 700, "init_p": 34.7, "init_r": 47.3, "init_f1": 40.0,
             "opt_p": 55.3, "opt_r": 70.8, "opt_f1": 60.5},
    "Recorded": {"scenes": 20, "init_p": 70.1, "init_r": 49.5, "init_f1": 56.5,
                 "opt_p": 95.7, "opt_r": 96.6, "opt_f1": 95.9},
    "Kinfu": {"scenes": 2, "init_p": 37.2, "init_r": 28.2, "init_f1": 32.1,
              "opt_p": 96.4, "opt_r": 84.0, "opt_f1": 89.7},
}

#: Table 2 of the paper: F1 initial -> optimized per rotation perturbation (degrees).
PAPER_TABLE2: dict[str, dict[int, tuple[float, float]]] = {
    "chair_01": {0: (20.0, 100.0), 5: (20.51, 100.0), 10: (20.51, 97.8), 15: (17.14, 87.8)},
    "chair_02": {0: (21.43, 100.0), 5: (20.69, 100.0), 10: (14.29, 97.5), 15: (14.29, 94.7)},
}

#: Table 3 of the paper (Fig. 13 is the synthetic 18-box scene; 16 and 14 are recordings).
PAPER_TABLE3: dict[str, dict[str, float]] = {
    "Fig. 13": {"proxies": 18, "contacts": 41, "max_valence": 6, "median_valence": 5,
                "mean_valence": 4.55, "min_valence": 1, "init_p": 85.19, "init_r": 56.10,
                "opt_p": 90.24, "opt_r": 90.24, "init_f1": 67.65, "opt_f1": 90.24},
    "Fig. 16": {"proxies": 17, "contacts": 29, "max_valence": 11, "median_valence": 2,
                "mean_valence": 3.35, "min_valence": 1, "init_p": 58.82, "init_r": 34.48,
                "opt_p": 100.0, "opt_r": 89.66, "init_f1": 43.48, "opt_f1": 94.55},
    "Fig. 14": {"proxies": 56, "contacts": 64, "max_valence": 11, "median_valence": 2,
                "mean_valence": 2.32, "min_valence": 1, "init_p": 15.56, "init_r": 10.77,
                "opt_p": 98.33, "opt_r": 90.77, "init_f1": 12.73, "opt_f1": 94.40},
}


# ------------------------------------------------------------------------- running
def suite_size(args: argparse.Namespace, default: int, quick_n: int = 1) -> tuple[Path, bool, int]:
    """``(out, quick, n)`` of a suite run: the output folder (created), whether
    ``--quick`` was given, and ``--n`` or else ``quick_n`` (quick) or ``default``."""
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    quick = bool(getattr(args, "quick", False))
    n = args.n if getattr(args, "n", None) is not None else (quick_n if quick else default)
    return out, quick, n


def run_suite_tasks(args: argparse.Namespace, tasks: Iterable, label: str):
    """Run a suite's tasks with the scale-out options of ``unseen eval``.

    Returns the :class:`eval.runner.RunSummary`; records are under ``args.out/tasks``.
    The summary is also appended to ``args.task_summaries``, from which ``unseen eval``
    exits 1 when any task failed (:func:`eval.runner.failure_line`).
    """
    from eval.runner import run_tasks

    summary = run_tasks(tasks, args.out, seed=args.seed, workers=getattr(args, "workers", 1),
                        dask=getattr(args, "dask", None), label=label)
    if not isinstance(getattr(args, "task_summaries", None), list):
        args.task_summaries = []
    args.task_summaries.append(summary)
    return summary


def score_record(pred, gt, initial=None, graph: str = "union",  # noqa: ANN001
                 unseen: Sequence[str] | None = None) -> dict:
    """A compact JSON record of :func:`eval.metrics.score_arrangement` for a task result.

    Keeps the edge counts (so scenes can be summed, micro-averaged), mean IoU, the
    size error and Table 3's valence statistics of the true and predicted graphs;
    aggregate with :func:`aggregate_prf` on ``"optimized.typed"`` etc.  The geometry of
    the matched boxes is kept as sums that pool over scenes (:func:`geometry`):
    ``n_matched``, ``iou_sum`` (their IoUs), ``side_abs`` / ``side_len`` (metres, see
    :class:`eval.metrics.Score`).  With ``unseen`` (ids of true parts the scan saw too
    little of) also ``n_seen`` (true parts seen), ``n_matched_seen`` (those matched),
    ``unseen`` and ``fn_unseen`` (missed true contacts touching an unseen part).
    """
    from eval.metrics import contact_graph, score_arrangement, valence_stats

    s = score_arrangement(pred, gt, initial=initial, graph=graph)
    rec: dict[str, Any] = {"n_pred": s.n_pred, "n_gt": s.n_gt,
                           "mean_iou": s.mean_iou if s.n_gt else None,
                           "n_matched": len(s.matching.pairs), "iou_sum": float(s.iou.sum()),
                           "side_abs": s.side_abs, "side_len": s.side_len}
    if unseen is not None:
        hidden = set(unseen)
        matched = {g for _, g in s.matching.pairs}
        rec["n_seen"] = sum(1 for i in gt.ids if i not in hidden)
        rec["n_matched_seen"] = sum(1 for i in gt.ids if i not in hidden and i in matched)
        rec["unseen"] = list(unseen)
        rec["fn_unseen"] = sum(1 for e in s.optimized.false_negatives
                               if e[0] in hidden or e[1] in hidden)
    source = s.graph_source
    rec["valence"] = {"gt": valence_stats(contact_graph(gt, source), gt.ids).to_json(),
                      "optimized": valence_stats(contact_graph(pred, source), pred.ids).to_json()}
    for name, g in (("optimized", s.optimized), ("initial", s.initial)):
        if g is None:
            continue
        rec[name] = {kind: {"tp": p.tp, "n_pred": p.n_pred, "n_gt": p.n_gt}
                     for kind, p in (("typed", g.typed), ("untyped", g.untyped))}
    if s.size is not None:
        rec["size"] = s.size.to_json()
    return rec


def _get(record: Mapping, dotted: str) -> Any:
    cur: Any = record
    for part in dotted.split("."):
        if not isinstance(cur, Mapping) or part not in cur:
            return None
        cur = cur[part]
    return cur


def aggregate_prf(records: Iterable[Mapping], key: str = "optimized.typed") -> dict[str, float]:
    """Precision, recall and F1 over many scenes.

    Parameters
    ----------
    records : task results holding ``{"tp", "n_pred", "n_gt"}`` at the dotted ``key``
        (as :func:`score_record` writes them).  Records without it are skipped.

    Returns
    -------
    dict
        ``precision``, ``recall``, ``f1`` micro-averaged (edge counts summed over scenes,
        in [0, 1]), ``macro_f1`` (mean of per-scene F1) and ``n`` (scenes counted).
    """
    from eval.metrics import PRF

    total = PRF(0, 0, 0)
    f1s = []
    for rec in records:
        c = _get(rec, key)
        if c is None:
            continue
        p = PRF(int(c["tp"]), int(c["n_pred"]), int(c["n_gt"]))
        total = total + p
        f1s.append(p.f1)
    n = len(f1s)
    return {"precision": total.precision if n else float("nan"),
            "recall": total.recall if n else float("nan"),
            "f1": total.f1 if n else float("nan"),
            "macro_f1": sum(f1s) / n if n else float("nan"), "n": n}


def seen_bound(records: Iterable[Mapping]) -> float:
    """The typed F1 of results right about everything the scans saw (``table1_unseen``).

    Every true contact is found except those touching a part the scan saw too little of
    (``fn_unseen`` of :func:`score_record` with ``unseen``), and none is added: with
    ``best = n_gt - fn_unseen`` summed over the records, ``2 best / (best + n_gt)``.
    NaN when no record has the counts.
    """
    n_gt = fn_unseen = 0
    for r in records:
        c = _get(r, "optimized.typed")
        if c is None or "fn_unseen" not in r:
            continue
        n_gt += int(c["n_gt"])
        fn_unseen += int(r["fn_unseen"])
    best = n_gt - fn_unseen
    return 2 * best / (best + n_gt) if n_gt else float("nan")


def geometry(records: Iterable[Mapping]) -> dict[str, float]:
    """Geometry of the matched boxes over many scenes (sums pooled, see :func:`score_record`).

    Returns
    -------
    dict
        ``matched_share``: matched true parts seen / true parts seen (records without
        ``n_seen``: matched / true parts); ``iou``: mean IoU of the matched boxes;
        ``side_error``: ``sum |s - s^GT| / sum s^GT`` over their sides.  NaN when
        undefined.
    """
    nan = float("nan")
    seen = matched = n_pairs = 0
    iou = side_abs = side_len = 0.0
    for r in records:
        if "n_seen" in r:
            seen += int(r["n_seen"])
            matched += int(r["n_matched_seen"])
        elif "n_gt" in r and "n_matched" in r:
            seen += int(r["n_gt"])
            matched += int(r["n_matched"])
        if "iou_sum" in r:
            n_pairs += int(r["n_matched"])
            iou += float(r["iou_sum"])
            side_abs += float(r["side_abs"])
            side_len += float(r["side_len"])
    return {"matched_share": matched / seen if seen else nan,
            "iou": iou / n_pairs if n_pairs else nan,
            "side_error": side_abs / side_len if side_len > 0 else nan}


def geometry_cells(records: Iterable[Mapping]) -> list[str]:
    """The three cells of :data:`GEOMETRY_COLUMNS`: matched share (%), IoU, side error."""
    g = geometry(records)
    return [pct(g["matched_share"]), dec(g["iou"]), dec(g["side_error"])]


#: The keys of a :func:`score_record` that :func:`geometry` pools.
GEOMETRY_KEYS = ("n_gt", "n_matched", "iou_sum", "side_abs", "side_len", "n_seen",
                 "n_matched_seen")


def geometry_part(record: Mapping) -> dict:
    """The part of a :func:`score_record` that :func:`geometry` reads (for compact records)."""
    return {k: record[k] for k in GEOMETRY_KEYS if k in record}


#: Columns of :func:`geometry_cells`, printed next to every F1 (a prior that raises F1 by
#: making boxes wrong shows here).
GEOMETRY_COLUMNS = ["matched share (%)", "IoU (matched)", "side error"]

def geometry_note() -> str:
    """What :data:`GEOMETRY_COLUMNS` mean, for a table's note."""
    from eval.metrics import MIN_MATCH_IOU
    from pipeline.segment import MIN_INSTANCE_POINTS

    return (f"A predicted box counts as its true part only when their 3D IoU is at least "
            f"{MIN_MATCH_IOU:g} (otherwise its contacts are false and the part's missed).  "
            f"Matched share: true parts seen (at least {MIN_INSTANCE_POINTS} points in the "
            f"scan) that have a matching box; IoU (matched): mean IoU of the matched boxes; "
            f"side error: sum |s - s_true| / sum s_true over their sides.")


#: Resamples and generator seed of :func:`bootstrap_f1`.
BOOTSTRAP_RESAMPLES = 2000
BOOTSTRAP_SEED = 0


def bootstrap_f1(records: Sequence[Mapping], key: str = "optimized.typed", *,
                 level: float = 0.95, resamples: int = BOOTSTRAP_RESAMPLES,
                 seed: int = BOOTSTRAP_SEED) -> tuple[float, float]:
    """Percentile bootstrap interval of the micro F1 over scenes.

    Scenes are drawn with replacement (``resamples`` times, as many as there are, from a
    ``numpy.random.Generator`` seeded with ``seed``); each resample's F1 is
    ``2 tp / (n_pred + n_gt)`` of its summed counts.  The scenes' counts are sorted first,
    so the same scenes in any order give the same interval.

    Returns
    -------
    (lo, hi) : floats in [0, 1], NaN when no record has ``key``
    """
    import numpy as np

    counts = [c for c in (_get(r, key) for r in records) if c is not None]
    if not counts:
        return float("nan"), float("nan")
    c = np.array([[int(x["tp"]), int(x["n_pred"]) + int(x["n_gt"])] for x in counts], float)
    c = c[np.lexsort((c[:, 1], c[:, 0]))]  # independent of the records' order
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, len(c), size=(resamples, len(c)))
    tp, denom = c[idx, 0].sum(axis=1), c[idx, 1].sum(axis=1)
    f1 = np.divide(2.0 * tp, denom, out=np.zeros_like(tp), where=denom > 0)
    alpha = (1.0 - level) / 2.0
    lo, hi = np.quantile(f1, [alpha, 1.0 - alpha])
    return float(lo), float(hi)


def paired_bootstrap(before: Sequence[Mapping], after: Sequence[Mapping], rng,  # noqa: ANN001
                     n: int = BOOTSTRAP_RESAMPLES) -> tuple[float, float]:
    """95 % percentile interval of F1(after) - F1(before), in F1 units, over the scenes
    resampled with replacement ``n`` times from ``rng`` (a ``numpy.random.Generator``):
    the same scenes for both, ``before[i]`` and ``after[i]`` being one scene's two
    records (typed counts under ``optimized.typed``)."""
    import numpy as np

    def counts(recs: Sequence[Mapping]) -> np.ndarray:
        return np.array([[int(r["optimized"]["typed"][k]) for k in ("tp", "n_pred", "n_gt")]
                         for r in recs], float)

    a, b = counts(before), counts(after)
    idx = rng.integers(0, len(a), size=(n, len(a)))
    sa, sb = a[idx].sum(axis=1), b[idx].sum(axis=1)
    fa = 2 * sa[:, 0] / np.maximum(sa[:, 1] + sa[:, 2], 1)
    fb = 2 * sb[:, 0] / np.maximum(sb[:, 1] + sb[:, 2], 1)
    lo, hi = np.percentile(fb - fa, [2.5, 97.5])
    return float(lo), float(hi)


def read_earlier(folder: Path, name: str, suite: str, keys: Sequence[str]) -> dict:
    """The JSON object ``folder/name`` that an earlier ``unseen eval suite`` run wrote,
    holding ``keys`` (``--compare``).

    Raises
    ------
    pipeline.errors.InputError
        No readable such file there, or one without ``keys``: one line.
    """
    from pipeline.errors import InputError

    try:
        record = json.loads((Path(folder) / name).read_text(encoding="utf-8"))
        if isinstance(record, dict) and all(k in record for k in keys):
            return record
    except (OSError, ValueError):
        pass
    raise InputError(f"--compare {folder}: no readable {name} there; give the --out of an "
                     f"earlier 'unseen eval {suite}' run")


def check_not_out(folder: Path, out: Path) -> None:
    """``--compare`` is not the ``--out`` of this run (one line)."""
    from pipeline.errors import InputError

    if Path(folder).resolve() == Path(out).resolve():
        raise InputError(f"--compare {folder}: is the --out of this run; give the --out of "
                         f"an earlier run of the same scenes")


def clear_comparison(out: str | Path) -> None:
    """Remove the ``compare.*`` an earlier run with ``--compare`` wrote into ``out``: it no
    longer describes a run without it."""
    for name in ("compare.md", "compare.csv", "compare.json"):
        (Path(out) / name).unlink(missing_ok=True)


def interval_cell(interval: tuple[float, float]) -> str:
    """``91.2-95.4`` (percent) or ``-``."""
    lo, hi = interval
    return "-" if lo != lo else f"{100 * lo:.1f}-{100 * hi:.1f}"


def group_records(results: Mapping[str, Mapping], key: Callable[[str, Mapping], Any]
                  ) -> dict[Any, list[Mapping]]:
    """Group task results (id -> result) by ``key(task_id, result)``, keys in first-seen order."""
    groups: dict[Any, list[Mapping]] = {}
    for tid, rec in results.items():
        groups.setdefault(key(tid, rec), []).append(rec)
    return groups


def pr_cell(agg: Mapping[str, float]) -> str:
    """The paper's "P / R" cell in percent: ``96.2 / 84.7``."""
    return f"{100 * agg['precision']:.1f} / {100 * agg['recall']:.1f}"


def pct(x: float, digits: int = 1) -> str:
    """A fraction as a percentage string (``nan`` stays ``-``)."""
    return "-" if x != x else f"{100 * x:.{digits}f}"


def dec(x: float, digits: int = 3) -> str:
    """A number with ``digits`` decimals (``nan`` stays ``-``)."""
    return "-" if x != x else f"{x:.{digits}f}"


#: Columns of :func:`pr_f1_rows` (the layout of the paper's Table 1, then geometry).
PR_F1_COLUMNS = ["scenes", "#scenes", "initial P / R (%)", "initial F1",
                 "optimized P / R (%)", "optimized F1", "F1 95% interval", "untyped F1",
                 *GEOMETRY_COLUMNS]


def pr_f1_rows(groups: Mapping[str, Sequence[Mapping]], *, total: str | None = "all"
               ) -> list[list]:
    """Table 1 rows from :func:`score_record` results grouped by scene family.

    Each row: name, scene count, initial ``P / R`` and F1, optimized ``P / R`` and F1
    (typed, micro-averaged over the group's edges, percent), its bootstrap interval
    (:func:`bootstrap_f1`), optimized untyped F1 and the geometry of the matched boxes
    (:func:`geometry_cells`).  ``total`` adds a row over every group (None: no total row).
    """
    items = list(groups.items())
    if total is not None:
        items.append((total, [r for recs in groups.values() for r in recs]))
    rows = []
    for name, recs in items:
        init = aggregate_prf(recs, "initial.typed")
        opt = aggregate_prf(recs, "optimized.typed")
        unt = aggregate_prf(recs, "optimized.untyped")
        rows.append([name, len(recs),
                     pr_cell(init) if init["n"] else "-", pct(init["f1"]),
                     pr_cell(opt) if opt["n"] else "-", pct(opt["f1"]),
                     interval_cell(bootstrap_f1(recs)), pct(unt["f1"]), *geometry_cells(recs)])
    return rows


# ------------------------------------------------------------------------- tables
def _cell(v: Any, floatfmt: str) -> str:
    if isinstance(v, float):
        return "-" if v != v else format(v, floatfmt)
    return "" if v is None else str(v)


def markdown_table(columns: Sequence[str], rows: Iterable[Sequence[Any]],
                   floatfmt: str = ".3g") -> str:
    """A GitHub Markdown table (floats formatted with ``floatfmt``, NaN as ``-``)."""
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    for row in rows:
        cells = [_cell(v, floatfmt).replace("|", "\\|") for v in row]
        if len(cells) != len(columns):
            raise ValueError(f"row has {len(cells)} cells, table has {len(columns)} columns")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def write_table(out: str | Path, name: str, columns: Sequence[str],
                rows: Sequence[Sequence[Any]], *, title: str = "", note: str = "",
                floatfmt: str = ".3g") -> str:
    """Write ``out/<name>.md`` and ``out/<name>.csv`` atomically; return the Markdown.

    The CSV keeps full float precision (``repr``); the Markdown is for reading.
    """
    out = Path(out)
    md = (f"## {title}\n\n" if title else "") + markdown_table(columns, rows, floatfmt)
    if note:
        md += f"\n{note}\n"
    atomic.write_text(out / f"{name}.md", md)
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(columns)
    writer.writerows([["" if v is None else v for v in row] for row in rows])
    atomic.write_text(out / f"{name}.csv", buf.getvalue())
    return md


# ------------------------------------------------------------------------- plots
def _figure(**kwargs: Any):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt, plt.subplots(**kwargs)


def _save(fig, path: str | Path) -> None:  # noqa: ANN001
    import matplotlib.pyplot as plt

    with atomic.atomic_path(path) as tmp:
        # no Software/date stamp: the same figure gives the same bytes
        fig.savefig(tmp, dpi=110, metadata={"Software": None})
    plt.close(fig)


def plot_series(path: str | Path, series: Mapping[str, tuple[Sequence[float], Sequence[float]]],
                *, xlabel: str, ylabel: str, title: str = "", logx: bool = False,
                logy: bool = False) -> None:
    """Line plot of ``{label: (xs, ys)}`` written atomically to ``path`` (PNG)."""
    plt, (fig, ax) = _figure(figsize=(6.4, 4.2))
    for label, (xs, ys) in series.items():
        ax.plot(list(xs), list(ys), marker="o", label=label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    if logx:
        ax.set_xscale("log")
    if logy:
        ax.set_yscale("log")
    ax.grid(True, alpha=0.3)
    if series:
        ax.legend()
    fig.tight_layout()
    _save(fig, path)


def plot_bars(path: str | Path, groups: Mapping[str, Mapping[str, float]], *, ylabel: str,
              title: str = "", ylim: tuple[float, float] | None = None) -> None:
    """Grouped bars: ``{category: {series: value}}`` (e.g. family -> initial/optimized F1)."""
    import numpy as np

    cats = list(groups)
    names = list(dict.fromkeys(n for g in groups.values() for n in g))
    # the legend beside the bars, never over them
    plt, (fig, ax) = _figure(figsize=(max(6.4, 0.9 * len(groups) + 2) + 2.2, 4.2))
    width = 0.8 / max(len(names), 1)
    x = np.arange(len(cats))
    for k, name in enumerate(names):
        vals = [groups[c].get(name, np.nan) for c in cats]
        ax.bar(x + (k - (len(names) - 1) / 2) * width, vals, width, label=name)
    ax.set_xticks(x, cats, rotation=30 if len(cats) > 6 else 0)
    ax.set_ylabel(ylabel)
    if ylim:
        ax.set_ylim(*ylim)
    if title:
        ax.set_title(title)
    if names:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    ax.grid(True, axis="y", alpha=0.3)
    fig.tight_layout()
    _save(fig, path)


# ------------------------------------------------------------------------- checks
def regressions(actual: Mapping[str, Mapping[str, float]],
                expected: Mapping[str, Mapping[str, float]], *,
                higher_better: Iterable[str] = (), lower_better: Iterable[str] = (),
                tol: float = 1e-9) -> list[str]:
    """Where ``actual`` got worse than the stored ``expected`` figures (regression suite).

    Parameters
    ----------
    actual, expected : {case: {figure: value}}
        E.g. ``{"stack-0": {"f1": 0.96, "fixed": 2}}``.  A case or figure that is
        expected but missing from ``actual`` is a regression.
    higher_better, lower_better : figure names compared one-sidedly; any other figure
        in ``expected`` must match within ``tol``.
    tol : absolute slack.

    Returns
    -------
    list of str
        One line per regression (empty: nothing got worse).
    """
    up, down = set(higher_better), set(lower_better)
    out = []
    for case, figures in expected.items():
        got = actual.get(case)
        if got is None:
            out.append(f"{case}: missing (expected {dict(figures)})")
            continue
        for name, want in figures.items():
            have = got.get(name)
            if have is None or have != have:
                out.append(f"{case}: {name} missing (expected {want})")
            elif name in up and have < want - tol:
                out.append(f"{case}: {name} {have:.6g} < stored {want:.6g}")
            elif name in down and have > want + tol:
                out.append(f"{case}: {name} {have:.6g} > stored {want:.6g}")
            elif name not in up and name not in down and abs(have - want) > tol:
                out.append(f"{case}: {name} {have:.6g} != stored {want:.6g}")
    return out


def failures_markdown(summary) -> str:  # noqa: ANN001 - eval.runner.RunSummary
    """A Markdown list of the tasks that failed (empty string when none did)."""
    failures = summary.failures
    if not failures:
        return ""
    lines = [f"Failed tasks ({len(failures)} of {len(summary.records)}); tracebacks are in "
             "tasks/<id>.json:", ""]
    lines += [f"- `{tid}`: {err}" for tid, err in failures.items()]
    return "\n".join(lines) + "\n"
