"""Two solid boxes cannot overlap: an overlap between fitted boxes is fitting noise.

Evidence: the fitted boxes, their point counts, the first camera.  Physics: solids do
not interpenetrate, so an overlap is no contact and must go before the candidates are
made.  Two overlapping boxes of one object with the same axes are one part seen as two
slabs and merge (unless the segmentation named two parts).  A box resting on a broader
one gives way at the face they share.  Otherwise the box that loses the smallest share
of its extent gives way through its least overlapping face; when each would lose more
than half (two books a centimetre deep, one behind the other) the faces are chosen by
share, a box fitted to ``evidence_ratio`` times the other's points keeps the space (the
other first squared to it when more than ``square_min_deg`` askew), two slabs both seen
face-on are never cleared along the view (the camera saw both fronts), two boxes side by
side never from below; and when still both would lose over half, both give way by half.
A box reaching below a support plane loses the part below it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import (
    floor_height,
    horizontal_axes,
    lifted_from_plane,
    merged,
    penetrating,
    points_of,
    relative_overlap,
    resting_cut,
    same_axes,
    same_part,
    side_by_side,
    squared_to,
    trimmed,
)
from ..contacts import find_contacts
from ..model import Cuboid
from .base import Edit, Prior, principle_of


@dataclass(frozen=True)
class Params:
    max_rounds: int = 10  #: passes over the overlapping pairs
    evidence_ratio: float = 4.0  #: points one box needs over the other to keep the space
    square_min_deg: float = 10.0  #: degrees askew beyond which the weak box is squared
    thin_fraction: float = 0.5  #: a slab seen face-on: thin / wide horizontal extent
    face_on_deg: float = 45.0  #: degrees: its thin axis within this of the view


def face_on_axis(c: Cuboid, eye: np.ndarray, p: Params) -> int | None:
    """The horizontal axis of ``c`` within ``p.face_on_deg`` of the horizontal viewing
    direction from ``eye`` when ``c`` is a slab seen face-on along it, else None."""
    look = c.center - eye
    look[2] = 0.0
    if np.linalg.norm(look) < 1e-9:
        return None
    look /= np.linalg.norm(look)
    horizontal = horizontal_axes(c)
    for axis in horizontal:
        width = max((float(c.size[a]) for a in horizontal if a != axis), default=0.0)
        if (abs(float(c.rotation[:, axis] @ look)) >= np.cos(np.radians(p.face_on_deg))
                and c.size[axis] < p.thin_fraction * width):
            return axis
    return None


def _clear_pair(ci: Cuboid, cj: Cuboid, eye, floor, p: Params):
    """(new ci, new cj, how) for one overlapping pair; ``None`` for a box merged away."""
    if (ci.object is not None and ci.object == cj.object and same_axes(ci, cj)
            and same_part(ci, cj)):
        return merged(ci, cj), None, "one part seen as two slabs: merged"
    if not penetrating(ci, cj):
        return ci, cj, ""  # an earlier cut of this round already cleared them
    rest = resting_cut(ci, cj, slabs=floor)
    if rest is not None:
        return rest[0], rest[1], "cleared at the face one rests on"
    ri, rj = relative_overlap(ci, cj), relative_overlap(cj, ci)
    by_share = min(ri, rj) > 0.5
    skip = None
    side = False
    if by_share:  # thin boxes: clear through the face that costs least of them
        side = side_by_side(ci, cj)
        if eye is not None:
            ai, aj = face_on_axis(ci, eye, p), face_on_axis(cj, eye, p)
            if (ai is not None and aj is not None
                    and abs(ci.rotation[:, ai] @ cj.rotation[:, aj]) > 0.9):
                skip = (ai, aj)
        ri = relative_overlap(ci, cj, True, None if skip is None else skip[0], side)
        rj = relative_overlap(cj, ci, True, None if skip is None else skip[1], side)
        # ... unless one was fitted to far more points: the other gives way
        pi, pj = points_of(ci), points_of(cj)
        if pj >= p.evidence_ratio * pi:
            ri, rj = 0.0, 1.0
            ci = squared_to(ci, cj, p.square_min_deg)
        elif pi >= p.evidence_ratio * pj:
            ri, rj = 1.0, 0.0
            cj = squared_to(cj, ci, p.square_min_deg)
        if not penetrating(ci, cj):
            return ci, cj, "squared to the better-seen box"
    si, sj = (None, None) if skip is None else skip
    if min(ri, rj) <= 0.5:  # the box that loses least of itself gives way
        if ri <= rj:
            ci = trimmed(ci, cj, by_share=by_share, skip=si, sideways=side)
        else:
            cj = trimmed(cj, ci, by_share=by_share, skip=sj, sideways=side)
        return ci, cj, "the box losing the least share gives way"
    return (trimmed(ci, cj, share=0.5, by_share=by_share, skip=si, sideways=side),
            trimmed(cj, ci, share=0.5, by_share=by_share, skip=sj, sideways=side),
            "both give way by half")


def apply(arr, evidence, p: Params, ctx):
    eye = evidence.eye
    floor = floor_height(arr)
    for _ in range(p.max_rounds):
        cs = find_contacts(arr)
        if not cs.penetrations:
            break
        cubs: list[Cuboid | None] = list(arr.cuboids)
        idx = arr.index
        for a_id, b_id, _depth in cs.penetrations:
            if b_id.startswith(("ground", "wall:")):
                k = idx[a_id]
                if cubs[k] is not None:
                    new = lifted_from_plane(cubs[k], arr.support(b_id))
                    v = yield Edit((new,), f"below {b_id}: cut at its plane")
                    if v.ok:
                        cubs[k] = new
                continue
            i, j = idx[a_id], idx[b_id]
            ci, cj = cubs[i], cubs[j]
            if ci is None or cj is None:
                continue
            ni, nj, how = _clear_pair(ci, cj, eye, floor, p)
            if not how:
                continue
            changed = tuple(c for c, old in ((ni, ci), (nj, cj)) if c is not None and c is not old)
            v = yield Edit(changed, f"{a_id} and {b_id} overlap: {how}",
                           removed=(cj.id,) if nj is None else ())
            if v.ok:
                cubs[i], cubs[j] = ni, nj
        arr = arr.with_(cuboids=tuple(c for c in cubs if c is not None))


PRIOR = Prior("overlaps", "prepare", Params(), apply, principle_of(__doc__))
