"""The parts of one object share its yaw.

Evidence: the segmentation's object of each box, and (with views) the observed points.
Regularity: a chair's legs and seat, a shelf's boards and sides, are square to each
other.  The parts of an object whose yaws (modulo 90 degrees) lie within ``max_deg`` of
the object's volume-weighted mean yaw take one yaw: the mean when they agree within a
degree, else (with views) the yaw between their least and greatest that holds the most
observed points in all of them together (the middle of the plateau, as ``yaw_fit``
picks), each part turned about its own centre.  Slanted and tilted parts keep theirs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import is_upright, quarter_turn, turned_by
from .base import Edit, Prior, principle_of
from .yaw_fit import plateau_middle, yaw_counts


@dataclass(frozen=True)
class Params:
    max_deg: float = 30.0  #: degrees: a part further off its object's yaw keeps its own
    step_deg: float = 1.0  #: degrees between tried yaws; parts within it agree


def object_yaw(cubs, idx, yaws: np.ndarray, mean: float, p: Params, evidence) -> float:
    """The yaw the upright parts ``idx`` of one object share, fitted to the views."""
    parts = []
    for i, y in zip(idx, yaws, strict=True):
        d = quarter_turn(mean, y)
        if abs(d) <= np.radians(p.max_deg) and is_upright(cubs[i]):
            parts.append((i, float(d)))
    ds = [d for _, d in parts]
    if not ds or max(ds) - min(ds) <= np.radians(p.step_deg):
        return mean  # the parts agree: nothing to choose between
    pts, tol, tree = evidence.observed_cloud()
    if not len(pts):
        return mean
    pad = float(tol.max())
    step = np.radians(p.step_deg)
    sweep = mean + np.arange(min(ds), max(ds) + 1e-9, step)
    total = np.zeros(len(sweep), int)
    for i, d in parts:
        c = cubs[i]
        near = tree.query_ball_point(c.center, float(np.linalg.norm(c.size)) / 2 + pad)
        if near:
            total += yaw_counts(c, pts, tol, near, sweep - (mean + d))
    if total.max() <= 0:
        return mean
    return float(sweep[plateau_middle(total)])


def apply(arr, evidence, p: Params, ctx):
    cubs = list(arr.cuboids)
    groups: dict[str, list[int]] = {}
    for i, c in enumerate(cubs):
        if c.object is not None and not c.extra.get("slanted"):
            groups.setdefault(c.object, []).append(i)
    for obj, idx in groups.items():
        if len(idx) < 2:
            continue
        yaws, weights = [], []
        for i in idx:
            R = cubs[i].rotation
            h = R[:, int(np.argmin(np.abs(R[2])))]  # a horizontal axis
            yaws.append(np.arctan2(h[1], h[0]))
            weights.append(float(np.prod(cubs[i].size)))
        yaws = np.array(yaws)
        mean = np.angle(np.sum(np.array(weights) * np.exp(4j * yaws))) / 4.0
        if evidence:
            mean = object_yaw(cubs, idx, yaws, mean, p, evidence)
        turned = []
        for i, y in zip(idx, yaws, strict=True):
            d = quarter_turn(mean, y)
            if 1e-9 < abs(d) <= np.radians(p.max_deg) and is_upright(cubs[i]):
                turned.append(turned_by(cubs[i], -d))
        if turned:
            yield Edit(tuple(turned), f"parts of {obj} onto its yaw "
                                      f"{np.degrees(mean) % 90:.1f} deg (mod 90)")


PRIOR = Prior("object_yaw", "prepare", Params(), apply, principle_of(__doc__))
