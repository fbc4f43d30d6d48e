"""Rows of upright boxes on one support: books on a shelf board seen from afar.

Fitted to a few dozen noisy points each, the books of a row overlap along the row by
centimetres (depth noise at 5 m smears a spine seen obliquely along the row), so no two
of them can stand side by side: the overlap repair then sets them one in front of the
other, a zig-zag in which a book touches the side panel and the book two places on while
its true neighbours float apart.  :func:`resolve_rows` puts such a row back side by side:
the order along the row is the order of the box centres (the noise smears both ends
alike), each overlap is split at its middle, and each box's face away from the camera
goes back as far as the row's farthest back face, through space no view saw empty.
"""

from __future__ import annotations

import numpy as np

from .model import Arrangement, Cuboid, ObservedBox

#: Two boxes on one support belong to one row when they overlap along the support's long
#: axis by at least this fraction of the narrower one while standing one in front of
#: the other (their extents across the support apart) ...
ROW_OVERLAP = 0.3
#: ... their yaws within this many degrees of the support's (a row's boxes are turned
#: onto its axes) ...
ROW_AXES_DEG = 15.0
#: ... and their bottoms within this many metres of its top.
ROW_REST_GAP = 0.04
#: Only boxes at least this many times as tall as they are wide along the row take part.
ROW_MIN_HEIGHT_REL = 2.0
#: The image orders a row unless the camera looks along it, within this cosine.
ROW_ALONG_COS = float(np.cos(np.radians(20.0)))
#: A split that leaves a box narrower than this along the row (metres) is not made.
ROW_MIN_WIDTH = 0.005


def _axis_towards(c: Cuboid, u: np.ndarray) -> tuple[int, float]:
    """(axis of ``c`` most nearly along ``u``, its cosine with ``u``, signed)."""
    dots = c.rotation.T @ u
    k = int(np.argmax(np.abs(dots)))
    return k, float(dots[k])


def _range(c: Cuboid, origin: np.ndarray, u: np.ndarray) -> tuple[float, float]:
    """Extent of ``c`` along the unit vector ``u`` from ``origin``."""
    half = 0.5 * float(np.abs(c.rotation.T @ u) @ c.size)
    m = float((c.center - origin) @ u)
    return m - half, m + half


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
    from .model import rotation_about_axis

    ax_c = next(k for k in range(3) if abs(c.rotation[2, k]) < 0.5)
    ax_s = next(k for k in range(3) if abs(s.rotation[2, k]) < 0.5)
    a = np.arctan2(c.rotation[1, ax_c], c.rotation[0, ax_c])
    b = np.arctan2(s.rotation[1, ax_s], s.rotation[0, ax_s])
    turn = (b - a + np.pi / 4) % (np.pi / 2) - np.pi / 4
    if abs(turn) < 1e-9:
        return c
    return c.with_(rotation=rotation_about_axis(np.array([0.0, 0.0, 1.0]), turn) @ c.rotation)


def _row_order(c: Cuboid, s: Cuboid, X: np.ndarray, views: list) -> float:
    """Where ``c`` lies along the row (support ``s``'s long axis ``X``): measured in the
    image where the scan is one view (depth noise moves a box's centre along its ray,
    which the image does not see), else along ``X`` (a box fitted to the points of
    several views is not noisy along any one view's rays; a view looking along the row,
    within :data:`ROW_ALONG_COS`, sees its boxes one behind the other)."""
    if len(views) != 1:
        return float((c.center - s.center) @ X)
    from .camera import invert, project, transform

    v = views[0]
    ray = s.center - np.asarray(v.T_world_cam, float)[:3, 3]
    if abs(float(ray @ X)) > ROW_ALONG_COS * float(np.linalg.norm(ray)):
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


_UP = np.array([0.0, 0.0, 1.0])


