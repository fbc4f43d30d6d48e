"""A repository of furniture meshes for model retrieval (``unseen models make``).

Each model is a triangle mesh built from ``trimesh.creation`` primitives (boxes,
cylinders, discs) and concatenated: real meshes with some detail beyond the scene
generator's boxes (round legs, a pedestal column on a disc foot, drawer fronts, arm
rests), in the kinds and styles the generator builds (:mod:`synth_scenes.objects`; three legs,
pedestals, chair arms and armless sofas only when the family is asked for them):

=========  ==========================================================================
kind       variants
=========  ==========================================================================
table      ``four_legs`` (the generator's), ``three_legs``, ``pedestal``
chair      ``board`` and ``posts`` (the generator's backs), ``board_arms``, ``posts_arms``
shelf      ``boards2`` .. ``boards7`` (number of boards; the generator makes 2-7)
desk       ``panels`` and ``drawers`` (the generator's: second panel or drawer block)
sofa       ``arms`` (the generator's), ``no_arms``
monitor    ``stand``
box        ``plain`` (what small things on surfaces are)
=========  ==========================================================================

Proportions are drawn from :data:`synth_scenes.objects.WIDE`, the ranges the scene
families draw from, with the ``rng`` passed in: a repository made with another seed than
the scenes has other exact proportions.

Model frame (as the generator's objects): z up, standing on z = 0, centred on the
origin in x and y, front toward -y, metres.  The files are binary glTF, which is y up by
its specification: each mesh is rotated by -90 degrees about x on export (as
:mod:`simulate.gltf` does), and ``index.json`` records ``"up": "y"`` per model so a
reader turns it back (:mod:`pipeline.retrieve` reads it).

``index.json``::

    {"format": "unseen.models", "version": 1, "units": "m", "seed": 0,
     "models": [{"file": "table_000.glb", "kind": "table", "variant": "pedestal",
                 "up": "y", "front": "-y (z-up frame)",
                 "extents": [W, D, H],             # bounding box in the z-up frame, m
                 "params": {"width": ..., ...}}, ...]}
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.retrieve_output import KIND_RGB, Y_UP_FROM_Z_UP

from .objects import WIDE

#: Variants per kind, in the order :func:`make_repository` cycles through them.
VARIANTS: dict[str, tuple[str, ...]] = {
    "table": ("four_legs", "three_legs", "pedestal"),
    "chair": ("board", "posts", "board_arms", "posts_arms"),
    "shelf": ("boards2", "boards3", "boards4", "boards5", "boards6", "boards7"),
    "desk": ("panels", "drawers"),
    "sofa": ("arms", "no_arms"),
    "monitor": ("stand",),
    "box": ("plain",),
}
#: The variants :mod:`synth_scenes.objects` builds by default (the others on request:
#: ``table(style=...)``, ``chair(arms=True)``, ``sofa(arms=False)``).
GENERATOR_VARIANTS: dict[str, tuple[str, ...]] = {
    "table": ("four_legs",), "chair": ("board", "posts"),
    "shelf": ("boards2", "boards3", "boards4", "boards5", "boards6", "boards7"),
    "desk": ("panels", "drawers"), "sofa": ("arms",), "monitor": ("stand",), "box": ("plain",),
}
KINDS = tuple(VARIANTS)
#: What ``unseen models make`` writes by default: the furniture.  A plain box is the
#: cuboid abstraction itself: its solid covers any solid structure, so with boxes in the
#: repository every chunky object retrieves a box (``--kinds ...,box`` adds them).
FURNITURE = ("table", "chair", "shelf", "desk", "sofa", "monitor")
#: Default models per kind.
N_PER_KIND = 12
#: Segments of a round part's circle.
SECTIONS = 20
#: A colour per kind (RGBA 0-255, the retrieval pictures' colours), so a picture of
#: retrieved models tells kinds apart.
KIND_COLORS: dict[str, tuple[int, int, int, int]] = {k: (*rgb, 255)
                                                      for k, rgb in KIND_RGB.items()}


@dataclass(frozen=True)
class ModelSpec:
    """One repository model before it is written: its mesh and what it is."""

    kind: str
    variant: str
    params: dict
    mesh: object  #: trimesh.Trimesh in the model frame (z up, on z = 0)


def _u(rng: np.random.Generator, lo_hi) -> float:
    return float(rng.uniform(lo_hi[0], lo_hi[1]))


def _box(size, center):
    import trimesh

    T = np.eye(4)
    T[:3, 3] = center
    return trimesh.creation.box(extents=np.asarray(size, float), transform=T)


def _cylinder(radius: float, z0: float, z1: float, x: float = 0.0, y: float = 0.0):
    """A vertical cylinder from z0 to z1 about (x, y)."""
    import trimesh

    T = np.eye(4)
    T[:3, 3] = (x, y, (z0 + z1) / 2)
    return trimesh.creation.cylinder(radius=radius, height=z1 - z0, sections=SECTIONS,
                                     transform=T)


def _leg(round_: bool, side: float, z1: float, x: float, y: float):
    """A leg from the floor to ``z1``: a square post of ``side`` or a round one inside it."""
    if round_:
        return _cylinder(side / 2, 0.0, z1, x, y)
    return _box((side, side, z1), (x, y, z1 / 2))


def _join(parts):
    import trimesh

    mesh = trimesh.util.concatenate(parts)
    mesh.merge_vertices()
    return mesh


# ----------------------------------------------------------------------------- kinds
def table_model(rng: np.random.Generator, variant: str) -> ModelSpec:
    """A table top on four or three legs (square or round) or on a pedestal column."""
    r = WIDE["table"]
    W, D, T, H = _u(rng, r["width"]), _u(rng, r["depth"]), _u(rng, r["top"]), _u(rng, r["height"])
    leg, inset = _u(rng, r["leg"]), _u(rng, r["inset"])
    round_ = bool(rng.random() < 0.5)
    parts = [_box((W, D, T), (0, 0, H - T / 2))]
    ex, ey = W / 2 - inset - leg / 2, D / 2 - inset - leg / 2
    params = {"width": W, "depth": D, "height": H, "top": T}
    if variant == "four_legs":
        parts += [_leg(round_, leg, H - T, sx * ex, sy * ey) for sx in (-1, 1) for sy in (-1, 1)]
        params.update(leg=leg, inset=inset, round_legs=round_)
    elif variant == "three_legs":
        parts += [_leg(round_, leg, H - T, sx * ex, ey) for sx in (-1, 1)]
        parts.append(_leg(round_, leg, H - T, 0.0, -ey))
        params.update(leg=leg, inset=inset, round_legs=round_)
    elif variant == "pedestal":
        col = _u(rng, (0.04, 0.08)) * max(1.0, min(W, D) / 0.8)
        foot_r = _u(rng, (0.3, 0.42)) * min(W, D)
        foot_t = _u(rng, (0.02, 0.04))
        parts.append(_cylinder(foot_r, 0.0, foot_t))
        parts.append(_cylinder(col, foot_t, H - T))
        params.update(column_radius=col, foot_radius=foot_r, foot=foot_t)
    else:
        raise ValueError(f"table variant {variant!r}")
    return ModelSpec("table", variant, params, _join(parts))


def chair_model(rng: np.random.Generator, variant: str) -> ModelSpec:
    """Seat on four legs, a back (a board, or two posts and a rail), maybe arm rests."""
    r = WIDE["chair"]
    W, D, T, H = _u(rng, r["width"]), _u(rng, r["depth"]), _u(rng, r["seat"]), _u(rng, r["height"])
    leg, inset = _u(rng, r["leg"]), _u(rng, r["inset"])
    bt, bh = _u(rng, r["back"]), _u(rng, r["back_height"])
    round_ = bool(rng.random() < 0.5)
    parts = [_box((W, D, T), (0, 0, H - T / 2))]
    ex, ey = W / 2 - inset - leg / 2, D / 2 - inset - leg / 2
    parts += [_leg(round_, leg, H - T, sx * ex, sy * ey) for sx in (-1, 1) for sy in (-1, 1)]
    yb = D / 2 - bt / 2
    params = {"width": W, "depth": D, "height": H, "seat": T, "leg": leg,
              "back": bt, "back_height": bh, "round_legs": round_}
    if variant.startswith("board"):
        parts.append(_box((W, bt, bh), (0, yb, H + bh / 2)))
    elif variant.startswith("posts"):
        pw, rh = _u(rng, (0.03, 0.045)), _u(rng, (0.08, 0.15))
        ph = bh - rh
        parts.append(_box((W, bt, rh), (0, yb, H + ph + rh / 2)))
        parts += [_box((pw, bt, ph), (sx * (W / 2 - pw / 2), yb, H + ph / 2)) for sx in (-1, 1)]
        params.update(post=pw, rail=rh)
    else:
        raise ValueError(f"chair variant {variant!r}")
    if variant.endswith("_arms"):
        aw, ah = _u(rng, (0.03, 0.06)), min(_u(rng, (0.18, 0.26)), 0.9 * bh)
        ad = D - bt
        for sx in (-1, 1):
            x = sx * (W / 2 - aw / 2)
            parts.append(_box((aw, ad, 0.03), (x, -D / 2 + ad / 2, H + ah - 0.015)))
            parts.append(_box((aw, 0.03, ah - 0.03), (x, -D / 2 + 0.015, H + (ah - 0.03) / 2)))
        params.update(arm=aw, arm_height=ah)
    return ModelSpec("chair", variant, params, _join(parts))


def shelf_model(rng: np.random.Generator, variant: str) -> ModelSpec:
    """Two side boards and ``n`` boards between them (``boards<n>``)."""
    r = WIDE["shelf"]
    n = int(variant.removeprefix("boards"))
    W, D = _u(rng, r["width"]), _u(rng, r["depth"])
    # tall enough for n boards at the generator's least spacing
    H = max(_u(rng, r["height"]), 0.1 + (n - 1) * r["spacing"] + 0.02)
    s, t = _u(rng, r["side"]), _u(rng, r["board"])
    parts = [_box((s, D, H), (sx * (W / 2 - s / 2), 0, H / 2)) for sx in (-1, 1)]
    bottom = _u(rng, (0.04, 0.1))
    zs = np.linspace(bottom, H - t, n)
    parts += [_box((W - 2 * s, D, t), (0, 0, z + t / 2)) for z in zs]
    return ModelSpec("shelf", variant, {"width": W, "depth": D, "height": H, "side": s,
                                        "board": t, "boards": n}, _join(parts))


def desk_model(rng: np.random.Generator, variant: str) -> ModelSpec:
    """A top on two side panels, or on a panel and a drawer block with drawer fronts."""
    r = WIDE["desk"]
    W, D, T, H = _u(rng, r["width"]), _u(rng, r["depth"]), _u(rng, r["top"]), _u(rng, r["height"])
    p = _u(rng, r["panel"])
    parts = [_box((W, D, T), (0, 0, H - T / 2)),
             _box((p, D, H - T), (-W / 2 + p / 2, 0, (H - T) / 2))]
    params = {"width": W, "depth": D, "height": H, "top": T, "panel": p}
    if variant == "panels":
        parts.append(_box((p, D, H - T), (W / 2 - p / 2, 0, (H - T) / 2)))
    elif variant == "drawers":
        dw = _u(rng, r["drawer"])
        h = H - T
        parts.append(_box((dw, D - 0.04, h), (W / 2 - dw / 2, 0.02, h / 2)))
        n = int(rng.integers(2, 5))
        gap = 0.01
        fh = (h - (n + 1) * gap) / n
        front = -D / 2 + 0.04            # the block's front face
        for k in range(n):   # drawer fronts, 8 mm proud of the block's front face
            z = gap + k * (fh + gap) + fh / 2
            parts.append(_box((dw - 2 * gap, 0.008, fh), (W / 2 - dw / 2, front - 0.004, z)))
        params.update(drawer=dw, drawers=n)
    else:
        raise ValueError(f"desk variant {variant!r}")
    return ModelSpec("desk", variant, params, _join(parts))


def sofa_model(rng: np.random.Generator, variant: str) -> ModelSpec:
    """Seat block and back, with or without arms (the back spans the arms)."""
    r = WIDE["sofa"]
    W, D, h = _u(rng, r["width"]), _u(rng, r["depth"]), _u(rng, r["seat"])
    aw, ah = _u(rng, r["arm"]), _u(rng, r["arm_height"])
    bd, bh = _u(rng, r["back"]), _u(rng, r["back_height"])
    arms = variant == "arms"
    if variant not in ("arms", "no_arms"):
        raise ValueError(f"sofa variant {variant!r}")
    span = W + 2 * aw if arms else W
    parts = [_box((W, D, h), (0, 0, h / 2)), _box((span, bd, bh), (0, D / 2 + bd / 2, bh / 2))]
    params = {"width": W, "depth": D, "seat": h, "back": bd, "back_height": bh}
    if arms:
        parts += [_box((aw, D, ah), (sx * (W / 2 + aw / 2), 0, ah / 2)) for sx in (-1, 1)]
        params.update(arm=aw, arm_height=ah)
    return ModelSpec("sofa", variant, params, _join(parts))


def monitor_model(rng: np.random.Generator, variant: str = "stand") -> ModelSpec:
    """A round base, a neck and a screen with a thinner bezel frame at its back."""
    br, bt = _u(rng, (0.08, 0.12)), _u(rng, (0.012, 0.02))
    nw, nt, nh = _u(rng, (0.04, 0.06)), _u(rng, (0.025, 0.04)), _u(rng, (0.25, 0.35))
    sw, st, sh = _u(rng, (0.45, 0.62)), _u(rng, (0.02, 0.035)), _u(rng, (0.28, 0.38))
    zb = bt + _u(rng, (0.05, 0.09))
    parts = [_cylinder(br, 0.0, bt, 0.0, 0.0), _box((nw, nt, nh), (0, 0.02, bt + nh / 2)),
             _box((sw, st, sh), (0, 0.02 - nt / 2 - st / 2, zb + sh / 2))]
    return ModelSpec("monitor", variant, {"base_radius": br, "screen": [sw, st, sh],
                                          "neck_height": nh}, _join(parts))


def box_model(rng: np.random.Generator, variant: str = "plain") -> ModelSpec:
    """A cardboard box."""
    s = rng.uniform(0.08, 0.5, size=3)
    return ModelSpec("box", variant, {"size": [float(v) for v in s]},
                     _join([_box(s, (0, 0, s[2] / 2))]))


BUILDERS: dict[str, Callable[[np.random.Generator, str], ModelSpec]] = {
    "table": table_model, "chair": chair_model, "shelf": shelf_model, "desk": desk_model,
    "sofa": sofa_model, "monitor": monitor_model, "box": box_model,
}


def make_models(rng: np.random.Generator, n_per_kind: int = N_PER_KIND,
                kinds: tuple[str, ...] = KINDS) -> list[ModelSpec]:
    """``n_per_kind`` models of every kind, cycling through its variants (so each appears
    ``n_per_kind // len(variants)`` or one more times), proportions drawn from ``rng``."""
    if n_per_kind < 1:
        raise ValueError(f"n_per_kind: must be at least 1, got {n_per_kind}")
    out = []
    for kind in kinds:
        variants = VARIANTS[kind]
        for i in range(n_per_kind):
            out.append(BUILDERS[kind](rng, variants[i % len(variants)]))
    return out


def model_glb(spec: ModelSpec) -> bytes:
    """The ``.glb`` bytes of one model: coloured by its kind, turned to glTF's y up."""
    import trimesh

    mesh = spec.mesh.copy()
    mesh.visual.face_colors = np.tile(np.array(KIND_COLORS[spec.kind], np.uint8),
                                      (len(mesh.faces), 1))
    mesh.apply_transform(Y_UP_FROM_Z_UP)
    scene = trimesh.Scene()
    scene.add_geometry(mesh, node_name=f"{spec.kind}:{spec.variant}", geom_name="model")
    return scene.export(file_type="glb")


def _jsonable(v):
    if isinstance(v, (np.floating, float)):
        return round(float(v), 6)
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, (list, tuple, np.ndarray)):
        return [_jsonable(x) for x in v]
    return v


