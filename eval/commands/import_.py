"""``unseen import FILE --out ARRANGEMENT.json``: an MJCF or URDF scene of boxes -> arrangement."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

EPILOG = """what maps to what (MuJoCo compiles both formats: defaults, includes, every
orientation form and nested frames are resolved as the engine resolves them):
  box geom / URDF box collision   -> one cuboid (size = full edges, id = the geom's name)
  plane geom                      -> a support: 'support:<id>' keeps its id, else the most
                                     upward plane is 'ground' and the others 'wall:k'
  box named support:<id>          -> that support (the slabs of 'unseen export' URDF)
  boxes of one rigid body         -> 'fixed' contacts between those that touch (they must)
  body welded to the world        -> static: 'fixed' to the ground (else the walls) it touches
  any other touching pair         -> 'touch' contact
  mass                            -> density per box (MJCF: the geom's; URDF: fitted to
                                     each link's mass, centre of mass and inertia)
  friction                        -> meta.mu when every geom agrees (URDF: PyBullet's
                                     lateral_friction f of every link, mu = f^2)
  <weld> equality (MJCF)          -> the welded bodies are one rigid body
  URDF root link named 'world'    -> the world: a floating joint from it makes a free body;
                                     any other root link is static
refused (exit 2, one line): spheres, meshes, cylinders and other non-box geoms; hinge,
slide or ball joints; URDF <plane> (name a floor slab support:ground); parts of one body that do not touch or that overlap; a static part
touching no ground or wall.  Visual-only geoms (contype = conaffinity = 0) are skipped.

'unseen export' writes scene.xml and scene.urdf that import back to the same boxes,
contacts and verdicts."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", type=Path, help="MJCF (<mujoco>) or URDF (<robot>) file")
    parser.add_argument("--out", type=Path, required=True,
                        help="arrangement.json to write (atomically); an existing file is replaced only when it is an arrangement")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")


def _is_arrangement(path: Path) -> bool:
    """Whether ``path`` holds an arrangement file (its JSON's ``format``), which an import
    may replace; any other file is a user's and is never overwritten."""
    from pipeline.arrangement_io import FORMAT
    from pipeline.errors import InputError
    from pipeline.safe_read import load_json

    try:
        data = load_json(path, "arrangement file")
    except (InputError, OSError):
        return False
    return isinstance(data, dict) and data.get("format") == FORMAT


def run(args: argparse.Namespace) -> int:
    from pipeline.arrangement_io import write_arrangement
    from pipeline.contacts import find_contacts
    from pipeline.errors import InputError
    from simulate.bodies import rigid_bodies
    from simulate.importers import import_scene

    out: Path = args.out
    if str(out).strip() == "":
        raise InputError("--out: empty path; give the arrangement.json to write")
    if out.is_dir():
        raise InputError(f"--out {out}: is a folder; give a file name, e.g. {out}/arrangement.json")
    if out.exists() and args.scene.exists() and out.resolve() == args.scene.resolve():
        raise InputError(f"--out {out}: is the input file; inputs are never overwritten")
    if out.exists() and not _is_arrangement(out):
        raise InputError(f"--out {out}: exists and is not an arrangement file; it is left "
                         "as it is: give a new file name or remove it first")
    arr = import_scene(args.scene)
    bodies, _ = rigid_bodies(arr)
    fixed = sum(c.type == "fixed" for c in arr.contacts)
    overlaps = len(find_contacts(arr).penetrations)
    write_arrangement(arr, out)
    fmt = arr.meta["source"]["format"]
    summary = {"arrangement": str(out), "source": str(args.scene), "format": fmt,
               "cuboids": len(arr.cuboids), "bodies": len(bodies),
               "static_bodies": sum(b.static for b in bodies),
               "contacts": len(arr.contacts), "fixed": fixed,
               "supports": list(arr.support_ids), "mu": arr.meta.get("mu"),
               "overlapping_pairs": overlaps}
    if args.json:
        print(json.dumps(summary, indent=1))
        return 0
    line = (f"{args.scene} ({fmt.upper()}) -> {out}: {len(arr.cuboids)} cuboids in "
            f"{len(bodies)} bodies ({summary['static_bodies']} static), "
            f"{len(arr.contacts)} contacts of which {fixed} fixed, supports "
            f"{', '.join(arr.support_ids) or 'none'}")
    if summary["mu"] is not None:
        line += f", mu {summary['mu']:g}"
    if overlaps:
        line += f"; {overlaps} pairs of boxes overlap (unseen check calls that interpenetration)"
    print(line)
    return 0
