"""Furniture is built of boards, and no part of it is thinner than one.

Evidence: the completed boxes and the depth views.  Regularity: a box fitted to one seen
face of a part is as thin as the noise's spread about that face (a sofa's arm seen from
outside comes out 9 mm thick, a shelf board seen from above 1 cm), while the solid parts
of furniture and the things on it are at least a board thick: ``min_thickness``, 18 mm,
the common thickness of particle board and plywood panels.  A box left thinner than that
after the other rules of the ``complete`` stage has the face on its thinnest axis away
from the camera pushed back to that thickness, in ``steps`` increments tried longest
first, as far as no view saw the added space empty and nothing is entered; its seen face
stays.  Pushes shorter than ``min_push`` are noise and are not proposed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model import Arrangement
from .base import Prior, principle_of
from .deepen import away_from, pushed_back


@dataclass(frozen=True)
class Params:
    min_thickness: float = 0.018  #: metres: no part is thinner than a board
    min_push: float = 0.001  #: metres: a shorter push is not proposed
    steps: int = 4  #: increments of the push, tried longest first
    layers: bool = True  #: no layer a push adds was seen empty (off: the added space as a whole)


def thin_pushes(arr: Arrangement, eye: np.ndarray, p: Params):
    """``(k, axis, u, length)``: box ``k``'s thinnest extent, below ``p.min_thickness``
    by more than ``p.min_push``, reaches it when its face towards ``u`` (away from the
    camera at ``eye``) is pushed out by ``length``."""
    out = []
    for k, c in enumerate(arr.cuboids):
        if c.extra.get("hallucinated"):
            continue
        axis = int(np.argmin(c.size))
        length = p.min_thickness - float(c.size[axis])
        if length > p.min_push:
            out.append((k, axis, away_from(c, axis, eye), length))
    return out


def apply(arr, evidence, p: Params, ctx):
    if not evidence or p.min_thickness <= 0:
        return
    yield from pushed_back(arr, evidence, p, thin_pushes(arr, evidence.eye, p),
                           "thinner than a board")


PRIOR = Prior("boards", "complete", Params(), apply, principle_of(__doc__))
