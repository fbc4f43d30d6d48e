"""``export_all``: write MJCF, URDF and glTF of an arrangement into a folder.

The rigid bodies the files are made of come from :mod:`simulate.bodies` (re-exported
here for callers of the old names); the text of each format from :mod:`simulate.mjcf`,
:mod:`simulate.urdf` and :mod:`simulate.gltf`.  Imports go one way:
``export -> mjcf/urdf/gltf -> bodies``.
"""

from __future__ import annotations

import os
from pathlib import Path

from pipeline.model import Arrangement

from .bodies import (  # noqa: F401 - re-exported
    WELDS,
    RigidBody,
    Weld,
    box_inertias,
    check_welds,
    rigid_bodies,
    scene_extent,
)
from .gltf import arrangement_glb
from .mjcf import arrangement_to_mjcf
from .urdf import arrangement_to_urdf_files


def export_all(arr: Arrangement, out_dir: str | os.PathLike, welds: str = "exact",
               mu: float | None = None) -> dict[str, Path]:
    """Write ``scene.xml`` (MJCF), ``scene.urdf`` (+ ``urdf/*.urdf`` for PyBullet) and
    ``arrangement.glb`` into ``out_dir``, each atomically.

    Returns
    -------
    dict
        Role (``mjcf``, ``urdf``, ``glb``, ``urdf:<file>``) -> written path.
    """
    from pipeline.atomic import write_bytes, write_text
    from pipeline.constants import DEFAULT_MU

    check_welds(welds)
    mu = DEFAULT_MU if mu is None else float(mu)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: dict[str, Path] = {}
    write_text(out / "scene.xml", arrangement_to_mjcf(arr, mu=mu, welds=welds))
    written["mjcf"] = out / "scene.xml"
    for rel, text in arrangement_to_urdf_files(arr, mu=mu, welds=welds).items():
        write_text(out / rel, text)
        written["urdf" if rel == "scene.urdf" else f"urdf:{rel}"] = out / rel
    write_bytes(out / "arrangement.glb", arrangement_glb(arr))
    written["glb"] = out / "arrangement.glb"
    return written
