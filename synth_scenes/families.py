"""Scene families: seeded functions ``make_<family>(rng, **opts) -> Arrangement``.

Each returns a ground-truth arrangement: cuboids ``b0..b{K-1}`` (each with its
``object`` name, e.g. ``table0``), the supports (``ground``, walls ``wall:<k>`` with
normals into the room) and every touching pair as a typed contact (``fixed`` where
parts are fused, ``touch`` otherwise).  Physical validity (settling in MuJoCo, analytic
statics) is checked separately by :mod:`synth_scenes.truth`, which rejects and
resamples.  ``meta["family"]`` names the family.

=============  ====================================================  ==========
family         what                                                   cuboids
=============  ====================================================  ==========
stack          ``n_boxes`` boxes: tower, staggered pier, pyramid,     n (3-10)
               or scattered short towers (``variant``)
counterweight  plank over a block's edge held by a weight             3-4
bridge         pillars and decks (1-2 spans), boxes on top            4-11
table          top + 4 legs fused, things on the top (``style``:      6-15
               3 legs, or a pedestal: column on a foot)
chair          seat + 4 legs + back (board or posts and rail) fused   6-8
               (``arms``: two arm panels more)
shelf          sides + boards fused, books (some leaning), boxes      10-38
wall_shelf     boards (and brackets) fused to wall:0, things on them  2-13
desk           top on panels/drawer block, monitor, keyboard, things  7-14
sofa           seat, back, arms fused; seat and back cushions         6-10
               (``arms=False``: no arms)
room           floor, walls wall:0/wall:1 and a mix of the above      20-60
=============  ====================================================  ==========

(cuboid ranges seen over seeds 0-19 with default options)

Every family draws its objects' proportions from :data:`synth_scenes.objects.WIDE`.
"""

from __future__ import annotations

import numpy as np

from pipeline.model import Arrangement, Support

from . import objects
from .builder import SceneBuilder

STACK_VARIANTS = ("column", "staggered", "pyramid", "piles")
#: The proportion ranges of every family's objects.
WIDE = objects.WIDE


def ranges_for(builder: str, proportions: dict | None = None) -> dict:
    """The proportion ranges of one builder: :data:`WIDE` with ``proportions`` (name ->
    ``(lo, hi)`` metres, e.g. ``{"height": (0.5, 0.9)}`` for tables) put in its place."""
    if not proportions:
        return WIDE[builder]
    return {**WIDE[builder], **{k: tuple(float(x) for x in v) for k, v in proportions.items()}}


def _single(group, name: str, rng: np.random.Generator, yaw: bool = True) -> Arrangement:
    b = SceneBuilder()
    b.place(group, 0.0, 0.0, float(rng.uniform(-np.pi, np.pi)) if yaw else 0.0)
    return b.build({"family": name})


def make_stack(rng: np.random.Generator, n_boxes: int | None = None,
               variant: str | None = None) -> Arrangement:
    """``n_boxes`` boxes (default 3-10): a tower, a staggered pier, a pyramid or short piles.

    Towers are at most 6 boxes and staggered piers at most 8; larger counts pick a
    pyramid or piles.
    """
    n = int(rng.integers(3, 11)) if n_boxes is None else int(n_boxes)
    if n < 1:
        raise ValueError(f"n_boxes: must be at least 1, got {n}")
    if variant is None:
        allowed = [v for v, cap in zip(STACK_VARIANTS, (6, 8, 10**6, 10**6), strict=True)
                   if n <= cap]
        variant = str(rng.choice(allowed))
    if variant not in STACK_VARIANTS:
        raise ValueError(f"variant: must be one of {STACK_VARIANTS}, got {variant!r}")
    if variant == "column":
        g = objects.column(rng, n, ranges=WIDE["column"])
    elif variant == "staggered":
        g = objects.column(rng, n, staggered=True, ranges=WIDE["column"])
    elif variant == "pyramid":
        g = objects.pyramid(rng, n, ranges=WIDE["pyramid"])
    else:
        g = objects.piles(rng, n, ranges=WIDE["column"])
    arr = _single(g, "stack", rng)
    return arr.with_(meta={**arr.meta, "variant": variant})


def make_counterweight(rng: np.random.Generator, proportions: dict | None = None) -> Arrangement:
    """A plank overhanging a block so far it tips alone, held down by a weight on its back end."""
    return _single(objects.counterweight(rng, ranges_for("counterweight", proportions)),
                   "counterweight", rng)


def make_bridge(rng: np.random.Generator, proportions: dict | None = None) -> Arrangement:
    """Pillars carrying one or two decks, maybe with boxes on the decks."""
    return _single(objects.bridge(rng, ranges_for("bridge", proportions)), "bridge", rng)


