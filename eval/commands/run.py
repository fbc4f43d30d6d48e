"""``unseen run INPUT --out DIR``: scan -> arrangement.

Stage ``initial`` (section 4.1) writes ``arrangement.json`` (the initial cuboids, no
contacts), ``overlay.png``, ``view.png`` and ``report.md``.  The full pipeline (the
default, :mod:`eval.run_full`) calls :func:`run_initial` and continues from its result.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

R = "../shared/data/real"
EPILOG = f"""\
inputs:
  a scene directory (unseen synth):  unseen run scenes/table0 --out out --stage initial
  an RGB-D folder with color.png, depth.png (16-bit mm), intrinsics.json
  [camera_pose.json, instance.png, scribbles.png]:  unseen run frame_dir --out out
  a point cloud (.ply, .pcd ascii/binary/binary_compressed with 'label', .npz 'pc'):
                                     unseen run cloud.pcd --out out

the real scans in {R} load with no flag (a depth file of a known data set
brings its colour image, encoding and intrinsics: pipeline.scan_io.known_layout);
explicit flags override, and the same works for any folder with them:
  mOSD organised PCD with labels (object id = label // 10, table labels -> background):
    unseen run {R}/osd_stacked_boxes/test16.pcd --out out/osd16
  Shao/RAPter Kinect boxes (float32 .dat metres; derived/<x>_rgb_640x480.png; TIANJIAS K):
    unseen run {R}/shao_kinect_boxes/3boxes_depth16bits.dat --out out/shao3
  Metric3D NYU (registered jpg + mm png; K and scale from test_annotations.json):
    unseen run {R}/metric3d_nyu/sync_depth_00050.png --out out/nyu50
  Open3D test data: NYU raw (little-endian PGM disparity), TUM (depth / 5000), SUN
  (bit-rotated mm, cut at 7 m); Kinect default K 525,525,319.5,239.5:
    unseen run {R}/open3d_testdata_rgbd/NYU_depth.pgm --out out/nyu_raw
    unseen run {R}/open3d_testdata_rgbd/TUM_depth.png --out out/tum
    unseen run {R}/open3d_testdata_rgbd/SUN_depth.png --out out/sun
  SUN RGB-D (mmdet3d) frame, derived mm depth, K from 000001_calib.txt:
    unseen run {R}/sunrgbd_mmdet3d/derived/000001_depth_mm.png --out out/sunrgbd1
  SUN RGB-D points only (upright, z up):  unseen run {R}/sunrgbd_mmdet3d/000001_lidar.npz --out out/s1pc
  the same with explicit flags, e.g. TUM:
    unseen run {R}/open3d_testdata_rgbd --color TUM_color.png --depth TUM_depth.png \\
      --depth-scale 5000 --intrinsics 525,525,319.5,239.5 --out out/tum

The floor: with a camera pose (a scene directory's scan/camera_pose.json, a multi-view
folder, --pose) the floor is the pose's world z = 0, and RANSAC only refines it; so is
--floor-height H with --up (H metres along up in the input frame):
    unseen run frame_dir --out out --up=-y --floor-height -1.2
Without either the floor is the lowest large plane RANSAC finds; if it is not found, say
which way is up in the input frame: --up=-y (camera frames, y down), --up z (z-up clouds).

exit status: 0 the result stands; 1 it is the best effort and does not (report.md names
the boxes nothing could hold: several real frames above end so); 2 bad input.
"""


def add_frame_arguments(p: argparse.ArgumentParser) -> None:
    """The flags that say how to read an RGB-D frame (shared with ``unseen edit``)."""
    p.add_argument("--color", help="colour image file (absolute, or relative to INPUT: a scene "
                                   "directory's scan/ first, then INPUT itself)")
    p.add_argument("--depth", help="depth file (16-bit PNG/PGM or float32 .dat), found like --color")
    p.add_argument("--intrinsics", help="fx,fy,cx,cy or an intrinsics.json (default: INPUT's)")
    p.add_argument("--depth-format", default="auto",
                   choices=["auto", "png", "nyu-disparity", "sun-bitrot", "float32-dat"],
                   help="depth encoding (auto: .dat -> float32-dat, else png / --depth-scale)")
    p.add_argument("--depth-scale", type=float, default=None,
                   help="raw depth units per metre for png (default 1000 = mm; TUM: 5000)")


def frame_options(args: argparse.Namespace) -> dict:
    """The :class:`pipeline.run.LoadOptions` fields of :func:`add_frame_arguments`."""
    return {"color": args.color, "depth": args.depth, "intrinsics": args.intrinsics,
            "depth_format": args.depth_format, "depth_scale": args.depth_scale}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("input", help="scene dir, RGB-D folder, depth file, or .ply/.pcd/.npz cloud")
    p.add_argument("--out", required=True, help="output folder (created)")
    p.add_argument("--stage", default="full", choices=["initial", "full"],
                   help="full (default): initial cuboids, then extension, contact types and "
                        "refinement; initial: section 4.1 only")
    p.add_argument("--budget", type=float, default=10.0,
                   help="seconds for imagining the unseen: the contact search, searching again "
                        "without boxes nothing can hold up, and dropping glue joints (the best "
                        "found so far is kept); refinement then gets what is left, at least a "
                        "tenth of it; work-clock seconds (pipeline/workclock.py), so the same "
                        "scan gives the same result on any machine")
    p.add_argument("--mu", type=float, default=0.7,
                   help="friction coefficient (default 0.7): used by the search, written to "
                        "scene.xml / scene.urdf and recorded as meta.mu for check and export")
    p.add_argument("--check-engines", action="store_true",
                   help="settle the result in MuJoCo and PyBullet and report their verdicts")
    p.add_argument("--no-symmetry", action="store_true",
                   help="do not hallucinate wholly occluded parts (fourth legs) by symmetry "
                        "(the same as --disable symmetry)")
    p.add_argument("--disable", default="", metavar="PRIOR[,PRIOR...]",
                   help="switch priors off (see README, 'The method'): " + ", ".join(
                       _prior_names()))
    add_frame_arguments(p)
    p.add_argument("--max-depth", type=float, default=None, help="ignore depth beyond this (m)")
    p.add_argument("--scale", type=float, default=None,
                   help="metres per input unit (0.001 for a cloud in mm); default: a bare cloud "
                        "whose extent is not 0.2-50 m is rescaled by a power of ten (noted in "
                        "report.md, meta.input_scale), a depth scan is refused")
    p.add_argument("--up", help="up direction in the input frame: -y, z, or x,y,z")
    p.add_argument("--floor-height", type=float, default=None, metavar="H",
                   help="the floor's height in metres along up in the input frame (with "
                        "--up, or along a camera pose's up), e.g. -1.2 for a camera held "
                        "1.2 m above the floor with --up=-y: the floor comes from it and "
                        "RANSAC only refines it (a plane within 5 deg and 5 cm), so the "
                        "floor may be out of the picture")
    p.add_argument("--pose", metavar="FILE",
                   help="camera-to-world pose (a 4x4 JSON, or an earlier run's "
                        "arrangement.json: its meta.camera_pose) replacing INPUT's own "
                        "camera_pose.json; its world is z up with the floor at z = 0")
    p.add_argument("--instance", help="instance id image (16-bit, 0 = none)")
    p.add_argument("--scribbles", help="scribble image: one stroke id/colour per object")
    p.add_argument("--segmentation", default="auto",
                   choices=["auto", "parts", "instance", "cluster"],
                   help="auto: per-part ids of a scene directory (parts), else instance ids as "
                        "objects, else scribbles, else clustering")
    p.add_argument("--cell", type=float, default=None,
                   help="voxel size as a fraction of the scene diameter (default 0.005)")
    p.add_argument("--no-edges", action="store_true", help="skip the Canny edge refinement")
    p.add_argument("--seed", type=int, default=0, help="random seed (RANSAC)")


def _prior_names() -> list[str]:
    from pipeline.priors import BY_NAME, GROUPS

    return [*BY_NAME, *GROUPS]


def config_from_args(args: argparse.Namespace):
    """The :class:`pipeline.run.RunConfig` of ``unseen run``'s options."""
    from pipeline.priors import ImagineConfig
    from pipeline.run import LoadOptions, RunConfig

    disabled = {n for n in str(getattr(args, "disable", "") or "").split(",") if n.strip()}
    if getattr(args, "no_symmetry", False):
        disabled.add("symmetry")
    load = LoadOptions(**frame_options(args), up=args.up, max_depth=args.max_depth, instance=args.instance,
                       scribbles=args.scribbles,
                       floor_height=getattr(args, "floor_height", None),
                       pose=getattr(args, "pose", None), scale=getattr(args, "scale", None))
    imagine = ImagineConfig(budget=args.budget, mu=args.mu, disabled=frozenset(disabled))
    return RunConfig(seed=args.seed, segmentation=args.segmentation, cell=args.cell,
                     edges=not args.no_edges, stage=args.stage, imagine=imagine, load=load)


def run_initial(args: argparse.Namespace, progress=None):
    """Load INPUT and run section 4.1: returns (scan_input, arrangement, report dict)."""
    from dataclasses import replace

    from pipeline.run import run_scan

    res = run_scan(args.input, replace(config_from_args(args), stage="initial"), progress)
    return res.scan, res.initial, res.initial_report


def write_initial_outputs(out: Path, scan, arr, report: dict, command: str, seed: int) -> None:
    """arrangement.json, overlay.png, view.png, report.md (into ``out``, an
    :func:`pipeline.outdir.output_folder`'s temporary folder)."""
    import numpy as np

    from pipeline import atomic
    from pipeline.arrangement_io import write_arrangement
    from pipeline.camera import Intrinsics, look_at
    from pipeline.pictures import depth_picture, draw_overlay, draw_view, splat_points, write_png

    out.mkdir(parents=True, exist_ok=True)
    write_arrangement(arr, out / "arrangement.json")
    T = np.asarray(arr.meta["camera_pose"], float)
    world = report["world"]
    labels = report["labels"]
    if scan.image is not None:
        base, intr = scan.image, scan.intrinsics
    elif scan.depth is not None:
        base, intr = depth_picture(scan.depth), scan.intrinsics
    else:  # a cloud without a camera: render the points from a virtual camera
        intr = Intrinsics.kinect_v1()
        lo, hi = np.percentile(world, [2, 98], axis=0)
        mid, r = (lo + hi) / 2, float(np.linalg.norm(hi - lo))
        T = look_at(mid + np.array([0.0, -0.9 * r, 0.6 * r]), mid)
        base = splat_points(world, scan.colors, intr, T)
    tags = [[c.id for c in arr.cuboids]]
    overlay = draw_overlay(base, intr, T, [(arr, "palette", "solid")], labels=tags)
    write_png(out / "overlay.png", overlay)
    colors = scan.colors
    view = draw_view(world[labels >= 0], colors[labels >= 0] if colors is not None else None,
                     [(arr, "palette", "solid")],
                     title=f"{len(arr.cuboids)} initial cuboids, {report['counts']['objects']} objects")
    write_png(out / "view.png", view)
    atomic.write_text(out / "report.md", report_markdown(arr, report, command, seed))


def report_markdown(arr, report: dict, command: str, seed: int) -> str:
    try:
        from importlib.metadata import version
        ver = version("unseen")
    except Exception:  # noqa: BLE001
        ver = "unknown"
    c = report["counts"]
    lines = ["# unseen run: initial cuboids", "",
             f"- command: `{command}`", f"- seed: {seed}", f"- unseen {ver}",
             f"- segmentation: {report['segmentation']}",
             f"- voxel cell: {report['cell'] * 1000:.1f} mm, plane threshold "
             f"{report['plane_threshold'] * 1000:.1f} mm", "",
             "## Timings", "", "| step | seconds |", "|---|---|"]
    lines += [f"| {k} | {v:.3f} |" for k, v in report["timings"].items()]
    lines += ["", "## Counts", "", "| what | count |", "|---|---|"]
    lines += [f"| {k} | {v} |" for k, v in c.items()]
    lines += ["", "## Cuboids", "", "| id | object | points | size (m) | centre (m) |",
              "|---|---|---|---|---|"]
    for cb in arr.cuboids:
        lines.append(f"| {cb.id} | {cb.object} | {cb.extra.get('points', '')} | "
                     f"{' x '.join(f'{v:.3f}' for v in cb.size)} | "
                     f"{', '.join(f'{v:.3f}' for v in cb.center)} |")
    lines += ["", "Supports: " + ", ".join(s.id for s in arr.supports)]
    if report["notes"]:
        lines += ["", "Notes: " + "; ".join(report["notes"])]
    return "\n".join(lines) + "\n"


def run(args: argparse.Namespace) -> int:
    from eval.run_checks import inputs, validate_args

    validate_args(args)
    if args.stage == "full":
        from eval.run_full import run_full

        code, line = run_full(args, config_from_args(args))
        print(line)
        return code
    from pipeline.outdir import output_folder
    from pipeline.progress import Progress

    out = Path(args.out)
    command = "unseen run " + " ".join(shlex.quote(a) for a in sys.argv[2:]) \
        if len(sys.argv) > 1 and sys.argv[1] == "run" else f"unseen run {args.input}"
    with output_folder(out, inputs=inputs(args), command="run") as tmp:
        with Progress(None, "unseen run") as bar:
            scan, arr, report = run_initial(args, progress=lambda name: bar.update(note=name))
        write_initial_outputs(tmp, scan, arr, report, command, args.seed)
    c = report["counts"]
    print(f"{c['cuboids']} cuboids from {c['objects']} objects, {c['walls']} walls, "
          f"{report['timings']['total']:.2f} s -> {out}")
    return 0

