"""Accuracy of the initial cuboids (section 4.1) on synthetic scans with ground truth.

For every scene family, seed, noise model and with/without edge refinement: the 3D IoU
between each ground-truth object's *visible part* and the union of the cuboids the run
attributed to it, and the number of cuboids per object.

The visible part of a ground-truth cuboid is the tight box, in that cuboid's own frame,
of the scan points whose instance id is that cuboid (clipped to the cuboid, so depth
noise cannot enlarge it); an object's visible part is the union over its cuboids.
IoU of unions is estimated on 60 000 uniform samples of their joint bounding box.

    python -m eval.initial_accuracy --out results/initial --seeds 1000 1001
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

FAMILIES = ("stack", "counterweight", "bridge", "table", "chair", "shelf", "wall_shelf", "desk",
            "sofa", "room")


def _inside(q: np.ndarray, c: np.ndarray, R: np.ndarray, s: np.ndarray) -> np.ndarray:
    return np.all(np.abs((q - c) @ R) <= s / 2 + 1e-12, axis=1)


def union_iou(a: list, b: list, rng: np.random.Generator, samples: int = 60_000) -> float:
    """IoU of two unions of boxes ``[(c, R, s), ...]`` by uniform sampling."""
    from pipeline.model import box_corners

    if not a or not b:
        return 0.0
    boxes = a + b
    corners = box_corners(np.stack([x[0] for x in boxes]), np.stack([x[1] for x in boxes]),
                          np.stack([x[2] for x in boxes])).reshape(-1, 3)
    lo, hi = corners.min(0), corners.max(0)
    q = lo + rng.random((samples, 3)) * (hi - lo)
    ina = np.zeros(samples, bool)
    inb = np.zeros(samples, bool)
    for c, R, s in a:
        ina |= _inside(q, c, R, s)
    for c, R, s in b:
        inb |= _inside(q, c, R, s)
    u = (ina | inb).sum()
    return float((ina & inb).sum() / u) if u else 0.0


def visible_parts(scene_dir: Path) -> dict[str, list]:
    """Object name -> list of visible boxes (c, R, s) of its ground-truth cuboids."""
    from pipeline.arrangement_io import read_arrangement
    from pipeline.camera import transform
    from pipeline.scan_io import load_scan

    gt = read_arrangement(scene_dir / "scene.json")
    scan = load_scan(scene_dir)
    world = transform(scan.T_world_cam, scan.points)
    out: dict[str, list] = {}
    for k, cb in enumerate(gt.cuboids):
        sel = scan.instance == k + 1
        if sel.sum() < 30:
            continue
        loc = np.clip((world[sel] - cb.center) @ cb.rotation, -cb.size / 2, cb.size / 2)
        lo, hi = loc.min(0), loc.max(0)
        out.setdefault(cb.object or cb.id, []).append(
            (cb.center + cb.rotation @ ((lo + hi) / 2), cb.rotation, np.maximum(hi - lo, 1e-3)))
    return out


def evaluate_scene(scene_dir: Path, edges: bool, rng: np.random.Generator,
                   segmentation: str = "instance") -> list[dict]:
    from pipeline.initial import initial_cuboids
    from pipeline.scan_io import load_scan

    truth = visible_parts(scene_dir)
    scan = load_scan(scene_dir)
    arr, report = initial_cuboids(scan, rng=np.random.default_rng(0), edges=edges,
                                  segmentation=segmentation)
    rows = []
    for obj, vis in truth.items():
        pred = [(c.center, c.rotation, c.size) for c in arr.cuboids if c.object == obj]
        rows.append({"object": obj, "gt_parts": len(vis), "cuboids": len(pred),
                     "iou": union_iou(vis, pred, rng),
                     "edge_refined": report["counts"]["edge_refined"],
                     "time": report["timings"]["total"]})
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1000, 1001])
    ap.add_argument("--families", nargs="+", default=list(FAMILIES))
    ap.add_argument("--segmentation", default="instance",
                    help="instance: object masks, slabs split objects into parts (default); "
                         "parts: per-part masks; cluster: no masks")
    args = ap.parse_args(argv)
    os.environ.setdefault("MUJOCO_GL", "egl")
    from synth_scenes.scene_dir import make_scene_dir

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    records = []
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as tmp:
        for fam in args.families:
            for seed in args.seeds:
                for noise in ("none", "kinect"):
                    d = Path(tmp) / f"{fam}_{seed}_{noise}"
                    try:
                        make_scene_dir(fam, d, seed, noise=noise)
                    except Exception as exc:  # noqa: BLE001 - a family may fail to sample
                        sys.stderr.write(f"skip {fam} {seed} {noise}: {exc}\n")
                        continue
                    for edges in (False, True):
                        for r in evaluate_scene(d, edges, rng, args.segmentation):
                            records.append({"family": fam, "seed": seed, "noise": noise,
                                            "edges": edges, **r})
                    sys.stderr.write(f"{fam} {seed} {noise} done\n")
    (out / "initial_accuracy.json").write_text(json.dumps(records, indent=1))
    (out / "initial_accuracy.md").write_text(table(records))
    sys.stdout.write(table(records))
    return 0


def table(records: list[dict]) -> str:
    lines = ["| family | noise | edges | objects | mean IoU (visible part) | median IoU | "
             "cuboids / object | GT parts / object |", "|---|---|---|---|---|---|---|---|"]
    keys = sorted({(r["family"], r["noise"], r["edges"]) for r in records},
                  key=lambda k: (FAMILIES.index(k[0]) if k[0] in FAMILIES else 99, k[1], k[2]))
    for fam, noise, edges in keys + [("all", n, e) for n in ("none", "kinect") for e in (False, True)]:
        rs = [r for r in records if (fam == "all" or r["family"] == fam) and r["noise"] == noise
              and r["edges"] == edges]
        if not rs:
            continue
        iou = np.array([r["iou"] for r in rs])
        lines.append(f"| {fam} | {noise} | {'on' if edges else 'off'} | {len(rs)} | "
                     f"{iou.mean():.3f} | {np.median(iou):.3f} | "
                     f"{np.mean([r['cuboids'] for r in rs]):.2f} | "
                     f"{np.mean([r['gt_parts'] for r in rs]):.2f} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
