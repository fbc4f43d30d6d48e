"""Our own labels of the real scans in ``../shared/data/real`` and how a result is scored
against them (``unseen eval real``).

Annotations
-----------
``eval/real/annotations/<folder>__<file>.json`` (the file name's dots as ``_``), one per
input scan, written by hand from the data itself (colour crops, heights, gaps, face
planes; each object and relation carries a one-line ``why``)::

    {"scan": "shao_kinect_boxes/5boxes_depth16bits.dat",   # relative to the data folder
     "group": "boxes" | "rooms",
     "up": [x, y, z],                                       # in the input frame, for reading
     "objects": [{"id": "box_top", "what": "...", "why": "...",
                  "box": {"center": [3], "size": [3], "rotation": [[3], [3], [3]]}}],
     "relations": [{"a": "box_top", "b": "box_mid" | "floor" | "wall",
                    "type": "on" | "leans" | "fixed", "confidence": 0.95, "why": "..."}]}

An object is a *visible-point box*: an oriented box in the scan's input frame (the frame
and units :func:`pipeline.scan_io.load_scan` returns; the box's axes are the rotation's
columns) that holds that object's visible points.  Every scan point belongs to the first
object whose box holds it.

Scoring
-------
A result's cuboids live in its world frame; ``meta.camera_pose`` and ``meta.input_scale``
take the scan's points there (``p_world = T (s p_input)``).  Each predicted object (the
cuboids sharing an ``object`` name) is matched to the annotated object holding most of the
scan points inside its cuboids, when that is at least :data:`MATCH_SHARE` of the labelled
points inside them; an annotated object is *found* when the predicted objects matched to
it hold at least :data:`FOUND_SHARE` of its points.

The support graph is scored on unordered pairs, untyped: a predicted contact between two
matched objects (``ground`` reads as ``floor``, ``wall:k`` as ``wall``) is a pair; a
contact inside one object or with an unmatched object says nothing about the labels and
is left out.  A support graph says who rests on whom: its contacts are the ``fixed``
ones and the ``touch`` contacts that carry load in the statics' solution
(:attr:`pipeline.stability.StabilityResult.contact_load`); a lamp that merely grazes the
wall behind it is no support.  ``contacts`` scores every listed contact instead.  Annotated relations with ``confidence`` of at least :data:`SURE` are the
truth; less sure ones are do-not-care (neither missed nor false when predicted).
``fixed`` contacts between different predicted objects, or with the floor or a wall, are
counted as glue.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: Where the annotation files live.
ANNOTATIONS = Path(__file__).with_name("annotations")
#: The real data beside the checkout (``../shared/data/real`` from the repository root).
DEFAULT_DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "real"
#: Relations at least this sure are the truth; less sure ones are do-not-care.
SURE = 0.5
#: A predicted object is matched to an annotated one holding at least this share of the
#: labelled scan points inside its cuboids.
MATCH_SHARE = 0.5
#: An annotated object is found when its matched predicted objects hold this share of it.
FOUND_SHARE = 0.3
#: Cuboids are grown by this much (metres) when collecting the points inside them: a
#: fitted face sits on the noisy surface, half its points just outside.
INSIDE_MARGIN = 0.02
GROUPS = ("boxes", "rooms")
TYPES = ("on", "leans", "fixed")
SUPPORTS = ("floor", "wall")


class AnnotationError(ValueError):
    """An annotation file that does not follow the format (the message names the file)."""


@dataclass(frozen=True)
class LabelBox:
    id: str
    what: str
    center: np.ndarray
    size: np.ndarray
    rotation: np.ndarray

    def contains(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        local = (np.asarray(points, float) - self.center) @ self.rotation
        return np.all(np.abs(local) <= self.size / 2 + margin, axis=1)


@dataclass(frozen=True)
class Relation:
    a: str
    b: str
    type: str
    confidence: float

    @property
    def pair(self) -> frozenset:
        return frozenset((self.a, self.b))


@dataclass(frozen=True)
class Annotation:
    name: str
    scan: str
    group: str
    objects: tuple[LabelBox, ...]
    relations: tuple[Relation, ...]
    path: Path | None = None

    def labels(self, points: np.ndarray) -> np.ndarray:
        """Per point the index of the first object whose box holds it, -1 for none."""
        out = np.full(len(points), -1, np.int64)
        for k, o in enumerate(self.objects):
            hit = (out < 0) & o.contains(points)
            out[hit] = k
        return out

    @property
    def sure_pairs(self) -> set[frozenset]:
        return {r.pair for r in self.relations if r.confidence >= SURE}

    @property
    def unsure_pairs(self) -> set[frozenset]:
        return {r.pair for r in self.relations if r.confidence < SURE} - self.sure_pairs


def _need(cond: bool, where: str, msg: str) -> None:
    if not cond:
        raise AnnotationError(f"{where}: {msg}")


def _vector(v, n: int, where: str) -> np.ndarray:
    try:
        a = np.asarray(v, float)
    except (TypeError, ValueError):
        a = np.zeros(0)
    _need(a.shape == (n,) and bool(np.all(np.isfinite(a))), where, f"{n} finite numbers")
    return a


def load_annotation(path: str | Path) -> Annotation:
    """Read and check one annotation file.

    Raises
    ------
    AnnotationError
        Not JSON, a field missing or malformed, a rotation that is not one, a duplicate
        id, or a relation naming an object that is not there.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise AnnotationError(f"{path}: not a readable JSON file ({exc})") from None
    w = str(path)
    _need(isinstance(data, dict), w, "the top level must be an object")
    for key in ("scan", "group", "objects", "relations"):
        _need(key in data, w, f"field '{key}' is missing")
    _need(data["group"] in GROUPS, w, f"group must be one of {GROUPS}")
    objects = []
    for k, o in enumerate(data["objects"]):
        where = f"{w}: objects[{k}]"
        _need(isinstance(o, dict) and isinstance(o.get("id"), str) and "box" in o, where,
              "needs an 'id' and a 'box'")
        b = o["box"]
        _need(isinstance(b, dict), where, "box must be {center, size, rotation}")
        c = _vector(b.get("center"), 3, where + ".box.center")
        s = _vector(b.get("size"), 3, where + ".box.size")
        _need(bool(np.all(s > 0)), where, "box.size must be positive")
        try:
            R = np.asarray(b.get("rotation"), float)
        except (TypeError, ValueError):
            R = np.zeros(0)
        _need(R.shape == (3, 3) and np.allclose(R.T @ R, np.eye(3), atol=1e-4)
              and np.linalg.det(R) > 0, where, "box.rotation must be a 3x3 rotation")
        objects.append(LabelBox(o["id"], str(o.get("what", "")), c, s, R))
    ids = [o.id for o in objects]
    _need(len(set(ids)) == len(ids), w, "object ids must be unique")
    _need(not set(ids) & set(SUPPORTS), w, f"{SUPPORTS} are not object ids")
    relations = []
    for k, r in enumerate(data["relations"]):
        where = f"{w}: relations[{k}]"
        _need(isinstance(r, dict), where, "must be an object")
        for end in ("a", "b"):
            _need(r.get(end) in ids or r.get(end) in SUPPORTS, where,
                  f"'{end}' = {r.get(end)!r} is neither an object id nor one of {SUPPORTS}")
        _need(r["a"] != r["b"], where, "a relation needs two different ends")
        _need(r.get("type") in TYPES, where, f"type must be one of {TYPES}")
        conf = r.get("confidence")
        _need(isinstance(conf, (int, float)) and 0 <= conf <= 1, where,
              "confidence must be a number in [0, 1]")
        relations.append(Relation(r["a"], r["b"], r["type"], float(conf)))
    return Annotation(path.stem, str(data["scan"]), data["group"], tuple(objects),
                      tuple(relations), path)


