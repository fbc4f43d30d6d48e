"""``unseen models make --out DIR``: a repository of furniture meshes for ``unseen retrieve``."""

from __future__ import annotations

import argparse
import json

from eval.run_checks import check_seed, comma_list
from pipeline.outdir import out_arg

EPILOG = """writes:
  DIR/<kind>_<nnn>.glb   one binary glTF mesh per model (glTF is y up; index says "up": "y")
  DIR/index.json         one entry per model: file, kind, variant, up, extents (m), params
  DIR/manifest.json      every file above with its size and SHA-256 (written last)

kinds and variants (synth_scenes.models): table four_legs/three_legs/pedestal, chair
board/posts/board_arms/posts_arms, shelf boards2..boards7, desk panels/drawers, sofa
arms/no_arms, monitor stand; with --kinds also box plain (not by default: a plain box
covers any solid structure and would be retrieved for every chunky object).  Each kind
cycles through its variants; proportions are drawn from the scene generator's ranges
with --seed.

Any folder of .glb/.obj/.ply meshes works as a repository too, with an index.json
{"models": [{"file": "chair_a.obj", "kind": "chair", "variant": "arms", "up": "z"}]}
("up" defaults to y for glTF, z otherwise), or without one (kind from the file name)."""

ACTIONS = ("make",)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("action", choices=ACTIONS, help="make: write a model repository")
    p.add_argument("--out", type=out_arg, required=True, help="output folder (created)")
    p.add_argument("--n-per-kind", type=int, default=None, metavar="K",
                   help="models per kind (default 12)")
    p.add_argument("--kinds", default=None, metavar="LIST",
                   help="comma-separated kinds (default: the furniture, table,chair,shelf,"
                        "desk,sofa,monitor; 'box' adds plain boxes)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the proportions")
    p.add_argument("--json", action="store_true", help="print a summary as JSON")


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from pipeline.errors import InputError
    from pipeline.outdir import check_out, output_folder
    from synth_scenes.models import FURNITURE, KINDS, N_PER_KIND, make_models, write_repository

    n = N_PER_KIND if args.n_per_kind is None else args.n_per_kind
    if n < 1 or n > 1000:
        raise InputError(f"--n-per-kind: must be 1-1000, got {n}")
    kinds = FURNITURE
    check_seed(args.seed)
    if args.kinds is not None:
        kinds = comma_list(args.kinds)
        bad = [k for k in kinds if k not in KINDS]
        if bad or not kinds:
            raise InputError(f"--kinds: unknown kind {', '.join(bad) or '(none)'}; "
                             f"choose from {', '.join(KINDS)}")
    check_out(args.out, command="models")
    specs = make_models(np.random.default_rng(args.seed), n, kinds)
    with output_folder(args.out, command="models") as tmp:
        index = write_repository(tmp, specs, seed=args.seed)
    counts: dict[str, int] = {}
    for e in index["models"]:
        counts[f"{e['kind']}:{e['variant']}"] = counts.get(f"{e['kind']}:{e['variant']}", 0) + 1
    if args.json:
        print(json.dumps({"out": str(args.out), "models": len(index["models"]),
                          "variants": counts}, indent=1))
    else:
        print(f"{len(index['models'])} models of {len(kinds)} kinds -> {args.out}")
    return 0
