"""Seeded random arrangements with known geometry, for the analytic-vs-engines study.

``random_arrangement(rng, kind=None)`` draws one arrangement of a kind in :data:`KINDS`:
stacks and towers with random offsets and yaw, overhangs, counterweights, bridges,
cantilevers and shelves with random ``touch``/``fixed``, leaning planks, fused furniture.
The parameters are drawn so that many cases sit near their tipping point.  Every
arrangement is exactly in contact where it should be (faces coincide by construction),
lists every touching pair as a contact (``touch`` or ``fixed``), and records in ``meta``:

``kind``
    The family.
``margin``
    Where a closed form exists, the signed *tipping angle* in radians: how far the part
    that can tip must be turned before it topples (positive: stable).  For block stacks
    (every interface horizontal) it is the smallest, over the non-fused interfaces, of
    ``atan2(d, h)``: ``d`` the signed distance from the centre of mass of everything
    above to the edge of the interface polygon (shapely intersection), ``h`` its height
    above the interface; a pure stack is stable exactly when every ``d`` is positive
    (friction plays no part when all interfaces are horizontal).  An angle, not a
    distance, because a tall tower on a narrow base is fragile in any simulator even
    when ``d`` is a good fraction of a box (measured: both engines topple a 0.75 m tower
    whose centre of mass is 12 mm inside a 12 x 16 cm base, a 1.7 degree margin).  For
    leaning planks it is ``angle - limit`` with the thick-ladder limit
    ``tan(limit) = (1 - mu^2) / (2 mu + (1 + mu^2) t / L)`` (friction mu at floor and
    wall, contacts on the underside; the thin ladder has ``t = 0``).  ``None`` where there
    is no closed form (then the analytic energy decides what is "near the threshold").

The deterministic builders (:func:`column`, :func:`overhang`, :func:`leaning_plank`,
:func:`side_friction_trap`, :func:`cantilever`, :func:`yawed_on_edge`) are the oracles of
``tests/simulate/test_engines.py``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from pipeline.constants import DEFAULT_MU
from pipeline.model import (
    Arrangement,
    Contact,
    Cuboid,
    Support,
    box,
    box_corners,
    ground,
    rotation_about_axis,
    rotation_about_z,
)

WALL = Support("wall:0", np.zeros(3), np.array([1.0, 0.0, 0.0]))  # the plane x = 0, free x > 0


def ladder_limit_deg(mu: float = DEFAULT_MU, thickness_ratio: float = 0.0) -> float:
    """Smallest angle from the ground (degrees) at which a plank with friction ``mu`` at the
    floor and at the wall stands.

    Derivation (2-D, plank of length L and thickness t resting on its underside edge at
    both ends, centre of mass t/2 above that line): at the limit both frictions are
    saturated, ``N_wall = mu m g / (1 + mu^2)``, ``F_wall = mu N_wall``; moments about
    the floor contact give ``tan(theta) = (1 - mu^2) / (2 mu + (1 + mu^2) t / L)``
    (``thickness_ratio = t / L``; 0 is the classic thin ladder, 20.0 degrees at mu = 0.7).
    """
    return float(np.degrees(np.arctan2(1.0 - mu * mu,
                                       2.0 * mu + (1.0 + mu * mu) * thickness_ratio)))


# ---------------------------------------------------------------------------- builders
def column(n: int = 10, size: float = 0.1) -> Arrangement:
    """``n`` cubes of edge ``size`` stacked exactly on the ground (stable)."""
    cubes = tuple(box(f"c{i}", (0.0, 0.0, size * (i + 0.5)), (size, size, size))
                  for i in range(n))
    contacts = [Contact("c0", "ground")] + [Contact(f"c{i}", f"c{i + 1}") for i in range(n - 1)]
    arr = Arrangement(cubes, (ground(),), tuple(contacts))
    ids = [c.id for c in cubes]
    lower = {c: (ids[i - 1] if i else None) for i, c in enumerate(ids)}
    return arr.with_(meta={"kind": "column", "margin": stack_margin(arr, ids, lower)})


def overhang(fraction: float, size: float = 0.2, yaw: float = 0.0) -> Arrangement:
    """A cube resting on an equal cube, shifted by ``fraction`` of its edge along x.

    Stable for ``fraction < 0.5`` (centre of mass over the support), unstable above;
    margin ``atan2((0.5 - fraction) size, size / 2)``.  With ``yaw`` the top cube is also
    turned about its vertical axis (the interface is then a polygon cut by the base's
    edge x = size / 2, and the margin is unchanged for small yaw).
    """
    base = box("base", (0.0, 0.0, size / 2), (size, size, size))
    top = box("top", (fraction * size, 0.0, 1.5 * size), (size, size, size), yaw=yaw)
    return Arrangement((base, top), (ground(),),
                       (Contact("base", "ground"), Contact("base", "top")),
                       meta={"kind": "overhang",
                             "margin": float(np.arctan2(0.5 - fraction, 0.5))})


def yawed_on_edge(offset: float, size: float = 0.1, yaw: float = np.radians(30)) -> Arrangement:
    """A yawed cube on a wide base whose edge is x = 0.2; the cube's centre at 0.2 + ``offset``.

    The interface is the yawed footprint cut by x <= 0.2, which contains the cube's
    centre exactly when ``offset < 0`` (stable) - a closed-form oracle for a rotated box.
    """
    base = box("base", (0.0, 0.0, 0.1), (0.4, 0.4, 0.2))
    top = box("top", (0.2 + offset, 0.0, 0.2 + size / 2), (size, size, size), yaw=yaw)
    return Arrangement((base, top), (ground(),),
                       (Contact("base", "ground"), Contact("base", "top")),
                       meta={"kind": "yawed", "margin": float(np.arctan2(-offset, size / 2))})


def leaning_plank(angle_deg: float, length: float = 1.0, thickness: float = 0.02,
                  width: float = 0.2) -> Arrangement:
    """A plank leaning against the wall x = 0 at ``angle_deg`` from the ground.

    Its lower edge rests on the ground, its upper edge on the wall.  A thin plank with
    friction 0.7 at both ends stands above 20.0 degrees (:func:`ladder_limit_deg`; 19.6
    degrees for the default 2 cm x 1 m plank).
    """
    phi = np.radians(angle_deg)
    R = rotation_about_axis((0.0, 1.0, 0.0), -(np.pi / 2 - phi))  # local z = (-cos, 0, sin)
    corners = box_corners(np.zeros((1, 3)), R[None], np.array([[thickness, width, length]]))[0]
    center = np.array([-corners[:, 0].min(), 0.0, -corners[:, 2].min()])
    plank = Cuboid("plank", center, R, np.array([thickness, width, length]))
    lim = ladder_limit_deg(DEFAULT_MU, thickness / length)
    return Arrangement((plank,), (ground(), WALL),
                       (Contact("plank", "ground"), Contact("plank", "wall:0")),
                       meta={"kind": "plank", "margin": float(np.radians(angle_deg - lim)),
                             "angle_deg": angle_deg, "limit_deg": lim})


def side_friction_trap(gap_fill: float = 1.0) -> Arrangement:
    """A cube held only by friction between the side faces of two columns fixed to the ground.

    The columns (0.1 x 0.1 x 0.4) stand at x = -0.1 and x = +0.1; the cube of edge 0.1
    fills the gap exactly at mid height and does not touch the ground.  Plain statics
    with friction on vertical faces would call it stable (friction can carry its weight
    with zero normal force only in the limit, and any squeeze makes it feasible); a
    resting cube has no squeeze, and both engines drop it.
    """
    s = 0.1 * gap_fill
    left = box("left", (-0.1, 0.0, 0.2), (0.1, 0.1, 0.4))
    right = box("right", (0.1, 0.0, 0.2), (0.1, 0.1, 0.4))
    mid = box("mid", (0.0, 0.0, 0.3), (s, 0.1, 0.1))
    return Arrangement((left, right, mid), (ground(),),
                       (Contact("left", "ground", "fixed"), Contact("right", "ground", "fixed"),
                        Contact("mid", "left"), Contact("mid", "right")),
                       meta={"kind": "trap", "margin": None})


def cantilever(length: float = 0.8, beam_fixed: bool = True, column_fixed: bool = True
               ) -> Arrangement:
    """A 0.5 m column with a beam of ``length`` fused (or touching) to its side at the top.

    With the column fixed to the ground and the beam fixed to the column it is one static
    body: a fused cantilever must not sag.
    """
    col = box("column", (0.0, 0.0, 0.25), (0.1, 0.1, 0.5))
    beam = box("beam", (0.05 + length / 2, 0.0, 0.475), (length, 0.1, 0.05))
    return Arrangement((col, beam), (ground(),),
                       (Contact("column", "ground", "fixed" if column_fixed else "touch"),
                        Contact("column", "beam", "fixed" if beam_fixed else "touch")),
                       meta={"kind": "cantilever", "margin": None})


# ---------------------------------------------------------------------------- margins
def _footprint(c: np.ndarray, R: np.ndarray, size: np.ndarray):
    """Shapely polygon of a box's horizontal footprint (boxes with a vertical local z)."""
    from shapely.geometry import Polygon

    h = size[:2] / 2
    loc = np.array([[-h[0], -h[1]], [h[0], -h[1]], [h[0], h[1]], [-h[0], h[1]]])
    return Polygon(c[:2] + loc @ R[:2, :2].T)


