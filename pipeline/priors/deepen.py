"""A part seen only face-on has depth the sensor could not see.

Evidence: the box's extents against the first view's horizontal viewing direction, the
other parts of its object, and the depth views.  Regularity: solid parts are not
millimetre slivers; a leg, a pillar or a box behind a table top seen from the front is
fitted a few millimetres deep along the view because its depth is not in the data.  A
box whose extent along a horizontal axis within ``face_on_part_deg`` of the view is
below ``thin_fraction`` of its other horizontal extent (within ``face_on_deg`` for a
slab standing on its edge that is a box of its own or shows a face of
``big_face`` metres: a box in a pile seen obliquely, a sofa's base) has its back face
pushed away from the camera towards that other extent (a square footprint), in
``steps`` increments, as far as no view saw the added space empty and nothing is
entered; a part goes no deeper than its object's other parts span along that axis, nor
further than they reach behind it.  Blocked within a step by a broad face (a back
cushion a few degrees askew to the sofa's back), it goes as deep as it fits, to
``resolution``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import (
    broad_face,
    horizontal_axes,
    object_depth,
    object_reach,
    overlap_face,
    push_face,
    resting_cut,
    single_part,
    trimmed,
    up_axis,
)
from ..contacts import find_contacts
from ..model import Arrangement, is_support_id
from .base import Edit, Prior, principle_of


@dataclass(frozen=True)
class Params:
    thin_fraction: float = 0.5  #: thin extent / other horizontal extent of a slab
    face_on_part_deg: float = 45.0  #: degrees between the thin axis and the view
    face_on_deg: float = 70.0  #: degrees, for a box of its own or a big face
    big_face: float = 0.2  #: metres: both sides of a big seen face
    steps: int = 4  #: increments of the push
    resolution: float = 0.002  #: metres: how finely a blocked push is found


def settle_resting(arr: Arrangement, cid: str) -> Arrangement | None:
    """``arr`` with the overlaps of box ``cid`` cleared where they are a box resting on
    another (:func:`pipeline.boxops.resting_cut`) or where ``cid`` reaches into the other
    by at most a tenth of its extent; None when another overlap remains."""
    for _ in range(4):
        pens = [(a, b) for a, b, _ in find_contacts(arr).penetrations if cid in (a, b)]
        if not pens:
            return arr
        cubs = list(arr.cuboids)
        for a, b in pens:
            if b.startswith(("ground", "wall:")):
                return None
            ia, ib = arr.index[a], arr.index[b]
            rest = resting_cut(cubs[ia], cubs[ib])
            if rest is not None:
                cubs[ia], cubs[ib] = rest
                continue
            # else the deepened box gives way where it reaches least far, if by little
            k, other = (ia, cubs[ib]) if a == cid else (ib, cubs[ia])
            face = overlap_face(cubs[k], other)
            if face is None or face[0] > 0.1 * float(cubs[k].size[face[1]]):
                return None
            cubs[k] = trimmed(cubs[k], other)
        arr = arr.with_(cuboids=tuple(cubs))
    return None


def apply(arr, evidence, p: Params, ctx):
    from ..extend import Extension

    if not evidence:
        return
    eye = evidence.eye
    for k in range(len(arr.cuboids)):
        c = arr.cuboids[k]
        look = c.center - eye
        look[2] = 0.0  # the horizontal viewing direction (cameras often look down steeply)
        if np.linalg.norm(look) < 1e-9:
            continue
        look /= np.linalg.norm(look)
        horizontal = horizontal_axes(c)
        height = float(c.size[up_axis(c)])
        for axis in horizontal:
            along = float(c.rotation[:, axis] @ look)
            width = max((float(c.size[a]) for a in horizontal if a != axis), default=0.0)
            if c.size[axis] >= p.thin_fraction * width:
                continue
            if abs(along) < np.cos(np.radians(p.face_on_part_deg)):
                # seen obliquely: only a box of its own or a big face, and only a slab
                # standing on its edge (not a keyboard seen from above)
                big = np.delete(c.size, axis).min() >= p.big_face
                if (abs(along) < np.cos(np.radians(p.face_on_deg))
                        or not (big or single_part(arr, c))
                        or c.size[axis] >= p.thin_fraction * height):
                    continue
            side = 1 if along > 0 else 0  # the face away from the camera
            u = c.rotation[:, axis] * (1.0 if side else -1.0)
            target = min(width, object_depth(arr, c, axis),
                         object_reach(arr, c, u) + float(c.size[axis]) / 2)
            full = target - float(c.size[axis])
            if full <= 1e-4:
                break

            def deeper(length: float, base=arr, k=k, cid=c.id, axis=axis, u=u
                       ) -> Arrangement | None:
                return settle_resting(push_face(base, k, axis, u, length), cid)

            best, done = None, 0.0
            for j in range(1, p.steps + 1):
                length = full * j / p.steps
                from ..evidence import slab_samples

                if evidence.seen_empty(slab_samples(arr, Extension(k, axis, side, length))):
                    break
                trial = deeper(length)
                if trial is None:
                    # blocked within this step by a broad face: as deep as it goes (a
                    # wall, the floor or a small box in the way say nothing of the depth)
                    pens = find_contacts(push_face(arr, k, axis, u, length)).penetrations
                    into = [q if pp == c.id else pp for pp, q, _ in pens if c.id in (pp, q)]
                    if any(is_support_id(q) or not broad_face(arr.cuboid(q), -u)
                           for q in into):
                        break
                    lo, hi = done, length
                    while hi - lo > p.resolution:
                        mid = 0.5 * (lo + hi)
                        trial = deeper(mid)
                        if trial is None:
                            hi = mid
                        else:
                            lo, best = mid, trial
                    break
                best, done = trial, length
            if best is not None:
                changed = tuple(b for b, old in zip(best.cuboids, arr.cuboids, strict=True)
                                if b is not old)
                v = yield Edit(changed, f"seen face-on, {1000 * float(c.size[axis]):.0f} mm "
                                        f"deep: pushed back from the camera")
                if v.ok:
                    arr = v.arrangement
            break


PRIOR = Prior("deepen", "complete", Params(), apply, principle_of(__doc__))