def make_table(rng: np.random.Generator, n_items: int | None = None,
               style: str | None = None, proportions: dict | None = None) -> Arrangement:
    """A table (top fused to four legs) with a few things on it.

    ``style``: ``three_legs`` or ``pedestal`` instead (:data:`objects.TABLE_STYLES`)."""
    return _single(objects.table(rng, n_items, ranges_for("table", proportions), style), "table", rng)


def make_chair(rng: np.random.Generator, arms: bool | None = None,
               proportions: dict | None = None) -> Arrangement:
    """A chair: seat, four legs and a back, fused; ``arms=True``: with arm panels."""
    return _single(objects.chair(rng, ranges_for("chair", proportions), bool(arms)), "chair", rng)


def make_shelf(rng: np.random.Generator, proportions: dict | None = None) -> Arrangement:
    """A free-standing bookshelf with books (some leaning) and boxes."""
    return _single(objects.shelf(rng, ranges_for("shelf", proportions)), "shelf", rng)


def make_desk(rng: np.random.Generator, proportions: dict | None = None) -> Arrangement:
    """A desk with a monitor, a keyboard and a few things."""
    return _single(objects.desk(rng, ranges_for("desk", proportions)), "desk", rng)


def make_sofa(rng: np.random.Generator, arms: bool | None = None,
              proportions: dict | None = None) -> Arrangement:
    """A sofa of several fused cuboids with cushions; ``arms=False``: without arms."""
    return _single(objects.sofa(rng, ranges_for("sofa", proportions), arms is not False), "sofa", rng)


def wall(k: int, point, normal) -> Support:
    """Support ``wall:<k>`` through ``point`` with unit ``normal`` into the room."""
    return Support(f"wall:{k}", np.asarray(point, float), np.asarray(normal, float))


def make_wall_shelf(rng: np.random.Generator, proportions: dict | None = None) -> Arrangement:
    """Boards hanging on wall ``wall:0`` (fused to it), with things on them."""
    from pipeline.model import ground

    yaw = float(rng.uniform(-np.pi, np.pi))
    w = wall(0, (0.0, 0.0, 0.0), (np.cos(yaw), np.sin(yaw), 0.0))
    b = SceneBuilder((ground(), w))
    b.place_on_wall(objects.wall_shelf(rng, ranges_for("wall_shelf", proportions)), w, 0.0)
    return b.build({"family": "wall_shelf"})


#: room object kinds: (builder, stands against a wall, weight)
_ROOM_KINDS = {
    "table": (lambda rng: objects.table(rng, ranges=WIDE["table"]), False, 3.0),
    "chair": (lambda rng: objects.chair(rng, WIDE["chair"]), False, 3.0),
    "shelf": (lambda rng: objects.shelf(rng, WIDE["shelf"]), True, 2.0),
    "wall_shelf": (lambda rng: objects.wall_shelf(rng, WIDE["wall_shelf"]), True, 1.5),
    "desk": (lambda rng: objects.desk(rng, WIDE["desk"]), True, 2.0),
    "sofa": (lambda rng: objects.sofa(rng, WIDE["sofa"]), True, 1.5),
    "stack": (lambda rng: objects.column(rng, int(rng.integers(2, 5)), ranges=WIDE["column"]),
              False, 1.5),
    "pyramid": (lambda rng: objects.pyramid(rng, int(rng.integers(3, 7)), WIDE["pyramid"]),
                False, 1.0),
    "box": (lambda rng: objects.box_item(rng, 0.2, 0.5), False, 1.5),
    "counterweight": (lambda rng: objects.counterweight(rng, WIDE["counterweight"]), False, 0.5),
    "bridge": (lambda rng: objects.bridge(rng, WIDE["bridge"]), False, 0.5),
}

#: gap kept between furniture footprints in a room, metres
ROOM_GAP = 0.08


