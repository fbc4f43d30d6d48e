"""An MJCF or URDF scene of boxes -> :class:`~pipeline.model.Arrangement` (``unseen import``).

The engines parse their own formats.  Both MJCF and URDF are compiled by MuJoCo
(``mujoco.MjSpec.from_file`` then ``compile``), which resolves what a hand-written reader
would get wrong: default classes, ``<include>``, every orientation form (``quat``,
``euler`` with the file's ``eulerseq`` and angle unit, ``axisangle``, ``xyaxes``,
``zaxis``, ``fromto``; URDF ``rpy``), nested body frames and joint origins.  After
``mj_kinematics`` at ``qpos0`` (the file's own pose) the model gives, per geom, its type,
half sizes ``geom_size``, world pose ``geom_xpos`` / ``geom_xmat`` (row-major, columns =
local axes), its body and that body's ``body_weldid`` (bodies joined without a joint
share it; 0 = welded to the world); per-geom density comes from the spec.

URDF goes through MuJoCo too, with ``fusestatic`` off so that every link keeps its name.
PyBullet was the other candidate and is worse here: it turns ``floating`` joints into
fixed ones (the free bodies of our own ``scene.urdf`` would import as static), drops
collision names, and reports collision frames relative to each link's inertial frame.
In MuJoCo's reading a root link named ``world`` is the world, a ``floating`` joint from it
makes a free body, and any other root link is welded to the world; a ``floating`` joint
deeper in the tree is refused.  MuJoCo ignores PyBullet's ``<contact>`` (read here for
the friction) and has no ``<plane>`` (refused, with what to write instead).

Mapping
-------
- box geom -> one cuboid: ``size = 2 * geom_size``, ``rotation = geom_xmat``; id = the
  geom name when it is a valid, unused id, else ``b<k>``; ``object`` = the name of the
  rigid body (the weld root; for world-welded geoms their own body, none for world).
- ``plane`` geom -> a support (point ``geom_xpos``, normal its local z).  A geom named
  ``support:<id>`` (our MJCF export) keeps that id; otherwise the most upward plane with
  ``n_z >= GROUND_MIN_NZ`` is ``ground`` and the others ``wall:0``, ``wall:1`` ...
- A static box named ``support:<id>``, or unnamed in a body so named (our URDF export's
  slabs) -> that support: the face across its thinnest axis facing the scene.
- Touching boxes (:func:`pipeline.contacts.find_contacts`) of one rigid group (bodies
  joined without a joint, or by an MJCF ``<weld>`` equality as ``--welds constraint``
  writes) -> ``fixed`` contacts; a moving group must be connected by them.  Boxes welded to the
  world are split into touching groups, each fixed to the ground where it touches it,
  else to the walls it touches; one that touches no support is an error.
- Every other touching pair -> ``touch``.  Density: per geom from the spec where the file
  gives geom densities or masses, else (an explicit ``<inertial>``, every URDF link) the
  densities that reproduce the rigid body's mass, centre of mass and inertia
  (:func:`fit_densities`).  Friction: ``meta.mu`` when every geom agrees
  (MJCF: as compiled, so MuJoCo's default 1 when the file is silent; URDF: PyBullet's
  ``lateral_friction`` f of every link, which PyBullet multiplies: ``mu = f^2``).
- Anything else (sphere, mesh, cylinder, ..., hinge or slide joints, boxes of one body
  that do not touch or that overlap) is one :class:`~pipeline.errors.InputError` line.
  Geoms that cannot collide (``contype = conaffinity = 0``: visual only) are skipped.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.constants import DEFAULT_DENSITY, MU_RANGE
from pipeline.errors import InputError
from pipeline.model import Arrangement, Contact, Cuboid, Support, is_support_id

#: Largest scene file read, bytes.
MAX_SCENE_BYTES = 64 * 2**20
#: Root element -> format name.
FORMATS = {"mujoco": "mjcf", "robot": "urdf"}
#: A plane whose unit normal has at least this z component may be the ground (60 degrees).
GROUND_MIN_NZ = 0.5
#: Significant digits kept of a density derived as mass / volume and of a URDF friction
#: squared: the files hold 12, so the last digits are the file's rounding.
DERIVED_DIGITS = 10


@dataclass(frozen=True)
class SceneGeoms:
    """The G colliding geoms of a compiled scene, posed at ``qpos0``.

    ``names``, ``bodies``: geom name ('' when unnamed) and its body's name; ``objects``:
    the rigid body's name (the cuboid's ``object``); ``kind``: ``box`` or ``plane``;
    ``group (G,) int``: rigid group, 0 = welded to the world; ``centers (G, 3)``,
    ``rotations (G, 3, 3)`` (columns = local axes in world), ``sizes (G, 3)`` full edges
    (planes: 0); ``density (G,)`` kg/m^3; ``friction (G,)`` sliding, as compiled.
    """

    names: tuple[str, ...]
    bodies: tuple[str, ...]
    objects: tuple[str | None, ...]
    kind: tuple[str, ...]
    group: np.ndarray
    centers: np.ndarray
    rotations: np.ndarray
    sizes: np.ndarray
    density: np.ndarray
    friction: np.ndarray

    def describe(self, k: int) -> str:
        """``geom 'b3' of body 'table'`` (or ``geom #3`` when unnamed)."""
        geom = f"geom {self.names[k]!r}" if self.names[k] else f"geom #{k}"
        return f"{geom} of {_body_text(self.bodies[k])}"


# ------------------------------------------------------------------------------ entry
def import_scene(path: str | os.PathLike) -> Arrangement:
    """Read an MJCF (``<mujoco>``) or URDF (``<robot>``) file, chosen by its root element.

    Raises
    ------
    InputError
        One line naming the file and what is wrong with it.
    """
    path, root = _read_root(path)
    return _import(path, FORMATS[root.tag], root)


def arrangement_from_mjcf(path: str | os.PathLike) -> Arrangement:
    """The arrangement of an MJCF file (see the module docstring)."""
    return _import_as(path, "mjcf")


def arrangement_from_urdf(path: str | os.PathLike) -> Arrangement:
    """The arrangement of a URDF file (see the module docstring)."""
    return _import_as(path, "urdf")


def _import_as(path: str | os.PathLike, fmt: str) -> Arrangement:
    path, root = _read_root(path)
    if FORMATS[root.tag] != fmt:
        raise InputError(f"{path}: is {FORMATS[root.tag].upper()} (<{root.tag}>), not "
                         f"{fmt.upper()}; use unseen import")
    return _import(path, fmt, root)


def _read_root(path: str | os.PathLike):
    import xml.etree.ElementTree as ET

    from pipeline.safe_read import read_bytes

    path = Path(path)
    data = read_bytes(path, MAX_SCENE_BYTES, "scene file (MJCF or URDF)")
    if b"<!ENTITY" in data:
        raise InputError(f"{path}: declares XML entities, which are refused; expand them")
    try:
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        line, col = exc.position
        raise InputError(f"{path}: not an XML file (syntax error at line {line}, column "
                         f"{col}); expected an MJCF (<mujoco>) or URDF (<robot>) file") from None
    if root.tag not in FORMATS:
        raise InputError(f"{path}: root element <{root.tag}> is neither MJCF <mujoco> nor "
                         "URDF <robot>; export the scene as one of those")
    return path, root


def _import(path: Path, fmt: str, root) -> Arrangement:
    if fmt == "urdf" and root.find(".//collision/geometry/plane") is not None:
        raise InputError(f"{path}: a URDF <plane> (PyBullet's extension) is not read; stand "
                         "for the floor with a box collision named 'support:ground' whose "
                         "top face is the floor, as unseen export writes")
    _refuse_non_finite(path, root)
    spec, model = _compile(path, fmt)
    geoms = scene_geoms(spec, model, path)
    mu = _uniform_mu(geoms.friction) if fmt == "mjcf" else _urdf_mu(root)
    meta: dict = {"source": {"path": str(path), "format": fmt}}
    if mu is not None:
        meta["mu"] = mu
    return arrangement_from_geoms(geoms, where=str(path), meta=meta)


def _body_text(name: str) -> str:
    """``body 'table'``, or ``an unnamed body``."""
    return f"body {name!r}" if name else "an unnamed body"


#: MJCF and URDF attributes that hold names, not numbers (a body may be named "inf").
NAME_ATTRIBUTES = frozenset({
    "name", "class", "childclass", "prefix", "file", "filename", "material", "mesh",
    "texture", "hfield", "body", "body1", "body2", "joint", "joint1", "joint2", "geom",
    "geom1", "geom2", "site", "site1", "site2", "tendon", "target", "objname", "link",
    "parent", "child", "type", "objtype"})


def _refuse_non_finite(path: Path, root) -> None:
    """InputError naming the first numeric attribute holding NaN or infinity (MuJoCo
    would print its own warning and carry on)."""
    for elem in root.iter():
        for key, value in elem.attrib.items():
            if key in NAME_ATTRIBUTES:
                continue
            tokens = value.split()
            try:
                numbers = [float(t) for t in tokens]
            except ValueError:
                continue  # not a list of numbers
            if numbers and not np.all(np.isfinite(numbers)):
                name = elem.get("name")
                where = f"<{elem.tag} name={name!r}>" if name else f"<{elem.tag}>"
                raise InputError(f"{path}: {where} {key}={value!r} holds NaN or infinity; "
                                 "give finite numbers")


def _compile(path: Path, fmt: str):
    """(spec, model) of the file, compiled by MuJoCo; InputError with MuJoCo's message."""
    import mujoco

    try:
        if path.suffix.lower() in (".xml", ".urdf"):  # MuJoCo picks its decoder by suffix
            spec = mujoco.MjSpec.from_file(str(path))
        else:  # no includes resolved relative to the file then
            spec = mujoco.MjSpec.from_string(path.read_text("utf-8"))
        if fmt == "urdf":
            spec.compiler.fusestatic = False  # keep every link (and its name) a body
        model = spec.compile()
    except (ValueError, UnicodeDecodeError) as exc:
        msg = "; ".join(s.strip() for s in str(exc).splitlines() if s.strip())
        if fmt == "urdf" and "free joint can only be used on top level" in msg:
            msg += " (a floating joint's parent must be the root link, named 'world')"
        raise InputError(f"{path}: MuJoCo cannot compile it as {fmt.upper()}: {msg}") from None
    return spec, model


# --------------------------------------------------------------------- compiled model
def scene_geoms(spec, model, path: Path) -> SceneGeoms:
    """The colliding geoms of a compiled model at ``qpos0`` (errors name ``path``)."""
    import mujoco

    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    body_name = [model.body(b).name for b in range(model.nbody)]
    hinged = np.flatnonzero(model.jnt_type != mujoco.mjtJoint.mjJNT_FREE)
    if len(hinged):
        j = int(hinged[0])
        kind = mujoco.mjtJoint(model.jnt_type[j]).name[6:].lower()
        raise InputError(f"{path}: {_body_text(body_name[model.jnt_bodyid[j]])} has a {kind} joint; "
                         "unseen models free bodies (freejoint, URDF floating) and static ones, "
                         "not articulated scenes")
    collides = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
    rows = np.flatnonzero(collides)
    types = model.geom_type[rows]
    box_t, plane_t = int(mujoco.mjtGeom.mjGEOM_BOX), int(mujoco.mjtGeom.mjGEOM_PLANE)
    names = tuple(model.geom(int(g)).name for g in rows)
    bodies = tuple(body_name[model.geom_bodyid[g]] for g in rows)
    bad = np.flatnonzero((types != box_t) & (types != plane_t))
    if len(bad):
        k = int(bad[0])
        what = mujoco.mjtGeom(int(types[k])).name[7:].lower()
        geom = f"geom {names[k]!r}" if names[k] else f"geom #{int(rows[k])}"
        raise InputError(f"{path}: {geom} of {_body_text(bodies[k])} is a {what}; unseen handles "
                         f"boxes only (planes for the ground and walls): replace it by a box")
    body_group = _rigid_groups(model, body_name, path)
    weld = body_group[model.geom_bodyid[rows]]
    objects = tuple((body_name[w] if w else (b if b != "world" else "")) or None
                    for w, b in zip(weld.tolist(), bodies))
    half = np.where((types == box_t)[:, None], model.geom_size[rows], 0.0)
    density = _densities(spec, model, data, rows, body_group, 2.0 * half)
    return SceneGeoms(names, bodies, objects,
                      tuple("box" if t == box_t else "plane" for t in types), weld,
                      data.geom_xpos[rows].copy(), data.geom_xmat[rows].reshape(-1, 3, 3).copy(),
                      2.0 * half, density, model.geom_friction[rows, 0].copy())


def _rigid_groups(model, body_name: list[str], path: Path) -> np.ndarray:
    """(nbody,) rigid group of every body, numbered by its first body (0: the world):
    MuJoCo's ``body_weldid`` (bodies joined without a joint) merged over active
    ``<weld>`` equalities (``unseen export --welds constraint``)."""
    import mujoco
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    eq = np.flatnonzero(model.eq_active0)
    other = eq[model.eq_type[eq] != mujoco.mjtEq.mjEQ_WELD]
    if len(other):
        kind = mujoco.mjtEq(model.eq_type[other[0]]).name[5:].lower()
        raise InputError(f"{path}: a {kind} equality constraint; unseen models rigid welds "
                         "only (a <weld> fuses two bodies)")
    ends = np.stack([model.eq_obj1id[eq], model.eq_obj2id[eq]])
    site = model.eq_objtype[eq] == mujoco.mjtObj.mjOBJ_SITE
    ends[:, site] = model.site_bodyid[ends[:, site]]
    weld = model.body_weldid.astype(np.int64)
    n = model.nbody
    label = connected_components(coo_matrix((np.ones(len(eq)), weld[ends]), shape=(n, n)),
                                 directed=False)[1]
    first = np.full(label.max() + 1, n)
    np.minimum.at(first, label, np.arange(n))
    return first[label[weld]]


def _densities(spec, model, data, rows: np.ndarray, body_group: np.ndarray,
               sizes: np.ndarray) -> np.ndarray:
    """(G,) density of every geom.

    Where the file gives geom densities (MuJoCo derives a body's inertia from its
    geoms): each geom's ``density``, or ``mass / volume`` when it states a mass.  Where it
    states a body's mass (an explicit ``<inertial>``, as every URDF link has, or
    ``inertiafromgeom="false"``): :func:`fit_densities` to the rigid group's compiled
    mass, centre of mass and inertia, else its mass over its box volume.  Static parts
    keep the geom's density (their mass plays no part).
    """
    import mujoco

    by_id = {g.id: g for g in spec.geoms}
    vol = np.prod(sizes, axis=1)
    rho = np.full(len(rows), DEFAULT_DENSITY)
    for k, g in enumerate(rows.tolist()):
        sg = by_id.get(g)
        if sg is not None and vol[k] > 0:
            rho[k] = sg.mass / vol[k] if np.isfinite(sg.mass) and sg.mass > 0 else sg.density
    ifg, enum = spec.compiler.inertiafromgeom, mujoco.mjtInertiaFromGeom
    explicit = np.zeros(model.nbody, bool)
    for b in spec.bodies:
        explicit[b.id] = ifg == enum.mjINERTIAFROMGEOM_FALSE or (
            ifg == enum.mjINERTIAFROMGEOM_AUTO and b.explicitinertial)
    weld = body_group[model.geom_bodyid[rows]]
    for w in np.unique(weld[weld > 0]).tolist():
        m, bodies = (weld == w) & (vol > 0), np.flatnonzero(body_group == w)
        M = float(model.body_mass[bodies].sum())
        if not explicit[bodies].any() or M <= 0:
            continue
        com = model.body_mass[bodies] @ data.xipos[bodies] / M
        d = data.xipos[bodies] - com
        R = data.ximat[bodies].reshape(-1, 3, 3)
        inertia = (np.einsum("bij,bj,bkj->ik", R, model.body_inertia[bodies], R)
                   + np.einsum("b,bij->ij", model.body_mass[bodies], _parallel(d)))
        fit = fit_densities(M, com, inertia, data.geom_xpos[rows[m]],
                            data.geom_xmat[rows[m]].reshape(-1, 3, 3), sizes[m])
        rho[m] = np.array([float(f"{x:.{DERIVED_DIGITS}g}") for x in fit])
    rho[~np.isfinite(rho) | (rho <= 0)] = DEFAULT_DENSITY
    return rho


def _parallel(d: np.ndarray) -> np.ndarray:
    """(n, 3, 3) parallel-axis term ``|d|^2 I - d d^T`` per unit mass."""
    return (d * d).sum(axis=1)[:, None, None] * np.eye(3) - d[:, :, None] * d[:, None, :]


def fit_densities(mass: float, com: np.ndarray, inertia: np.ndarray, centers: np.ndarray,
                  rotations: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """Densities of n boxes whose union has the given mass properties.

    Parameters
    ----------
    mass : float
    com : (3,) float, centre of mass
    inertia : (3, 3) float, about ``com`` in world axes
    centers, rotations, sizes : (n, 3), (n, 3, 3), (n, 3) the boxes

    Returns
    -------
    (n,) float
        The densities nearest to a uniform one (least-norm change) that reproduce the 10
        numbers (mass, first moment, inertia) to ``1e-8`` of their scale; the uniform
        ``mass / volume`` when none does or one would be negative.  Exact for boxes of
        any densities as long as the 10 numbers determine them (up to 10 boxes in
        general position); uniform when uniform fits.
    """
    V = np.prod(sizes, axis=1)
    d = centers - com
    local = ((sizes**2).sum(axis=1, keepdims=True) - sizes**2) / 12.0
    per_rho = V[:, None, None] * (np.einsum("nij,nj,nkj->nik", rotations, local, rotations)
                                  + _parallel(d))
    L = float(sizes.max())
    iu = np.triu_indices(3)
    A = np.vstack([V / mass, (V[:, None] * d).T / (mass * L),
                   per_rho[:, iu[0], iu[1]].T / (mass * L * L)])
    b = np.r_[1.0, 0.0, 0.0, 0.0, inertia[iu] / (mass * L * L)]
    uniform = np.full(len(V), mass / V.sum())
    rho = uniform + np.linalg.lstsq(A, b - A @ uniform, rcond=None)[0]
    if np.abs(A @ rho - b).max() < 1e-8 and np.all(rho > 0):
        return rho
    return uniform


def _uniform_mu(friction: np.ndarray) -> float | None:
    """The friction coefficient when every geom states the same one (MuJoCo takes the
    larger of a pair, so that is every pair's), else None."""
    if len(friction) and np.all(friction == friction[0]) and \
            MU_RANGE[0] <= friction[0] <= MU_RANGE[1]:
        return float(friction[0])
    return None


def _urdf_mu(root) -> float | None:
    """Pair friction of a URDF whose colliding links all state the same PyBullet
    ``lateral_friction`` f: PyBullet multiplies a pair's, so mu = f^2."""
    values = []
    for link in root.iter("link"):
        if link.find("collision") is None:
            continue
        node = link.find("contact/lateral_friction")
        try:
            values.append(float(node.get("value")) if node is not None else None)
        except (TypeError, ValueError):
            return None
    if not values or None in values or len(set(values)) != 1:
        return None
    return _uniform_mu(np.array([float(f"{values[0] ** 2:.{DERIVED_DIGITS}g}")]))


# ------------------------------------------------------------------- geoms -> boxes
def _support_name(geom: str, body: str) -> str | None:
    for name in (geom, body if not geom else ""):
        if name.startswith("support:") and is_support_id(name[8:]):
            return name[8:]
    return None


def arrangement_from_geoms(g: SceneGeoms, *, where: str, meta: dict) -> Arrangement:
    """Boxes, supports and typed contacts of posed geoms (see the module docstring);
    ``where`` names the source in error messages, ``meta`` is the arrangement's."""
    from pipeline.arrangement_io import arrangement_from_dict, arrangement_to_dict

    G = len(g.kind)
    plane = np.array([k == "plane" for k in g.kind], bool)
    sup_name = [_support_name(n, b) for n, b in zip(g.names, g.bodies)]
    slab = ~plane & np.array([s is not None for s in sup_name], bool)
    for k in np.flatnonzero((plane | slab) & (g.group != 0)).tolist():
        raise InputError(f"{where}: {g.describe(k)} stands for a support but moves; "
                         "planes and support slabs must be welded to the world")
    rows = np.flatnonzero(~plane & ~slab)
    boxes_c = g.centers[rows].mean(axis=0) if len(rows) else np.zeros(3)
    supports = _supports(g, plane, slab, sup_name, boxes_c, where)

    taken = {s.id for s in supports}
    ids: list[str | None] = []
    for k in rows.tolist():
        n = g.names[k]
        ok = bool(n) and not is_support_id(n) and not n.startswith("support:") and \
            n not in taken and n.isprintable()
        ids.append(n if ok else None)
        taken.add(n)
    free_ids = (f"b{i}" for i in range(3 * G + 1) if f"b{i}" not in taken)
    ids = [i if i is not None else next(free_ids) for i in ids]
    cuboids = tuple(Cuboid(ids[i], g.centers[k], g.rotations[k], g.sizes[k], g.density[k],
                           g.objects[k]) for i, k in enumerate(rows.tolist()))
    arr = Arrangement(cuboids, supports, (), meta=meta)
    try:  # the reader's checks: sizes, coordinates and densities in range, names legal
        arrangement_from_dict(arrangement_to_dict(arr))
    except InputError as exc:
        raise InputError(f"{where}: imported {exc}") from None
    return arr.with_(contacts=_typed_contacts(arr, g.group[rows], rows, g, where))


def _supports(g: SceneGeoms, plane: np.ndarray, slab: np.ndarray, sup_name: list,
              boxes_c: np.ndarray, where: str) -> tuple[Support, ...]:
    """Supports in geom order: planes through their origin along local z, slabs by the
    face across their thinnest axis that faces the boxes' mean centre."""
    idx = np.flatnonzero(plane | slab)
    point, normal = g.centers[idx].copy(), g.rotations[idx, :, 2].copy()
    thin = np.argmin(np.where(slab[idx, None], g.sizes[idx], np.inf), axis=1)
    for r in np.flatnonzero(slab[idx]).tolist():
        k, t = int(idx[r]), int(thin[r])
        n = g.rotations[k, :, t] * (1.0 if (boxes_c - g.centers[k]) @ g.rotations[k, :, t]
                                    >= 0 else -1.0)
        point[r], normal[r] = g.centers[k] + n * g.sizes[k, t] / 2, n
    names = [sup_name[k] for k in idx.tolist()]
    for n in names:
        if n is not None and names.count(n) > 1:
            raise InputError(f"{where}: two geoms stand for the support {n!r}; rename one")
    if "ground" not in names:
        cand = [r for r, n in enumerate(names) if n is None and normal[r, 2] >= GROUND_MIN_NZ]
        if cand:
            names[max(cand, key=lambda r: normal[r, 2])] = "ground"
    walls = (f"wall:{i}" for i in range(len(names) + 1) if f"wall:{i}" not in names)
    names = [n if n is not None else next(walls) for n in names]
    return tuple(Support(n, p, v) for n, p, v in zip(names, point, normal))


def _typed_contacts(arr: Arrangement, group: np.ndarray, rows: np.ndarray, g: SceneGeoms,
                    where: str) -> tuple[Contact, ...]:
    """Every touching pair, ``fixed`` inside a rigid group and from world-welded boxes
    to their anchor support, ``touch`` otherwise; InputError where a group cannot be one
    rigid body of touching boxes."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from pipeline.contacts import find_contacts

    K = len(arr.cuboids)
    cs = find_contacts(arr)
    for x, y, depth in cs.penetrations:
        i, j = arr.index.get(x), arr.index.get(y)
        if i is not None and j is not None and group[i] == group[j]:
            raise InputError(f"{where}: {g.describe(int(rows[i]))} and {g.describe(int(rows[j]))} "
                             f"overlap by {depth:.3g} m; unseen's parts of one rigid body must "
                             "meet face to face, not overlap: trim one")
    a, b = cs.a, cs.b
    box_pair = b < K
    same = np.zeros(len(a), bool)
    same[box_pair] = group[a[box_pair]] == group[b[box_pair]]
    e = np.stack([a[same], b[same]])
    label = connected_components(coo_matrix((np.ones(e.shape[1]), e), shape=(K, K)),
                                 directed=False)[1] if K else np.zeros(0, int)
    for w in np.unique(group[group > 0]).tolist():
        members = np.flatnonzero(group == w)
        apart = members[label[members] != label[members[0]]]
        if len(apart):
            raise InputError(f"{where}: {g.describe(int(rows[members[0]]))} and "
                             f"{g.describe(int(rows[apart[0]]))} are one rigid body but do not "
                             "touch; unseen fuses only touching parts: move them into contact "
                             "or into separate bodies")
    fixed = same.copy()
    names = cs.names
    for comp in np.unique(label[group == 0]).tolist():
        on_sup = np.flatnonzero(~box_pair & (label[a] == comp) & (group[a] == 0))
        if not len(on_sup):
            k = int(rows[np.flatnonzero(label == comp)[0]])
            raise InputError(f"{where}: {g.describe(k)} is welded to the world but touches no "
                             "ground or wall; add a plane geom for the floor or wall it rests "
                             "on, or give its body a freejoint")
        ground = on_sup[[names[b[m]] == "ground" for m in on_sup]]
        fixed[ground if len(ground) else on_sup] = True
    return tuple(Contact(names[i], names[j], "fixed" if f else "touch")
                 for i, j, f in zip(a.tolist(), b.tolist(), fixed.tolist()))
