"""``unseen demo``: the whole product on a built-in scene, in under a minute.

Synthesizes a default occluded scene (a table whose legs the top and the things on it
partly hide, and a stack of boxes whose lower boxes are hidden), scans it with the
virtual Kinect, runs the pipeline, checks the result in MuJoCo and PyBullet, scores
it against the ground truth and says where the pictures are.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from pipeline.outdir import out_arg

EPILOG = """outputs: OUT/scene (the synthetic scene directory with its ground truth) and
OUT/result (arrangement.json, scene.xml, scene.urdf, arrangement.glb, overlay.png,
view.png, report.md).  Exit 0 when the result stands in every check."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=out_arg, default=Path("demo_out"),
                   help="output folder (default: demo_out)")
    p.add_argument("--seed", type=int, default=2, help="scene seed (default 2)")
    p.add_argument("--family", default="demo",
                   help="scene family to synthesize (default: demo = table + hidden stack)")
    p.add_argument("--budget", type=float, default=10.0, help="search budget, seconds")


def run(args: argparse.Namespace) -> int:
    from eval.commands.synth import KINDS
    from eval.run_checks import check_seed
    from pipeline.errors import InputError
    from pipeline.outdir import check_out, output_folder

    check_seed(args.seed)
    if not (0.01 <= args.budget <= 86400):
        raise InputError(f"--budget: must be a positive number of seconds up to a day, got "
                         f"{args.budget}")
    if args.family not in KINDS:
        raise InputError(f"--family: unknown scene family {args.family!r}; choose one of: "
                         + ", ".join(KINDS))
    check_out(args.out, command="demo")
    t0 = time.perf_counter()
    out = Path(args.out)
    with output_folder(out, command="demo") as tmp:
        made, scan, initial, result, engines = _make(args, tmp, out)
    scene_dir, result_dir = out / "scene", out / "result"
    return _summary(args, made, initial, result, engines, scene_dir, result_dir, t0)


def _make(args: argparse.Namespace, tmp: Path, out: Path):
    from eval.run_full import check_engines, write_full_outputs
    from pipeline.errors import InputError
    from pipeline.imagine import imagine
    from pipeline.priors import ImagineConfig
    from pipeline.progress import Progress
    from pipeline.run import RunConfig, run_scan
    from synth_scenes.scene_dir import make_scene_dir

    scene_dir, result_dir = tmp / "scene", tmp / "result"
    with Progress(5, "unseen demo") as bar:
        bar.update(0, "synthesizing the scene")
        # the demo camera looks from the front, so the table hides the tower's lower boxes
        ranges = {"azimuth": (-115.0, -65.0), "elevation": (15.0, 25.0),
                  "distance": (1.5, 3.0)} \
            if args.family == "demo" else None
        made = make_scene_dir(args.family, scene_dir, seed=args.seed, view_ranges=ranges)
        if made.truth.status != "ok":
            raise InputError(f"--family {args.family}: no physically valid scene for seed "
                             f"{args.seed}; try another --seed")
        bar.update(1, "initial cuboids")
        config = RunConfig(stage="initial", imagine=ImagineConfig(budget=args.budget))
        first = run_scan(scene_dir, config)
        scan, initial, report0 = first.scan, first.initial, first.initial_report
        bar.update(1, "imagining the unseen")
        result = imagine(initial, first.evidence, config.imagine)
        bar.update(1, "engines")
        engines = check_engines(result.arrangement, 0.7)
        bar.update(1, "writing")
        write_full_outputs(result_dir, scan, initial, result, report0, engines,
                           f"unseen demo --out {out} --seed {args.seed}", 0)
        bar.update(1)
    return made, scan, initial, result, engines


def _summary(args, made, initial, result, engines, scene_dir: Path, result_dir: Path,
             t0: float) -> int:
    from eval.metrics import score_arrangement

    score = score_arrangement(result.arrangement, made.truth.arrangement, initial=initial)
    final = result.arrangement
    rep = result.report
    n_fixed = sum(c.type == "fixed" for c in final.contacts)
    print(f"scene:   {scene_dir} ({args.family}, seed {args.seed}: "
          f"{len(made.truth.arrangement.cuboids)} true cuboids, "
          f"{len(made.truth.arrangement.contacts)} true contacts)")
    print(f"result:  {len(initial.cuboids)} initial cuboids -> {len(final.cuboids)} cuboids"
          f"{' (' + str(len(rep.hallucinated)) + ' hallucinated)' if rep.hallucinated else ''}, "
          f"{len(final.contacts)} contacts ({n_fixed} fixed), added "
          f"{rep.added_volume_m3 * 1000:.1f} litres; search {rep.search['seconds']:.2f} s")
    verdicts = {"analytic": bool(rep.stable)}
    verdicts.update({k: bool(v["stable"]) for k, v in engines.items()})
    print("stands:  " + ", ".join(f"{k} {'yes' if v else 'NO'}" for k, v in verdicts.items()))
    if score.initial is not None:
        print(f"contact graph F1 (typed): initial {100 * score.initial.typed.f1:.1f} -> "
              f"optimized {100 * score.optimized.typed.f1:.1f}; untyped "
              f"{100 * score.initial.untyped.f1:.1f} -> {100 * score.optimized.untyped.f1:.1f}")
    print(f"mean IoU with the truth: {score.mean_iou:.3f}")
    print(f"pictures: {result_dir / 'overlay.png'}  {result_dir / 'view.png'}")
    print(f"report:   {result_dir / 'report.md'}   ({time.perf_counter() - t0:.1f} s in all)")
    return 0 if all(verdicts.values()) else 1
