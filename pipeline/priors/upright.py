"""Furniture stands: a box tilted by a few degrees is a fitting error and stands upright.

Evidence: the box's own axes.  Regularity: indoor objects and their parts stand square
to gravity; a box whose axis nearest the vertical is off by at most ``max_deg`` was
tilted by the noise of the points it was fitted to, and is turned about its centre to
stand upright.  Boxes the fit found leaning (``slanted``: two face planes fitted at an
angle) are left alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import up_axis
from ..model import rotation_about_axis
from .base import Edit, Prior, principle_of


@dataclass(frozen=True)
class Params:
    max_deg: float = 15.0  #: degrees: the largest tilt taken for fitting noise


def apply(arr, evidence, p: Params, ctx):
    limit = np.radians(p.max_deg)
    for c in arr.cuboids:
        if c.extra.get("slanted"):
            continue
        k = up_axis(c)
        a = c.rotation[:, k] * np.sign(c.rotation[2, k])
        tilt = float(np.arccos(np.clip(a[2], -1.0, 1.0)))
        if 1e-9 < tilt <= limit:
            R = rotation_about_axis(np.cross(a, [0.0, 0.0, 1.0]), tilt) @ c.rotation
            yield Edit((c.with_(rotation=R),),
                       f"tilted {np.degrees(tilt):.1f} deg from the vertical")


PRIOR = Prior("upright", "prepare", Params(), apply, principle_of(__doc__))
