"""Hand-built scenes for the end-to-end tests: boxes written out by hand, not drawn from
``synth_scenes`` families, scanned by the virtual sensor and run through ``unseen run``.

Every scene is an :class:`pipeline.model.Arrangement` with the true contacts written by
hand (the test's truth, independent of the pipeline's contact finder), a camera pose and
a one-line description.  :func:`write_scene_dir` writes it as a scene directory exactly
like ``unseen synth`` does (``scene.json`` + ``scan/``, Kinect noise, a fixed seed), and
:func:`run_user` runs ``unseen run SCENE --out OUT`` in-process, as a user would.

Conventions: world z up, the floor z = 0, the wall (when there is one) the plane y = 0
with its normal +y (the room is on the +y side), metres.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.camera import Intrinsics, look_at
from pipeline.model import (
    Arrangement,
    Contact,
    Cuboid,
    Support,
    box_corners,
    ground,
    rotation_about_axis,
)

#: Small images keep the tests fast (the pipeline accepts any intrinsics): a Kinect v1's
#: field of view (f = 525 at 640x480) at half the resolution.
INTRINSICS = Intrinsics(320, 240, 262.5, 262.5, 159.5, 119.5)
#: The seed of every scan (Kinect noise) and of ``unseen run`` (RANSAC).
SEED = 7
MU = 0.7
X_AXIS = np.array([1.0, 0.0, 0.0])


@dataclass(frozen=True)
class HandScene:
    """A hand-built scene: the truth (typed contacts by hand) and where the camera is."""

    name: str
    truth: Arrangement
    eye: tuple[float, float, float]
    target: tuple[float, float, float]

    @property
    def pose(self) -> np.ndarray:
        return look_at(np.asarray(self.eye, float), np.asarray(self.target, float))


def wall(k: int = 0) -> Support:
    """The wall y = 0, facing +y."""
    return Support(f"wall:{k}", np.zeros(3), np.array([0.0, 1.0, 0.0]))


def part(id: str, lo, hi, obj: str | None = None, rotation=None) -> Cuboid:
    """An axis-aligned box from its lower and upper corners (or rotated about its centre)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    R = np.eye(3) if rotation is None else np.asarray(rotation, float)
    return Cuboid(id, (lo + hi) / 2, R, hi - lo, object=obj or id)


def edges(*triples: tuple[str, str, str]) -> tuple[Contact, ...]:
    return tuple(Contact(a, b, t) for a, b, t in triples)


# ------------------------------------------------------------------------------ scenes
def ladder_limit_deg(mu: float = MU) -> float:
    """The steepest lean from the wall a plank stands at (friction ``mu`` on floor and wall).

    A thin plank of weight W leaning at ``theta`` from the vertical: at the limit both
    frictions are ``mu`` times their normal forces, N_floor = W / (1 + mu^2), and moments
    about the foot give ``tan(theta) = 2 mu / (1 - mu^2)``: 70.0 degrees from the wall
    (20.0 degrees from the floor) for mu = 0.7.  Without wall friction it is
    ``tan(theta) = 2 mu``: 54.5 degrees.
    """
    return float(np.degrees(np.arctan2(2 * mu, 1 - mu * mu)))


def plank_scene(lean_deg: float = 20.0) -> HandScene:
    """A 1.2 m plank leaning ``lean_deg`` from the vertical on the wall y = 0.

    Its bottom edge is on the floor, its top edge on the wall; the floor friction it
    needs is ``tan(lean) / 2`` = 0.18 at 20 degrees (frictionless wall), a quarter of mu.
    """
    size = np.array([0.40, 0.03, 1.20])              # width (x), thickness, length
    R = rotation_about_axis(X_AXIS, np.radians(lean_deg))  # top towards the wall (-y)
    c = box_corners(np.zeros((1, 3)), R[None], size[None])[0]
    center = np.array([0.0, -c[:, 1].min(), -c[:, 2].min()])
    plank = Cuboid("plank", center, R, size, object="plank")
    truth = Arrangement((plank,), (ground(), wall()),
                        edges(("plank", "ground", "touch"), ("plank", "wall:0", "touch")))
    return HandScene("plank", truth, eye=(1.3, 2.3, 1.3), target=(0.0, 0.25, 0.55))


def cantilever_scene() -> HandScene:
    """A shelf board glued to the side of one pillar, seen from the side.

    The board (0.6 m out from the pillar's face) touches nothing else: only a joint that
    takes a moment holds it, so board-pillar is ``fixed`` (without glue it falls).  The
    pillar stands on the floor: the common centre of mass is 4.0 cm from the pillar's
    axis, inside its 20 x 20 cm footprint, so pillar-ground is a ``touch``.
    """
    pillar = part("pillar", (-0.10, -0.10, 0.00), (0.10, 0.10, 1.00))
    board = part("board", (0.10, -0.125, 0.70), (0.70, 0.125, 0.73))
    truth = Arrangement((pillar, board), (ground(),),
                        edges(("pillar", "ground", "touch"), ("board", "pillar", "fixed")))
    return HandScene("cantilever", truth, eye=(0.35, -1.9, 1.55), target=(0.3, 0.0, 0.55))


