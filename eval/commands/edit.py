"""``unseen edit SCAN RESULT --move OBJ DX DY [--remove OBJ] --out DIR``: edit the colour image.

The paper's image manipulation (section 6 iii) in the original camera view: the object
moves along the floor with what it carries, or disappears; the hole it leaves is filled,
it is drawn at its new place with a shadow from above, and moves the arrangement's
physics forbids are refused.  The method is :mod:`simulate.edit` (the image) and
:mod:`simulate.edit_plan` (what moves, what is refused).
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
from pathlib import Path

from eval.commands.run import add_frame_arguments, frame_options
from pipeline.outdir import out_arg

EPILOG = """\
SCAN is what 'unseen run' read (a scene directory, an RGB-D folder or a depth file; the
same --color/--depth/--intrinsics/--depth-format/--depth-scale flags if the run needed
them); RESULT is that run's output folder or its arrangement.json.  OBJ is an object
name of the result (the 'object' field of its cuboids: table0, box1, ...).  DX DY are
metres along the world floor (x, y of the arrangement's frame, z up).

  unseen demo --out demo_out              # demo_out/scene (the scan), demo_out/result
  unseen edit demo_out/scene demo_out/result --move table0 0.3 0 --out edits/table
  unseen edit demo_out/scene demo_out/result --remove box4 --out edits/no_box4
  a real frame (Shao's Kinect boxes): remove the box leaning on the big one
    unseen run ../shared/data/real/shao_kinect_boxes/3boxes_depth16bits.dat --out runs/shao3
    unseen edit ../shared/data/real/shao_kinect_boxes/3boxes_depth16bits.dat runs/shao3 \
      --remove cluster3 --out edits/shao3

An object moves with everything resting on it (transitively) or fixed to it; an object
only leaning on it stays.  --remove takes what the object carries too.  Removals are
applied first, then moves in the order given.  Refused, one line and exit 2: an unknown
object (the line lists them), a move into another object or a wall ('would enter box3
by 4.2 cm'), a move off what holds it up ('nothing under box0 at its new place'), and a
move or removal after which something that stood no longer stands.

writes:
  DIR/before.png   the original colour image
  DIR/after.png    the edited image
  DIR/compare.png  before | after, 320 pixels wide each
  DIR/mask.png     deleted pixels (white), new silhouette (grey), shadow (dark grey)
  DIR/edit.json    operations, moved and carried objects, 4x4 transforms, checks passed
  DIR/edited.json  the edited arrangement (unseen check edited.json)
  DIR/report.md    the same, for reading
The hole is filled surface by surface (--fill surface: pull-push from the pixels that
see the same floor, wall or box, OpenCV Telea for the rest) or by OpenCV alone
(--fill telea, --fill ns).  Light from above: straight down, shadow strength 0.45.
With --retrieved DIR (the output of 'unseen retrieve RESULT'), a moved object that has a
retrieved model is drawn as that model; its cuboids still decide what is deleted, the
shadow and the checks."""


#: Width of each panel of compare.png, pixels (a preview; before.png and after.png are
#: full size).
COMPARE_WIDTH = 320


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scan", help="the scan the result came from (scene dir, RGB-D folder, depth file)")
    p.add_argument("result", help="the output folder of 'unseen run' on SCAN, or its arrangement.json")
    p.add_argument("--move", nargs=3, action="append", default=[], metavar=("OBJ", "DX", "DY"),
                   help="move object OBJ by DX, DY metres along the floor (repeatable)")
    p.add_argument("--remove", action="append", default=[], metavar="OBJ",
                   help="remove object OBJ and what it carries (repeatable)")
    p.add_argument("--out", type=out_arg, required=True, help="output folder (created)")
    p.add_argument("--fill", default="surface", choices=["surface", "telea", "ns"],
                   help="how the hole is filled (default surface; telea/ns: OpenCV inpainting)")
    p.add_argument("--margin", type=float, default=0.03,
                   help="depth points within this many metres of a moving cuboid are deleted "
                        "(default 0.03)")
    p.add_argument("--no-shadow", action="store_true", help="draw no shadow")
    p.add_argument("--retrieved", metavar="DIR",
                   help="an 'unseen retrieve' output folder for RESULT: a moved object with a "
                        "retrieved model is drawn as that model instead of its cuboids")
    p.add_argument("--json", action="store_true", help="print edit.json to stdout")
    add_frame_arguments(p)  # INPUT in their help is SCAN here


def operations(args: argparse.Namespace) -> list:
    """The :class:`simulate.edit_plan.Operation` list of the options (removals first)."""
    from pipeline.errors import InputError
    from simulate.edit_plan import Operation

    ops = [Operation("remove", name) for name in args.remove]
    for name, dx, dy in args.move:
        try:
            x, y = float(dx), float(dy)
        except ValueError:
            raise InputError(f"--move {name} {dx} {dy}: DX and DY must be numbers (metres)") \
                from None
        if not (math.isfinite(x) and math.isfinite(y)) or max(abs(x), abs(y)) > 100:
            raise InputError(f"--move {name} {dx} {dy}: DX and DY must be finite metres, at "
                             "most 100")
        if x == 0 and y == 0:
            raise InputError(f"--move {name} {dx} {dy}: moves nothing; give a DX or DY other "
                             "than 0")
        ops.append(Operation("move", name, x, y))
    if not ops:
        raise InputError("nothing to do: give --move OBJ DX DY or --remove OBJ")
    return ops


def _result_file(result: str) -> Path:
    from pipeline.errors import InputError

    p = Path(result)
    if p.is_dir():
        p = p / "arrangement.json"
        if not p.is_file():
            raise InputError(f"RESULT {result}: no arrangement.json in this folder (give the "
                             "output folder of 'unseen run')")
    elif not p.exists():
        raise InputError(f"RESULT {result}: no such file or folder")
    return p


def edit_record(plan, images, params, scan: str, result: str) -> dict:
    """The JSON of ``edit.json``."""
    import numpy as np

    ops = []
    for g in plan.groups:
        T = np.eye(4)
        T[:3, 3] = g.offset
        ops.append({"kind": g.operation.kind, "object": g.operation.object,
                    "dx": g.operation.dx, "dy": g.operation.dy, "objects": list(g.objects),
                    "carried": list(g.objects[1:]), "cuboids": list(g.cuboids),
                    "transform": T.tolist() if g.operation.kind == "move" else None})
    return {"format": "unseen.edit", "version": 1, "scan": scan, "result": result,
            "operations": ops,
            "moved": {k: [float(x) for x in v] for k, v in plan.moved.items()},
            "removed": list(plan.removed), "checks": list(plan.checks), "refusal": None,
            "params": {"fill": params.fill, "margin": params.margin,
                       "dilate_px": params.dilate_px, "shadow": params.shadow,
                       "light": list(params.light), "shadow_strength": params.shadow_strength,
                       "shadow_soft": params.shadow_soft, "supersample": params.supersample},
            "pixels": {"deleted": int(images.hole.sum()),
                       "foreground": int((images.alpha > 0.5).sum()),
                       "shadow": int((images.shadow > 0.05).sum())}}


def mask_picture(images):
    """mask.png: deleted pixels white, new silhouette grey, shadow dark grey."""
    import numpy as np

    m = np.zeros(images.hole.shape, np.uint8)
    m[images.shadow > 0.05] = 70
    m[images.alpha > 0.5] = 150
    m[images.hole] = 255
    return np.repeat(m[..., None], 3, axis=2)


def report_markdown(rec: dict, command: str) -> str:
    lines = ["# unseen edit", "", f"- command: `{command}`", f"- scan: {rec['scan']}",
             f"- result: {rec['result']}", "", "## Operations", "",
             "| operation | object | carried | cuboids | offset (m) |", "|---|---|---|---|---|"]
    for op in rec["operations"]:
        off = f"({op['dx']:+.3f}, {op['dy']:+.3f})" if op["kind"] == "move" else "-"
        lines.append(f"| {op['kind']} | {op['object']} | {', '.join(op['carried']) or '-'} | "
                     f"{', '.join(op['cuboids'])} | {off} |")
    lines += ["", "## Checks passed", ""] + [f"- {c}" for c in rec["checks"]]
    p = rec["params"]
    lines += ["", "## Image", "",
              f"- deleted pixels: {rec['pixels']['deleted']} (depth points within "
              f"{p['margin']} m of a moving or removed cuboid, dilated {p['dilate_px']} px)",
              f"- fill: {p['fill']}",
              f"- foreground pixels: {rec['pixels']['foreground']}",
              f"- shadow: {'light along ' + str(p['light']) if p['shadow'] else 'none'}, "
              f"{rec['pixels']['shadow']} pixels darkened",
              "", "before.png, after.png, compare.png, mask.png; edited.json is the edited "
              "arrangement."]
    return "\n".join(lines) + "\n"


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from eval.run_checks import check_frame_flags
    from pipeline import atomic
    from pipeline.arrangement_io import read_arrangement, write_arrangement
    from pipeline.errors import InputError
    from pipeline.outdir import check_out, output_folder
    from pipeline.pictures import write_png
    from pipeline.progress import Progress
    from pipeline.run import LoadOptions, load
    from simulate.compare_images import side_by_side
    from simulate.edit import EditParams, edit_image, read_retrieved
    from simulate.edit_plan import plan_edit
    from simulate.view import view_of

    ops = operations(args)
    if not (math.isfinite(args.margin) and 0 <= args.margin <= 1):
        raise InputError(f"--margin: must be in [0, 1] metres, got {args.margin}")
    check_frame_flags(args)
    check_out(args.out, command="edit")
    result_file = _result_file(args.result)
    arr = read_arrangement(result_file)
    scan = load(args.scan, LoadOptions(**frame_options(args)))
    view = view_of(scan, arr)
    params = EditParams(margin=float(args.margin), fill=args.fill, shadow=not args.no_shadow)
    meshes = read_retrieved(args.retrieved, arr) if args.retrieved else None
    with Progress(None, "unseen edit") as bar:
        bar.update(note="checks")
        plan = plan_edit(arr, ops)
        if not plan.ok:
            raise InputError(plan.refusal)
        images = edit_image(view, plan, params, progress=lambda s: bar.update(note=s),
                            meshes=meshes)
    command = "unseen edit " + " ".join(shlex.quote(a) for a in sys.argv[2:]) \
        if len(sys.argv) > 1 and sys.argv[1] == "edit" else "unseen edit"
    rec = edit_record(plan, images, params, str(args.scan), str(args.result))
    moved_objects = {o for g in plan.groups if g.operation.kind == "move" for o in g.objects}
    rec["drawn_as_models"] = sorted(moved_objects & set(meshes or {}))
    with output_folder(args.out, inputs=[args.scan, args.result, args.retrieved],
                       command="edit") as tmp:
        write_png(tmp / "before.png", images.before)
        write_png(tmp / "after.png", images.after)
        write_png(tmp / "compare.png", side_by_side([images.before, images.after],
                                                    ["before", "after"], width=COMPARE_WIDTH))
        write_png(tmp / "mask.png", mask_picture(images))
        atomic.write_text(tmp / "edit.json", json.dumps(rec, indent=1) + "\n")
        write_arrangement(plan.after, tmp / "edited.json")
        atomic.write_text(tmp / "report.md", report_markdown(rec, command))
    if args.json:
        print(json.dumps(rec, indent=1))
    else:
        what = "; ".join(
            f"{g.operation.describe()}" + (f" (carrying {', '.join(g.objects[1:])})"
                                           if len(g.objects) > 1 else "")
            for g in plan.groups)
        print(f"{what}; {int(np.sum(images.hole))} pixels refilled -> {args.out}")
    return 0
