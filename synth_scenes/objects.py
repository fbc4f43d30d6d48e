"""Object builders: furniture, boxes, books, stacks, each a :class:`Group` in its own frame.

Every builder takes a ``numpy.random.Generator`` and returns a group standing on the
floor z = 0 (hanging groups: against the wall y = 0, normal +y), roughly centred on
the origin, with its contacts listed by construction.  Sizes are realistic ranges in
metres.  Parts of one piece of furniture are fused (``fixed``); things resting on
something (items on a table top, books on a board, a piece of furniture on the floor)
``touch``.  Unlisted boxes keep at least :data:`~synth_scenes.builder.CLEARANCE` apart.

Stability is designed in, with margins (the centre of mass of every load lies inside
its support polygon shrunk by a margin); the engines confirm it (``synth_scenes.truth``).

Proportions come from a table of ranges per builder (``ranges=``): :data:`CLASSIC`, the
ranges the builders were first written with (the default: the demo scene draws from
them), and :data:`WIDE`, what the scene families draw from: tables 0.4-1.1 m high, one
to seven shelf boards, thin and thick legs and panels, low and deep sofas, and more
things on tables, desks, shelves and chair seats, so that no rule of the method can lean
on one family's proportions.  Lengths in metres; ``(lo, hi)`` pairs are uniform ranges,
counts are inclusive integer ranges, ``p_*`` are probabilities.
"""

from __future__ import annotations

import numpy as np

from pipeline.model import box_corners, rotation_about_axis, rotation_about_z

from .builder import CLEARANCE, Group

X_AXIS = np.array([1.0, 0.0, 0.0])
Y_AXIS = np.array([0.0, 1.0, 0.0])

#: The builders' first ranges (the default of every ``ranges=``; the demo scene's).
CLASSIC: dict[str, dict] = {
    "column": {"side": (0.15, 0.45), "height": (0.1, 0.35), "brick": ((0.2, 0.4), (0.15, 0.3),
                                                                     (0.08, 0.2))},
    "pyramid": {"width": (0.2, 0.4), "height": (0.12, 0.3), "depth": (0.2, 0.4)},
    "counterweight": {"block": ((0.2, 0.4), (0.25, 0.45), (0.3, 0.7)), "length": (0.9, 1.5),
                      "thickness": (0.03, 0.06)},
    "bridge": {"pillar": ((0.15, 0.3), (0.2, 0.4), (0.3, 0.8)), "span": (0.4, 1.0),
               "deck": (0.03, 0.08), "items": (0, 2)},
    "table": {"width": (0.8, 1.6), "depth": (0.6, 0.9), "top": (0.03, 0.05),
              "height": (0.7, 0.78), "leg": (0.04, 0.07), "inset": (0.02, 0.1), "items": (1, 4)},
    "chair": {"width": (0.4, 0.5), "depth": (0.4, 0.5), "seat": (0.03, 0.05),
              "height": (0.42, 0.48), "leg": (0.03, 0.05), "inset": (0.0, 0.04),
              "back": (0.02, 0.04), "back_height": (0.35, 0.5), "p_seat_item": 0.0},
    "shelf": {"width": (0.6, 1.1), "depth": (0.25, 0.4), "height": (0.9, 1.9),
              "side": (0.015, 0.03), "board": (0.015, 0.03), "spacing": 0.32, "boards": (3, 5),
              "p_box": 0.6, "boxes": (1, 1), "top_items": (0, 0)},
    "wall_shelf": {"boards": (1, 3), "width": (0.5, 1.2), "depth": (0.18, 0.3),
                   "board": (0.02, 0.035), "lowest": (0.9, 1.4), "gap": (0.35, 0.45),
                   "items": (0, 2), "top_max": None},
    "desk": {"width": (1.0, 1.6), "depth": (0.6, 0.8), "top": (0.025, 0.04),
             "height": (0.72, 0.76), "panel": (0.02, 0.035), "drawer": (0.35, 0.45),
             "items": (0, 2), "p_monitor": 1.0},
    "sofa": {"width": (1.2, 2.0), "depth": (0.55, 0.7), "seat": (0.3, 0.4),
             "arm": (0.12, 0.22), "arm_height": (0.55, 0.68), "back": (0.15, 0.25),
             "back_height": (0.75, 0.9), "cushions": (2, 3), "cushion": (0.08, 0.14)},
}

