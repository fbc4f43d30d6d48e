"""Read and write ``arrangement.json`` (format ``unseen.arrangement``, version 1).

The format is the contract in DESIGN.md.  Reading validates every field and raises
:class:`~pipeline.errors.InputError` with one line naming the field
(``cuboids[3].size: must be 3 positive numbers``).  Writing is atomic and exact:
floats are written with Python's shortest round-tripping repr, so
``read(write(a)) == a`` bit for bit and ``write(read(f))`` reproduces ``f``.
"""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from . import atomic
from .constants import (
    DENSITY_RANGE,
    MAX_COORDINATE,
    MAX_CUBOIDS,
    ROTATION_TOL,
    SIZE_RANGE,
)
from .errors import InputError
from .model import (
    CONTACT_TYPES,
    Arrangement,
    Contact,
    Cuboid,
    ObservedBox,
    StabilitySummary,
    Support,
    is_support_id,
)

FORMAT = "unseen.arrangement"
VERSION = 1

_CUBOID_KEYS = {"id", "center", "rotation", "size", "density", "object", "observed"}


# ---------------------------------------------------------------------------- reading
def read_arrangement(path: str | os.PathLike) -> Arrangement:
    """Read and validate an arrangement file.

    Raises
    ------
    InputError
        One line naming the file and the bad field.
    """
    from .safe_read import load_json

    path = Path(path)
    data = load_json(path, "arrangement.json file")
    try:
        return arrangement_from_dict(data)
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None


def _fail(field: str, what: str) -> InputError:
    return InputError(f"{field}: {what}")


def _vector(value: Any, field: str, n: int = 3, positive: bool = False) -> np.ndarray:
    what = f"must be {n} {'positive ' if positive else ''}numbers"
    if not isinstance(value, list) or len(value) != n:
        raise _fail(field, what)
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        raise _fail(field, what)
    try:
        arr = np.array(value, dtype=float)
    except OverflowError:
        arr = np.full(n, np.inf)
    if not np.all(np.isfinite(arr)):
        raise _fail(field, f"{what} (found NaN or infinity)")
    if positive and not np.all(arr > 0):
        raise _fail(field, what)
    return arr


def _size(value: Any, field: str) -> np.ndarray:
    size = _vector(value, field, positive=True)
    lo, hi = SIZE_RANGE
    if size.min() < lo or size.max() > hi:
        raise _fail(field, f"edges must lie in [{lo:g}, {hi:g}] m, got "
                           f"{' '.join(f'{v:.3g}' for v in size)}")
    return size


def _coordinates(value: Any, field: str) -> np.ndarray:
    v = _vector(value, field)
    if np.abs(v).max() > MAX_COORDINATE:
        raise _fail(field, f"coordinates must lie within +-{MAX_COORDINATE:g} m, got "
                           f"{' '.join(f'{x:.3g}' for x in v)}")
    return v


#: Characters refused in ids and names: C0/C1 controls, and what XML 1.0 cannot hold
#: (lone surrogates, U+FFFE/U+FFFF).  Exported MJCF/URDF name every geom by its id.
_BAD_NAME_CHARS = re.compile("[\x00-\x1f\x7f-\x9f\ud800-\udfff\ufffe\uffff]")


def check_name(value: str, field: str) -> str:
    """``value`` when it has no control or XML-illegal character; else InputError."""
    m = _BAD_NAME_CHARS.search(value)
    if m:
        raise _fail(field, f"contains the control character U+{ord(m.group()):04X} at "
                           f"position {m.start()}; use printable characters")
    return value


def _rotation(value: Any, field: str) -> np.ndarray:
    what = "must be a 3x3 list of numbers (row-major rotation matrix)"
    if not isinstance(value, list) or len(value) != 3:
        raise _fail(field, what)
    rows = [_vector(row, f"{field}[{i}]") for i, row in enumerate(value)]
    R = np.array(rows)
    err = float(np.abs(R.T @ R - np.eye(3)).max())
    if err > ROTATION_TOL or np.linalg.det(R) < 0:
        raise _fail(field, f"not a rotation matrix (orthonormality error {err:.2g}, "
                           f"det {np.linalg.det(R):.4g}; columns must be orthonormal, det +1)")
    return R


def _string(value: Any, field: str) -> str:
    if not isinstance(value, str) or not value:
        raise _fail(field, "must be a non-empty string")
    return check_name(value, field)