def chair_scene() -> HandScene:
    """A chair facing -y (seat, four legs, a back board on the seat's rear edge), filmed
    from behind and above the back (the camera at +y).

    One object: the back and the legs are glued to the seat (``fixed``); the legs stand
    on the floor (``touch``).
    """
    W, D, T, H, leg, inset = 0.46, 0.44, 0.04, 0.46, 0.04, 0.02
    parts = [part("seat", (-W / 2, -D / 2, H - T), (W / 2, D / 2, H), "chair")]
    tri = []
    for k, (sx, sy) in enumerate(((-1, -1), (1, -1), (-1, 1), (1, 1))):
        x0 = sx * (W / 2 - inset) - (leg if sx > 0 else 0.0)
        y0 = sy * (D / 2 - inset) - (leg if sy > 0 else 0.0)
        parts.append(part(f"leg{k}", (x0, y0, 0.0), (x0 + leg, y0 + leg, H - T), "chair"))
        tri += [(f"leg{k}", "seat", "fixed"), (f"leg{k}", "ground", "touch")]
    parts.append(part("back", (-W / 2, D / 2 - 0.03, H), (W / 2, D / 2, H + 0.45), "chair"))
    tri.append(("back", "seat", "fixed"))
    truth = Arrangement(tuple(parts), (ground(),), edges(*tri))
    return HandScene("chair", truth, eye=(0.55, 1.75, 1.45), target=(0.0, 0.0, 0.4))


def wall_shelf_scene() -> HandScene:
    """Two boards on the wall y = 0 filmed head-on from 2.2 m, the floor barely in the
    picture: a low board glued to the wall holding a box, and a high board on two
    brackets (brackets glued to the wall and to the board: one object).
    """
    low = part("low", (-0.45, 0.0, 1.00), (0.45, 0.26, 1.025), "low")
    high = part("high", (-0.40, 0.0, 1.45), (0.40, 0.24, 1.475), "high")
    br = [part(f"bracket{k}", (x - 0.0125, 0.0, 1.33), (x + 0.0125, 0.16, 1.45), "high")
          for k, x in enumerate((-0.32, 0.32))]
    item = part("box", (-0.30, 0.05, 1.025), (-0.08, 0.20, 1.185))
    truth = Arrangement((low, high, *br, item), (ground(), wall()),
                        edges(("low", "wall:0", "fixed"), ("high", "wall:0", "fixed"),
                              ("bracket0", "wall:0", "fixed"), ("bracket1", "wall:0", "fixed"),
                              ("bracket0", "high", "fixed"), ("bracket1", "high", "fixed"),
                              ("box", "low", "touch")))
    return HandScene("wall_shelf", truth, eye=(0.1, 2.2, 1.15), target=(0.0, 0.0, 1.05))


def table_scene(leg_hidden: bool = False) -> HandScene:
    """A table (top glued to four legs, legs on the floor) with a box on the floor under
    it, filmed from low down (45 cm) so the box shows between the legs.

    The camera is 25 cm right of the table's centre, so all four legs show; with
    ``leg_hidden`` it is 50 cm right, in line with the right legs, and the front right
    leg hides the back right one completely (a part only a prior can bring back).
    """
    W, D, T, H, leg, inset = 1.2, 0.7, 0.04, 0.74, 0.05, 0.04
    parts = [part("top", (-W / 2, -D / 2, H - T), (W / 2, D / 2, H), "table")]
    tri = []
    for k, (sx, sy) in enumerate(((-1, -1), (1, -1), (-1, 1), (1, 1))):
        x0 = sx * (W / 2 - inset) - (leg if sx > 0 else 0.0)
        y0 = sy * (D / 2 - inset) - (leg if sy > 0 else 0.0)
        parts.append(part(f"leg{k}", (x0, y0, 0.0), (x0 + leg, y0 + leg, H - T), "table"))
        tri += [(f"leg{k}", "top", "fixed"), (f"leg{k}", "ground", "touch")]
    parts.append(part("box", (-0.10, -0.12, 0.0), (0.30, 0.18, 0.30)))
    tri.append(("box", "ground", "touch"))
    truth = Arrangement(tuple(parts), (ground(),), edges(*tri))
    return HandScene("table_leg_hidden" if leg_hidden else "table", truth,
                     eye=(0.5 if leg_hidden else 0.25, -1.9, 0.45), target=(0.0, 0.0, 0.35))