#: What the scene families draw from (:mod:`synth_scenes.families`): wider proportions
#: and more clutter on surfaces.
WIDE: dict[str, dict] = {
    "column": {"side": (0.1, 0.6), "height": (0.05, 0.45), "brick": ((0.15, 0.5), (0.1, 0.35),
                                                                    (0.05, 0.25))},
    "pyramid": {"width": (0.12, 0.5), "height": (0.06, 0.4), "depth": (0.12, 0.5)},
    "counterweight": {"block": ((0.15, 0.5), (0.2, 0.5), (0.2, 0.9)), "length": (0.7, 1.8),
                      "thickness": (0.02, 0.08)},
    "bridge": {"pillar": ((0.1, 0.35), (0.15, 0.5), (0.2, 1.0)), "span": (0.3, 1.3),
               "deck": (0.02, 0.1), "items": (0, 3)},
    "table": {"width": (0.5, 2.0), "depth": (0.5, 1.1), "top": (0.02, 0.06),
              "height": (0.4, 1.1), "leg": (0.03, 0.09), "inset": (0.0, 0.1), "items": (0, 6)},
    "chair": {"width": (0.35, 0.6), "depth": (0.35, 0.6), "seat": (0.02, 0.06),
              "height": (0.3, 0.65), "leg": (0.02, 0.06), "inset": (0.0, 0.05),
              "back": (0.015, 0.05), "back_height": (0.2, 0.7), "p_seat_item": 0.3},
    "shelf": {"width": (0.4, 1.4), "depth": (0.2, 0.5), "height": (0.5, 2.1),
              "side": (0.012, 0.04), "board": (0.012, 0.04), "spacing": 0.25, "boards": (2, 7),
              "p_box": 0.8, "boxes": (1, 2), "top_items": (0, 2)},
    "wall_shelf": {"boards": (1, 4), "width": (0.3, 1.6), "depth": (0.12, 0.4),
                   "board": (0.015, 0.045), "lowest": (0.4, 1.5), "gap": (0.28, 0.55),
                   "items": (0, 3), "top_max": 2.3},
    "desk": {"width": (0.8, 1.9), "depth": (0.45, 0.9), "top": (0.018, 0.05),
             "height": (0.6, 1.05), "panel": (0.015, 0.05), "drawer": (0.3, 0.5),
             "items": (0, 4), "p_monitor": 0.85},
    "sofa": {"width": (0.8, 2.1), "depth": (0.5, 0.8), "seat": (0.25, 0.45),
             "arm": (0.08, 0.22), "arm_height": (0.5, 0.8), "back": (0.1, 0.3),
             "back_height": (0.65, 1.0), "cushions": (1, 4), "cushion": (0.06, 0.18)},
}


def _count(rng: np.random.Generator, lo_hi: tuple[int, int]) -> int:
    """An integer in the inclusive range ``lo_hi``."""
    return int(rng.integers(lo_hi[0], lo_hi[1] + 1))


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi))


# ---------------------------------------------------------------------------- 2D layout
def rect_polygon(footprint: np.ndarray, x: float, y: float, yaw: float):
    """Shapely polygon of the local AABB ``footprint (2, 2)`` rotated by ``yaw`` and moved."""
    from shapely.geometry import Polygon

    (x0, y0), (x1, y1) = footprint
    local = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    c, s = np.cos(yaw), np.sin(yaw)
    world = local @ np.array([[c, s], [-s, c]]) + np.array([x, y])
    return Polygon(world)


def scatter(rng: np.random.Generator, footprints: list[np.ndarray], region,
            clearance: float = CLEARANCE, yaw_range: tuple[float, float] = (-np.pi, np.pi),
            placed: list | None = None, tries: int = 60) -> list[tuple[float, float, float] | None]:
    """Random non-overlapping planar poses for footprints inside a shapely ``region``.

    Parameters
    ----------
    footprints : list of (2, 2) float
        Local ``[[xmin, ymin], [xmax, ymax]]`` of each thing to place, in order.
    region : shapely Polygon
        Where footprints must lie entirely.
    clearance : float
        Minimum distance between any two footprints (and to ``placed``).
    placed : list of shapely geometries, optional
        Obstacles already there; accepted footprints are appended to it.

    Returns
    -------
    poses : list of (x, y, yaw) or None
        None where no pose was found within ``tries`` samples.
    """
    placed = [] if placed is None else placed
    (bx0, by0, bx1, by1) = region.bounds
    out: list[tuple[float, float, float] | None] = []
    for fp in footprints:
        pose = None
        for _ in range(tries):
            yaw = _u(rng, *yaw_range) if yaw_range[1] > yaw_range[0] else float(yaw_range[0])
            x, y = _u(rng, bx0, bx1), _u(rng, by0, by1)
            poly = rect_polygon(fp, x, y, yaw)
            if region.contains(poly) and all(poly.distance(q) >= clearance for q in placed):
                pose = (x, y, yaw)
                placed.append(poly)
                break
        out.append(pose)
    return out


def place_items(rng: np.random.Generator, g: Group, support: int, items: list[Group],
                rect: tuple[float, float, float, float], margin: float = 0.03,
                yaw_range: tuple[float, float] = (-0.5, 0.5), placed: list | None = None) -> int:
    """Put item groups (built standing on z = 0) on the horizontal top face of part ``support``.

    ``rect`` = ``(xmin, xmax, ymin, ymax)`` of the usable top face in ``g``'s frame; items
    keep ``margin`` from its border and :data:`CLEARANCE` from each other.  Items that do
    not fit are dropped.  Returns how many were placed.
    """
    from shapely.geometry import box as shapely_box

    x0, x1, y0, y1 = rect
    if x1 - x0 <= 2 * margin or y1 - y0 <= 2 * margin:
        return 0
    region = shapely_box(x0 + margin, y0 + margin, x1 - margin, y1 - margin)
    z = g.top(support)
    poses = scatter(rng, [it.footprint() for it in items], region, CLEARANCE, yaw_range, placed)
    n = 0
    for item, pose in zip(items, poses, strict=True):
        if pose is None:
            continue
        g.extend(item, (pose[0], pose[1], z), pose[2], ground_as=support)
        n += 1
    return n


# ---------------------------------------------------------------------------- small items
def box_item(rng: np.random.Generator, lo: float = 0.08, hi: float = 0.3) -> Group:
    """A cardboard box standing on the floor."""
    g = Group()
    s = rng.uniform(lo, hi, size=3)
    s[2] = min(s[2], 1.5 * min(s[0], s[1]))  # not a tall thin pole
    g.touch(g.add((0, 0, s[2] / 2), s, "box"), "ground")
    return g


