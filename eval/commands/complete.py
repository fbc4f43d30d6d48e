"""``unseen complete PARTIAL --template GOOD --out DIR``: structure-guided completion.

Both scans go through the pipeline (:func:`pipeline.run.run_scan`, ``unseen run``'s
defaults); :func:`pipeline.complete.complete` matches their objects' cuboids, aligns the
good scan to the partial one and carries its points over.  Writes ``completed.ply``,
``transform.json``, ``completion.png`` and ``report.md`` (with ``manifest.json``,
atomically).
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
from pathlib import Path

import numpy as np

from eval.run_checks import check_seed

EPILOG = """\
PARTIAL and GOOD are anything `unseen run` reads with no flags (a scene directory, an
RGB-D folder, a depth file of a known data set, a .ply/.pcd/.npz cloud); both are run
through the whole pipeline here (--stage initial: section 4.1 only, faster).  The
object completed is --object (default: the object with the most points in PARTIAL);
the template object is --template-object (default: the one with the most points in
GOOD).  Object names are those of arrangement.json's "object" fields (table0, cluster2).

steps: the two objects' cuboids are matched by spectral matching on part dimensions
(Leordeanu and Hebert 2005; a pair is pruned when the heights differ by more than
--height-tol and the horizontal lengths by more than --length-tol, the paper's 0.05 m
and 0.1 m), the good scan is aligned by a matched pair of footprint edges projected to
the ground (the best of all candidate pairs by point distance), refined by ICP
(Open3D point-to-plane, kept upright), the parts are matched again by their aligned
positions, and the points are carried over: --transfer parts carries each matched
part's points into its partner box, scaled to its size (the rest by the affine map of
the matched boxes); --transfer rigid moves them all by the rigid transform (the paper);
--transfer auto (default) does both and keeps the one whose points lie nearer the
partial scan's points and less in space it saw empty.
Carried points the partial scan's depth saw through are dropped (--no-carve keeps them).

outputs in DIR:
  completed.ply    x y z, red green blue, source (0 = partial scan, 1 = from GOOD)
  transform.json   4x4 T_partial_template, the matching, alignment and ICP figures
  completion.png   the partial points, the completed cloud and the partial boxes
  report.md        the same in words

example (synthetic: a chair seen once, completed from another chair seen from 8 views):
  unseen synth chair --out scenes/chair_a --seed 3
  unseen synth chair --out scenes/chair_b --seed 7 --views 8
  unseen complete scenes/chair_a --template scenes/chair_b --out completed
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("partial", help="the partial scan (anything unseen run reads)")
    p.add_argument("--template", required=True, metavar="GOOD",
                   help="a good (e.g. multi-view) scan of an object of the same kind")
    p.add_argument("--out", required=True, help="output folder (created)")
    p.add_argument("--object", default=None, metavar="NAME",
                   help="the partial scan's object to complete (default: most points)")
    p.add_argument("--template-object", default=None, metavar="NAME",
                   help="the template's object (default: most points)")
    p.add_argument("--transfer", default="auto", choices=["auto", "parts", "rigid"],
                   help="parts: each matched part's points into its partner box; rigid: the "
                        "whole template moved rigidly (the paper); auto (default): both, "
                        "keeping the one nearer the partial points and less in space the "
                        "partial scan saw empty")
    p.add_argument("--edge-pairs", default="all", choices=["all", "matched"],
                   help="which pairs of parts give candidate alignments: all (default; each "
                        "judged by its transfer) or only the spectrally matched ones (the "
                        "paper)")
    p.add_argument("--no-carve", action="store_true",
                   help="keep carried points that the partial scan's depth saw through")
    p.add_argument("--height-tol", type=float, default=0.05,
                   help="prune part pairs whose heights differ by more (and lengths by more "
                        "than --length-tol), metres (default 0.05)")
    p.add_argument("--length-tol", type=float, default=0.10,
                   help="... and whose horizontal lengths differ by more, metres (default 0.1)")
    p.add_argument("--icp-distance", type=float, default=0.05,
                   help="ICP's largest correspondence distance, metres (default 0.05)")
    p.add_argument("--stage", default="full", choices=["full", "initial"],
                   help="pipeline run on both scans: full (default) or initial (4.1 only)")
    p.add_argument("--budget", type=float, default=10.0,
                   help="seconds of search per scan for the full pipeline (default 10)")
    p.add_argument("--seed", type=int, default=0, help="random seed (RANSAC, sampling)")
    p.add_argument("--json", action="store_true", help="print one JSON summary line")