def _rows_by_support(arr: Arrangement, min_members: int = 2):
    """``(support, (X, Y), {index: box turned onto its axes})`` for each upright
    support with at least ``min_members`` standing slabs on it: boxes resting on it
    (bottoms within :data:`ROW_REST_GAP` of its top), yaws within :data:`ROW_AXES_DEG`
    of its own, not parts of its object, at least :data:`ROW_MIN_HEIGHT_REL` times as
    tall as wide along its long axis ``X`` (a book on its edge, not a keyboard or a
    monitor's foot).  ``Y``: the support's short horizontal axis."""
    from .imagine import _resting_on

    cos_tol = np.cos(np.radians(ROW_AXES_DEG))
    by_support: dict[str, list[int]] = {}
    for k, c in enumerate(arr.cuboids):
        if c.extra.get("hallucinated") or abs(c.rotation[2]).max() < cos_tol:
            continue
        s = _resting_on(arr, c, ROW_REST_GAP)
        if s is None or (c.object is not None and c.object == s.object):
            continue
        if (abs(s.rotation[2]).max() < 1 - 1e-9
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
            z0, z1 = _range(c, s.center, _UP)
            if z1 - z0 >= ROW_MIN_HEIGHT_REL * (x1 - x0):
                cubs[k] = c
        if len(cubs) >= min_members:
            out.append((s, (X, Y), cubs))
    return out


def resolve_rows(arr: Arrangement, views: list | None = None, margin: float = 0.0
                 ) -> tuple[Arrangement, list[str]]:
    """Set the boxes of each row on a support side by side (module docstring).

    A row: boxes resting on one upright support (bottoms within :data:`ROW_REST_GAP` of
    its top, axes within :data:`ROW_AXES_DEG` of its own, not parts of its object),
    linked by pairs that overlap along the support's long axis by :data:`ROW_OVERLAP` of
    the narrower while apart across it.  A row is changed only when no split leaves a
    box narrower than :data:`ROW_MIN_WIDTH` and no changed box enters another box;
    a box goes back only where no view saw the added space empty.  Returns the
    arrangement and the ids of the boxes changed.
    """
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    from .contacts import find_contacts
    from .extend import FREE_FRACTION_MAX, visible_free_fraction
    from .symmetry import _box_samples

    views = views or []
    eye = np.asarray(views[0].T_world_cam, float)[:3, 3] if views else None
    changed: list[str] = []
    for s, (X, Y), cubs in _rows_by_support(arr):
        members = sorted(cubs)
        xr = {k: _range(c, s.center, X) for k, c in cubs.items()}
        yr = {k: _range(c, s.center, Y) for k, c in cubs.items()}
        zr = {k: _range(c, s.center, _UP) for k, c in cubs.items()}
        links = np.zeros((len(members), len(members)), dtype=bool)
        for n, i in enumerate(members):
            for m in range(n + 1, len(members)):
                j = members[m]
                over = min(xr[i][1], xr[j][1]) - max(xr[i][0], xr[j][0])
                narrow = min(xr[i][1] - xr[i][0], xr[j][1] - xr[j][0])
                apart = yr[i][1] <= yr[j][0] + 1e-9 or yr[j][1] <= yr[i][0] + 1e-9
                level = min(zr[i][1], zr[j][1]) > max(zr[i][0], zr[j][0])
                links[n, m] = over >= ROW_OVERLAP * narrow and apart and level
        _, group = connected_components(csr_matrix(links), directed=False)
        rows: dict[int, list[int]] = {}
        for n, k in enumerate(members):
            rows.setdefault(int(group[n]), []).append(k)
        for row in rows.values():
            if len(row) < 2:
                continue
            row.sort(key=lambda k: _row_order(cubs[k], s, X, views))
            lo = [xr[k][0] for k in row]
            hi = [xr[k][1] for k in row]
            for n in range(len(row) - 1):
                if hi[n] > lo[n + 1]:
                    mid = 0.5 * (hi[n] + lo[n + 1])
                    hi[n], lo[n + 1] = mid, mid
            if any(h - l < ROW_MIN_WIDTH for l, h in zip(lo, hi)):
                continue
            # the face away from the camera goes back to the row's farthest one
            away = 1.0 if eye is None or float((s.center - eye) @ Y) >= 0 else -1.0
            back = max(yr[k][1] if away > 0 else -yr[k][0] for k in row)
            trial = list(arr.cuboids)
            for n, k in enumerate(row):
                c = cubs[k]
                new = _with_range(c, s.center, X, lo[n], hi[n])
                new = new.with_(observed=_observed_within(c, new, X))
                y0, y1 = _range(new, s.center, Y)
                a0, a1 = (y1, back) if away > 0 else (-back, y0)
                if a1 > a0:
                    added = _with_range(new, s.center, Y, a0, a1)
                    if not (views and visible_free_fraction(_box_samples(added), views, margin)
                            > FREE_FRACTION_MAX):
                        new = _with_range(new, s.center, Y, min(y0, a0), max(y1, a1))
                trial[k] = new
            cand = arr.with_(cuboids=tuple(trial))
            ids = {cubs[k].id for k in row}
            if any(a in ids or b in ids for a, b, _ in find_contacts(cand).penetrations):
                continue
            arr = cand
            changed += sorted(ids)
    return arr, changed


__all__ = ["resolve_rows", "ROW_OVERLAP", "ROW_AXES_DEG", "ROW_REST_GAP", "ROW_MIN_WIDTH"]