def _signed_distance(poly, xy: np.ndarray) -> float:
    from shapely.geometry import Point

    pt = Point(float(xy[0]), float(xy[1]))
    if poly.is_empty:
        return -float("inf")
    d = poly.exterior.distance(pt)
    return d if poly.contains(pt) else -d


def stack_margin(arr: Arrangement, order: list[str], lower: dict[str, str | None]) -> float:
    """Tipping angle of a pure stack, radians (see the module docstring).

    ``order``: cuboid ids bottom to top; ``lower[id]``: the id it rests on (``None`` =
    the ground).  Interfaces listed as ``fixed`` carry tension and are skipped; a stack
    fused to the ground below a touch interface is handled the same way.
    """
    fixed = arr.fixed_pairs()
    m = np.asarray(arr.masses)
    idx = arr.index
    best = np.inf
    for level, cid in enumerate(order):
        below = lower[cid]
        key = tuple(sorted((cid, below if below is not None else "ground")))
        if key in fixed:
            continue
        above = [idx[o] for o in order[level:]]
        com = (m[above, None] * arr.centers[above]).sum(0) / m[above].sum()
        c = arr.cuboid(cid)
        poly = _footprint(c.center, c.rotation, c.size)
        if below is not None:
            b = arr.cuboid(below)
            poly = poly.intersection(_footprint(b.center, b.rotation, b.size))
        z_interface = c.center[2] - c.size[2] / 2
        best = min(best, float(np.arctan2(_signed_distance(poly, com), com[2] - z_interface)))
    return float(best) if np.isfinite(best) else float(np.pi / 2)