def tripod_table_scene() -> HandScene:
    """A three-legged table (top glued to two legs at its back corners and one at the
    middle of its front, legs on the floor), filmed from the front, right and above.

    Three legs in three quadrants of the top are all the legs it has: no fourth is
    hidden (the ``copies`` prior completes a rectangle only from a right angle, and the
    corner a rectangle would put beyond the top's left edge is in plain view, empty).
    """
    W, D, T, H, leg, inset = 1.0, 0.6, 0.04, 0.72, 0.05, 0.04
    parts = [part("top", (-W / 2, -D / 2, H - T), (W / 2, D / 2, H), "table")]
    spots = ((-W / 2 + inset, D / 2 - inset - leg), (W / 2 - inset - leg, D / 2 - inset - leg),
             (-leg / 2 + 0.03, -D / 2 + inset))
    tri = []
    for k, (x0, y0) in enumerate(spots):
        parts.append(part(f"leg{k}", (x0, y0, 0.0), (x0 + leg, y0 + leg, H - T), "table"))
        tri += [(f"leg{k}", "top", "fixed"), (f"leg{k}", "ground", "touch")]
    truth = Arrangement(tuple(parts), (ground(),), edges(*tri))
    return HandScene("tripod_table", truth, eye=(0.4, -1.9, 1.2), target=(0.0, 0.0, 0.35))


def lever_scene() -> HandScene:
    """A plank on a block with a weight on its near end, filmed end-on along the plank.

    The plank (1.2 m along y) rests on a block under its far half; the weight (6.9 kg at
    density 1000, on the plank's near end, as wide as the plank) has its centre 0.22 m
    past the block's edge and the plank's own far arm balances it: the common centre of
    mass of plank and weight lies 0.105 m inside the block's edge.  From the camera in
    line with the plank, just below the weight's top, the plank shows only its end: its
    length runs away behind the weight, hidden.  All contacts are ``touch``.
    """
    block = part("block", (-0.20, -0.30, 0.00), (0.20, 0.10, 0.80))
    plank = part("plank", (-0.12, -0.80, 0.80), (0.12, 0.40, 0.84))
    weight = part("weight", (-0.12, 0.24, 0.84), (0.12, 0.40, 1.02))
    truth = Arrangement((block, plank, weight), (ground(),),
                        edges(("block", "ground", "touch"), ("plank", "block", "touch"),
                              ("weight", "plank", "touch")))
    return HandScene("lever", truth, eye=(0.0, 2.6, 0.95), target=(0.0, 0.0, 0.6))


def sofa_scene() -> HandScene:
    """A sofa filmed from beside one arm, above it: the two seat cushions show their
    tops over the arm, the seat block under them is hidden behind the arm.

    The sofa is one object (two arms, a back, the seat block: ``fixed`` where they
    touch, each on the floor); each cushion is an object of its own resting on the seat
    block, flush with its front, 3 cm clear of the arms and the back and 4 cm clear of
    each other.
    """
    sofa = [part("armA", (-0.80, -0.35, 0.0), (-0.65, 0.35, 0.62), "sofa"),
            part("armB", (0.65, -0.35, 0.0), (0.80, 0.35, 0.62), "sofa"),
            part("back", (-0.80, 0.35, 0.0), (0.80, 0.50, 0.85), "sofa"),
            part("seat", (-0.65, -0.35, 0.0), (0.65, 0.35, 0.33), "sofa")]
    cushions = [part("cushion0", (-0.62, -0.35, 0.33), (-0.02, 0.32, 0.45)),
                part("cushion1", (0.02, -0.35, 0.33), (0.62, 0.32, 0.45))]
    tri = [(k, "ground", "touch") for k in ("armA", "armB", "back", "seat")]
    tri += [("seat", "armA", "fixed"), ("seat", "armB", "fixed"), ("seat", "back", "fixed"),
            ("armA", "back", "fixed"), ("armB", "back", "fixed"),
            ("cushion0", "seat", "touch"), ("cushion1", "seat", "touch")]
    truth = Arrangement(tuple(sofa + cushions), (ground(),), edges(*tri))
    return HandScene("sofa", truth, eye=(-2.0, 0.0, 1.9), target=(0.0, 0.0, 0.35))


# ------------------------------------------------------------------------ scan and run
def write_scene_dir(scene: HandScene, out: Path, seed: int = SEED,
                    intrinsics: Intrinsics = INTRINSICS) -> Path:
    """Scan ``scene`` once (Kinect noise, ``seed``) and write a scene directory."""
    from pipeline.arrangement_io import write_arrangement
    from simulate.scan import scan_arrangement, write_scan

    out = Path(out)
    arr = scene.truth.with_(meta={"generator": "tests/handbuilt", "scene": scene.name})
    scan = scan_arrangement(arr, np.random.default_rng(seed), noise="kinect",
                            intrinsics=intrinsics, poses=[scene.pose])
    out.mkdir(parents=True, exist_ok=True)
    write_scan(scan, out / "scan")
    write_arrangement(arr, out / "scene.json")
    return out


def run_user(scene_dir: Path, out: Path, *extra: str) -> tuple[int, Arrangement]:
    """``unseen run SCENE --out OUT --seed SEED``, in-process: (exit code, arrangement)."""
    from eval.cli import main
    from pipeline.arrangement_io import read_arrangement

    code = main(["run", str(scene_dir), "--out", str(out), "--seed", str(SEED), *extra])
    arr = read_arrangement(Path(out) / "arrangement.json") if code in (0, 1) else None
    return code, arr
