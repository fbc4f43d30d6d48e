"""``unseen score PRED.json GT [--json]``: score a predicted arrangement against ground truth."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

EPILOG = """\
GT is a scene directory (its scene.json is the truth) or an arrangement.json.
Predicted cuboids match true ones through the scan's instance ids when they carry
them (extra "instance"), else by 3D IoU with Hungarian assignment; every match needs a
3D IoU of at least --min-iou (default 0.1): a box that names a part it does not overlap
is unmatched, its contacts count as false and the part's as missed.  Reported:
contact-graph precision/recall/F1 over typed edges (same pair, same type) and untyped
edges, for the optimized graph and the initial one (every touching pair among the
observed boxes, all 'touch'), the paper's size error (equations 5-6) and per-cuboid IoU.
Exit 0, or 2 on bad input."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("prediction", type=Path,
                        help="predicted arrangement.json (or the unseen run folder holding it)")
    parser.add_argument("truth", type=Path, help="scene directory (scene.json) or arrangement.json")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--initial", type=Path, default=None,
                        help="initial arrangement (default: the prediction's observed boxes)")
    parser.add_argument("--graph", choices=("union", "listed", "geometry"), default="union",
                        help="edges of a graph: listed contacts, touching geometry, or both "
                             "(default: union)")
    parser.add_argument("--min-iou", type=float, default=None,
                        help="smallest 3D IoU of any match, by instance id or by IoU "
                             "(default 0.1)")
    parser.add_argument("--per-cuboid", action="store_true",
                        help="also list every matched cuboid with its IoU")


def truth_path(path: Path) -> Path:
    """The ground-truth file named by ``path``: a scene directory's scene.json or the file."""
    from pipeline.errors import InputError

    if path.is_dir():
        scene = path / "scene.json"
        if not scene.is_file():
            raise InputError(f"{path}: a scene directory needs scene.json (the ground truth)")
        return scene
    if not path.exists():
        raise InputError(f"{path}: no such file or scene directory")
    return path


def prediction_path(path: Path) -> Path:
    """The predicted arrangement named by ``path``: a file, or a run folder's arrangement.json."""
    from pipeline.errors import InputError

    if path.is_dir():
        found = path / "arrangement.json"
        if not found.is_file():
            raise InputError(f"{path}: a result folder needs arrangement.json (unseen run writes it)")
        return found
    return path


def run(args: argparse.Namespace) -> int:
    from eval.metrics import MIN_MATCH_IOU, score_arrangement
    from pipeline.arrangement_io import read_arrangement
    from pipeline.errors import InputError

    min_iou = MIN_MATCH_IOU if args.min_iou is None else args.min_iou
    if not 0.0 <= min_iou <= 1.0:
        raise InputError(f"--min-iou: must be between 0 and 1, got {min_iou}")
    pred_file = prediction_path(args.prediction)
    pred = read_arrangement(pred_file)
    gt_file = truth_path(args.truth)
    gt = read_arrangement(gt_file)
    if not gt.cuboids:
        raise InputError(f"{gt_file}: the truth has no cuboids, so there is nothing to match or "
                         "score against; give the scene's ground truth")
    initial = read_arrangement(args.initial) if args.initial is not None else None
    score = score_arrangement(pred, gt, initial=initial, graph=args.graph, min_iou=min_iou)
    if args.json:
        out = {"prediction": str(pred_file), "truth": str(gt_file), **score.to_json()}
        print(json.dumps(out, indent=1))
        return 0
    print(report(score, str(pred_file), str(gt_file), per_cuboid=args.per_cuboid))
    return 0


def report(score, pred_name: str, gt_name: str, per_cuboid: bool = False) -> str:  # noqa: ANN001
    """A readable summary of a :class:`eval.metrics.Score`."""
    m = score.matching
    n_inst = sum(h == "instance" for h in m.how)
    n_obj = sum(h == "object" for h in m.how)
    lines = [
        f"prediction: {pred_name} ({score.n_pred} cuboids)",
        f"truth:      {gt_name} ({score.n_gt} cuboids)",
        f"matched {len(m.pairs)} of {score.n_gt} true cuboids ({n_inst} by instance id, "
        f"{n_obj} by IoU within their object, {len(m.pairs) - n_inst - n_obj} by IoU); "
        f"{len(m.unmatched_pred)} predicted unmatched; "
        f"mean IoU {score.mean_iou:.3f} (matched boxes {score.matched_iou:.3f}, "
        f"side error {score.side_error:.3f})",
        "",
        f"contact graph ({score.graph_source})   precision   recall      F1   edges pred/true",
    ]
    rows = [("optimized", score.optimized)]
    if score.initial is not None:
        rows.insert(0, ("initial", score.initial))
    for name, g in rows:
        for kind, prf in (("typed", g.typed), ("untyped", g.untyped)):
            lines.append(f"  {name:<9} {kind:<8}       {100 * prf.precision:6.1f}%  "
                         f"{100 * prf.recall:6.1f}%  {100 * prf.f1:6.1f}   {prf.n_pred}/{prf.n_gt}")
    wrong = [f"  + {a} - {b} {t}  (predicted, not true)" for a, b, t in score.optimized.false_positives]
    wrong += [f"  - {a} - {b} {t}  (true, missed)" for a, b, t in score.optimized.false_negatives]
    if wrong:
        lines += ["", "optimized graph, wrong typed edges:"] + wrong
    if score.size is not None:
        s = score.size
        lines += ["", f"size error (paper eqs 5-6): {s.error:.3f} over {s.n_changed} sides changed "
                      f"by > 5% (signed improvement {s.improvement:+.3f}); mean relative side error "
                      f"{s.mean_init:.3f} initial -> {s.mean_opt:.3f} optimized"]
    if per_cuboid and m.pairs:
        lines += ["", "cuboid -> truth      IoU   initial IoU  how"]
        for k, (p, g) in enumerate(m.pairs):
            init = "" if score.iou_initial is None else f"{score.iou_initial[k]:.3f}"
            lines.append(f"  {p} -> {g}  {score.iou[k]:.3f}  {init:>11}  {m.how[k]}")
    if m.unmatched_gt:
        lines += ["", "true cuboids without a prediction: " + ", ".join(m.unmatched_gt)]
    lines += [f"note: {n}" for n in score.notes]
    return "\n".join(lines)
