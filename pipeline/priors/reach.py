"""A box hidden behind a broad part reaches on to it, through that part's shadow.

Evidence: the first camera, the boxes with broad faces, the depth views.  Regularity:
a part whose visible face looks towards the camera with a broad part ahead of it
across that whole face (seat cushions seen from behind a sofa, whose back hides the
rest) goes on, unseen, to that part.  A fitted upright box is turned onto the broad
box's axes (when within ``square_max_deg`` in yaw) and grown to touch it when the gap
is more than ``min_gap`` and at most ``max_rel`` of the box's widest horizontal extent,
at least ``shadow_fraction`` of the added slab lies behind the broad box as seen from
the camera, and no view saw any of it empty.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import BROAD_FACE_AREA, broad_face, is_upright, overlap_across, push_face
from .base import Edit, Prior, principle_of


@dataclass(frozen=True)
class Params:
    max_rel: float = 1.0  #: the longest growth, in the box's widest horizontal extents
    min_gap: float = 1e-3  #: metres: a box closer than this already touches
    shadow_fraction: float = 0.9  #: share of the added slab the broad part must hide
    square_max_deg: float = 15.0  #: degrees of yaw the box is turned onto the broad part


def apply(arr, evidence, p: Params, ctx):
    from ..evidence import slab_samples
    from ..extend import Extension
    from ..model import rotation_about_axis

    if not evidence:
        return
    eye = evidence.eye
    # the parts that could hide a box: upright, with some face broad enough
    broad = [o.id for o in arr.cuboids if is_upright(o)
             and float(np.prod(o.size) / o.size.min()) >= BROAD_FACE_AREA]
    for k in range(len(arr.cuboids)):
        c = arr.cuboids[k]
        if not broad:
            break
        if (c.observed is None or c.extra.get("hallucinated") or c.extra.get("slanted")
                or not is_upright(c)):
            continue
        to_eye = eye - c.center
        to_eye[2] = 0.0
        if np.linalg.norm(to_eye) < 1e-9:
            continue
        to_eye /= np.linalg.norm(to_eye)
        widest = max(float(c.size[a]) for a in range(3) if abs(c.rotation[2, a]) <= 0.5)
        best = None
        for axis in range(3):
            if abs(c.rotation[2, axis]) > 0.5:
                continue
            for side in (0, 1):
                u = c.rotation[:, axis] * (1.0 if side else -1.0)
                if float(u @ to_eye) <= 0.0:
                    continue
                face = float(c.center @ u + c.size[axis] / 2)
                for o in (arr.cuboid(i) for i in broad):
                    if o.id == c.id:
                        continue
                    if not broad_face(o, -u) or not overlap_across(c, o, u):
                        continue
                    g = float((o.corners() @ u).min()) - face
                    if p.min_gap < g <= p.max_rel * widest and (best is None or g < best[0]):
                        best = (g, axis, side, o)
        if best is None:
            continue
        _, axis, side, o = best
        # onto the broad box's axes (a strip's yaw is a guess), then the gap again
        ax_c = next(a for a in range(3) if abs(c.rotation[2, a]) < 0.5)
        ax_o = next(a for a in range(3) if abs(o.rotation[2, a]) < 0.5)
        turn = ((np.arctan2(o.rotation[1, ax_o], o.rotation[0, ax_o])
                 - np.arctan2(c.rotation[1, ax_c], c.rotation[0, ax_c]) + np.pi / 4)
                % (np.pi / 2) - np.pi / 4)
        if abs(np.degrees(turn)) > p.square_max_deg:
            continue
        sq = c.with_(rotation=rotation_about_axis([0.0, 0.0, 1.0], turn) @ c.rotation)
        u = sq.rotation[:, axis] * (1.0 if side else -1.0)
        g = float((o.corners() @ u).min()) - float(sq.center @ u + sq.size[axis] / 2)
        if g <= p.min_gap or g > p.max_rel * widest:
            continue
        base = arr.with_(cuboids=tuple(sq if i == k else b for i, b in enumerate(arr.cuboids)))
        samples = slab_samples(base, Extension(k, axis, side, g))
        if (evidence.in_shadow(samples, o).mean() < p.shadow_fraction
                or evidence.free_fraction(samples) > 0.0):
            continue
        trial = push_face(base, k, axis, u, g)
        v = yield Edit((trial.cuboids[k],), f"hidden behind {o.id}: grown {100 * g:.0f} cm "
                                            f"to touch it")
        if v.ok:
            arr = v.arrangement


PRIOR = Prior("reach_occluders", "complete", Params(), apply, principle_of(__doc__))
