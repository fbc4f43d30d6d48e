"""``unseen retrieve RESULT --models DIR --out DIR``: a repository model for every object."""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from eval.run_checks import check_seed, comma_list
from pipeline.outdir import out_arg

EPILOG = """RESULT is an 'unseen run' output folder (its arrangement.json: the imagined,
completed structure; initial.json with --structure initial) or an arrangement.json.

For each object (cuboids sharing an 'object' name) every repository model is stood
upright, scaled into the bounding box of the object's cuboids at sampled yaws and scored:
share of the model's surface covered by the cuboids + share of the cuboids' volume
covered by the model (0-2).  The best of each kind is refined with ICP against the points
the scan saw of the object, and the best overall is placed.

The run folder does not keep the points: give the scan with --scan (the INPUT that
'unseen run' read; it is read with run's default options and brought into the result's
world by its meta.camera_pose).  Without --scan there is no ICP and no picture over the
colour image (the models are still placed by the structure).

writes:
  DIR/retrieved.glb    the placed models (one node per object), the cuboids of smaller
                       objects (cuboid:<id>, grey) and the ground, glTF y up
  DIR/retrieval.json   per object: model file, kind, variant, 4x4 transform (model file
                       -> world, z up), score and its parts, ICP, runner-up, best per kind
  DIR/retrieval.png    the models over the colour image (with --scan) and a 3D view
  DIR/report.md        the table, command, options
  DIR/manifest.json

examples:
  unseen models make --out models
  unseen synth chair --out scenes/chair0 --seed 0 && unseen run scenes/chair0 --out res
  unseen retrieve res --models models --scan scenes/chair0 --out retrieved
  unseen retrieve res --models models --structure initial --kinds chair,table --out r2"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("result", type=Path, help="an 'unseen run' output folder or arrangement.json")
    p.add_argument("--models", type=Path, required=True, metavar="DIR",
                   help="model repository (unseen models make, or meshes + index.json)")
    p.add_argument("--out", type=out_arg, required=True, help="output folder (created)")
    p.add_argument("--structure", choices=("imagined", "initial"), default="imagined",
                   help="imagined (default): the completed arrangement.json; initial: "
                        "initial.json, the cuboids before imagining")
    p.add_argument("--scan", type=Path, default=None, metavar="INPUT",
                   help="the scan the result was made from (for ICP and the picture)")
    p.add_argument("--kinds", default=None, metavar="LIST",
                   help="only models of these kinds (the paper's keyword search)")
    p.add_argument("--fit", choices=("axis", "uniform"), default="axis",
                   help="scale models into the structure's box per axis (default) or "
                        "keeping their proportions")
    p.add_argument("--stretch-cost", type=float, default=None, metavar="X",
                   help="score lost, when kinds are compared, per factor of e of uneven "
                        "stretch of a model into the object's box (default 0.5; 0: the "
                        "paper's score alone)")
    p.add_argument("--no-icp", action="store_true", help="skip the ICP refinement")
    p.add_argument("--min-cuboids", type=int, default=2, metavar="N",
                   help="retrieve models for objects of at least N cuboids (default 2); "
                        "smaller objects (a book, a box) stay their cuboids, drawn grey")
    p.add_argument("--seed", type=int, default=0, help="seeds the score's samples")
    p.add_argument("--json", action="store_true", help="print retrieval.json's objects")


def _arrangement_path(result: Path, structure: str) -> Path:
    from pipeline.errors import InputError

    if result.is_dir():
        name = "arrangement.json" if structure == "imagined" else "initial.json"
        path = result / name
        if not path.is_file():
            raise InputError(f"{result}: no {name}; RESULT must be an 'unseen run' output "
                             "folder or an arrangement.json")
        return path
    if result.is_file():
        if structure == "initial":
            raise InputError(f"--structure initial: needs a run folder with initial.json, "
                             f"got the file {result}")
        return result
    raise InputError(f"{result}: no such file or folder")


def scan_world(scan_path: Path, arr):  # noqa: ANN001, ANN201
    """(scan, world points) of the scan a result was made from, in the result's world."""
    import numpy as np

    from pipeline.camera import check_same_frame, transform
    from pipeline.errors import InputError
    from pipeline.run import load
    from pipeline.units import to_metres

    if "camera_pose" not in arr.meta:
        raise InputError("--scan: the result has no meta.camera_pose to bring the scan into "
                         "its world")
    scan = load(scan_path)
    if scan.intrinsics is not None:  # a frame: the one the result was made from
        check_same_frame(arr.meta, scan.intrinsics, f"--scan {scan_path}")
    scale = arr.meta.get("input_scale")
    scan, _, _ = to_metres(scan, float(scale) if isinstance(scale, (int, float)) else None)
    T = np.asarray(arr.meta["camera_pose"], float)
    return scan, transform(T, np.asarray(scan.points, float))


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from pipeline.arrangement_io import read_arrangement
    from pipeline.errors import InputError
    from pipeline.outdir import check_out, output_folder
    from pipeline.progress import Progress
    from pipeline.retrieve import RetrieveConfig, load_repository, points_by_object, retrieve
    from pipeline.retrieve_output import write_outputs

    path = _arrangement_path(args.result, args.structure)
    check_seed(args.seed)
    kinds = None
    if args.kinds is not None:
        kinds = comma_list(args.kinds)
        if not kinds:
            raise InputError("--kinds: give at least one kind, e.g. --kinds chair,table")
    if args.min_cuboids < 1:
        raise InputError(f"--min-cuboids: must be at least 1, got {args.min_cuboids}")
    if args.stretch_cost is not None and not (np.isfinite(args.stretch_cost)
                                              and args.stretch_cost >= 0):
        raise InputError(f"--stretch-cost: a number >= 0, got {args.stretch_cost}")
    if args.scan is not None and not args.scan.exists():
        raise InputError(f"--scan {args.scan}: no such file or folder")
    check_out(args.out, command="retrieve")
    arr = read_arrangement(path)
    if not arr.cuboids:
        raise InputError(f"{path}: no cuboids to retrieve models for")
    models = load_repository(args.models, kinds, seed=args.seed)
    notes: list[str] = []
    points = image = intr = T = None
    if args.scan is not None:
        scan, world = scan_world(args.scan, arr)
        points = points_by_object(world, arr)
        image, intr = scan.image, scan.intrinsics
        T = np.asarray(arr.meta["camera_pose"], float)
        near = sum(len(p) for p in points.values())
        if near < 0.05 * len(world):
            notes.append(f"only {near} of {len(world)} scan points lie near the cuboids: is "
                         "--scan the input of this result?")
    else:
        notes.append("no --scan: no ICP refinement, models placed by the structure alone")
    cost = {} if args.stretch_cost is None else {"stretch_cost": args.stretch_cost}
    cfg = RetrieveConfig(fit=args.fit, icp=not args.no_icp, kinds=kinds, seed=args.seed, **cost)
    with Progress(None, "unseen retrieve") as bar:
        results = retrieve(arr, models, points, cfg, progress=lambda d, t: bar.update(),
                           min_cuboids=args.min_cuboids)
    if not results:
        notes.append(f"no object has {args.min_cuboids} or more cuboids: nothing retrieved "
                     "(--min-cuboids 1 retrieves for single cuboids too)")
    command = "unseen " + " ".join(shlex.quote(a) for a in sys.argv[1:]) \
        if len(sys.argv) > 1 and sys.argv[1] == "retrieve" else f"unseen retrieve {args.result}"
    header = {"command": command, "result": str(path), "structure": args.structure,
              "models": str(args.models), "n_models": len(models), "fit": args.fit,
              "stretch_cost": cfg.stretch_cost,
              "icp": (not args.no_icp) and args.scan is not None, "seed": args.seed,
              "kinds": list(kinds) if kinds else "all", "min_cuboids": args.min_cuboids}
    inputs = [args.result, args.models] + ([args.scan] if args.scan is not None else [])
    with output_folder(args.out, inputs=inputs, command="retrieve") as tmp:
        write_outputs(tmp, arr, models, results, header, notes, image, intr, T)
    if args.json:
        print((args.out / "retrieval.json").read_text(encoding="utf-8"), end="")
    else:
        summary = ", ".join(f"{r.object}: {r.best.kind}:{r.best.variant} ({r.best.score:.2f})"
                            for r in results)
        print(f"{len(results)} objects -> {args.out} [{summary}]")
    return 0