def book_flat(rng: np.random.Generator) -> Group:
    """A book lying flat."""
    g = Group()
    s = np.array([_u(rng, 0.15, 0.3), _u(rng, 0.11, 0.22), _u(rng, 0.015, 0.05)])
    g.touch(g.add((0, 0, s[2] / 2), s, "book"), "ground")
    return g


def book_stack(rng: np.random.Generator, n: int | None = None) -> Group:
    """2-4 books lying on each other with small offsets and turns."""
    g = Group()
    n = int(rng.integers(2, 5)) if n is None else n
    base = np.array([_u(rng, 0.18, 0.3), _u(rng, 0.13, 0.22)])
    z, below = 0.0, "ground"
    for _ in range(n):
        s = np.array([*(base * rng.uniform(0.85, 1.0, size=2)), _u(rng, 0.015, 0.05)])
        off = rng.uniform(-0.06, 0.06, size=2) * base
        k = g.add((off[0], off[1], z + s[2] / 2), s, g.new_label("book"),
                  rotation_about_z(_u(rng, -0.15, 0.15)))
        g.touch(k, below)
        z, below = z + s[2], k
    return g


def surface_items(rng: np.random.Generator, n: int, kinds=("box", "book", "books")) -> list[Group]:
    """``n`` random small things to put on a surface."""
    out = []
    for kind in rng.choice(list(kinds), size=n):
        if kind == "box":
            out.append(box_item(rng, 0.06, 0.25))
        elif kind == "book":
            out.append(book_flat(rng))
        else:
            out.append(book_stack(rng))
    return out


def lean_angle(rng: np.random.Generator, t: float, h: float, lo_deg: float,
               hi_deg: float, factor: float = 2.0) -> float:
    """A lean from vertical (radians) far enough past ``atan(t / h)`` to rest on its support.

    A box of thickness ``t`` and height ``h`` leaning at ``theta`` has its centre of mass
    on the wall side of its bottom pivot edge only when ``tan(theta) > t / h``; below
    that it would stand back up.  We ask for ``tan(theta) >= factor * t / h``.
    """
    return max(np.radians(_u(rng, lo_deg, hi_deg)), float(np.arctan(factor * t / h)))


def lean_box(size, toward: int, theta: float, base_z: float, stop: float,
             other: float) -> tuple[np.ndarray, np.ndarray]:
    """Pose of a box leaning at ``theta`` from vertical toward ``-axis[toward]``.

    Its bottom edge rests on the plane z = ``base_z`` and its top edge touches the
    vertical plane ``coord[toward] = stop`` (the thing it leans on).  ``size`` is local
    (thickness along ``toward``); ``other`` is the centre coordinate along the remaining
    horizontal axis.  Returns ``center (3,)`` and ``rotation (3, 3)``.
    """
    R = (rotation_about_axis(Y_AXIS, -theta) if toward == 0
         else rotation_about_axis(X_AXIS, theta))
    corners = box_corners(np.zeros((1, 3)), R[None], np.asarray(size, float)[None])[0]
    center = np.zeros(3)
    center[toward] = stop - corners[:, toward].min()
    center[1 - toward] = other
    center[2] = base_z - corners[:, 2].min()
    return center, R


# ---------------------------------------------------------------------------- stacks
def _column_ok(centers: np.ndarray, sizes: np.ndarray, yaws: np.ndarray, margin: float) -> bool:
    """Every load (box i and all above it) has its centre of mass inside its support polygon.

    The support polygon of box ``i > 0`` is the overlap of its footprint with box
    ``i - 1``'s, shrunk by ``margin``; for box 0 its own footprint.
    """
    masses = np.prod(sizes, axis=1)
    polys = [rect_polygon(np.array([-s[:2] / 2, s[:2] / 2]), c[0], c[1], y)
             for c, s, y in zip(centers, sizes, yaws, strict=True)]
    from shapely.geometry import Point

    for i in range(len(centers)):
        com = (masses[i:, None] * centers[i:, :2]).sum(axis=0) / masses[i:].sum()
        support = polys[0] if i == 0 else polys[i].intersection(polys[i - 1])
        if support.is_empty or not support.buffer(-margin).contains(Point(com)):
            return False
    return True


def column(rng: np.random.Generator, n: int, staggered: bool = False, jitter: float = 0.2,
           max_yaw: float = 0.4, ranges: dict | None = None) -> Group:
    """A tower of ``n`` boxes, each on the one below, with random offsets and turns.

    ``staggered``: equal bricks alternately shifted left and right (a brick pier).
    Offsets shrink until every sub-tower's centre of mass is at least a margin inside
    the face it rests on.  ``ranges``: box sizes (default ``CLASSIC["column"]``).
    """
    r = CLASSIC["column"] if ranges is None else ranges
    if staggered:
        brick = np.array([_u(rng, *r["brick"][0]), _u(rng, *r["brick"][1]),
                          _u(rng, *r["brick"][2])])
        sizes = np.tile(brick, (n, 1))
        shift = _u(rng, 0.12, 0.22) * brick[0]
        offsets = np.zeros((n, 2))
        offsets[:, 0] = shift * np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
        yaws = np.zeros(n)
    else:
        sizes = np.column_stack([rng.uniform(*r["side"], n), rng.uniform(*r["side"], n),
                                 rng.uniform(*r["height"], n)])
        offsets = rng.uniform(-jitter, jitter, (n, 2)) * sizes[:, :2].min(axis=1, keepdims=True)
        offsets[0] = 0.0
        yaws = np.where(rng.random(n) < 0.5, rng.uniform(-max_yaw, max_yaw, n), 0.0)
    margin = max(0.02, 0.12 * float(sizes[:, :2].min()))
    z = np.concatenate([[0.0], np.cumsum(sizes[:-1, 2])]) + sizes[:, 2] / 2
    scale = 1.0
    for _ in range(8):
        xy = offsets * scale if staggered else np.cumsum(offsets * scale, axis=0)
        centers = np.column_stack([xy, z])
        if _column_ok(centers, sizes, yaws * scale, margin):
            break
        scale *= 0.5
    else:
        scale = 0.0
        centers = np.column_stack([np.zeros((n, 2)), z])
    centers[:, :2] -= centers[0, :2]
    g = Group()
    below: int | str = "ground"
    for k in range(n):
        i = g.add(centers[k], sizes[k], g.new_label("box"), rotation_about_z(yaws[k] * scale))
        g.touch(i, below)
        below = i
    return g


