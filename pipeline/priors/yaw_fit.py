"""A box takes the yaw that holds the most observed points, when the points say so clearly.

Evidence: the observed points (every second pixel of every view) grown by twice the
sensor's noise.  An upright box fitted to few points can come with a yaw that is off (a
shelf's board turned 15 degrees about its centre pokes out of the shelf at one end).
The points inside the box are counted at yaws within ``max_deg`` of its own, every
``step_deg``; a box that holds ``gain`` times as many (and ``min_points`` more) at
another yaw takes the middle of the plateau of best yaws.  Slanted or tilted boxes are
left alone.

Fits that agree outweigh a count: a part whose yaw ``agree_parts`` other parts of its
object, fitted from their own segments, share within ``agree_deg`` keeps it.  Parts fitted
apart are independent witnesses of their object's yaw, while the count is biased for a
thin panel: turned about its centre, its ends sweep through the points of its neighbours
(the books beside a shelf's side) and it holds more at a wrong yaw.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import is_upright, quarter_turn, turned_by, yaw_of
from .base import Edit, Prior, principle_of


@dataclass(frozen=True)
class Params:
    max_deg: float = 20.0  #: degrees either side of the box's own yaw
    step_deg: float = 1.0  #: degrees between tried yaws
    gain: float = 1.15  #: the turned box must hold this many times the points ...
    min_points: int = 50  #: ... and at least this many more
    agree_parts: int = 2  #: a part this many others of its object agree with keeps its yaw
    agree_deg: float = 1.0  #: degrees (modulo 90) within which two parts' yaws agree


def yaw_counts(c, pts: np.ndarray, tol: np.ndarray, near: list[int],
               offsets: np.ndarray) -> np.ndarray:
    """Observed points (grown by their tolerance) box ``c`` holds turned by each of
    ``offsets`` (radians) about the vertical through its centre."""
    d = pts[near] - c.center
    lim = c.size / 2 + tol[near][:, None]
    cos, sin = np.cos(offsets), np.sin(offsets)
    inside = np.zeros(len(offsets), int)
    for k in range(len(offsets)):
        # the box turned by +a about z holds the points turned by -a
        q = np.stack([cos[k] * d[:, 0] + sin[k] * d[:, 1],
                      -sin[k] * d[:, 0] + cos[k] * d[:, 1], d[:, 2]], axis=1) @ c.rotation
        inside[k] = int(np.count_nonzero(np.all(np.abs(q) <= lim, axis=1)))
    return inside


def agreeing_parts(square, agree_deg: float) -> list[int]:
    """For each box of ``square`` (upright boxes), how many other boxes of its object among
    them have its yaw within ``agree_deg`` degrees, modulo a quarter turn (0 for a box of
    no object)."""
    yaws = [yaw_of(c.rotation) for c in square]
    tol = np.radians(agree_deg)
    by_object: dict[str, list[int]] = {}
    for i, c in enumerate(square):
        if c.object is not None:
            by_object.setdefault(c.object, []).append(i)
    out = [0] * len(square)
    for members in by_object.values():
        for i in members:
            out[i] = sum(1 for j in members
                         if j != i and abs(quarter_turn(yaws[i], yaws[j])) <= tol)
    return out


def plateau_middle(counts: np.ndarray) -> int:
    """The middle of the yaws holding the most points within their counting noise."""
    top = np.flatnonzero(counts >= counts.max() - max(1, 0.005 * counts.max()))
    return int(top[len(top) // 2])


def apply(arr, evidence, p: Params, ctx):
    if not evidence:
        return
    pts, tol, tree = evidence.observed_cloud()
    if not len(pts):
        return
    pad = float(tol.max())
    offsets = np.radians(np.arange(-p.max_deg, p.max_deg + 1e-9, p.step_deg))
    zero = int(np.argmin(np.abs(offsets)))
    square = [c for c in arr.cuboids if not c.extra.get("slanted") and is_upright(c)]
    for c, agree in zip(square, agreeing_parts(square, p.agree_deg), strict=True):
        if agree >= p.agree_parts:
            continue
        near = tree.query_ball_point(c.center, float(np.linalg.norm(c.size)) / 2 + pad)
        if len(near) < p.min_points:
            continue
        inside = yaw_counts(c, pts, tol, near, offsets)
        best = plateau_middle(inside)
        if inside[best] >= p.gain * inside[zero] and inside[best] - inside[zero] >= p.min_points:
            yield Edit((turned_by(c, offsets[best]),),
                       f"holds {inside[best]} observed points turned by "
                       f"{np.degrees(offsets[best]):+.0f} deg, {inside[zero]} as fitted")


PRIOR = Prior("yaw_fit", "prepare", Params(), apply, principle_of(__doc__))
