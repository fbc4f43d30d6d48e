"""``unseen synth KIND --out DIR --seed N``: a valid synthetic scene with ground truth, scanned."""

from __future__ import annotations

import argparse
import json
import sys

from eval.run_checks import check_seed
from pipeline.outdir import out_arg

#: the scene families (same order as ``synth_scenes.registry.FAMILIES``; a test checks it)
KINDS = ("stack", "counterweight", "bridge", "table", "chair", "shelf", "wall_shelf", "desk",
         "sofa", "room", "demo")

EPILOG = """families:
  stack          --n-boxes N boxes (default 3-10): tower, staggered pier, pyramid or piles
  counterweight  a plank over a block's edge, held by a weight (stable only as a whole)
  bridge         pillars and decks, maybe boxes on top
  table          top + 4 legs fused, things on the top        chair   seat, legs, back fused
  shelf          bookshelf: boards fused to sides, books (some leaning), boxes
  wall_shelf     boards fused to wall:0 (hanging), things on them, maybe a leaning book
  desk           desk with monitor, keyboard, books            sofa    seat, back, arms, cushions
  room           floor, two walls and a mix of the above (20-60 cuboids; --n-objects N)

writes DIR/scene.json (ground truth: cuboids b0.., object names, typed contacts) and
DIR/scan/ (color.png, depth.png 16-bit mm, instance.png 16-bit with id k = cuboids[k-1],
intrinsics.json, camera_pose.json, points.ply; view<k>/ per view when --views > 1).
A scene is kept only if it stands (analytic statics and MuJoCo settling; --engine all adds
PyBullet); rejected samples are redrawn.  Same command and seed: byte-identical files.
Exit 0 written, 1 no valid scene found within --max-attempts, 2 bad input."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("kind", metavar="KIND", help="scene family: " + ", ".join(KINDS))
    parser.add_argument("--out", type=out_arg, required=True, metavar="DIR", help="scene directory (created)")
    parser.add_argument("--seed", type=int, default=0, metavar="N", help="random seed (default 0)")
    parser.add_argument("--views", type=int, default=1, metavar="K", help="camera views (default 1)")
    parser.add_argument("--noise", default="kinect", choices=("kinect", "none"),
                        help="depth noise model (default kinect)")
    parser.add_argument("--n-boxes", type=int, default=None, metavar="N", help="stack: number of boxes")
    parser.add_argument("--n-objects", type=int, default=None, metavar="N", help="room: number of objects")
    parser.add_argument("--renderer", default="mujoco", choices=("mujoco", "pybullet"),
                        help="render backend of the virtual sensor (default mujoco)")
    parser.add_argument("--engine", default="all", choices=("mujoco", "pybullet", "all"),
                        help="engines a scene must stand in to be kept (default all: "
                             "MuJoCo and PyBullet)")
    parser.add_argument("--max-attempts", type=int, default=None, metavar="N",
                        help="samples to try before giving up (default 25)")
    parser.add_argument("--json", action="store_true", help="print a JSON summary")


#: Bounds of the options (memory and time: ``--views 1000`` peaked at 22 GB).
MAX_VIEWS = 64
MB_PER_VIEW = 25
MAX_BOXES = 200
MAX_OBJECTS = 100
MAX_ATTEMPTS = 1000


class _NothingWritten(Exception):
    """No valid scene: leave --out as it was."""

    def __init__(self, result) -> None:
        super().__init__("no valid scene")
        self.result = result


def run(args: argparse.Namespace) -> int:
    try:
        return _run(args)
    except _NothingWritten as exc:
        gt = exc.result.truth
        if args.json:
            print(json.dumps(_summary(args, exc.result), indent=2))
        print(f"unseen synth: no valid {args.kind} scene in {gt.attempts} attempts (seed "
              f"{args.seed}); nothing written. Try another --seed.", file=sys.stderr)
        return 1


def _summary(args: argparse.Namespace, result) -> dict:
    gt = result.truth
    arr = gt.arrangement
    return {"out": str(args.out), "family": args.kind, "seed": args.seed,
            "status": gt.status, "cuboids": len(arr.cuboids),
            "objects": len({c.object for c in arr.cuboids}),
            "contacts": len(arr.contacts),
            "fixed": sum(c.type == "fixed" for c in arr.contacts),
            "attempts": gt.attempts, "validation": gt.validation.verdicts(),
            "views": args.views, "points": result.n_points, "seconds": round(gt.seconds, 3)}


def _run(args: argparse.Namespace) -> int:
    from pipeline.errors import InputError
    from pipeline.outdir import check_out, output_folder
    from pipeline.progress import Progress
    from synth_scenes.scene_dir import make_scene_dir

    if args.kind not in KINDS:
        raise InputError(f"KIND: unknown scene family {args.kind!r}; choose one of: "
                         + ", ".join(KINDS))
    for name, top in (("n_boxes", MAX_BOXES), ("n_objects", MAX_OBJECTS),
                      ("max_attempts", MAX_ATTEMPTS)):
        v = getattr(args, name)
        if v is not None and not 1 <= v <= top:
            raise InputError(f"--{name.replace('_', '-')}: must be from 1 to {top}, got {v}")
    check_seed(args.seed)
    if args.views < 1:
        raise InputError(f"--views: must be from 1 to {MAX_VIEWS}, got {args.views}")
    if args.views > MAX_VIEWS:
        raise InputError(f"--views: must be from 1 to {MAX_VIEWS}, got {args.views} (each view "
                         f"takes about {MB_PER_VIEW} MB of memory while the scan is made: "
                         f"{args.views} views would need about "
                         f"{args.views * MB_PER_VIEW / 1000:.1f} GB)")
    check_out(args.out, command="synth")
    engines = ("mujoco", "pybullet") if args.engine == "all" else (args.engine,)
    with output_folder(args.out, command="synth") as tmp, Progress(None, f"synth {args.kind}") as bar:
        result = make_scene_dir(args.kind, tmp, args.seed, views=args.views,
                                noise=args.noise, renderer=args.renderer, engines=engines,
                                max_attempts=args.max_attempts, n_boxes=args.n_boxes,
                                n_objects=args.n_objects)
        bar.update()
        if result.truth.status != "ok":
            raise _NothingWritten(result)
    gt = result.truth
    summary = _summary(args, result)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        stands = " and ".join(engines)
        print(f"wrote {args.out}: {args.kind}, {summary['cuboids']} cuboids in "
              f"{summary['objects']} objects, {summary['contacts']} contacts "
              f"({summary['fixed']} fixed); stands (analytic, {stands}) after "
              f"{gt.attempts} attempt(s); scan: {args.views} view(s), "
              f"{result.n_points} points")
    return 0