# ---------------------------------------------------------------------------- kinds
def _touch_or_fixed(rng: np.random.Generator, p_fixed: float) -> str:
    return "fixed" if rng.random() < p_fixed else "touch"


def _stack(rng: np.random.Generator) -> Arrangement:
    """A tower of 2-6 boxes, random sizes, yaw and offsets; some interfaces fused."""
    n = int(rng.integers(2, 7))
    cuboids, contacts, order, lower = [], [], [], {}
    z = 0.0
    prev = None
    p_fixed = rng.choice([0.0, 0.0, 0.2, 0.5])
    yaw_on = rng.random() < 0.5
    for i in range(n):
        size = rng.uniform([0.08, 0.08, 0.04], [0.35, 0.35, 0.25])
        yaw = rng.uniform(-np.pi, np.pi) if yaw_on else 0.0
        if prev is None:
            xy = np.zeros(2)
        else:
            # offset scaled to the lower box so the interface is often near an edge
            direction = rng.normal(size=2)
            direction /= np.linalg.norm(direction)
            reach = 0.5 * float(np.min(prev.size[:2]))
            xy = prev.center[:2] + direction * reach * rng.uniform(0.0, 1.1)
        c = box(f"s{i}", (xy[0], xy[1], z + size[2] / 2), size, yaw=yaw)
        cuboids.append(c)
        contacts.append(Contact(c.id, prev.id if prev is not None else "ground",
                                _touch_or_fixed(rng, p_fixed if prev is not None else 0.0)))
        order.append(c.id)
        lower[c.id] = prev.id if prev is not None else None
        z += size[2]
        prev = c
    arr = Arrangement(tuple(cuboids), (ground(),), tuple(contacts))
    arr = _drop_non_touching(arr)
    return arr.with_(meta={"kind": "stack", "margin": stack_margin(arr, order, lower)})