def pyramid(rng: np.random.Generator, n: int, ranges: dict | None = None) -> Group:
    """Rows of boxes, each upper box bridging the gap between two below (n boxes in all).

    The boxes of a row either stand apart or (40 %) touch side by side, which gives the
    densely connected graphs of the paper's stacking scenes (valence up to 6).
    ``ranges``: box sizes (default ``CLASSIC["pyramid"]``).
    """
    r = CLASSIC["pyramid"] if ranges is None else ranges
    b = 1
    while b * (b + 1) // 2 < n:
        b += 1
    w = _u(rng, *r["width"])
    # touching rows (gap 0: side contacts, valence up to 6) or rows with gaps
    gap = 0.0 if rng.random() < 0.4 else max(0.03, _u(rng, 0.1, 0.35) * w)
    g = Group()
    z, remaining, m = 0.0, n, b
    below: list[int] = []
    while remaining > 0 and m > 0:
        h = _u(rng, *r["height"])
        slots = np.arange(m)
        if remaining < m:
            slots = np.sort(rng.choice(m, size=remaining, replace=False))
        row: list[int] = []
        for j in slots:
            x = (j - (m - 1) / 2) * (w + gap)
            d = _u(rng, *r["depth"])
            k = g.add((x, _u(rng, -0.02, 0.02), z + h / 2), (w, d, h), g.new_label("box"))
            if not below:
                g.touch(k, "ground")
            else:
                g.touch(k, below[j])
                g.touch(k, below[j + 1])
            if gap == 0.0 and row and slots[len(row) - 1] == j - 1:
                g.touch(k, row[-1])
            row.append(k)
        below = row if len(row) == m else []
        remaining -= len(slots)
        z += h
        m -= 1
    return g


def piles(rng: np.random.Generator, n: int, ranges: dict | None = None) -> Group:
    """``n`` boxes as several short towers (1-4 boxes each) scattered on the floor.

    ``ranges``: box sizes of the towers (:func:`column`)."""
    from shapely.geometry import box as shapely_box

    heights = []
    while sum(heights) < n:
        heights.append(int(min(rng.integers(1, 5), n - sum(heights))))
    towers = [column(rng, h, ranges=ranges) for h in heights]
    side = 0.7 * np.sqrt(len(towers)) + 0.4
    while True:
        placed: list = []
        poses = scatter(rng, [t.footprint() for t in towers],
                        shapely_box(-side / 2, -side / 2, side / 2, side / 2), 0.05,
                        placed=placed)
        if all(p is not None for p in poses):
            break
        side *= 1.2
    g = Group()
    for t, (x, y, yaw) in zip(towers, poses, strict=True):
        g.extend(t, (x, y, 0.0), yaw)
    return g


# ---------------------------------------------------------------------------- structures
def counterweight(rng: np.random.Generator, ranges: dict | None = None) -> Group:
    """A plank on a block, overhanging so far it tips alone, held by a weight on its back end.

    The plank's own centre is beyond the block's edge; the weight's mass is solved so the
    combined centre of mass lies at a random point in the middle half of the block top.
    Optionally a load hangs on the overhanging tip too (then the weight is heavier).
    ``ranges``: block, plank length and thickness (default ``CLASSIC["counterweight"]``).
    """
    r = CLASSIC["counterweight"] if ranges is None else ranges
    for _ in range(100):
        bw, bd, bh = (_u(rng, *r["block"][k]) for k in range(3))
        L, t = _u(rng, *r["length"]), _u(rng, *r["thickness"])
        pd = _u(rng, 0.2, min(bd, 0.35))
        xp = bw / 2 + _u(rng, 0.06, 0.2)            # plank centre beyond the edge
        x_back = xp - L / 2
        if x_back > -bw / 2 - 0.25:                  # needs a back arm for the weight
            continue
        mp = L * pd * t
        loads = [(mp, xp)]
        tip = None
        if rng.random() < 0.4:
            ts = np.array([_u(rng, 0.08, 0.16), _u(rng, 0.08, min(0.16, pd - 0.04)),
                           _u(rng, 0.06, 0.15)])
            xt = xp + L / 2 - ts[0] / 2 - _u(rng, 0.01, 0.05)
            tip = (ts, xt)
            loads.append((float(np.prod(ts)), xt))
        ww = _u(rng, 0.1, 0.2)
        wd = _u(rng, 0.1, pd - 0.02)
        xw = x_back + ww / 2 + _u(rng, 0.0, 0.03)
        X = _u(rng, -bw / 4, bw / 4)                 # target centre of mass
        if xw > X - 0.05:
            continue
        mw = sum(m * (x - X) for m, x in loads) / (X - xw)
        wh = mw / (ww * wd)
        if not 0.04 <= wh <= 0.5:
            continue
        g = Group()
        base = g.add((0, 0, bh / 2), (bw, bd, bh), g.new_label("block"))
        g.touch(base, "ground")
        plank = g.add((xp, 0, bh + t / 2), (L, pd, t), g.new_label("plank"))
        g.touch(plank, base)
        zt = bh + t
        w = g.add((xw, _u(rng, -0.01, 0.01), zt + wh / 2), (ww, wd, wh), g.new_label("weight"))
        g.touch(w, plank)
        if tip is not None:
            ts, xt = tip
            k = g.add((xt, 0, zt + ts[2] / 2), ts, g.new_label("box"))
            g.touch(k, plank)
        return g
    raise RuntimeError("counterweight: no feasible sample in 100 tries")  # pragma: no cover


