"""``unseen export ARRANGEMENT.json --out DIR``: MJCF, URDF and glTF of an arrangement."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from pipeline.outdir import out_arg

EPILOG = """writes:
  DIR/scene.xml        MJCF for MuJoCo (mujoco.MjModel.from_xml_path)
  DIR/scene.urdf       the whole scene as one URDF tree (free bodies on floating joints)
  DIR/urdf/world.urdf  PyBullet: supports and static bodies (load with useFixedBase)
  DIR/urdf/bodyN.urdf  PyBullet: one file per free rigid body (URDF_USE_INERTIA_FROM_FILE)
  DIR/arrangement.glb  binary glTF for any 3D viewer
  DIR/manifest.json    every file above with its size and SHA-256 (written last)

DIR is replaced whole: files of an earlier export that this one does not write (a
bodyN.urdf of a scene with more bodies) are gone.  DIR must be new, empty or an earlier
unseen output; a second command writing the same DIR at once is refused.

--welds exact (default): cuboids fused by 'fixed' contacts become one rigid body
(static when fused to the ground or a wall).  --welds constraint: one body per cuboid
and engine weld constraints (MuJoCo equality/weld, PyBullet JOINT_FIXED)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("arrangement", type=Path, help="arrangement.json to export")
    parser.add_argument("--out", type=out_arg, required=True, help="output folder (created)")
    parser.add_argument("--welds", choices=("exact", "constraint"), default="exact",
                        help="how 'fixed' contacts are modelled (default: exact)")
    parser.add_argument("--mu", type=float, default=None,
                        help="friction coefficient of every pair (default: the file's meta.mu, "
                             "which unseen run records, else 0.7)")
    parser.add_argument("--json", action="store_true", help="print the written files as JSON")


def run(args: argparse.Namespace) -> int:
    from eval.commands.check import check_mu, file_mu
    from pipeline.arrangement_io import read_arrangement
    from pipeline.contacts import find_contacts
    from pipeline.outdir import check_out, output_folder
    from pipeline.stability import fixed_node_pairs
    from simulate.export import export_all

    check_mu(args.mu)
    check_out(args.out, command="export")
    arr = read_arrangement(args.arrangement)
    mu = file_mu(arr, args.mu, args.arrangement)
    fixed_node_pairs(arr, find_contacts(arr))  # a listed fixed contact must touch, as in check
    with output_folder(args.out, inputs=[args.arrangement], command="export") as tmp:
        written = export_all(arr, tmp, welds=args.welds, mu=mu)
    written = {k: args.out / v.relative_to(tmp) for k, v in written.items()}
    if args.json:
        print(json.dumps({k: str(v) for k, v in written.items()}, indent=2))
    else:
        for path in written.values():
            print(path)
    return 0
