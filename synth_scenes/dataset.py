"""Benchmark datasets: many scene directories, their plan, their manifest, and a loader.

A dataset is a folder made by ``unseen dataset make`` (:mod:`eval.commands.dataset`)::

    DIR/<split>/<family>-<seed>/      one scene directory per scene (DESIGN.md's format:
                                      scene.json + scan/), e.g. DIR/train/table-000017/
    DIR/manifest.jsonl                one JSON line per scene, in plan order (below)
    DIR/dataset.json                  the configuration that made it (:class:`DatasetConfig`)
    DIR/DATASET.md, DIR/stats.png     the dataset card and its per-family statistics
    DIR/bop/                          optional BOP export (:mod:`synth_scenes.bop`)

**The plan** (:func:`plan`) is a pure function of the configuration.  Scene ``i`` (0-based)
is of family ``families[i % F]`` and has seed ``first_seed + i``; ``unseen synth FAMILY
--seed SEED`` with the same options writes the same scene.  Its knobs (views, family
options such as the number of boxes, the scale) are drawn from a generator of that seed
alone, so a scene does not change when ``--n`` does.  Splits are stratified: within each
family the scenes are dealt to the splits in the given proportions (largest remainders)
in an order shuffled by ``first_seed``.

**A manifest line** holds ``id``, ``index``, ``seed``, ``family``, ``split``, ``path``,
``parameters`` (what the scene was made with), ``counts`` (cuboids, objects, contacts,
fixed contacts, points, views), ``stands`` (analytic, MuJoCo, PyBullet verdicts: a
scene is kept only when all three say it stands), ``attempts`` (samples drawn; those
beyond the first failed to settle and were resampled) and ``files`` (SHA-256 of every
file, relative to the scene directory).  It holds no timings: the same configuration
gives byte-identical scenes and manifest whatever the number of workers.

:class:`Dataset` reads a dataset back as arrays and graphs (no command line involved).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
from collections.abc import Iterator, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.errors import InputError

#: Splits, in order; the proportions given to ``--split`` follow this order.
SPLITS = ("train", "val", "test")
#: The scene families a dataset can draw (the generator's, without the demo scene).
DATASET_FAMILIES = ("stack", "counterweight", "bridge", "table", "chair", "shelf",
                    "wall_shelf", "desk", "sofa", "room")
#: Integer family options a configuration may give as ranges, and their bounds.
FAMILY_OPTIONS = {"stack": {"n_boxes": (1, 200)}, "table": {"n_items": (0, 20)},
                  "room": {"n_objects": (1, 100)}}
#: Style options a configuration may give as a list of choices (one drawn per scene).
FAMILY_STYLES = {"table": {"style": ("four_legs", "three_legs", "pedestal")},
                 "chair": {"arms": (False, True)}, "sofa": {"arms": (True, False)}}
#: Bounds of the other knobs.
MAX_VIEWS = 16
SCALE_RANGE = (0.25, 4.0)
MANIFEST = "manifest.jsonl"
CONFIG_FILE = "dataset.json"
#: Relative path -> SHA-256 of every file of the BOP export (``bop/``), written with it.
BOP_MANIFEST = "bop_manifest.json"


# ---------------------------------------------------------------------------- config
@dataclass(frozen=True)
class DatasetConfig:
    """Everything a dataset is made from.  Ranges are closed ``(lo, hi)`` pairs.

    Attributes
    ----------
    families : tuple of str
        Families drawn in turn (scene ``i`` is ``families[i % len(families)]``).
    n : int
        Number of scenes.
    split : tuple of 3 float
        Proportions of train, val, test (sum 1).
    first_seed : int
        Seed of scene 0; scene ``i`` has seed ``first_seed + i``.
    views : (int, int)
        Camera views per scene, drawn uniformly.
    noise : {"kinect", "none"}
    renderer : {"mujoco", "pybullet"}
    camera : dict
        Viewpoint ranges (:class:`simulate.viewpoints.ViewRanges`): ``distance`` and
        ``height`` in metres, ``azimuth`` (or ``elevation``) in degrees; empty = defaults.
    scale : (float, float)
        Each scene is scaled as a whole by a factor drawn from this range.
    options : dict
        Family -> option -> (lo, hi) integer range (:data:`FAMILY_OPTIONS`: clutter and
        the number of objects) or a tuple of style choices (:data:`FAMILY_STYLES`: table
        legs or pedestal, chairs and sofas with or without arms).
    proportions : dict
        Family -> length name -> (lo, hi) metres, replacing the generator's range
        (:func:`proportion_names`), e.g. ``{"table": {"height": (0.5, 0.9)}}``.
    max_attempts : int
        Samples per scene before giving up (each failed sample is counted).
    """

    families: tuple[str, ...] = DATASET_FAMILIES
    n: int = 100
    split: tuple[float, float, float] = (0.8, 0.1, 0.1)
    first_seed: int = 0
    views: tuple[int, int] = (1, 1)
    noise: str = "kinect"
    renderer: str = "mujoco"
    camera: dict = field(default_factory=dict)
    scale: tuple[float, float] = (1.0, 1.0)
    options: dict = field(default_factory=dict)
    proportions: dict = field(default_factory=dict)
    max_attempts: int = 25

    def to_json(self) -> dict:
        d = asdict(self)
        d["families"] = list(self.families)
        d["split"] = dict(zip(SPLITS, self.split))
        d["views"] = list(self.views)
        d["scale"] = list(self.scale)
        d["options"] = {f: {k: list(v) for k, v in o.items()} for f, o in self.options.items()}
        d["proportions"] = {f: {k: list(v) for k, v in o.items()}
                            for f, o in self.proportions.items()}
        d["camera"] = {k: list(v) for k, v in self.camera.items()}
        return d


def _range(value: Any, where: str, kind: type, lo: float, hi: float) -> tuple:
    """A ``[lo, hi]`` list (or one number) checked against the bounds."""
    vals = value if isinstance(value, (list, tuple)) else [value]
    if len(vals) not in (1, 2) or any(isinstance(v, bool) or not isinstance(v, (int, float))
                                      for v in vals):
        raise InputError(f"{where}: expected a number or [lo, hi], got {value!r}")
    if kind is int and any(float(v) != int(v) for v in vals):
        raise InputError(f"{where}: expected whole numbers, got {value!r}")
    a, b = (kind(vals[0]), kind(vals[-1]))
    if not (math.isfinite(a) and math.isfinite(b) and lo <= a <= b <= hi):
        raise InputError(f"{where}: need {lo:g} <= lo <= hi <= {hi:g}, got {value!r}")
    return (a, b)


def _choices(value: Any, where: str, allowed: tuple) -> tuple:
    """A list of style choices (or one), each one of ``allowed``."""
    vals = value if isinstance(value, (list, tuple)) else [value]
    bad = [v for v in vals if v not in allowed or isinstance(v, bool) != isinstance(allowed[0], bool)]
    if not vals or bad:
        raise InputError(f"{where}: expected a list of {', '.join(map(repr, allowed))}, got "
                         f"{value!r}")
    return tuple(dict.fromkeys(vals))


def parse_split(text: str) -> tuple[float, float, float]:
    """``"80/10/10"`` (percent or any weights) -> proportions of train, val, test."""
    parts = str(text).replace(",", "/").split("/")
    try:
        w = [float(p) for p in parts]
    except ValueError:
        w = []
    if len(w) != 3 or any(not math.isfinite(x) or x < 0 for x in w) or sum(w) <= 0:
        raise InputError(f"--split {text!r}: expected three non-negative weights "
                         "train/val/test, e.g. 80/10/10")
    total = sum(w)
    return (w[0] / total, w[1] / total, w[2] / total)


def parse_views(text: str) -> tuple[int, int]:
    """``"2"`` or ``"1-3"`` -> the range of views per scene."""
    parts = str(text).split("-")
    try:
        vals = [int(p) for p in parts]
    except ValueError:
        vals = []
    if len(vals) not in (1, 2) or not 1 <= vals[0] <= vals[-1] <= MAX_VIEWS:
        raise InputError(f"--views {text!r}: expected K or LO-HI with 1 <= LO <= HI <= "
                         f"{MAX_VIEWS}, e.g. 1-3")
    return (vals[0], vals[-1])


def parse_families(text: str) -> tuple[str, ...]:
    """``"all"`` or ``"table,chair"`` -> the families, each checked."""
    if text.strip() == "all":
        return DATASET_FAMILIES
    fams = tuple(f.strip() for f in text.split(",") if f.strip())
    bad = [f for f in fams if f not in DATASET_FAMILIES]
    if not fams or bad:
        raise InputError(f"--families {text!r}: unknown {', '.join(bad) or '(none given)'}; "
                         f"use 'all' or a comma list of: {', '.join(DATASET_FAMILIES)}")
    if len(set(fams)) != len(fams):
        raise InputError(f"--families {text!r}: a family is named twice")
    return fams


#: The sections and keys a configuration file may hold.
CONFIG_KEYS = {"camera": ("distance", "height", "azimuth", "elevation"),
               "scan": ("noise", "renderer", "views"),
               "scene": ("scale", "max_attempts"),
               "families": tuple(dict.fromkeys([*FAMILY_OPTIONS, *FAMILY_STYLES])),
               "proportions": ("counterweight", "bridge", "table", "chair", "shelf",
                               "wall_shelf", "desk", "sofa")}


def proportion_names(family: str) -> tuple[str, ...]:
    """The lengths of a family's proportion table that a configuration may set: those
    whose range in :data:`synth_scenes.objects.WIDE` is one ``(lo, hi)`` pair of metres
    (counts, probabilities and per-axis triples stay the generator's)."""
    from .objects import WIDE

    return tuple(k for k, v in WIDE[family].items()
                 if isinstance(v, tuple) and len(v) == 2
                 and all(isinstance(x, float) for x in v))


def read_config(path: str | os.PathLike, base: DatasetConfig | None = None) -> DatasetConfig:
    """Read a TOML (``.toml``) or YAML (``.yaml``/``.yml``) configuration file.

    Layout (every key optional)::

        [camera]   distance = [1.0, 3.5]   height = [0.3, 2.0]   azimuth = [-60, 60]
        [scan]     noise = "kinect"        renderer = "mujoco"   views = [1, 3]
        [scene]    scale = [0.8, 1.25]     max_attempts = 25
        [families.stack]  n_boxes = [3, 8]
        [families.table]  n_items = [0, 4]
        [families.room]   n_objects = [4, 10]
        [families.table]  style = ["four_legs", "pedestal"]     # one drawn per scene
        [families.chair]  arms = [false, true]
        [proportions.table] height = [0.5, 0.9]    # metres, replaces the generator's range

    Raises :class:`InputError` naming the file and the key for anything unknown or out of
    range.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"--config {p}: cannot read it ({exc.__class__.__name__})") from None
    try:
        if p.suffix.lower() == ".toml":
            import tomllib

            data = tomllib.loads(text)
        elif p.suffix.lower() in (".yaml", ".yml"):
            import yaml

            data = yaml.safe_load(text) or {}
        else:
            raise InputError(f"--config {p}: expected a .toml, .yaml or .yml file")
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - the parsers' own error types
        line = " ".join(str(exc).split())[:200]
        raise InputError(f"--config {p}: not valid {p.suffix[1:].upper()}: {line}") from None
    return config_from_mapping(data, str(p), base)


def config_from_mapping(data: Any, source: str = "config",
                        base: DatasetConfig | None = None) -> DatasetConfig:
    """Validate a parsed configuration (see :func:`read_config`) over ``base``."""
    from simulate.viewpoints import ViewRanges

    cfg = base or DatasetConfig()
    if not isinstance(data, Mapping):
        raise InputError(f"{source}: expected sections camera, scan, scene, families")
    changes: dict[str, Any] = {}
    for section, body in data.items():
        where = f"{source}: [{section}]"
        if section not in CONFIG_KEYS:
            raise InputError(f"{where}: unknown section; expected one of "
                             f"{', '.join(CONFIG_KEYS)}")
        if not isinstance(body, Mapping):
            raise InputError(f"{where}: expected a table of keys")
        bad = [k for k in body if k not in CONFIG_KEYS[section]]
        if bad:
            raise InputError(f"{where} {bad[0]}: unknown key; expected one of "
                             f"{', '.join(CONFIG_KEYS[section])}")
        if section == "camera":
            cam = {}
            for key, value in body.items():
                hi = 360.0 if key in ("azimuth", "elevation") else 20.0
                lo = -360.0 if key == "azimuth" else (-89.0 if key == "elevation" else 0.01)
                cam[key] = _range(value, f"{where} {key}", float, lo, hi)
            ViewRanges.from_dict(cam)  # its own checks (height and elevation together, ...)
            changes["camera"] = cam
        elif section == "scan":
            for key, value in body.items():
                if key == "views":
                    changes["views"] = _range(value, f"{where} views", int, 1, MAX_VIEWS)
                elif key == "noise":
                    if value not in ("kinect", "none"):
                        raise InputError(f"{where} noise: 'kinect' or 'none', got {value!r}")
                    changes["noise"] = value
                else:
                    if value not in ("mujoco", "pybullet"):
                        raise InputError(f"{where} renderer: 'mujoco' or 'pybullet', got "
                                         f"{value!r}")
                    changes["renderer"] = value
        elif section == "scene":
            if "scale" in body:
                changes["scale"] = _range(body["scale"], f"{where} scale", float, *SCALE_RANGE)
            if "max_attempts" in body:
                changes["max_attempts"] = _range(body["max_attempts"], f"{where} max_attempts",
                                                 int, 1, 1000)[0]
        elif section == "proportions":
            props = {}
            for fam, fbody in body.items():
                if not isinstance(fbody, Mapping):
                    raise InputError(f"{where}.{fam}: expected a table of lengths")
                names = proportion_names(fam)
                for key, value in fbody.items():
                    where_k = f"{source}: [proportions.{fam}] {key}"
                    if key not in names:
                        raise InputError(f"{where_k}: unknown length; {fam} has "
                                         f"{', '.join(names)}")
                    props.setdefault(fam, {})[key] = _range(value, where_k, float, 0.001, 10.0)
            changes["proportions"] = props
        else:
            opts = {}
            for fam, fbody in body.items():
                if not isinstance(fbody, Mapping):
                    raise InputError(f"{where}.{fam}: expected a table of options")
                known = FAMILY_OPTIONS.get(fam, {})
                styles = FAMILY_STYLES.get(fam, {})
                for key, value in fbody.items():
                    where_k = f"{source}: [families.{fam}] {key}"
                    if key in styles:
                        opts.setdefault(fam, {})[key] = _choices(value, where_k, styles[key])
                    elif key in known:
                        opts.setdefault(fam, {})[key] = _range(value, where_k, int, *known[key])
                    else:
                        raise InputError(f"{where_k}: unknown option; {fam} takes "
                                         f"{', '.join([*known, *styles])}")
            changes["options"] = opts
    return DatasetConfig(**{**asdict(cfg), **changes})


# ------------------------------------------------------------------------------ plan
@dataclass(frozen=True)
class ScenePlan:
    """One scene of a dataset, before it is made."""

    index: int
    id: str
    family: str
    seed: int
    split: str
    views: int
    scale: float
    options: dict

    @property
    def path(self) -> str:
        """The scene directory relative to the dataset folder."""
        return f"{self.split}/{self.id}"

    def parameters(self, cfg: DatasetConfig) -> dict:
        """What the scene is made with (a manifest line's ``parameters``)."""
        return {"views": self.views, "scale": self.scale, "options": dict(self.options),
                "noise": cfg.noise, "renderer": cfg.renderer,
                "camera": {k: list(v) for k, v in cfg.camera.items()}}


def _knob_rng(seed: int) -> np.random.Generator:
    """The generator of a scene's knobs: its seed only, apart from the scene's own two."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), 0x6B6E6F62]))


def _deal(n: int, proportions: tuple[float, ...]) -> list[int]:
    """Counts per split for ``n`` items (largest remainders, ties to the earlier split)."""
    raw = [n * p for p in proportions]
    counts = [int(math.floor(r)) for r in raw]
    order = sorted(range(len(raw)), key=lambda k: (-(raw[k] - counts[k]), k))
    for k in order[:n - sum(counts)]:
        counts[k] += 1
    return counts


def plan(cfg: DatasetConfig) -> list[ScenePlan]:
    """The scenes of a dataset, in order (see the module docstring)."""
    fams = cfg.families
    members: dict[str, list[int]] = {f: [] for f in fams}
    for i in range(cfg.n):
        members[fams[i % len(fams)]].append(i)
    split_of: dict[int, str] = {}
    for k, fam in enumerate(fams):
        idx = members[fam]
        order = np.random.default_rng([int(cfg.first_seed), k, 0x73706C74]).permutation(len(idx))
        counts = _deal(len(idx), cfg.split)
        names = [s for s, c in zip(SPLITS, counts) for _ in range(c)]
        for pos, name in zip(order, names):
            split_of[idx[int(pos)]] = name
    out = []
    for i in range(cfg.n):
        fam = fams[i % len(fams)]
        seed = cfg.first_seed + i
        rng = _knob_rng(seed)
        views = int(rng.integers(cfg.views[0], cfg.views[1] + 1))
        lo, hi = cfg.scale
        scale = float(round(rng.uniform(lo, hi), 4)) if hi > lo else float(lo)
        opts = {}
        for k, v in sorted(cfg.options.get(fam, {}).items()):
            if k in FAMILY_STYLES.get(fam, {}):
                opts[k] = v[int(rng.integers(len(v)))]
            else:
                opts[k] = int(rng.integers(v[0], v[1] + 1))
        if cfg.proportions.get(fam):
            opts["proportions"] = {k: list(v) for k, v in sorted(cfg.proportions[fam].items())}
        out.append(ScenePlan(i, f"{fam}-{seed:06d}", fam, seed, split_of[i], views, scale, opts))
    return out


# ------------------------------------------------------------------------ one scene
def sha256(path: str | os.PathLike) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def file_hashes(scene_dir: str | os.PathLike) -> dict[str, str]:
    """Relative path -> SHA-256 of every file under a scene directory, sorted."""
    root = Path(scene_dir)
    return {p.relative_to(root).as_posix(): sha256(p)
            for p in sorted(root.rglob("*")) if p.is_file()}


def make_scene(sp: ScenePlan, cfg: DatasetConfig, root: str | os.PathLike) -> dict:
    """Make one planned scene under ``root`` and return its manifest line.

    The scene is written into a hidden sibling and renamed into place, so a scene
    directory is complete or absent.  Raises :class:`RuntimeError` when no sample of the
    family stood within ``cfg.max_attempts``.
    """
    from .scene_dir import make_scene_dir

    root = Path(root)
    final = root / sp.path
    tmp = final.parent / f".{sp.id}.tmp-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    final.parent.mkdir(parents=True, exist_ok=True)
    try:
        res = make_scene_dir(sp.family, tmp, sp.seed, views=sp.views, noise=cfg.noise,
                             renderer=cfg.renderer, engines=("mujoco", "pybullet"),
                             view_ranges=cfg.camera or None, max_attempts=cfg.max_attempts,
                             scale=sp.scale, **sp.options)
        gt = res.truth
        if gt.status != "ok":
            raise RuntimeError(f"{sp.id}: no {sp.family} sample stood in {gt.attempts} "
                               f"attempts (seed {sp.seed})")
        hashes = file_hashes(tmp)
        shutil.rmtree(final, ignore_errors=True)
        os.replace(tmp, final)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    arr = gt.arrangement
    v = gt.validation
    return {"id": sp.id, "index": sp.index, "seed": sp.seed, "family": sp.family,
            "split": sp.split, "path": sp.path, "parameters": sp.parameters(cfg),
            "counts": {"cuboids": len(arr.cuboids),
                       "objects": len({c.object or c.id for c in arr.cuboids}),
                       "contacts": len(arr.contacts),
                       "fixed": sum(c.type == "fixed" for c in arr.contacts),
                       "points": res.n_points, "views": sp.views},
            "stands": {"analytic": bool(v.analytic), "mujoco": bool(v.engines.get("mujoco")),
                       "pybullet": bool(v.engines.get("pybullet"))},
            "attempts": gt.attempts, "files": hashes}


def manifest_line(rec: Mapping) -> str:
    """One manifest line: compact JSON, keys in a fixed order."""
    return json.dumps(rec, separators=(",", ":"))


def check_scene(root: str | os.PathLike, rec: Mapping) -> str | None:
    """Why a scene's files do not match its manifest line (None when they do)."""
    folder = Path(root) / rec["path"]
    if not folder.is_dir():
        return f"{rec['path']}: missing"
    have = file_hashes(folder)
    want = rec["files"]
    if set(have) != set(want):
        extra = sorted(set(have) - set(want))
        gone = sorted(set(want) - set(have))
        return f"{rec['path']}: files differ (missing {gone[:3]}, extra {extra[:3]})"
    for name, digest in want.items():
        if have[name] != digest:
            return f"{rec['path']}/{name}: hash differs from the manifest"
    return None


# ---------------------------------------------------------------------------- loader
@dataclass(frozen=True)
class View:
    """One camera view of a scene, as arrays."""

    color: np.ndarray       #: (H, W, 3) uint8 RGB
    depth: np.ndarray       #: (H, W) float32 metres, 0 = no reading
    instance: np.ndarray    #: (H, W) uint16, k = scene cuboid k-1, 0 = none
    K: np.ndarray           #: (3, 3) intrinsic matrix
    T_world_cam: np.ndarray  #: (4, 4) camera-to-world (OpenCV camera frame)


@dataclass(frozen=True)
class Sample:
    """One scene of a dataset: its manifest line, ground truth, views and contact graph."""

    record: dict
    path: Path
    arrangement: Any      #: pipeline.model.Arrangement (scene.json)
    views: tuple[View, ...]

    @property
    def id(self) -> str:
        return self.record["id"]

    @property
    def split(self) -> str:
        return self.record["split"]

    @property
    def family(self) -> str:
        return self.record["family"]

    @property
    def graph(self) -> list[tuple[str, str, str]]:
        """Typed contact edges ``(a, b, type)``, ``a < b``, supports named ``ground`` and
        ``wall:<k>``, sorted."""
        return sorted((*sorted((c.a, c.b)), c.type) for c in self.arrangement.contacts)

    @property
    def poses(self) -> np.ndarray:
        """(n, 4, 4) world poses of the cuboids (rotation and centre)."""
        arr = self.arrangement
        T = np.tile(np.eye(4), (len(arr.cuboids), 1, 1))
        T[:, :3, :3] = arr.rotations
        T[:, :3, 3] = arr.centers
        return T

    @property
    def sizes(self) -> np.ndarray:
        """(n, 3) full edge lengths of the cuboids, metres."""
        return self.arrangement.sizes


def read_view(folder: str | os.PathLike) -> View:
    """One view folder (``color.png``, ``depth.png``, ``instance.png``, camera files)."""
    import cv2

    from pipeline.camera import read_intrinsics, read_pose

    f = Path(folder)
    color = cv2.imread(str(f / "color.png"), cv2.IMREAD_COLOR)
    depth = cv2.imread(str(f / "depth.png"), cv2.IMREAD_UNCHANGED)
    inst = cv2.imread(str(f / "instance.png"), cv2.IMREAD_UNCHANGED)
    if color is None or depth is None or inst is None:
        raise InputError(f"{f}: a view needs color.png, depth.png and instance.png")
    intr = read_intrinsics(f / "intrinsics.json")
    K = np.array([[intr.fx, 0.0, intr.cx], [0.0, intr.fy, intr.cy], [0.0, 0.0, 1.0]])
    return View(np.ascontiguousarray(color[..., ::-1]), depth.astype(np.float32) / 1000.0,
                inst.astype(np.uint16), K, read_pose(f / "camera_pose.json"))


def read_views(scan_dir: str | os.PathLike) -> tuple[View, ...]:
    """The views of a scan folder: the folder itself, or ``view0/``, ``view1/``, ..."""
    scan = Path(scan_dir)
    subs = sorted((p for p in scan.glob("view*") if p.name[4:].isdigit()),
                  key=lambda p: int(p.name[4:]))
    return tuple(read_view(p) for p in subs) if subs else (read_view(scan),)


class Dataset:
    """A dataset made by ``unseen dataset make``, read as arrays and graphs.

    >>> ds = Dataset("data", split="train")            # doctest: +SKIP
    >>> for s in ds:                                  # doctest: +SKIP
    ...     s.views[0].depth, s.views[0].instance, s.graph, s.poses, s.sizes

    Parameters
    ----------
    root : path
        The dataset folder (holding ``manifest.jsonl``).
    split : str, optional
        Only this split (``train``, ``val``, ``test``).
    family : str, optional
        Only this family.
    """

    def __init__(self, root: str | os.PathLike, split: str | None = None,
                 family: str | None = None) -> None:
        self.root = Path(root)
        path = self.root / MANIFEST
        if not path.is_file():
            raise InputError(f"{self.root}: no {MANIFEST}; is it a folder made by "
                             "'unseen dataset make'?")
        recs = []
        for k, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if not line.strip():
                continue
            try:
                rec = json.loads(line)
            except ValueError:
                raise InputError(f"{path}:{k}: not a JSON line") from None
            if not isinstance(rec, dict) or not {"id", "path", "split", "family"} <= set(rec):
                raise InputError(f"{path}:{k}: a manifest line needs id, path, split, family")
            recs.append(rec)
        if split is not None and split not in SPLITS:
            raise InputError(f"split {split!r}: expected one of {', '.join(SPLITS)}")
        self.records = [r for r in recs if (split is None or r["split"] == split)
                        and (family is None or r["family"] == family)]

    def __len__(self) -> int:
        return len(self.records)

    def __iter__(self) -> Iterator[Sample]:
        for k in range(len(self.records)):
            yield self[k]

    def __getitem__(self, k: int) -> Sample:
        from pipeline.arrangement_io import read_arrangement

        rec = self.records[k]
        folder = self.root / rec["path"]
        return Sample(rec, folder, read_arrangement(folder / "scene.json"),
                      read_views(folder / "scan"))

    def verify(self) -> list[str]:
        """Every scene whose files differ from the manifest (empty when all match)."""
        return [why for r in self.records if (why := check_scene(self.root, r)) is not None]


def verify_dataset(root: str | os.PathLike) -> tuple[int, list[str], list[str]]:
    """(scenes listed, problems of the whole, problems of listed scenes) of a dataset
    folder.  The whole: its configuration (``dataset.json``, whose ``n`` scenes the
    manifest must list, each once) and scene folders the manifest does not list; the
    scenes: every listed scene's files (:meth:`Dataset.verify`)."""
    root = Path(root)
    ds = Dataset(root)
    problems = []
    try:
        cfg = json.loads((root / CONFIG_FILE).read_text(encoding="utf-8"))
        n = cfg["n"]
        if isinstance(n, bool) or not isinstance(n, int):
            raise TypeError
    except (OSError, ValueError, TypeError, KeyError):
        problems.append(f"{CONFIG_FILE}: missing, or not the configuration of a dataset")
    else:
        if len(ds.records) != n:
            problems.append(f"{MANIFEST}: lists {len(ds.records)} scenes; {CONFIG_FILE} "
                            f"made {n}")
    paths = [r["path"] for r in ds.records]
    if len(set(paths)) != len(paths):
        problems.append(f"{MANIFEST}: lists a scene more than once")
    listed = set(paths)
    for split in SPLITS:
        if (root / split).is_dir():
            for d in sorted((root / split).iterdir()):
                if d.is_dir() and f"{split}/{d.name}" not in listed:
                    problems.append(f"{split}/{d.name}: a scene folder the manifest does not list")
    problems += verify_bop(root)
    return len(ds), problems, ds.verify()


def write_bop_manifest(root: str | os.PathLike) -> None:
    """Record the hashes of the BOP export (``root/bop``) in :data:`BOP_MANIFEST`."""
    from pipeline import atomic

    root = Path(root)
    atomic.write_text(root / BOP_MANIFEST,
                      json.dumps(file_hashes(root / "bop"), indent=1, sort_keys=True) + "\n")


def verify_bop(root: str | os.PathLike) -> list[str]:
    """Why the BOP export under ``root`` does not match its recorded hashes (empty when it
    does, or when there is no export)."""
    root = Path(root)
    if not (root / "bop").is_dir():
        return [f"{BOP_MANIFEST}: lists a BOP export, but bop/ is missing"] if (
            root / BOP_MANIFEST).is_file() else []
    try:
        want = json.loads((root / BOP_MANIFEST).read_text(encoding="utf-8"))
        if not isinstance(want, dict):
            raise TypeError
    except (OSError, ValueError, TypeError):
        return [f"bop/: no readable {BOP_MANIFEST} to check it against (rerun dataset make "
                "with --bop)"]
    have = file_hashes(root / "bop")
    if set(have) != set(want):
        gone = sorted(set(want) - set(have))
        extra = sorted(set(have) - set(want))
        return [f"bop/: files differ from {BOP_MANIFEST} (missing {gone[:3]}, extra {extra[:3]})"]
    return [f"bop/{name}: hash differs from {BOP_MANIFEST}"
            for name in sorted(want) if have[name] != want[name]][:3]