def write_repository(folder: str | os.PathLike, specs: list[ModelSpec], seed: int | None = None
                     ) -> dict:
    """Write ``<kind>_<nnn>.glb`` per model and ``index.json`` into ``folder``; return the index."""
    from pipeline import atomic

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    counts: dict[str, int] = {}
    entries = []
    for spec in specs:
        k = counts.get(spec.kind, 0)
        counts[spec.kind] = k + 1
        name = f"{spec.kind}_{k:03d}.glb"
        atomic.write_bytes(folder / name, model_glb(spec))
        lo, hi = spec.mesh.bounds
        entries.append({"file": name, "kind": spec.kind, "variant": spec.variant, "up": "y",
                        "front": "-y (z-up frame)", "extents": _jsonable(hi - lo),
                        "params": {k2: _jsonable(v) for k2, v in spec.params.items()}})
    index = {"format": "unseen.models", "version": 1, "units": "m", "seed": seed,
             "frame": "glTF y up; the z-up model frame is x, -z, y of the file",
             "models": entries}
    atomic.write_text(folder / "index.json", json.dumps(index, indent=1) + "\n")
    return index


# --------------------------------------------------------------- variants of scene objects
def variant_of(kind: str, centers: np.ndarray, rotations: np.ndarray,
               sizes: np.ndarray) -> str | None:
    """The repository variant a generated object was built as, read from its true cuboids.

    Parameters
    ----------
    kind : the object's kind (its name without the number: ``chair`` of ``chair3``)
    centers, rotations, sizes : (k, 3), (k, 3, 3), (k, 3) its cuboids (all parts of one
        generated piece of furniture share one rotation, so sizes are along common axes)

    Returns
    -------
    str or None
        None for a kind the repository does not hold.
    """
    sizes = np.asarray(sizes, float)
    lo_z = np.asarray(centers, float)[:, 2] - _half_heights(rotations, sizes)
    on_floor = lo_z < lo_z.min() + 0.01
    if kind == "table":
        n = int(on_floor.sum())
        return {4: "four_legs", 3: "three_legs"}.get(n, "pedestal")
    if kind == "chair":
        seat = int(np.argmax(np.where(on_floor, -np.inf, sizes[:, 0] * sizes[:, 1]
                                      / np.maximum(sizes[:, 2], 1e-9))))
        top = lo_z[seat] + sizes[seat, 2]
        above = lo_z > top - 0.01
        thin = (sizes[:, 0] < 0.05) & (sizes[:, 1] < 0.06)
        long_ = sizes[:, 1] > 0.5 * sizes[seat, 1]
        back = "posts" if bool(np.any(above & thin & (sizes[:, 2] > 0.04))) else "board"
        return back + ("_arms" if bool(np.any(above & long_)) else "")
    if kind == "shelf":
        return f"boards{max(len(sizes) - 2, 0)}"
    if kind == "desk":
        legs = np.flatnonzero(on_floor)
        return "drawers" if bool(np.any(np.min(sizes[legs, :2], axis=1) > 0.1)) else "panels"
    if kind == "sofa":
        return "arms" if len(sizes) >= 4 else "no_arms"
    if kind in ("monitor", "box"):
        return VARIANTS[kind][0]
    return None


def _half_heights(rotations, sizes) -> np.ndarray:
    """Half vertical extent of each box: sum_j |R[2, j]| s_j / 2."""
    R = np.asarray(rotations, float)
    return 0.5 * np.einsum("kj,kj->k", np.abs(R[:, 2, :]), sizes)
