"""A part seen in part is as big as its twin: the two sides of a desk are alike.

Evidence: the segmentation's objects, the observed boxes, the depth views.  Regularity:
an object's part under one end of its top has a twin under the other end (the sides of
a desk, the brackets of a board).  Where the mirror image, across the top's centre, of
another of its parts as the sensor saw it (its observed box, not a deepening's guess)
overlaps a part seen with fewer points, axes parallel within ``axes_deg``, the part grows
to the bounding box of itself and that image where the image reaches past it by at least
``min_growth`` (never above the top's underside, and never wider across than the twin by
more than twice ``slack``; a twin seen face-on as a sliver counts as twice ``slack``
thick), where it enters no other box and no view saw its space empty.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import box_samples, separations, up_axis
from .base import Edit, Prior, principle_of
from .copies import MIRROR_SLACK, mirror_support, top_of


@dataclass(frozen=True)
class Params:
    axes_deg: float = 5.0  #: degrees the part's and the image's axes may differ
    min_growth: float = 0.02  #: metres the part must grow somewhere
    slack: float = MIRROR_SLACK  #: metres the image may lie off the part along one axis


def apply(arr, evidence, p: Params, ctx):
    by_object: dict[str, list[int]] = {}
    for k, c in enumerate(arr.cuboids):
        if c.object is not None and not c.extra.get("hallucinated"):
            by_object.setdefault(c.object, []).append(k)
    cubs = list(arr.cuboids)
    cos = np.cos(np.radians(p.axes_deg))
    for obj, members in sorted(by_object.items()):
        if len(members) < 3:
            continue
        top = top_of([cubs[k] for k in members])
        top_bottom = float(top.center[2] - np.abs(top.rotation[2]) @ top.size / 2)
        for k in members:
            part = cubs[k]
            if part is top:
                continue
            for j in members:
                twin = cubs[j]
                if j == k or twin is top or (twin.extra.get("points", 0)
                                             <= part.extra.get("points", 0)):
                    continue
                # the twin as the sensor saw it (a deepening's guess is no evidence)
                seen = twin if twin.observed is None else twin.with_(
                    center=np.asarray(twin.observed.center, float),
                    size=np.asarray(twin.observed.size, float))
                image = mirror_support(top, seen, obj, 0, p.slack)
                if image is None or np.min(np.max(np.abs(part.rotation.T @ image.rotation),
                                                  axis=0)) < cos:
                    continue
                # both boxes in the part's frame
                own = part.rotation.T @ part.center
                corners = image.corners() @ part.rotation
                lo = np.minimum(own - part.size / 2, corners.min(axis=0))
                hi = np.maximum(own + part.size / 2, corners.max(axis=0))
                # up to the underside of the top, not into it (a strip whose noisy top
                # reaches into the top would carry that overlap along)
                up = up_axis(part)
                if part.rotation[2, up] > 0:
                    hi[up] = min(hi[up], top_bottom)
                else:
                    lo[up] = max(lo[up], -top_bottom)
                overlap = np.minimum(own + part.size / 2, corners.max(axis=0)) - \
                    np.maximum(own - part.size / 2, corners.min(axis=0))
                growth = (hi - lo) - part.size
                # the same part: overlapping along two axes, and along the third at most
                # p.slack apart (a thin panel's mirror image lands a few mm off)
                if (np.sum(overlap > 0) < 2 or np.any(overlap <= -p.slack)
                        or growth.max() < p.min_growth):
                    continue
                # ... and no bigger than its twin (with the slack) once grown: a leg's
                # foot and the image of another leg 30 cm off are two legs, not one
                twin_size = np.abs(part.rotation.T @ seen.rotation) @ seen.size
                horiz = np.abs(part.rotation[2]) < 0.5
                # (a twin seen face-on as a sliver is at least twice the slack thick: its
                # depth is not in the data, and the part's own fit may be wider)
                twin_size = np.maximum(twin_size, 2 * p.slack)
                if np.any(((hi - lo) > twin_size + 2 * p.slack) & horiz):
                    continue
                new = part.with_(center=part.rotation @ ((lo + hi) / 2), size=hi - lo)
                rest = arr.with_(cuboids=tuple(c for n, c in enumerate(cubs) if n != k))
                before, tol = separations(rest, part)
                after, _ = separations(rest, new)
                if np.any((after < -tol) & (after < before - 1e-9)):
                    continue  # the growth enters another box (overlaps it had may stay)
                if evidence.seen_empty(box_samples(new)):
                    continue
                v = yield Edit((new,), f"{obj}: {part.id} grown to the mirror image of its "
                                       f"better-seen twin {twin.id}")
                if v.ok:
                    cubs[k] = new
                break


PRIOR = Prior("mirror", "complete", Params(), apply, principle_of(__doc__))
