"""``unseen export ARRANGEMENT.json --out DIR``: MJCF, URDF and glTF of an arrangement."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

EPILOG = """writes:
  DIR/scene.xml        MJCF for MuJoCo (mujoco.MjModel.from_xml_path)
  DIR/scene.urdf       the whole scene as one URDF tree (free bodies on floating joints)
  DIR/urdf/world.urdf  PyBullet: supports and static bodies (load with useFixedBase)
  DIR/urdf/bodyN.urdf  PyBullet: one file per free rigid body (URDF_USE_INERTIA_FROM_FILE)
  DIR/arrangement.glb  binary glTF for any 3D viewer

--welds exact (default): cuboids fused by 'fixed' contacts become one rigid body
(static when fused to the ground or a wall).  --welds constraint: one body per cuboid
and engine weld constraints (MuJoCo equality/weld, PyBullet JOINT_FIXED)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("arrangement", type=Path, help="arrangement.json to export")
    parser.add_argument("--out", type=Path, required=True, help="output folder (created)")
    parser.add_argument("--welds", choices=("exact", "constraint"), default="exact",
                        help="how 'fixed' contacts are modelled (default: exact)")
    parser.add_argument("--mu", type=float, default=None,
                        help="friction coefficient of every pair (default 0.7)")
    parser.add_argument("--json", action="store_true", help="print the written files as JSON")


def run(args: argparse.Namespace) -> int:
    from pipeline.arrangement_io import read_arrangement
    from pipeline.errors import InputError
    from simulate.export import export_all

    if args.mu is not None and not (args.mu >= 0):
        raise InputError(f"--mu: must be a non-negative number, got {args.mu}")
    arr = read_arrangement(args.arrangement)
    if args.out.exists() and not args.out.is_dir():
        raise InputError(f"--out {args.out}: exists and is not a folder; choose another path")
    kwargs = {} if args.mu is None else {"mu": args.mu}
    written = export_all(arr, args.out, welds=args.welds, **kwargs)
    if args.json:
        print(json.dumps({k: str(v) for k, v in written.items()}, indent=2))
    else:
        for path in written.values():
            print(path)
    return 0