def annotations(folder: str | Path = ANNOTATIONS) -> list[Annotation]:
    """Every annotation in ``folder``, by name."""
    return [load_annotation(p) for p in sorted(Path(folder).glob("*.json"))]


@dataclass
class RealScore:
    """How one result agrees with one annotation (see the module docstring)."""

    objects: int  #: annotated objects
    found: int  #: of them found
    predicted_objects: int
    matched_objects: int  #: predicted objects matched to an annotated one
    tp: int
    fp: int
    fn: int
    glue: int  #: fixed contacts between different predicted objects or with a support
    glue_between_objects: int  #: of them between two different annotated objects
    false_pairs: list = field(default_factory=list)
    missed_pairs: list = field(default_factory=list)
    match: dict = field(default_factory=dict)  #: predicted object -> annotated id

    #: (tp, fp, fn) over every listed contact (the other scoring of the same match)
    every: tuple[int, int, int] = (0, 0, 0)

    @property
    def precision(self) -> float:
        return prf(self.tp, self.fp, self.fn)[0]

    @property
    def recall(self) -> float:
        return prf(self.tp, self.fp, self.fn)[1]

    @property
    def f1(self) -> float:
        return prf(self.tp, self.fp, self.fn)[2]

    def to_json(self) -> dict:
        out = {k: getattr(self, k) for k in ("objects", "found", "predicted_objects",
                                             "matched_objects", "tp", "fp", "fn", "glue",
                                             "glue_between_objects")}
        out["false_pairs"] = [sorted(p) for p in self.false_pairs]
        out["missed_pairs"] = [sorted(p) for p in self.missed_pairs]
        out["match"] = dict(self.match)
        out["all_contacts"] = dict(zip(("tp", "fp", "fn"), self.every))
        return out