def _number(value: Any, field: str, positive: bool = False) -> float:
    if not isinstance(value, (int, float)) or isinstance(value, bool) or \
            not math.isfinite(float(value)):
        raise _fail(field, "must be a finite number")
    if positive and value <= 0:
        raise _fail(field, "must be a positive number")
    return float(value)


def arrangement_from_dict(data: Any) -> Arrangement:
    """Validate a parsed JSON object and build an :class:`Arrangement`."""
    if not isinstance(data, dict):
        raise _fail("(top level)", "must be a JSON object")
    if data.get("format") != FORMAT:
        raise _fail("format", f"unknown format {data.get('format')!r}, expected {FORMAT!r}")
    if data.get("version") != VERSION:
        raise _fail("version", f"unsupported version {data.get('version')!r}, expected {VERSION}")
    if data.get("units", "m") != "m":
        raise _fail("units", f"unsupported units {data.get('units')!r}, expected 'm'")
    up = _vector(data.get("up", [0, 0, 1]), "up")
    if np.linalg.norm(up) < 1e-9:
        raise _fail("up", "must be a non-zero vector")

    supports: list[Support] = []
    raw_supports = data.get("supports", [])
    if not isinstance(raw_supports, list):
        raise _fail("supports", "must be a list")
    for i, s in enumerate(raw_supports):
        f = f"supports[{i}]"
        if not isinstance(s, dict):
            raise _fail(f, "must be an object")
        sid = _string(s.get("id"), f"{f}.id")
        if not is_support_id(sid):
            raise _fail(f"{f}.id", f"{sid!r} must be 'ground' or 'wall:<k>'")
        point = _coordinates(s.get("point"), f"{f}.point")
        normal = _vector(s.get("normal"), f"{f}.normal")
        if np.linalg.norm(normal) < 1e-9:
            raise _fail(f"{f}.normal", "must be a non-zero vector")
        supports.append(Support(sid, point, normal))

    raw_cuboids = data.get("cuboids")
    if not isinstance(raw_cuboids, list):
        raise _fail("cuboids", "must be a list")
    if len(raw_cuboids) > MAX_CUBOIDS:
        raise _fail("cuboids", f"{len(raw_cuboids)} cuboids; at most {MAX_CUBOIDS} are supported")
    cuboids: list[Cuboid] = []
    for i, c in enumerate(raw_cuboids):
        f = f"cuboids[{i}]"
        if not isinstance(c, dict):
            raise _fail(f, "must be an object")
        cid = _string(c.get("id"), f"{f}.id")
        if is_support_id(cid):
            raise _fail(f"{f}.id", f"{cid!r} is reserved for supports")
        center = _coordinates(c.get("center"), f"{f}.center")
        rotation = _rotation(c.get("rotation"), f"{f}.rotation")
        size = _size(c.get("size"), f"{f}.size")
        density = _number(c.get("density", 1000.0), f"{f}.density", positive=True)
        if not DENSITY_RANGE[0] <= density <= DENSITY_RANGE[1]:
            raise _fail(f"{f}.density", f"must lie in [{DENSITY_RANGE[0]:g}, "
                                        f"{DENSITY_RANGE[1]:g}] kg/m^3, got {density:.3g}")
        obj = c.get("object")
        if obj is not None:
            obj = _string(obj, f"{f}.object")
        observed = None
        if c.get("observed") is not None:
            o = c["observed"]
            if not isinstance(o, dict):
                raise _fail(f"{f}.observed", "must be an object with center and size")
            observed = ObservedBox(_coordinates(o.get("center"), f"{f}.observed.center"),
                                   _vector(o.get("size"), f"{f}.observed.size", positive=True))
        extra = {k: v for k, v in c.items() if k not in _CUBOID_KEYS}
        cuboids.append(Cuboid(cid, center, rotation, size, density, obj, observed, extra))

    ids = [c.id for c in cuboids] + [s.id for s in supports]
    seen: set[str] = set()
    for i, name in enumerate(ids):
        if name in seen:
            where = f"cuboids[{i}].id" if i < len(cuboids) else f"supports[{i - len(cuboids)}].id"
            raise _fail(where, f"duplicate id {name!r}")
        seen.add(name)

    raw_contacts = data.get("contacts", [])
    if not isinstance(raw_contacts, list):
        raise _fail("contacts", "must be a list")
    contacts: list[Contact] = []
    pairs: set[tuple[str, str]] = set()
    for i, c in enumerate(raw_contacts):
        f = f"contacts[{i}]"
        if not isinstance(c, dict):
            raise _fail(f, "must be an object with a, b and type")
        a = _string(c.get("a"), f"{f}.a")
        b = _string(c.get("b"), f"{f}.b")
        for key, name in (("a", a), ("b", b)):
            if name not in seen:
                raise _fail(f"{f}.{key}", f"unknown id {name!r}")
        if a == b:
            raise _fail(f, f"a contact needs two different ids, got {a!r} twice")
        if is_support_id(a) and is_support_id(b):
            raise _fail(f, "a contact between two supports is meaningless")
        ctype = c.get("type", "touch")
        if ctype not in CONTACT_TYPES:
            raise _fail(f"{f}.type", f"must be 'touch' or 'fixed', got {ctype!r}")
        contact = Contact(a, b, ctype)
        if contact.key in pairs:
            raise _fail(f, f"duplicate contact between {a!r} and {b!r}")
        pairs.add(contact.key)
        contacts.append(contact)

    stability = None
    if data.get("stability") is not None:
        s = data["stability"]
        if not isinstance(s, dict):
            raise _fail("stability", "must be an object")
        if not isinstance(s.get("stable"), bool):
            raise _fail("stability.stable", "must be true or false")
        stability = StabilitySummary(_number(s.get("energy"), "stability.energy"), s["stable"],
                                     _number(s.get("threshold"), "stability.threshold"))
    meta = data.get("meta", {})
    if not isinstance(meta, dict):
        raise _fail("meta", "must be an object")
    return Arrangement(tuple(cuboids), tuple(supports), tuple(contacts), up / np.linalg.norm(up),
                       stability, meta)


