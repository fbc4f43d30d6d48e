"""A box whose yaw the points leave open takes the yaw of the box it stands on.

Evidence: the observed points and the supporting relation (a box's bottom on another's
top).  Regularity: what stands on a board is square to it (as Jia et al. orient boxes by
their supports).  A book seen by its spine between its neighbours is fitted to a few
hundred points on one face, whose counts vary by less than their Poisson noise over tens
of degrees of yaw.  An upright box standing on a narrow end (horizontal extent below
``thin_fraction`` of its height), a single part, resting on another upright box (its
bottom within ``gap`` of that box's top, over its footprint), takes that box's yaw (the
smaller of the two quarter turns, unless the other holds more of the points no other box
holds by over their noise) when there it holds at least the most it holds at any yaw less
``sigmas`` times that count's square root.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import is_upright, quarter_turn, resting_on, single_part, turned_by, up_axis, yaw_of
from .base import Edit, Prior, principle_of
from .yaw_fit import yaw_counts


@dataclass(frozen=True)
class Params:
    gap: float = 0.03  #: metres between a box's bottom and its support's top
    sigmas: float = 2.0  #: Poisson deviations the support's yaw may fall short by
    thin_fraction: float = 0.5  #: a box standing on a narrow end: horizontal / height
    step_deg: float = 1.0  #: degrees between tried yaws


def not_in_others(arr, c, pts: np.ndarray, near: list[int]) -> list[int]:
    """The points ``near`` that lie in no other box of ``arr`` than ``c`` (the points
    another box holds are its evidence)."""
    keep = np.ones(len(near), bool)
    P = pts[near]
    reach = float(np.linalg.norm(c.size)) / 2
    for o in arr.cuboids:
        if o.id == c.id or np.linalg.norm(o.center - c.center) > reach + float(
                np.linalg.norm(o.size)) / 2:
            continue
        q = (P - o.center) @ o.rotation
        keep &= ~np.all(np.abs(q) <= o.size / 2, axis=1)
    return [n for n, k in zip(near, keep, strict=True) if k]


def apply(arr, evidence, p: Params, ctx):
    if not evidence:
        return
    pts, tol, tree = evidence.observed_cloud()
    if not len(pts):
        return
    pad = float(tol.max())
    sweep = np.radians(np.arange(-90.0, 90.0, p.step_deg))
    for c in arr.cuboids:  # all judged on the boxes as this prior found them
        if c.extra.get("slanted") or not is_upright(c) or not single_part(arr, c):
            continue
        up = up_axis(c)
        if np.delete(c.size, up).min() >= p.thin_fraction * c.size[up]:
            continue  # not standing on its narrow end: its top face shows its yaw
        s = resting_on(arr, c, p.gap)
        if s is None or s.extra.get("slanted"):
            continue
        d = quarter_turn(yaw_of(c.rotation), yaw_of(s.rotation))
        if abs(d) <= np.radians(p.step_deg):
            continue
        near = tree.query_ball_point(c.center, float(np.linalg.norm(c.size)) / 2 + pad)
        near = not_in_others(arr, c, pts, near)
        if not near:
            continue
        to_support = np.array([d, d + np.pi / 2 if d < 0 else d - np.pi / 2])
        at = yaw_counts(c, pts, tol, near, to_support)
        # the smaller turn unless the points favour the other beyond their noise
        best = int(at[1] > at[0] + np.sqrt(max(int(at[1]), 1)))
        most = int(yaw_counts(c, pts, tol, near, sweep).max())
        if at[best] < most - p.sigmas * np.sqrt(most):
            continue
        yield Edit((turned_by(c, to_support[best]),),
                   f"on {s.id}: {at[best]} points at its yaw, {most} at the best")


PRIOR = Prior("support_yaw", "prepare", Params(), apply, principle_of(__doc__))
