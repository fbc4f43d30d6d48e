"""Books in a row stand side by side on their board, as deep as it is.

Evidence: boxes resting on one upright support, their observed centres in the image, and
the depth views.  Regularity: slabs standing on one board next to each other (books on a
shelf) stand side by side along it; fitted to a few dozen noisy points each at 5 m, they
overlap along the row by centimetres and the overlap repair sets them one behind the
other, a zig-zag in which true neighbours float apart.  A row is the boxes resting on one
upright support (bottoms within ``rest_gap`` of its top, axes within ``axes_deg`` of
its own, not parts of its object, ``min_height_rel`` times as tall as wide along it)
linked by pairs overlapping along the support's long axis by ``overlap`` of the narrower
while apart across it.  The row (of one box or more) is ordered as the image shows it
(noise moves a box along its ray, which the image does not see; by the fitted centres
when the view looks along the row within ``along_deg``), each overlap is split at its
middle (no box left narrower than ``min_width``), and each box's face away from the
camera goes back to the row's farthest or the board's back edge (``to_board``; a book
is seen by its spine, and the board under it says how deep the shelf is), no box deeper
than it is tall, as far as no view saw the added space empty and it enters no box
outside the row but its board (tried shorter in ``steps``; a spine fitted a few
millimetres into its board still goes back).  Two members apart across the row whose
extents along it overlap at all (``overlap``) cannot both reach the back edge: they are
neighbours, set side by side.  A box outside the row that the push back would enter
lies beside the member, not behind it, when its extent along the row covers one end of
the member's and at most ``beside_rel`` of its width (a neighbour whose foot the view
did not see, or one already as deep as the board): the member gives up that strip along
the row, as a split does, and goes back; a box covering more of it, or its middle,
stops the push as before.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..boxops import (
    UP,
    box_samples,
    entered,
    extent_along,
    is_free,
    is_upright,
    resting_on,
    turn_onto,
    turned_by,
)
from ..camera import invert, project, transform
from ..model import Arrangement, Cuboid, ObservedBox
from .base import Edit, Prior, principle_of


@dataclass(frozen=True)
class Params:
    overlap: float = 0.0  #: share of the narrower box two overlapping row members share
    axes_deg: float = 15.0  #: degrees a member's yaw may differ from its support's
    rest_gap: float = 0.04  #: metres between a member's bottom and the support's top
    min_height_rel: float = 2.0  #: a member is this many times as tall as wide
    along_deg: float = 20.0  #: degrees: a view this close to the row orders by centres
    min_width: float = 0.005  #: metres: no split leaves a member narrower
    steps: int = 4  #: a push back into space a view saw empty is tried shorter in steps
    to_board: bool = True  #: members go back to the board's back edge
    beside_rel: float = 0.5  #: share of its width a member gives up along the row to a neighbour


def _axis_towards(c: Cuboid, u: np.ndarray) -> tuple[int, float]:
    """(axis of ``c`` most nearly along ``u``, its cosine with ``u``, signed)."""
    dots = c.rotation.T @ u
    k = int(np.argmax(np.abs(dots)))
    return k, float(dots[k])


def _range(c: Cuboid, origin: np.ndarray, u: np.ndarray) -> tuple[float, float]:
    """Extent of ``c`` along the unit vector ``u`` from ``origin``."""
    lo, hi = extent_along(c, u)
    m0 = float(origin @ u)
    return lo - m0, hi - m0


def _with_range(c: Cuboid, origin: np.ndarray, u: np.ndarray, lo: float, hi: float
                ) -> Cuboid:
    """``c`` with its extent along ``u`` (one of its axes, nearly) set to ``[lo, hi]``."""
    k, cos = _axis_towards(c, u)
    axis = c.rotation[:, k] * np.sign(cos)
    old_lo, old_hi = _range(c, origin, u)
    size = c.size.copy()
    size[k] = hi - lo
    center = c.center + axis * (0.5 * (lo + hi) - 0.5 * (old_lo + old_hi))
    return c.with_(center=center, size=size)


def _beside(arr: Arrangement, new: Cuboid, added: Cuboid, origin: np.ndarray,
            X: np.ndarray, skip, p: Params) -> Cuboid | None:
    """``new`` as it may be pushed back into ``added`` (the space behind it): itself when
    ``added`` enters no box but those at ``skip``; narrowed along the row ``X`` to clear
    the boxes it enters when each lies beside it (its extent along ``X`` covers one end of
    ``new``'s, at most ``p.beside_rel`` of its width, and no less than ``p.min_width`` is
    left); else None."""
    hit = entered(arr, added, skip)
    if not len(hit):
        return new
    lo, hi = _range(new, origin, X)
    width = hi - lo
    for h in hit.tolist():
        h0, h1 = _range(arr.cuboids[h], origin, X)
        if h0 > lo and h0 < hi and h1 >= hi and hi - h0 <= p.beside_rel * width:
            hi = h0  # the neighbour beyond new's high end
        elif h1 < hi and h1 > lo and h0 <= lo and h1 - lo <= p.beside_rel * width:
            lo = h1
        else:
            return None
    if hi - lo < p.min_width:
        return None
    narrowed = _with_range(new, origin, X, lo, hi)
    narrowed = narrowed.with_(observed=_observed_within(new, narrowed, X))
    return narrowed if is_free(arr, _with_range(added, origin, X, lo, hi), skip) else None


def _observed_within(c: Cuboid, new: Cuboid, u: np.ndarray) -> ObservedBox | None:
    """``c``'s observed box cut along ``u`` to what ``new`` keeps of it (the rest was
    the noise the split took away)."""
    o = c.observed
    if o is None:
        return None
    k, cos = _axis_towards(c, u)
    axis = c.rotation[:, k] * np.sign(cos)
    olo = float(o.center @ axis) - o.size[k] / 2
    ohi = float(o.center @ axis) + o.size[k] / 2
    nlo = float(new.center @ axis) - new.size[k] / 2
    nhi = float(new.center @ axis) + new.size[k] / 2
    lo, hi = max(olo, nlo), min(ohi, nhi)
    if hi <= lo:  # nothing of it left: the new box's own extent
        lo, hi = nlo, nhi
    size = o.size.copy()
    size[k] = hi - lo
    return ObservedBox(o.center + axis * (0.5 * (lo + hi) - float(o.center @ axis)), size)


def _turned(c: Cuboid, s: Cuboid) -> Cuboid:
    """``c`` turned about the vertical through its centre onto the axes of the upright
    ``s`` (the turn of at most 45 degrees that does it): the yaw of a box fitted to a few
    dozen points is noise."""
    turn = turn_onto(c, s)
    return c if abs(turn) < 1e-9 else turned_by(c, turn)


def row_order(c: Cuboid, s: Cuboid, X: np.ndarray, views, along_deg: float = 20.0) -> float:
    """Where ``c`` lies along the row (support ``s``'s long axis ``X``): measured in the
    image where the scan is one view (depth noise moves a box's centre along its ray,
    which the image does not see), else along ``X`` (a box fitted to the points of
    several views is not noisy along any one view's rays; a view looking along the row,
    within ``along_deg``, sees its boxes one behind the other)."""
    if len(views) != 1:
        return float((c.center - s.center) @ X)
    v = views[0]
    ray = s.center - np.asarray(v.T_world_cam, float)[:3, 3]
    if abs(float(ray @ X)) > np.cos(np.radians(along_deg)) * float(np.linalg.norm(ray)):
        # looking along the row: the boxes' centres fall on nearly one image point
        return float((c.center - s.center) @ X)
    # where the sensor put it (the overlap repair since moved it across the row, which
    # is not along the ray)
    at = c.observed.center if c.observed is not None else c.center
    cam = transform(invert(np.asarray(v.T_world_cam, float)),
                    np.stack([at, s.center - 0.1 * X, s.center + 0.1 * X]))
    uv, z = project(cam, v.intrinsics)
    if np.any(z <= 0) or not np.all(np.isfinite(uv)):
        return float((c.center - s.center) @ X)
    along = uv[2] - uv[1]
    return float((uv[0] - uv[1]) @ along / max(float(np.linalg.norm(along)), 1e-9))


def rows_by_support(arr: Arrangement, p: Params, min_members: int = 1):
    """``(support, (X, Y), {index: box turned onto its axes})`` for each upright
    support with at least ``min_members`` standing slabs on it: boxes resting on it
    (bottoms within ``p.rest_gap`` of its top), yaws within ``p.axes_deg``
    of its own, not parts of its object, at least ``p.min_height_rel`` times as
    tall as wide along its long axis ``X`` (a book on its edge, not a keyboard or a
    monitor's foot).  ``Y``: the support's short horizontal axis."""
    cos_tol = np.cos(np.radians(p.axes_deg))
    by_support: dict[str, list[int]] = {}
    for k, c in enumerate(arr.cuboids):
        if c.extra.get("hallucinated") or not is_upright(c):
            continue
        s = resting_on(arr, c, p.rest_gap)
        if s is None or (c.object is not None and c.object == s.object):
            continue
        if (not is_upright(s)
                or np.min(np.abs(s.rotation.T @ c.rotation).max(axis=0)) < cos_tol):
            continue
        by_support.setdefault(s.id, []).append(k)
    out = []
    for sid, members in sorted(by_support.items()):
        s = arr.cuboid(sid)
        horiz = [a for a in range(3) if abs(s.rotation[2, a]) < 0.5]
        X = s.rotation[:, max(horiz, key=lambda a: float(s.size[a]))]
        Y = s.rotation[:, min(horiz, key=lambda a: float(s.size[a]))]
        cubs = {}
        for k in members:
            c = _turned(arr.cuboids[k], s)
            x0, x1 = _range(c, s.center, X)
            z0, z1 = _range(c, s.center, UP)
            if z1 - z0 >= p.min_height_rel * (x1 - x0):
                cubs[k] = c
        if len(cubs) >= min_members:
            out.append((s, (X, Y), cubs))
    return out


def apply(arr, evidence, p: Params, ctx):
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    views = evidence.views
    eye = evidence.eye
    for s, (X, Y), cubs in rows_by_support(arr, p):
        members = sorted(cubs)
        xr = {k: _range(c, s.center, X) for k, c in cubs.items()}
        yr = {k: _range(c, s.center, Y) for k, c in cubs.items()}
        zr = {k: _range(c, s.center, UP) for k, c in cubs.items()}
        links = np.zeros((len(members), len(members)), dtype=bool)
        for n, i in enumerate(members):
            for m in range(n + 1, len(members)):
                j = members[m]
                over = min(xr[i][1], xr[j][1]) - max(xr[i][0], xr[j][0])
                narrow = min(xr[i][1] - xr[i][0], xr[j][1] - xr[j][0])
                apart = yr[i][1] <= yr[j][0] + 1e-9 or yr[j][1] <= yr[i][0] + 1e-9
                level = min(zr[i][1], zr[j][1]) > max(zr[i][0], zr[j][0])
                links[n, m] = over >= p.overlap * narrow and apart and level
        _, group = connected_components(csr_matrix(links), directed=False)
        rows: dict[int, list[int]] = {}
        for n, k in enumerate(members):
            rows.setdefault(int(group[n]), []).append(k)
        for row in rows.values():
            row.sort(key=lambda k: row_order(cubs[k], s, X, views, p.along_deg))
            lo = [xr[k][0] for k in row]
            hi = [xr[k][1] for k in row]
            for n in range(len(row) - 1):
                if hi[n] > lo[n + 1]:
                    mid = 0.5 * (hi[n] + lo[n + 1])
                    hi[n], lo[n + 1] = mid, mid
            if any(h - l < p.min_width for l, h in zip(lo, hi)):
                continue
            # the face away from the camera goes back to the row's farthest one, or to
            # the board's back edge, no member deeper than it is tall
            away = 1.0 if eye is None or float((s.center - eye) @ Y) >= 0 else -1.0
            back = max(yr[k][1] if away > 0 else -yr[k][0] for k in row)
            s0, s1 = _range(s, s.center, Y)
            if p.to_board:
                back = max(back, s1 if away > 0 else -s0)
            new_boxes = []
            for n, k in enumerate(row):
                c = cubs[k]
                new = _with_range(c, s.center, X, lo[n], hi[n])
                new = new.with_(observed=_observed_within(c, new, X))
                y0, y1 = _range(new, s.center, Y)
                tall = zr[k][1] - zr[k][0]
                a0, a1 = ((y1, min(back, max(y1, y0 + tall))) if away > 0
                          else (max(-back, min(y0, y1 - tall)), y0))
                skip = row + [arr.index[s.id]]
                for j in range(p.steps, 0, -1):  # as far back as no view saw empty
                    b0, b1 = (a0, a0 + (a1 - a0) * j / p.steps) if away > 0 else (
                        a1 - (a1 - a0) * j / p.steps, a1)
                    if b1 - b0 <= 1e-4:
                        break
                    added = _with_range(new, s.center, Y, b0, b1)
                    if evidence.seen_empty(box_samples(added)):
                        continue
                    narrowed = _beside(arr, new, added, s.center, X, skip, p)
                    if narrowed is not None:
                        new = _with_range(narrowed, s.center, Y, min(y0, b0), max(y1, b1))
                        break
                new_boxes.append(new)
            v = yield Edit(tuple(new_boxes), f"a row of {len(row)} on {s.id} set side by side")
            if v.ok:
                arr = v.arrangement


PRIOR = Prior("rows", "complete", Params(), apply, principle_of(__doc__))