def bridge(rng: np.random.Generator, ranges: dict | None = None) -> Group:
    """Pillars (one box or two stacked) carrying decks; 1 or 2 spans, maybe boxes on top.

    ``ranges``: pillar, span, deck thickness, items per deck (default ``CLASSIC["bridge"]``).
    """
    r = CLASSIC["bridge"] if ranges is None else ranges
    spans = 1 if rng.random() < 0.65 else 2
    pw, pdp = _u(rng, *r["pillar"][0]), _u(rng, *r["pillar"][1])
    ph = _u(rng, *r["pillar"][2])
    stacked = rng.random() < 0.4
    span = _u(rng, *r["span"])
    xs = (np.arange(spans + 1) - spans / 2) * (span + pw)
    g = Group()
    tops = []
    for x in xs:
        if stacked:
            lo = g.add((x, 0, ph / 4), (pw, pdp, ph / 2), g.new_label("pillar"))
            g.touch(lo, "ground")
            hi = g.add((x, 0, 3 * ph / 4), (pw, pdp, ph / 2), g.new_label("pillar"))
            g.touch(hi, lo)
            tops.append(hi)
        else:
            k = g.add((x, 0, ph / 2), (pw, pdp, ph), g.new_label("pillar"))
            g.touch(k, "ground")
            tops.append(k)
    t = _u(rng, *r["deck"])
    dd = pdp * _u(rng, 0.8, 1.2)
    for s in range(spans):
        left = xs[s] - (pw / 2) * _u(rng, 0.2, 1.0) if s == 0 else xs[s] + 0.02
        right = (xs[s + 1] + (pw / 2) * _u(rng, 0.2, 1.0) if s == spans - 1
                 else xs[s + 1] - 0.02)
        deck = g.add(((left + right) / 2, 0, ph + t / 2), (right - left, dd, t),
                     g.new_label("deck"))
        g.touch(deck, tops[s])
        g.touch(deck, tops[s + 1])
        n_items = _count(rng, r["items"])
        largest = min(0.2, dd - 0.07)  # a deck narrower than 13 cm carries nothing
        if largest > 0.06:
            place_items(rng, g, deck, [box_item(rng, 0.06, largest) for _ in range(n_items)],
                        (left, right, -dd / 2, dd / 2), margin=0.02)
    return g


# ---------------------------------------------------------------------------- furniture
#: Table styles: ``four_legs`` (the default), ``three_legs`` (two at the back corners,
#: one at the middle of the front), ``pedestal`` (a square column on a square foot).
TABLE_STYLES = ("four_legs", "three_legs", "pedestal")


def table(rng: np.random.Generator, n_items: int | None = None,
          ranges: dict | None = None, style: str | None = None) -> Group:
    """A top fused to four legs (legs touch the floor) and a few things on the top.

    ``ranges``: sizes and the number of things (default ``CLASSIC["table"]``).
    ``style``: one of :data:`TABLE_STYLES` (None: four legs, drawing exactly what the
    builder always drew).
    """
    if style is not None and style not in TABLE_STYLES:
        raise ValueError(f"style: one of {', '.join(TABLE_STYLES)}, got {style!r}")
    r = CLASSIC["table"] if ranges is None else ranges
    W, D = _u(rng, *r["width"]), _u(rng, *r["depth"])
    T, H = _u(rng, *r["top"]), _u(rng, *r["height"])
    leg, inset = _u(rng, *r["leg"]), _u(rng, *r["inset"])
    g = Group()
    top = g.add((0, 0, H - T / 2), (W, D, T), "table")
    ex, ey = W / 2 - inset - leg / 2, D / 2 - inset - leg / 2
    if style in (None, "four_legs"):
        for sx in (-1, 1):
            for sy in (-1, 1):
                k = g.add((sx * ex, sy * ey, (H - T) / 2), (leg, leg, H - T), "table")
                g.fix(k, top)
                g.touch(k, "ground")
    elif style == "three_legs":
        for x, y in ((-ex, ey), (ex, ey), (0.0, -ey)):
            k = g.add((x, y, (H - T) / 2), (leg, leg, H - T), "table")
            g.fix(k, top)
            g.touch(k, "ground")
    else:  # pedestal: a square column on a square foot plate
        col = min(2.5 * leg, 0.3 * min(W, D))
        fw, ft = _u(rng, 0.55, 0.75) * min(W, D), _u(rng, 0.02, 0.04)
        foot = g.add((0, 0, ft / 2), (fw, fw, ft), "table")
        g.touch(foot, "ground")
        k = g.add((0, 0, ft + (H - T - ft) / 2), (col, col, H - T - ft), "table")
        g.fix(k, foot)
        g.fix(k, top)
    n_items = _count(rng, r["items"]) if n_items is None else n_items
    place_items(rng, g, top, surface_items(rng, n_items), (-W / 2, W / 2, -D / 2, D / 2))
    return g


