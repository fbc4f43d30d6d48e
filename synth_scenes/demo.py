"""The built-in demo scene of ``unseen demo``: a table and a stack, partly hidden.

A table with a few things on it (its top and the things hide parts of the legs from
the camera) stands in front of a tower of boxes whose lower boxes the table hides
(so their support must be imagined).  Seeded like every family; registered as
``demo`` in :mod:`synth_scenes.registry`.
"""

from __future__ import annotations

import numpy as np

from pipeline.model import Arrangement

from . import objects
from .builder import SceneBuilder


def make_demo(rng: np.random.Generator) -> Arrangement:
    """A table (fused legs, 2 things on top) and, 0.5 m behind it, a 3-box tower."""
    b = SceneBuilder()
    table = objects.table(rng, 2)
    fp = table.footprint()
    depth = float(fp[1, 1] - fp[0, 1])
    b.place(table, 0.0, 0.0, 0.0)
    tower = objects.column(rng, 3)
    b.place(tower, float(rng.uniform(-0.2, 0.2)), depth / 2 + 0.45, float(rng.uniform(-0.3, 0.3)))
    return b.build({"family": "demo"})
