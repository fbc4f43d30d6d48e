"""``unseen dataset make|verify``: benchmark datasets of synthetic scenes with exact contacts.

``make`` plans the scenes (:func:`synth_scenes.dataset.plan`), makes each one as a task
of :func:`eval.runner.run_tasks` (local processes or a Dask cluster), then writes
``manifest.jsonl``, the dataset card ``DATASET.md`` with ``stats.png``, and optionally the
BOP export with its hashes (``bop_manifest.json``).  ``verify`` checks every scene's
files against the manifest's hashes, the BOP export against its own, and the dataset as a
whole (:func:`synth_scenes.dataset.verify_dataset`).
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
from collections import Counter
from pathlib import Path

from eval.run_checks import check_seed
from pipeline.outdir import out_arg

EPILOG = """\
make: scene i is of family FAMILIES[i % F] with seed --first-seed + i (so 'unseen synth
FAMILY --seed SEED' with the same options writes it again); every scene stands in
analytic statics, MuJoCo and PyBullet, and a sample that does not is redrawn (counted in
the manifest's "attempts").  Splits are stratified per family.  Knobs (camera ranges,
noise, renderer, views, scale, clutter and number of objects per family) come from
--config FILE (.toml or .yaml, see synth_scenes.dataset.read_config); flags override it.
A rerun with the same options resumes: scenes already made and unchanged are kept.
--dask ADDRESS: the workers write the scenes, so --out must be on a disk they all see.
Layout: DIR/<split>/<family>-<seed>/ (scene directories), DIR/manifest.jsonl,
DIR/dataset.json, DIR/DATASET.md, DIR/stats.png, DIR/bop/ and DIR/bop_manifest.json
(--bop), DIR/.run/ (task records and timings).
verify: every scene's files against their hashes in the manifest, bop/ against
bop_manifest.json, the manifest's length against dataset.json, and no scene folder the
manifest does not list:
  unseen dataset verify data
Exit 0 done; 1 some scene failed (how many and the first error on stderr; rerun to
resume) or verify found a mismatch; 2 bad input."""

#: Subcommands.
ACTIONS = ("make", "verify")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("action", choices=ACTIONS, help="make a dataset, or verify one against "
                                                   "its manifest")
    p.add_argument("dir", nargs="?", type=Path, default=None, metavar="DIR",
                   help="verify: the dataset folder")
    p.add_argument("--out", type=out_arg, default=None, metavar="DIR",
                   help="make: the dataset folder (created; a rerun resumes)")
    p.add_argument("--families", default=None, metavar="LIST",
                   help="'all' (default) or a comma list, e.g. table,chair,room")
    p.add_argument("--n", type=int, default=None, help="number of scenes (default 100)")
    p.add_argument("--split", default=None, metavar="TRAIN/VAL/TEST",
                   help="proportions (default 80/10/10)")
    p.add_argument("--views", default=None, metavar="K|LO-HI",
                   help="camera views per scene, e.g. 1-3 (default 1)")
    p.add_argument("--first-seed", type=int, default=None, metavar="S",
                   help="seed of scene 0 (default 0)")
    p.add_argument("--config", type=Path, default=None, metavar="FILE",
                   help="randomisation knobs (.toml or .yaml)")
    group = p.add_mutually_exclusive_group()
    group.add_argument("--workers", type=int, default=1, help="local processes (default 1)")
    group.add_argument("--dask", default=None, metavar="ADDRESS",
                       help="a running Dask scheduler, e.g. tcp://127.0.0.1:8786")
    p.add_argument("--bop", action="store_true",
                   help="also write the BOP layout under DIR/bop (synth_scenes.bop)")


def build_config(args: argparse.Namespace):
    """The :class:`~synth_scenes.dataset.DatasetConfig` of the flags over ``--config``."""
    from dataclasses import replace

    from pipeline.errors import InputError
    from synth_scenes import dataset as ds

    cfg = ds.read_config(args.config) if args.config is not None else ds.DatasetConfig()
    changes = {}
    if args.families is not None:
        changes["families"] = ds.parse_families(args.families)
    if args.n is not None:
        if not 1 <= args.n <= 1_000_000:
            raise InputError(f"--n: must be from 1 to 1000000, got {args.n}")
        changes["n"] = args.n
    if args.split is not None:
        changes["split"] = ds.parse_split(args.split)
    if args.views is not None:
        changes["views"] = ds.parse_views(args.views)
    if args.first_seed is not None:
        check_seed(args.first_seed, "--first-seed")
        changes["first_seed"] = args.first_seed
    return replace(cfg, **changes)


def run(args: argparse.Namespace) -> int:
    from eval.commands.evaluate import pin_threads

    pin_threads()
    if args.action == "verify":
        return _verify(args)
    return _make(args)


def _verify(args: argparse.Namespace) -> int:
    from pipeline.errors import InputError
    from synth_scenes.dataset import verify_dataset

    if args.dir is None:
        raise InputError("verify: give the dataset folder, e.g. unseen dataset verify data")
    if not args.dir.is_dir():
        raise InputError(f"{args.dir}: " + ("is not a folder" if args.dir.exists()
                                            else "no such folder"))
    n, whole, scenes = verify_dataset(args.dir)
    for line in whole + scenes:
        print(f"unseen dataset verify: {line}", file=sys.stderr)
    print(f"{args.dir}: {n - len(scenes)} of {n} scenes match the manifest"
          + (f"; {len(whole)} problem{'s' if len(whole) != 1 else ''} with the dataset as a "
             "whole" if whole else ""))
    return 1 if whole or scenes else 0


def _prepare_out(out: Path, cfg) -> None:  # noqa: ANN001 - DatasetConfig
    """Refuse a folder that is not this dataset; record the configuration."""
    from pipeline import atomic
    from pipeline.errors import InputError
    from pipeline.outdir import check_out
    from synth_scenes.dataset import CONFIG_FILE

    check_out(out)
    want = json.dumps(cfg.to_json(), indent=1, sort_keys=True) + "\n"
    have_cfg = out / CONFIG_FILE
    if have_cfg.is_file():
        if have_cfg.read_text(encoding="utf-8") != want:
            raise InputError(f"--out {out}: holds a dataset made with other options "
                             f"(see {have_cfg}); resume with the same options or choose a "
                             "new folder")
    elif out.is_dir() and any(out.iterdir()):
        raise InputError(f"--out {out}: a folder of other files; choose a new or empty folder")
    out.mkdir(parents=True, exist_ok=True)
    atomic.write_text(have_cfg, want)


def _make(args: argparse.Namespace) -> int:
    from eval.runner import Task, failure_line, run_tasks
    from pipeline import atomic
    from pipeline.errors import InputError
    from synth_scenes import dataset as ds

    if args.out is None:
        raise InputError("make: --out DIR is required (the dataset folder)")
    if args.dir is not None:
        raise InputError(f"make: unexpected {args.dir}; the folder goes in --out")
    if args.workers < 1:
        raise InputError(f"--workers: must be at least 1, got {args.workers}")
    cfg = build_config(args)
    if args.dask:
        from eval.commands.evaluate import check_dask

        check_dask(args.dask)
    out = args.out
    _prepare_out(out, cfg)
    plans = ds.plan(cfg)
    work = out / ".run"
    for sp in plans:  # a scene whose files changed since its record is made again
        rec = work / "tasks" / f"{sp.id}.json"
        if rec.is_file():
            try:
                line = json.loads(rec.read_text(encoding="utf-8")).get("result")
            except ValueError:
                line = None
            if not line or ds.check_scene(out, line) is not None:
                rec.unlink()
    tasks = [Task(sp.id, _scene_task, {"plan": sp, "config": cfg},
                  cost=sp.views * (4.0 if sp.family == "room" else 1.0),
                  where={"root": str(out.resolve())}) for sp in plans]
    summary = run_tasks(tasks, work, seed=cfg.first_seed, workers=args.workers,
                        dask=args.dask, label=f"dataset {out.name}", progress=None)
    lines = [summary.results[sp.id] for sp in plans if sp.id in summary.results]
    atomic.write_text(out / ds.MANIFEST, "".join(ds.manifest_line(r) + "\n" for r in lines))
    write_card(out, cfg, lines, _command(args))
    if args.bop and lines:
        from synth_scenes.bop import export_bop

        export_bop(out)
        ds.write_bop_manifest(out)
    _print_summary(out, lines, summary, sys.stdout)
    line = failure_line([summary])
    if line is not None:
        print(f"unseen dataset make: {line.replace('tasks/', '.run/tasks/')}; rerun the same "
              "command to resume", file=sys.stderr)
        return 1
    return 0


def _scene_task(rng, plan, config, root):  # noqa: ANN001 - a runner task
    """Make one scene (runs on a worker).  ``rng`` is unused: the plan carries the seed."""
    from synth_scenes.dataset import make_scene

    return make_scene(plan, config, root)


def _command(args: argparse.Namespace) -> str:
    cmd = ["unseen", "dataset", "make", "--out", str(args.out)]
    for flag in ("families", "n", "split", "views", "first_seed", "config"):
        v = getattr(args, flag)
        if v is not None:
            cmd += ["--" + flag.replace("_", "-"), str(v)]
    if args.bop:
        cmd.append("--bop")
    return shlex.join(cmd)


def family_stats(lines: list[dict]) -> dict[str, dict]:
    """Per family: scenes per split and mean counts (the dataset card's table)."""
    import numpy as np

    out: dict[str, dict] = {}
    for fam in dict.fromkeys(r["family"] for r in lines):
        rs = [r for r in lines if r["family"] == fam]
        splits = Counter(r["split"] for r in rs)
        c = {k: np.array([r["counts"][k] for r in rs], dtype=float)
             for k in ("cuboids", "objects", "contacts", "fixed", "points", "views")}
        out[fam] = {"scenes": len(rs), "train": splits.get("train", 0),
                    "val": splits.get("val", 0), "test": splits.get("test", 0),
                    **{f"{k}_mean": float(v.mean()) for k, v in c.items()},
                    "cuboids_range": (int(c["cuboids"].min()), int(c["cuboids"].max())),
                    "resampled": int(sum(r["attempts"] - 1 for r in rs)),
                    "stands_all": int(sum(all(r["stands"].values()) for r in rs))}
    return out


def write_card(out: Path, cfg, lines: list[dict], command: str) -> None:  # noqa: ANN001
    """``DATASET.md`` and ``stats.png``: formats, conventions, how it was made, statistics."""
    from eval.commands.evaluate import package_versions
    from eval.suites._common import markdown_table, plot_bars
    from pipeline import atomic

    stats = family_stats(lines)
    rows = [[fam, s["scenes"], f"{s['train']}/{s['val']}/{s['test']}",
             f"{s['cuboids_mean']:.1f} ({s['cuboids_range'][0]}-{s['cuboids_range'][1]})",
             f"{s['objects_mean']:.1f}", f"{s['contacts_mean']:.1f}", f"{s['fixed_mean']:.1f}",
             f"{s['views_mean']:.2f}", f"{s['points_mean']:.0f}", s["resampled"],
             f"{s['stands_all']}/{s['scenes']}"] for fam, s in stats.items()]
    table = markdown_table(["family", "scenes", "train/val/test", "cuboids (range)", "objects",
                            "contacts", "fixed", "views", "points", "resampled",
                            "stand in all 3"], rows)
    versions = ", ".join(f"{k} {v}" for k, v in package_versions().items() if v)
    cfg_json = json.dumps(cfg.to_json(), indent=1, sort_keys=True)
    card = f"""# Dataset card

{len(lines)} synthetic indoor scenes of cuboids with exact ground truth: every cuboid's
pose and size, which parts form one object, and the typed contact graph (`touch` or
`fixed`, with the floor `ground` and walls `wall:<k>`).  Every scene stands under
gravity in rigid-block statics, MuJoCo and PyBullet.

## Made with

    {command}

{versions}.  The configuration is in `dataset.json`:

```json
{cfg_json}
```

## Files

- `<split>/<family>-<seed>/`: one scene directory per scene, the format of `unseen synth`:
  `scene.json` (the ground truth arrangement: `cuboids` with `center`, `rotation` (3x3,
  columns are the box axes in world), `size` (full edges, metres), `object`; `contacts`
  `{{a, b, type}}`; `supports`; `meta` with family, seed, options and verdicts) and
  `scan/`: `color.png` (8-bit RGB), `depth.png` (16-bit millimetres, 0 = no reading),
  `instance.png` (16-bit, k = `cuboids[k-1]`, 0 = floor, walls or nothing),
  `intrinsics.json` (`width height fx fy cx cy`), `camera_pose.json` (4x4
  camera-to-world), `points.ply` (world points with instance ids); with several views the
  per-view files are in `scan/view<k>/` and `points.ply` is their fusion.
- `manifest.jsonl`: one line per scene in plan order: `id`, `index`, `seed`, `family`,
  `split`, `path`, `parameters`, `counts`, `stands` (analytic, MuJoCo, PyBullet),
  `attempts` (samples drawn; the ones before the last did not stand and were redrawn),
  `files` (SHA-256 per file).  `unseen dataset verify DIR` checks the files against it.
- `bop/` (when made with `--bop`): the BOP layout (`scene_camera.json`, `scene_gt.json`,
  `scene_gt_info.json`, `rgb/`, `depth/`, `mask_visib/`); `obj_id` is the cuboid's
  instance id and its model a centred box of `obj_size_mm` (see `synth_scenes/bop.py`);
  `bop_manifest.json` holds the SHA-256 of each of its files, which `verify` checks.
- `stats.png`: the statistics below as bars.

## Conventions

SI units, z up, gravity -z, density 1000 kg/m^3, friction 0.7.  Cameras are OpenCV
pinhole (x right, y down, z forward), Kinect v1 intrinsics; depth has Kinect-like noise
unless the configuration says `noise = "none"`.  Scene `i` has seed
`first_seed + i`; `unseen synth FAMILY --seed SEED` makes it again from the same options.

## Reading it

```python
from synth_scenes.dataset import Dataset
for s in Dataset("{out.name}", split="train"):
    s.views[0].depth, s.views[0].instance, s.graph, s.poses, s.sizes
```

## Statistics per family

{table}
Means per scene.  Resampled: samples that did not stand in all three checks and were
drawn again.
"""
    atomic.write_text(out / "DATASET.md", card)
    groups = {fam: {"cuboids": s["cuboids_mean"], "contacts": s["contacts_mean"],
                    "fixed": s["fixed_mean"]} for fam, s in stats.items()}
    if groups:
        plot_bars(out / "stats.png", groups, ylabel="mean per scene",
                  title=f"{len(lines)} scenes: cuboids, contacts and fixed contacts per family")


def _print_summary(out: Path, lines: list[dict], summary, stream) -> None:  # noqa: ANN001
    by_fam: dict[str, list[float]] = {}
    secs = {r.id: r.seconds for r in summary.records if r.ok and not r.resumed}
    for r in lines:
        if r["id"] in secs:
            by_fam.setdefault(r["family"], []).append(secs[r["id"]])
    print(f"{out}: {len(lines)} scenes ({summary.n_resumed} kept from an earlier run), "
          f"{summary.n_failed} failed, {summary.wall_seconds:.1f} s on {summary.backend}",
          file=stream)
    if by_fam:
        print("family          made   s/scene (one process)", file=stream)
        for fam, s in by_fam.items():
            print(f"{fam:<15} {len(s):>4}   {sum(s) / len(s):7.2f}", file=stream)