def _config(args: argparse.Namespace):
    from pipeline.complete import CompleteConfig
    from pipeline.errors import InputError

    for flag, v in (("--height-tol", args.height_tol), ("--length-tol", args.length_tol),
                    ("--icp-distance", args.icp_distance)):
        if not (np.isfinite(v) and 0 < v <= 10):
            raise InputError(f"{flag}: must be a length in metres in (0, 10], got {v}")
    if not (np.isfinite(args.budget) and 0 < args.budget <= 86400):
        raise InputError(f"--budget: must be a positive number of seconds up to a day, "
                         f"got {args.budget}")
    check_seed(args.seed)
    return CompleteConfig(height_tol=args.height_tol, length_tol=args.length_tol,
                          icp_distance=args.icp_distance, transfer=args.transfer,
                          carve=not args.no_carve, edge_pairs=args.edge_pairs)


def _run_config(args: argparse.Namespace):
    from pipeline.priors import ImagineConfig
    from pipeline.run import RunConfig

    return RunConfig(seed=args.seed, stage=args.stage,
                     imagine=ImagineConfig(budget=float(args.budget)))


def _check_input(path: str, flag: str) -> None:
    from pipeline.errors import InputError

    if not str(path).strip():
        raise InputError(f"{flag}: empty path; give a scan (scene folder, RGB-D folder, cloud)")
    if not Path(path).exists():
        raise InputError(f"{flag} {path}: no such file or folder")


# ---------------------------------------------------------------------------- files
PARTIAL_COLOUR = (40, 110, 230)
TEMPLATE_COLOUR = (240, 130, 20)


def write_completed_ply(path: Path, points: np.ndarray, source: np.ndarray) -> None:
    """Binary little-endian PLY: x y z (float32), red green blue, source (uchar)."""
    from pipeline import atomic

    n = len(points)
    rec = np.zeros(n, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"),
                             ("green", "u1"), ("blue", "u1"), ("source", "u1")])
    rec["x"], rec["y"], rec["z"] = points[:, 0], points[:, 1], points[:, 2]
    col = np.where(source[:, None] == 0, PARTIAL_COLOUR, TEMPLATE_COLOUR).astype(np.uint8)
    rec["red"], rec["green"], rec["blue"] = col[:, 0], col[:, 1], col[:, 2]
    rec["source"] = source
    header = ("ply\nformat binary_little_endian 1.0\n"
              "comment unseen complete: source 0 = partial scan, 1 = carried from the template\n"
              f"element vertex {n}\nproperty float x\nproperty float y\nproperty float z\n"
              "property uchar red\nproperty uchar green\nproperty uchar blue\n"
              "property uchar source\nend_header\n")
    atomic.write_bytes(path, header.encode("ascii") + rec.tobytes())


def _box_edges(parts) -> list[np.ndarray]:
    from pipeline.model import box_corners

    corners = box_corners(parts.centers, parts.rotations, parts.sizes)
    edges = [(a, b) for a in range(8) for b in range(a + 1, 8)
             if bin(a ^ b).count("1") == 1]
    return [corners[k][[a, b]] for k in range(len(corners)) for a, b in edges]