def _drop_non_touching(arr: Arrangement) -> Arrangement:
    """Stacked boxes whose footprints do not overlap do not touch: drop what is above."""
    keep: list[Cuboid] = []
    for i, c in enumerate(arr.cuboids):
        if i > 0:
            b = keep[-1]
            inter = _footprint(c.center, c.rotation, c.size).intersection(
                _footprint(b.center, b.rotation, b.size))
            if inter.area < 1e-3 * float(min(c.size[0] * c.size[1], b.size[0] * b.size[1])):
                break
        keep.append(c)
    ids = {c.id for c in keep}
    contacts = tuple(k for k in arr.contacts if k.a in ids | {"ground"} and k.b in ids | {"ground"})
    return arr.with_(cuboids=tuple(keep), contacts=contacts)


def _overhang(rng: np.random.Generator) -> Arrangement:
    size = float(rng.uniform(0.08, 0.4))
    frac = float(rng.uniform(0.3, 0.7))
    yaw = float(rng.uniform(-0.5, 0.5)) if rng.random() < 0.5 else 0.0
    base = box("base", (0.0, 0.0, size / 2), (size, size, size))
    h = float(rng.uniform(0.3, 1.0)) * size
    top = box("top", (frac * size, 0.0, size + h / 2), (size, size * rng.uniform(0.5, 1.0), h),
              yaw=yaw)
    arr = Arrangement((base, top), (ground(),),
                      (Contact("base", "ground"), Contact("base", "top")))
    return arr.with_(meta={"kind": "overhang",
                           "margin": stack_margin(arr, ["base", "top"],
                                                  {"base": None, "top": "base"})})


def _counterweight(rng: np.random.Generator) -> Arrangement:
    """A plank overhanging its base, with a weight on the back end (or on the tip)."""
    bs = float(rng.uniform(0.1, 0.3))
    base = box("base", (0.0, 0.0, bs / 2), (bs, bs, bs))
    L = float(rng.uniform(2.0, 4.0)) * bs
    t = float(rng.uniform(0.01, 0.04))
    left = -bs / 2 + float(rng.uniform(0.0, 0.8)) * bs  # plank's back end, over the base
    plank = box("plank", (left + L / 2, 0.0, bs + t / 2), (L, bs, t))
    ws = float(rng.uniform(0.08, 0.2))
    rho = float(rng.uniform(1000.0, 8000.0))  # wood to steel
    # the weight position that puts the centre of mass of plank + weight exactly over the
    # base's edge e, then moved by a random fraction of the base so many cases are close
    e = bs / 2
    m_p, m_w = L * bs * t * 1000.0, ws ** 3 * rho
    wx = e - m_p * (left + L / 2 - e) / m_w + float(rng.normal(0.0, 0.15)) * bs
    wx = float(np.clip(wx, left + ws / 2, left + L - ws / 2))
    weight = box("weight", (wx, 0.0, bs + t + ws / 2), (ws, ws, ws), density=rho)
    fix = _touch_or_fixed(rng, 0.2)
    arr = Arrangement((base, plank, weight), (ground(),),
                      (Contact("base", "ground"), Contact("base", "plank"),
                       Contact("plank", "weight", fix)))
    return arr.with_(meta={"kind": "counterweight",
                           "margin": stack_margin(arr, ["base", "plank", "weight"],
                                                  {"base": None, "plank": "base",
                                                   "weight": "plank"})})