def prf(tp: int, fp: int, fn: int) -> tuple[float, float, float]:
    """(precision, recall, F1) of pair counts; NaN where a ratio has nothing to count."""
    nan = float("nan")
    return (tp / (tp + fp) if tp + fp else nan, tp / (tp + fn) if tp + fn else nan,
            2 * tp / (2 * tp + fp + fn) if 2 * tp + fp + fn else nan)


def world_points(points_input: np.ndarray, meta: dict) -> np.ndarray:
    """The scan's input-frame points in a result's world frame (``meta.camera_pose``,
    ``meta.input_scale``)."""
    T = np.asarray(meta.get("camera_pose", np.eye(4)), float)
    s = float(meta.get("input_scale", 1.0) or 1.0)
    p = s * np.asarray(points_input, float)
    return p @ T[:3, :3].T + T[:3, 3]


def _support_name(name: str) -> str | None:
    if name == "ground":
        return "floor"
    if name.startswith("wall"):
        return "wall"
    return None


def loaded_pairs(arr) -> set[tuple[str, str]]:
    """The touching pairs of ``arr`` that carry load in the statics' solution (sorted
    name pairs), at the arrangement's friction (``meta.mu``, else 0.7)."""
    from pipeline.errors import InputError
    from pipeline.stability import load_carrying

    try:
        cs, _, carries = load_carrying(arr, mu=float(arr.meta.get("mu", 0.7)))
    except InputError:
        return set()
    return {tuple(sorted(p)) for p, c in zip(cs.pairs, carries.tolist()) if c}


def score(arr, points_input: np.ndarray, ann: Annotation, contacts: str = "support"
          ) -> RealScore:
    """Score an arrangement (:class:`pipeline.model.Arrangement`) whose scan's points in
    the input frame are ``points_input`` against ``ann``; ``contacts``: ``support`` (the
    fixed and load-bearing contacts) or ``all`` (every listed contact)."""
    labels = ann.labels(points_input)
    world = world_points(points_input, arr.meta)
    n_obj = len(ann.objects)
    counts = np.bincount(labels[labels >= 0], minlength=n_obj)
    by_object: dict[str, list] = {}
    for c in arr.cuboids:
        by_object.setdefault(c.object or c.id, []).append(c)
    match: dict[str, str] = {}
    covered = np.zeros(n_obj, np.int64)
    for name, cubs in by_object.items():
        inside = np.zeros(len(world), bool)
        for c in cubs:
            local = (world - np.asarray(c.center)) @ np.asarray(c.rotation)
            inside |= np.all(np.abs(local) <= np.asarray(c.size) / 2 + INSIDE_MARGIN, axis=1)
        lab = labels[inside]
        lab = lab[lab >= 0]
        if not len(lab):
            continue
        hist = np.bincount(lab, minlength=n_obj)
        k = int(np.argmax(hist))
        if hist[k] >= MATCH_SHARE * len(lab):
            match[name] = ann.objects[k].id
            covered[k] += int(hist[k])
    found = int(np.sum((counts > 0) & (covered >= FOUND_SHARE * counts)))
    owner = {c.id: match.get(c.object or c.id) for c in arr.cuboids}
    obj_of = {c.id: c.object or c.id for c in arr.cuboids}
    support: set[frozenset] = set()
    every: set[frozenset] = set()
    glue = glue_objects = 0
    carry = loaded_pairs(arr)
    for ct in arr.contacts:
        ends = []
        for e in (ct.a, ct.b):
            ends.append(_support_name(e) if e not in owner else owner[e])
        different = (ct.a not in obj_of or ct.b not in obj_of or obj_of[ct.a] != obj_of[ct.b])
        if ct.type == "fixed" and different:
            glue += 1
            if None not in ends and ends[0] != ends[1] and not set(ends) & set(SUPPORTS):
                glue_objects += 1
        if None in ends or ends[0] == ends[1]:
            continue
        every.add(frozenset(ends))
        if ct.type == "fixed" or ct.key in carry:
            support.add(frozenset(ends))
    truth, unsure = ann.sure_pairs, ann.unsure_pairs

    def counts_of(predicted: set[frozenset]) -> tuple[int, list, list]:
        scored = predicted - unsure
        return (len(scored & truth), sorted(scored - truth, key=sorted),
                sorted(truth - predicted, key=sorted))

    tp_all, false_all, missed_all = counts_of(every)
    tp, false, missed = counts_of(support if contacts == "support" else every)
    return RealScore(objects=n_obj, found=found, predicted_objects=len(by_object),
                     matched_objects=len(match), tp=tp, fp=len(false), fn=len(missed),
                     glue=glue, glue_between_objects=glue_objects, false_pairs=false,
                     missed_pairs=missed, match=match,
                     every=(tp_all, len(false_all), len(missed_all)))


__all__ = ["Annotation", "AnnotationError", "LabelBox", "Relation", "RealScore", "annotations",
           "load_annotation", "loaded_pairs", "prf", "score", "world_points", "ANNOTATIONS", "DEFAULT_DATA"]