# ---------------------------------------------------------------------------- writing
def _floats(a: np.ndarray) -> list:
    return np.asarray(a, dtype=float).tolist()


def arrangement_to_dict(arr: Arrangement) -> dict:
    """The JSON object of an arrangement (plain Python types, floats exact)."""
    cuboids = []
    for c in arr.cuboids:
        d: dict[str, Any] = {"id": c.id, "center": _floats(c.center),
                             "rotation": _floats(c.rotation), "size": _floats(c.size),
                             "density": float(c.density)}
        if c.object is not None:
            d["object"] = c.object
        if c.observed is not None:
            d["observed"] = {"center": _floats(c.observed.center),
                             "size": _floats(c.observed.size)}
        d.update(c.extra)
        cuboids.append(d)
    out: dict[str, Any] = {
        "format": FORMAT,
        "version": VERSION,
        "units": "m",
        "up": _floats(arr.up),
        "supports": [{"id": s.id, "point": _floats(s.point), "normal": _floats(s.normal)}
                     for s in arr.supports],
        "cuboids": cuboids,
        "contacts": [{"a": c.a, "b": c.b, "type": c.type} for c in arr.contacts],
    }
    if arr.stability is not None:
        out["stability"] = {"energy": float(arr.stability.energy),
                            "stable": bool(arr.stability.stable),
                            "threshold": float(arr.stability.threshold)}
    out["meta"] = _jsonable(arr.meta)
    return out


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


_NUMBER_LIST = re.compile(r"\[\s*((?:-?[0-9.eE+-]+,\s*)*-?[0-9.eE+-]+)\s*\]")
_LIST_OF_LISTS = re.compile(r"\[\s*((?:\[[^\[\]]*\],\s*)*\[[^\[\]]*\])\s*\]")


def dumps(arr: Arrangement) -> str:
    """The file text: stable key order, vectors and matrices on one line, trailing newline."""
    text = json.dumps(arrangement_to_dict(arr), indent=1, allow_nan=False)
    text = _NUMBER_LIST.sub(lambda m: "[" + " ".join(m.group(1).split()) + "]", text)
    text = _LIST_OF_LISTS.sub(lambda m: "[" + " ".join(m.group(1).split()) + "]", text)
    return text + "\n"


def write_arrangement(arr: Arrangement, path: str | os.PathLike) -> None:
    """Write ``arr`` to ``path`` atomically (temporary file + rename)."""
    atomic.write_text(path, dumps(arr))