def _bridge(rng: np.random.Generator) -> Arrangement:
    """Two pillars and a beam across their tops; the beam may overhang one pillar."""
    h = float(rng.uniform(0.2, 0.6))
    p = float(rng.uniform(0.06, 0.15))
    gap = float(rng.uniform(0.2, 0.8))
    left = box("pillar_l", (-gap / 2 - p / 2, 0.0, h / 2), (p, p, h))
    right = box("pillar_r", (gap / 2 + p / 2, 0.0, h / 2), (p, p, h))
    L = gap + 2 * p
    shift = float(rng.uniform(0.0, 0.7)) * L * (1 if rng.random() < 0.5 else -1)
    t = float(rng.uniform(0.03, 0.08))
    beam = box("beam", (shift, 0.0, h + t / 2), (L, p * 1.5, t))
    contacts = [Contact("pillar_l", "ground", _touch_or_fixed(rng, 0.2)),
                Contact("pillar_r", "ground", _touch_or_fixed(rng, 0.2))]
    cuboids = [left, right, beam]
    beam_lo, beam_hi = shift - L / 2, shift + L / 2
    for pid, px in (("pillar_l", -gap / 2 - p / 2), ("pillar_r", gap / 2 + p / 2)):
        if min(beam_hi, px + p / 2) - max(beam_lo, px - p / 2) > 0.05 * p:
            contacts.append(Contact(pid, "beam", _touch_or_fixed(rng, 0.3)))
    if not any("beam" in (c.a, c.b) for c in contacts):
        cuboids.pop()
    return Arrangement(tuple(cuboids), (ground(),), tuple(contacts),
                       meta={"kind": "bridge", "margin": None})


def _cantilever(rng: np.random.Generator) -> Arrangement:
    """A column with a beam on its side at the top, random touch/fixed at both joints."""
    ch = float(rng.uniform(0.3, 0.8))
    cw = float(rng.uniform(0.08, 0.25))
    L = float(rng.uniform(0.2, 1.0))
    t = float(rng.uniform(0.03, 0.08))
    col = box("column", (0.0, 0.0, ch / 2), (cw, cw, ch))
    beam = box("beam", (cw / 2 + L / 2, 0.0, ch - t / 2), (L, cw, t))
    col_c = _touch_or_fixed(rng, 0.3)
    beam_c = _touch_or_fixed(rng, 0.7)
    arr = Arrangement((col, beam), (ground(),),
                      (Contact("column", "ground", col_c), Contact("column", "beam", beam_c)),
                      meta={"kind": "cantilever"})
    margin = None
    if beam_c == "fixed" and col_c == "touch":
        m = np.asarray(arr.masses)
        com = (m[:, None] * arr.centers).sum(0) / m.sum()
        margin = float(np.arctan2(cw / 2 - com[0], com[2]))
    elif beam_c == "touch":
        margin = -1.0  # a beam held by side friction only falls
    else:
        margin = 1.0
    return arr.with_(meta={"kind": "cantilever", "margin": margin})


def _shelf(rng: np.random.Generator) -> Arrangement:
    """A board on a bracket fixed to the wall x = 0; the board's back touches the wall."""
    bz = float(rng.uniform(0.3, 1.0))
    bd = float(rng.uniform(0.05, 0.2))  # bracket depth (x)
    bh = float(rng.uniform(0.03, 0.1))
    bracket = box("bracket", (bd / 2, 0.0, bz - bh / 2), (bd, 0.1, bh))
    depth = float(rng.uniform(1.0, 3.0)) * bd
    t = float(rng.uniform(0.015, 0.04))
    board = box("board", (depth / 2, 0.0, bz + t / 2), (depth, 0.4, t))
    board_c = _touch_or_fixed(rng, 0.3)
    arr = Arrangement((bracket, board), (ground(), WALL),
                      (Contact("bracket", "wall:0", "fixed"), Contact("board", "bracket", board_c),
                       Contact("board", "wall:0", _touch_or_fixed(rng, 0.2))))
    fixed_any = any(c.type == "fixed" for c in arr.contacts if "board" in (c.a, c.b))
    margin = 1.0 if fixed_any else float(np.arctan2(bd - depth / 2, t / 2))
    return arr.with_(meta={"kind": "shelf", "margin": margin})