def chair(rng: np.random.Generator, ranges: dict | None = None, arms: bool = False) -> Group:
    """Seat fused to four legs and a back (a board, or two posts and a rail); faces -y.

    ``ranges``: sizes, and ``p_seat_item``, the chance of a thing on the seat (default
    ``CLASSIC["chair"]``).  ``arms``: two side panels on the seat, fused to it and to the
    back (False: no arms, drawing exactly what the builder always drew).
    """
    r = CLASSIC["chair"] if ranges is None else ranges
    W, D = _u(rng, *r["width"]), _u(rng, *r["depth"])
    T, H = _u(rng, *r["seat"]), _u(rng, *r["height"])
    leg, inset = _u(rng, *r["leg"]), _u(rng, *r["inset"])
    g = Group()
    seat = g.add((0, 0, H - T / 2), (W, D, T), "chair")
    for sx in (-1, 1):
        for sy in (-1, 1):
            k = g.add((sx * (W / 2 - inset - leg / 2), sy * (D / 2 - inset - leg / 2),
                       (H - T) / 2), (leg, leg, H - T), "chair")
            g.fix(k, seat)
            g.touch(k, "ground")
    bt, bh = _u(rng, *r["back"]), _u(rng, *r["back_height"])
    yb = D / 2 - bt / 2
    posts: list[int] = []
    if rng.random() < 0.5:
        back = g.add((0, yb, H + bh / 2), (W, bt, bh), "chair")
        g.fix(back, seat)
    else:
        pw, rh = _u(rng, 0.03, 0.045), _u(rng, 0.08, 0.15)
        ph = bh - rh
        rail = g.add((0, yb, H + ph + rh / 2), (W, bt, rh), "chair")
        for sx in (-1, 1):
            k = g.add((sx * (W / 2 - pw / 2), yb, H + ph / 2), (pw, bt, ph), "chair")
            g.fix(k, seat)
            g.fix(rail, k)
            posts.append(k)
    x_free = W / 2
    if arms:
        # side panels on the seat from its front edge to the back: they touch the back
        # board, or the posts (and the rail when they reach it: then clearly above it)
        aw, ah = _u(rng, 0.03, 0.06), min(_u(rng, 0.15, 0.25), 0.8 * bh)
        if posts and ah > ph - CLEARANCE:
            ah = min(max(ah, ph + CLEARANCE), bh - 0.01)
        for i, sx in enumerate((-1, 1)):
            k = g.add((sx * (W / 2 - aw / 2), -bt / 2, H + ah / 2), (aw, D - bt, ah), "chair")
            g.fix(k, seat)
            if posts:
                g.fix(k, posts[i])
                if ah > ph:
                    g.fix(k, rail)
            else:
                g.fix(k, back)
        x_free = W / 2 - aw - CLEARANCE
    if r["p_seat_item"] > 0 and rng.random() < r["p_seat_item"]:
        place_items(rng, g, seat, surface_items(rng, 1, ("box", "book")),
                    (-x_free, x_free, -D / 2, D / 2 - bt - CLEARANCE), margin=0.02)
    return g


def _book_row(rng: np.random.Generator, g: Group, board: int, x0: float, x1: float,
              depth: float, clear: float, wall: int | None) -> float:
    """Upright books from x0 toward x1 on ``board`` (top z), maybe the last one leaning.

    ``wall``: the part the first book touches at x0 (a side board), or None.  Returns
    the x where the row ends (its rightmost point).
    """
    z = g.top(board)
    n = int(rng.integers(0, 9))
    x = x0
    last: int | None = wall
    last_h = np.inf
    for _ in range(n):
        t, w = _u(rng, 0.015, 0.05), _u(rng, 0.6, 0.95) * depth
        h = min(_u(rng, 0.15, 0.33), clear - 0.03)
        if h < 0.1 or x + t > x0 + 0.6 * (x1 - x0):
            break
        k = g.add((x + t / 2, _u(rng, -0.3, 0.3) * (depth - w), z + h / 2), (t, w, h),
                  g.new_label("book"))
        g.touch(k, board)
        if last is not None:
            g.touch(k, last)
        x, last, last_h = x + t, k, h
    if last is not None and rng.random() < 0.6:
        t, w = _u(rng, 0.015, 0.04), _u(rng, 0.6, 0.9) * depth
        h = _u(rng, 0.15, 0.3)
        theta = lean_angle(rng, t, h, 10, 25)
        h = min(h, 0.9 * last_h / np.cos(theta) if np.isfinite(last_h) else np.inf,
                (clear - 0.03 - t * np.sin(theta)) / np.cos(theta))
        if (h >= 0.1 and np.tan(theta) >= 1.8 * t / h
                and x + h * np.sin(theta) + t < x1 - 0.05):
            c, R = lean_box((t, w, h), 0, theta, z, x, _u(rng, -0.2, 0.2) * (depth - w))
            k = g.add(c, (t, w, h), g.new_label("book"), R)
            g.touch(k, board)
            g.touch(k, last)
            x = float(box_corners(c[None], R[None], np.array([[t, w, h]]))[0, :, 0].max())
    return x