def completion_picture(path: Path, completion, title: str = "", truth_boxes=None,
                       max_points: int = 6000) -> None:
    """Two 3D panels, same view: the partial object's points with its cuboids, and the
    completed cloud (partial blue, carried template orange).  ``truth_boxes``: a
    :class:`pipeline.complete.Parts` drawn grey in both (the true object, if known)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pipeline import atomic

    rng = np.random.default_rng(0)
    pts, src = completion.points, completion.source

    def thin(mask):
        idx = np.flatnonzero(mask)
        if len(idx) > max_points:
            idx = np.sort(rng.choice(idx, max_points, replace=False))
        return pts[idx]

    part, tmpl = thin(src == 0), thin(src == 1)
    allp = np.concatenate([part, tmpl]) if len(tmpl) else part
    lo, hi = allp.min(0), allp.max(0)
    mid, r = (lo + hi) / 2, float((hi - lo).max()) / 2 + 1e-3
    fig = plt.figure(figsize=(9.0, 4.4))
    panels = [("partial scan: points and cuboids", [(part, PARTIAL_COLOUR)]),
              ("completed", [(part, PARTIAL_COLOUR), (tmpl, TEMPLATE_COLOUR)])]
    for k, (name, clouds) in enumerate(panels):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        for c, colour in clouds:
            if len(c):
                ax.scatter(c[:, 0], c[:, 1], c[:, 2], s=0.6, c=[np.array(colour) / 255],
                           depthshade=False, linewidths=0)
        if truth_boxes is not None:
            for seg in _box_edges(truth_boxes):
                ax.plot(seg[:, 0], seg[:, 1], seg[:, 2], color="0.55", lw=0.6)
        if k == 0:
            for seg in _box_edges(completion.partial_parts):
                ax.plot(seg[:, 0], seg[:, 1], seg[:, 2], color="k", lw=0.7)
        ax.set_xlim(mid[0] - r, mid[0] + r)
        ax.set_ylim(mid[1] - r, mid[1] + r)
        ax.set_zlim(max(lo[2] - 0.02, mid[2] - r), max(lo[2] - 0.02, mid[2] - r) + 2 * r)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=25, azim=-60)
        ax.set_title(name, fontsize=9)
        ax.tick_params(labelsize=6)
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    with atomic.atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=80, metadata={"Software": None}, format="png")
    plt.close(fig)


def _rounded(value, digits: int = 9):
    """``value`` with every float rounded to ``digits`` significant digits: Open3D's ICP
    sums in threads, so its RMSE and the scores built on it move in the last bits from
    run to run; the file must not."""
    if isinstance(value, dict):
        return {k: _rounded(v, digits) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_rounded(v, digits) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(f"{float(value):.{digits}g}")
    return value


def transform_json(c, config, extra: dict | None = None) -> dict:
    """The ``transform.json`` record of a :class:`pipeline.complete.Completion`."""
    return {"format": "unseen.completion", "version": 1, "units": "m",
            "T_partial_template": np.round(c.T_partial_template, 9).tolist(),
            "objects": {"template": c.objects[0], "partial": c.objects[1]},
            "matching": [{"template": a, "partial": b, "confidence": round(conf, 6)}
                         for a, b, conf in c.matching_ids()],
            "spectral_matching": [{"template": a, "partial": b, "confidence": round(conf, 6)}
                                  for a, b, conf in c.matching_ids(spectral=True)],
            "candidates": c.spectral.candidates if c.spectral else c.matching.candidates,
            "pruned": c.spectral.pruned if c.spectral else c.matching.pruned,
            "alignment": _rounded({k: v for k, v in c.alignment.items()
                                   if k != "edge_transform"}),
            "edge_transform": np.round(np.asarray(c.alignment.get("edge_transform",
                                                                  np.eye(4))), 9).tolist(),
            "transfer": c.transfer, "carved": c.carved,
            "points": {"partial": int((c.source == 0).sum()),
                       "template": int((c.source == 1).sum())},
            "config": {"height_tol": config.height_tol, "length_tol": config.length_tol,
                       "icp_distance": config.icp_distance, "carve": config.carve,
                       "transfer": config.transfer, "edge_pairs": config.edge_pairs},
            **(extra or {})}


def report_markdown(c, record: dict, command: str) -> str:
    icp = c.alignment.get("icp", {})
    poor = _poor_fit(icp)
    lines = ["# unseen complete", "", f"- command: `{command}`",
             f"- partial object: {c.objects[1]} ({record['points']['partial']} points), "
             f"template object: {c.objects[0]}",
             f"- spectral matching: {len(c.spectral.pairs) if c.spectral else 0} pairs of "
             f"{len(c.template_parts)} template parts and {len(c.partial_parts)} partial parts "
             f"({record['candidates']} candidate pairs, {record['pruned']} pruned by "
             f"height/length); once aligned: {len(c.matching.pairs)} pairs",
             f"- ground-edge alignment: best of {c.alignment.get('candidates', 0)} candidate "
             f"poses (parts {c.alignment.get('edge_pair')}), transfer score "
             f"{c.alignment.get('edge_score', float('nan')):.4f} m",
             f"- ICP: fitness {icp.get('fitness_before', 0):.3f} -> {icp.get('fitness', 0):.3f}, "
             f"RMSE {icp.get('rmse_before', 0):.4f} -> {icp.get('rmse', 0):.4f} m"
             f"{'' if icp.get('kept', True) else ' (not kept: it moved away)'}"
             + (f" **warning: {poor}**" if poor else ""),
             f"- transfer: {c.transfer}; {record['points']['template']} points carried over, "
             f"{c.carved} dropped where the partial scan saw through them", "",
             "## Matching", "", "Once aligned (the transfer follows it):", "",
             "| template | partial | confidence |", "|---|---|---|"]
    lines += [f"| {a} | {b} | {conf:.3f} |" for a, b, conf in c.matching_ids()]
    lines += ["", "Spectral (the alignment came from it):", "",
              "| template | partial | confidence |", "|---|---|---|"]
    lines += [f"| {a} | {b} | {conf:.3f} |" for a, b, conf in c.matching_ids(spectral=True)]
    lines += ["", "## T_partial_template", "", "```"]
    lines += ["  ".join(f"{v: .6f}" for v in row) for row in c.T_partial_template]
    lines += ["```", "", "![completion](completion.png)", ""]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    from pipeline import atomic
    from pipeline.complete import complete
    from pipeline.errors import InputError
    from pipeline.outdir import check_out, output_folder
    from pipeline.progress import Progress
    from pipeline.run import run_scan

    _check_input(args.partial, "PARTIAL")
    _check_input(args.template, "--template")
    config = _config(args)
    check_out(args.out, command="complete")
    out = Path(args.out)
    run_cfg = _run_config(args)
    command = "unseen complete " + " ".join(shlex.quote(a) for a in sys.argv[2:]) \
        if len(sys.argv) > 1 and sys.argv[1] == "complete" else f"unseen complete {args.partial}"
    with output_folder(out, inputs=[args.partial, args.template],
                       command="complete") as tmp:
        # progress on stderr, drawn only when it is a terminal
        with Progress(3, "unseen complete") as bar:
            bar.update(0, note=f"pipeline on {args.partial}")
            partial = run_scan(args.partial, run_cfg)
            bar.update(1, note=f"pipeline on {args.template}")
            template = run_scan(args.template, run_cfg)
            bar.update(1, note="matching, aligning, carrying points over")
            try:
                c = complete(partial, template, config, partial_object=args.object,
                             template_object=args.template_object,
                             rng=np.random.default_rng(args.seed))
            except ValueError as exc:
                raise InputError(str(exc)) from None
            bar.update(1, note="done")
        record = transform_json(c, config, {"partial": str(args.partial),
                                            "template": str(args.template)})
        write_completed_ply(tmp / "completed.ply", c.points, c.source)
        atomic.write_text(tmp / "transform.json", json.dumps(record, indent=1) + "\n")
        completion_picture(tmp / "completion.png", c,
                           title=f"{c.objects[1]} completed from {c.objects[0]} "
                                 f"({c.transfer} transfer)")
        atomic.write_text(tmp / "report.md", report_markdown(c, record, command))
    icp = c.alignment.get("icp", {})
    line = {"out": str(out), "matched": len(c.matching.pairs),
            "partial_points": record["points"]["partial"],
            "template_points": record["points"]["template"],
            "icp_fitness": icp.get("fitness"), "icp_rmse": icp.get("rmse")}
    if args.json:
        print(json.dumps(line))
    else:
        print(f"{c.objects[1]}: {len(c.matching.pairs)} parts matched, "
              f"{line['template_points']} points carried over to {line['partial_points']}, "
              f"ICP fitness {icp.get('fitness', 0):.2f} -> {out}")
    poor = _poor_fit(icp)
    if poor:
        print(f"unseen complete: warning: {poor}", file=sys.stderr)
    return 0


#: Below this ICP fitness (the share of partial points within ``icp_distance`` of the
#: aligned template) the template does not explain the partial object.
POOR_FITNESS = 0.1


def _poor_fit(icp: dict) -> str | None:
    """The warning for an alignment that explains almost none of the partial points."""
    f = icp.get("fitness")
    if f is None or f >= POOR_FITNESS:
        return None
    return (f"ICP fitness {f:.2f}: fewer than {POOR_FITNESS:.0%} of the partial object's "
            "points lie near the aligned template; the objects may not be of one kind, and "
            "the completion is not to be trusted")