def _plank(rng: np.random.Generator) -> Arrangement:
    angle = float(rng.uniform(10.0, 40.0))
    arr = leaning_plank(angle, length=float(rng.uniform(0.5, 1.5)),
                        thickness=float(rng.uniform(0.015, 0.04)),
                        width=float(rng.uniform(0.1, 0.4)))
    return arr


def _furniture(rng: np.random.Generator) -> Arrangement:
    """A table (top fused to 1-4 legs) on the ground, maybe with a box on its top."""
    W, D = rng.uniform(0.5, 1.4), rng.uniform(0.4, 0.9)
    H = float(rng.uniform(0.4, 0.8))
    t = float(rng.uniform(0.02, 0.05))
    leg = float(rng.uniform(0.03, 0.07))
    top = box("top", (0.0, 0.0, H - t / 2), (W, D, t), object="table")
    corners = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
    n_legs = int(rng.choice([1, 2, 3, 4, 4, 4]))
    # which legs survive: a random contiguous run, so 2 legs can be on one side
    start = int(rng.integers(4))
    cuboids = [top]
    contacts = []
    for j in range(n_legs):
        sx, sy = corners[(start + j) % 4]
        lid = f"leg{j}"
        cuboids.append(box(lid, (sx * (W / 2 - leg / 2), sy * (D / 2 - leg / 2), (H - t) / 2),
                           (leg, leg, H - t), object="table"))
        contacts += [Contact(lid, "top", "fixed"), Contact(lid, "ground")]
    if rng.random() < 0.5:
        s = float(rng.uniform(0.05, 0.3))
        x = float(rng.uniform(-W / 2, W / 2))
        cuboids.append(box("load", (x, 0.0, H + s / 2), (s, s, s)))
        contacts.append(Contact("load", "top", _touch_or_fixed(rng, 0.2)))
    return Arrangement(tuple(cuboids), (ground(),), tuple(contacts),
                       meta={"kind": "furniture", "margin": None})


#: kind -> generator
KINDS: dict[str, Callable[[np.random.Generator], Arrangement]] = {
    "stack": _stack,
    "overhang": _overhang,
    "counterweight": _counterweight,
    "bridge": _bridge,
    "cantilever": _cantilever,
    "shelf": _shelf,
    "plank": _plank,
    "furniture": _furniture,
}


def random_arrangement(rng: np.random.Generator, kind: str | None = None) -> Arrangement:
    """One random arrangement.

    Parameters
    ----------
    rng : numpy.random.Generator
        The only source of randomness: the same seed gives the same arrangement.
    kind : str, optional
        One of :data:`KINDS`; drawn uniformly when None.

    Returns
    -------
    Arrangement
        With ``meta["kind"]`` and ``meta["margin"]`` (see the module docstring).
    """
    if kind is None:
        kind = str(rng.choice(sorted(KINDS)))
    if kind not in KINDS:
        raise ValueError(f"kind: expected one of {', '.join(sorted(KINDS))}, got {kind!r}")
    arr = KINDS[kind](rng)
    return arr.with_(meta={**arr.meta, "kind": kind})


def with_yaw(arr: Arrangement, yaw: float) -> Arrangement:
    """The whole arrangement turned by ``yaw`` about the vertical through the origin."""
    Rz = rotation_about_z(yaw)
    cub = tuple(c.with_(center=Rz @ c.center, rotation=Rz @ c.rotation) for c in arr.cuboids)
    sup = tuple(Support(s.id, Rz @ s.point, Rz @ s.normal) for s in arr.supports)
    return arr.with_(cuboids=cub, supports=sup)