def shelf(rng: np.random.Generator, ranges: dict | None = None) -> Group:
    """Two sides on the floor with boards fused between them; books (some leaning) and boxes.

    Faces -y (its back is at the largest y, to stand against a wall).  ``ranges``: sizes,
    board count and least spacing, boxes per board and things on top (default
    ``CLASSIC["shelf"]``).
    """
    r = CLASSIC["shelf"] if ranges is None else ranges
    W, D, H = _u(rng, *r["width"]), _u(rng, *r["depth"]), _u(rng, *r["height"])
    s = _u(rng, *r["side"])
    t = _u(rng, *r["board"])
    g = Group()
    sides = []
    for sx in (-1, 1):
        k = g.add((sx * (W / 2 - s / 2), 0, H / 2), (s, D, H), "shelf")
        g.touch(k, "ground")
        sides.append(k)
    n = max(2, int((H - 0.1) // r["spacing"]) + 1)
    n = min(n, _count(rng, r["boards"]))
    bottom = _u(rng, 0.04, 0.1)
    zs = np.linspace(bottom, H - t, n)
    boards = []
    for z in zs:
        k = g.add((0, 0, z + t / 2), (W - 2 * s, D, t), "shelf")
        g.fix(k, sides[0])
        g.fix(k, sides[1])
        boards.append(k)
    inner0, inner1 = -W / 2 + s, W / 2 - s
    for i, k in enumerate(boards[:-1]):
        clear = zs[i + 1] - (zs[i] + t)
        x_end = _book_row(rng, g, k, inner0, inner1, D, clear, sides[0])
        room_h = clear - 0.03
        if rng.random() < r["p_box"] and room_h > 0.08:
            n_box = 1 if r["boxes"][1] <= 1 else _count(rng, r["boxes"])
            items = [box_item(rng, 0.06, min(0.25, room_h)) for _ in range(n_box)]
            place_items(rng, g, k, items, (x_end + CLEARANCE, inner1, -D / 2, D / 2),
                        margin=0.01, yaw_range=(-0.3, 0.3))
    if r["top_items"][1] > 0:
        place_items(rng, g, boards[-1], surface_items(rng, _count(rng, r["top_items"])),
                    (inner0, inner1, -D / 2, D / 2), margin=CLEARANCE, yaw_range=(-0.3, 0.3))
    return g


def wall_shelf(rng: np.random.Generator, ranges: dict | None = None) -> Group:
    """Boards fused to the wall y = 0 (hanging, no legs), maybe on brackets; things on them.

    Some boards hold a book leaning against the wall (a ``touch`` with the wall).
    ``ranges``: board count and sizes, height of the lowest board, the gap between
    boards, things per board and ``top_max``, the highest a board may hang (default
    ``CLASSIC["wall_shelf"]``).
    """
    r = CLASSIC["wall_shelf"] if ranges is None else ranges
    n = _count(rng, r["boards"])
    W, D, t = _u(rng, *r["width"]), _u(rng, *r["depth"]), _u(rng, *r["board"])
    z0 = _u(rng, *r["lowest"])
    gap = _u(rng, *r["gap"])
    if r["top_max"] is not None:  # no board above the reach of a hand
        n = max(1, min(n, int((r["top_max"] - z0) // gap) + 1))
    brackets = rng.random() < 0.5
    g = Group()
    for i in range(n):
        zb = z0 + i * gap
        label = g.new_label("wall_shelf")          # each board (and its brackets): one object
        board = g.add((0, D / 2, zb + t / 2), (W, D, t), label)
        g.fix(board, "wall")
        if brackets:
            bh = min(0.12, gap - 0.1)
            for sx in (-1, 1):
                k = g.add((sx * (W / 2 - 0.06), 0.3 * D, zb - bh / 2), (0.025, 0.6 * D, bh),
                          label)
                g.fix(k, "wall")
                g.fix(k, board)
        x_free = -W / 2
        # headroom under the next board (and its brackets)
        clear = (gap - t - (min(0.12, gap - 0.1) if brackets else 0.0)) if i < n - 1 else 0.6
        if rng.random() < 0.5:
            w, bt = _u(rng, 0.12, 0.2), _u(rng, 0.015, 0.035)
            h = _u(rng, 0.18, 0.28)
            theta = lean_angle(rng, bt, h, 8, 22)
            h = min(h, (clear - 0.04) / np.cos(theta) - bt)
            if np.tan(theta) >= 1.8 * bt / h and h * np.sin(theta) + bt < D - 0.04:
                c, R = lean_box((w, bt, h), 1, theta, zb + t, 0.0, -W / 2 + 0.03 + w / 2)
                k = g.add(c, (w, bt, h), g.new_label("book"), R)
                g.touch(k, board)
                g.touch(k, "wall")
                x_free = -W / 2 + 0.03 + w + CLEARANCE
        items = [it for it in surface_items(rng, _count(rng, r["items"]))
                 if it.corners()[..., 2].max() < clear - 0.03]
        place_items(rng, g, board, items, (x_free, W / 2, CLEARANCE, D), margin=0.01,
                    yaw_range=(-0.3, 0.3))
    return g


def monitor(rng: np.random.Generator) -> Group:
    """Base plate, neck and screen, fused; faces -y."""
    bw, bd, bt = _u(rng, 0.18, 0.25), _u(rng, 0.15, 0.2), _u(rng, 0.012, 0.02)
    nw, nt, nh = _u(rng, 0.04, 0.06), _u(rng, 0.025, 0.04), _u(rng, 0.25, 0.35)
    sw, st, sh = _u(rng, 0.45, 0.62), _u(rng, 0.02, 0.035), _u(rng, 0.28, 0.38)
    g = Group()
    base = g.add((0, 0, bt / 2), (bw, bd, bt), "monitor")
    g.touch(base, "ground")
    neck = g.add((0, 0.02, bt + nh / 2), (nw, nt, nh), "monitor")
    g.fix(neck, base)
    zb = bt + _u(rng, 0.05, 0.09)
    screen = g.add((0, 0.02 - nt / 2 - st / 2, zb + sh / 2), (sw, st, sh), "monitor")
    g.fix(screen, neck)
    return g


def desk(rng: np.random.Generator, ranges: dict | None = None) -> Group:
    """A top on two side panels (or a panel and a drawer block), fused; monitor and things.

    ``ranges``: sizes, things besides the keyboard, and ``p_monitor`` (default
    ``CLASSIC["desk"]``).
    """
    r = CLASSIC["desk"] if ranges is None else ranges
    W, D = _u(rng, *r["width"]), _u(rng, *r["depth"])
    T, H = _u(rng, *r["top"]), _u(rng, *r["height"])
    p = _u(rng, *r["panel"])
    g = Group()
    top = g.add((0, 0, H - T / 2), (W, D, T), "desk")
    left = g.add((-W / 2 + p / 2, 0, (H - T) / 2), (p, D, H - T), "desk")
    if rng.random() < 0.5:
        right = g.add((W / 2 - p / 2, 0, (H - T) / 2), (p, D, H - T), "desk")
    else:
        dw = _u(rng, *r["drawer"])
        right = g.add((W / 2 - dw / 2, 0.02, (H - T) / 2), (dw, D - 0.04, H - T), "desk")
    for k in (left, right):
        g.fix(k, top)
        g.touch(k, "ground")
    placed: list = []
    if r["p_monitor"] >= 1.0 or rng.random() < r["p_monitor"]:
        place_items(rng, g, top, [monitor(rng)], (-W / 2, W / 2, 0.0, D / 2), margin=0.02,
                    yaw_range=(-0.15, 0.15), placed=placed)
    kb = Group()
    ks = np.array([_u(rng, 0.38, 0.46), _u(rng, 0.12, 0.16), _u(rng, 0.02, 0.03)])
    kb.touch(kb.add((0, 0, ks[2] / 2), ks, "keyboard"), "ground")
    items = [kb, *surface_items(rng, _count(rng, r["items"]))]
    place_items(rng, g, top, items, (-W / 2, W / 2, -D / 2, D / 2), margin=0.02,
                yaw_range=(-0.3, 0.3), placed=placed)
    return g


def sofa(rng: np.random.Generator, ranges: dict | None = None, arms: bool = True) -> Group:
    """Seat block, back and two arms fused (all on the floor), seat cushions, maybe back cushions.

    Back cushions lean on the back with their foot on the seat block itself, in a strip
    behind the (then shallower) seat cushions.  (Standing them on the seat cushions
    instead let the seat cushions slide 2 cm in PyBullet, though statics and MuJoCo
    agree they hold.)  Faces -y (back at the largest y).  ``ranges``: sizes and the
    number of seat cushions (default ``CLASSIC["sofa"]``).  ``arms=False``: no arms, the
    back as wide as the seat (the same draws, so the proportions are the armed sofa's).
    """
    r = CLASSIC["sofa"] if ranges is None else ranges
    W, D, h = _u(rng, *r["width"]), _u(rng, *r["depth"]), _u(rng, *r["seat"])
    aw, ah = _u(rng, *r["arm"]), _u(rng, *r["arm_height"])
    bd, bh = _u(rng, *r["back"]), _u(rng, *r["back_height"])
    g = Group()
    seat = g.add((0, 0, h / 2), (W, D, h), "sofa")
    with_arms = arms
    back = g.add((0, D / 2 + bd / 2, bh / 2), (W + 2 * aw if with_arms else W, bd, bh), "sofa")
    arms = [g.add((sx * (W / 2 + aw / 2), 0, ah / 2), (aw, D, ah), "sofa")
            for sx in (-1, 1)] if with_arms else []
    for k in (seat, back, *arms):
        g.touch(k, "ground")
    g.fix(seat, back)
    for a in arms:
        g.fix(a, seat)
        g.fix(a, back)
    n = _count(rng, r["cushions"])
    ch = _u(rng, *r["cushion"])
    cw = W / n
    with_back = rng.random() < 0.6
    bt, bch = _u(rng, 0.06, 0.1), _u(rng, 0.35, 0.45)
    theta = lean_angle(rng, bt, bch, 15, 28, factor=2.5)
    bch = min(bch, (bh - 0.04 - h - bt * np.sin(theta)) / np.cos(theta))  # below the back's top
    strip = bch * np.sin(theta) + bt * np.cos(theta) + CLEARANCE  # depth the back cushions take
    with_back = (with_back and bch >= 0.2 and np.tan(theta) >= 2.2 * bt / bch
                 and D - strip >= 0.35)
    dc = D - strip if with_back else D
    cushions = []
    for i in range(n):
        k = g.add((-W / 2 + cw * (i + 0.5), -D / 2 + dc / 2, h + ch / 2), (cw, dc, ch),
                  g.new_label("cushion"))
        g.touch(k, seat)
        if not with_back:
            g.touch(k, back)
        if i == 0 and arms:
            g.touch(k, arms[0])
        if i == n - 1 and arms:
            g.touch(k, arms[1])
        if i > 0:
            g.touch(k, cushions[-1])
        cushions.append(k)
    if with_back:
        bw = cw - 2 * CLEARANCE
        for i in range(n):
            x = -W / 2 + cw * (i + 0.5)
            # lean toward +y (the back): mirror of lean_box's -y convention
            c, R = lean_box((bw, bt, bch), 1, theta, h, -D / 2, x)
            c[1] = -c[1]
            R = np.diag([1.0, -1.0, 1.0]) @ R @ np.diag([1.0, -1.0, 1.0])
            k = g.add(c, (bw, bt, bch), g.new_label("cushion"), R)
            g.touch(k, seat)
            g.touch(k, back)
    return g