def make_room(rng: np.random.Generator, n_objects: int | None = None,
              min_cuboids: int = 20, max_cuboids: int = 60) -> Arrangement:
    """A room corner: floor, two walls and ``n_objects`` pieces (default: 20-60 cuboids).

    The walls are ``wall:0`` (the plane x = 0, normal +x) and ``wall:1`` (y = 0,
    normal +y); the room spans 3.5-5 m each way.  Shelves, desks and sofas stand with
    their backs 3-10 cm from a wall; wall shelves hang on one (fused); the rest stands
    free at random yaw, chairs preferably at a table's side facing it.  Floor
    footprints keep :data:`ROOM_GAP` apart, so only listed contacts touch.  Without
    ``n_objects``, objects are added until there are at least ``min_cuboids`` cuboids
    and 4 objects; a piece that would exceed ``max_cuboids`` is skipped.
    """
    from shapely.geometry import box as shapely_box

    from pipeline.model import ground

    target = None if n_objects is None else int(n_objects)
    if target is not None and target < 1:
        raise ValueError(f"n_objects: must be at least 1, got {target}")
    Lx, Ly = float(rng.uniform(3.5, 5.0)), float(rng.uniform(3.5, 5.0))
    walls = (wall(0, (0, 0, 0), (1, 0, 0)), wall(1, (0, 0, 0), (0, 1, 0)))
    along_dir = (np.array([0.0, 1.0]), np.array([1.0, 0.0]))   # room direction along each wall
    length = (Ly, Lx)
    b = SceneBuilder((ground(), *walls))
    free_region = shapely_box(0, 0, Lx, Ly).buffer(-0.08)
    placed: list = []
    kinds = list(_ROOM_KINDS)
    weights = np.array([_ROOM_KINDS[k][2] for k in kinds])
    tables: list[tuple[float, float, float, np.ndarray]] = []
    count = 0
    for _attempt in range(300):
        n_cub = len(b.centers)
        if target is not None and count >= target:
            break
        if target is None and n_cub >= min_cuboids and count >= 4:
            break
        kind = str(rng.choice(kinds, p=weights / weights.sum()))
        build, on_wall, _ = _ROOM_KINDS[kind]
        g = build(rng)
        if n_cub + len(g.parts) > max_cuboids:
            if target is None and n_cub >= min_cuboids:
                break
            continue
        fp = g.footprint()
        width = float(fp[1, 0] - fp[0, 0])
        if on_wall:
            k = int(rng.integers(0, 2))
            n2, t2 = walls[k].normal[:2], along_dir[k]
            if length[k] < width + 0.2:
                continue
            s = float(rng.uniform(0.1 + width / 2, length[k] - 0.1 - width / 2))
            if kind == "wall_shelf":
                # hung by place_on_wall: local x runs along the wall's own tangent
                w = walls[k]
                yaw = float(np.arctan2(w.normal[1], w.normal[0]) - np.pi / 2)
                tangent = np.array([np.cos(yaw), np.sin(yaw)])
                along = float((s * t2) @ tangent - (fp[0, 0] + fp[1, 0]) / 2)
                poly = objects.rect_polygon(fp, *(along * tangent), yaw)
                if any(poly.distance(q) < ROOM_GAP for q in placed):
                    continue
                b.place_on_wall(g, w, along)
                placed.append(poly)
                count += 1
                continue
            gap = float(rng.uniform(0.03, 0.1))
            yaw = float(np.arctan2(n2[0], -n2[1]))          # local +y (the back) -> -normal
            xy = (n2 * (gap + fp[1, 1]) + t2 * s
                  - _rot(yaw) @ np.array([(fp[0, 0] + fp[1, 0]) / 2, 0.0]))
            poly = objects.rect_polygon(fp, xy[0], xy[1], yaw)
            if any(poly.distance(q) < ROOM_GAP for q in placed):
                continue
            b.place(g, float(xy[0]), float(xy[1]), yaw)
            placed.append(poly)
            count += 1
            continue
        pose = None
        if kind == "chair" and tables and rng.random() < 0.7:
            tx, ty, tyaw, tfp = tables[int(rng.integers(len(tables)))]
            u = np.array([[1, 0], [-1, 0], [0, 1], [0, -1]], float)[int(rng.integers(4))]
            half = np.abs(tfp).max(axis=0)
            dist = float(u @ half + 0.3 + rng.uniform(0.0, 0.2))
            local = u * dist + (1 - np.abs(u)) * rng.uniform(-0.3, 0.3) * half
            xy = np.array([tx, ty]) + _rot(tyaw) @ local
            uw = _rot(tyaw) @ u
            cyaw = float(np.arctan2(-uw[0], uw[1]))           # chair back away from the table
            poly = objects.rect_polygon(fp, xy[0], xy[1], cyaw)
            if free_region.contains(poly) and all(poly.distance(q) >= ROOM_GAP for q in placed):
                pose = (float(xy[0]), float(xy[1]), cyaw)
                placed.append(poly)
        if pose is None:
            pose = objects.scatter(rng, [fp], free_region, ROOM_GAP, placed=placed, tries=40)[0]
        if pose is None:
            continue
        b.place(g, *pose)
        count += 1
        if kind == "table":
            tables.append((pose[0], pose[1], pose[2], fp))
    return b.build({"family": "room", "room_size": [Lx, Ly], "n_objects": count})


def _rot(yaw: float) -> np.ndarray:
    """(2, 2) planar rotation."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s], [s, c]])
