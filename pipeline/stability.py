r"""Static equilibrium of an arrangement of rigid blocks (Whiting et al. 2009; paper eq. 2-3).

Problem
-------
Bodies are the cuboids, except that cuboids joined by ``fixed`` contacts form one rigid
body, and a body fixed to a support (ground or wall) is anchored (it needs no balance).
Every geometric contact between two different bodies, or between a free body and a
support, carries a force at each vertex :math:`p_k` of its interface polygon (see
:mod:`pipeline.contacts`).  In the contact frame :math:`(u, v, n)` (``n`` points from
``b`` into ``a``) the force is written as a non-negative combination of the edges of
the friction pyramid inscribed in the Coulomb cone,

.. math::  f_k = \sum_{j=1}^{8} \lambda_{kj}\, g_{kj}, \quad
           g_{kj} = n + \mu (\cos\theta_j\, u + \sin\theta_j\, v), \quad
           \theta_j = 2\pi j / 8, \quad \lambda \ge 0,

which enforces :math:`f_n \ge 0` (compression only) and :math:`\|f_t\| \le \mu f_n`
(the octagon is inscribed, so it under-allows friction by at most 7.6 %).  Force
:math:`f_k` acts on body ``a`` and :math:`-f_k` on body ``b``.  For every free body
:math:`g` with mass :math:`m_g`, centre of mass :math:`c_g`, weight
:math:`W_g = m_g\,9.81` and size :math:`L_g` (largest distance from :math:`c_g` to a
corner), the six equilibrium equations are

.. math::  \sum_k \pm f_k - W_g e_z = 0, \qquad \sum_k (p_k - c_g) \times (\pm f_k) = 0.

Stacked over all bodies this is :math:`D \lambda + w = 0` (eq. 2).  Rows are made
scale-free by dividing the force rows of body :math:`g` by :math:`W_g` and its torque
rows by :math:`W_g L_g`, giving :math:`\tilde D \lambda = \tilde b`.  The energy is

.. math::  E = \min_{\lambda \ge 0} \|\tilde D \lambda - \tilde b\|^2        \qquad (3)

a sum over bodies of squared residual force (in body weights) and torque (in weight x
size): invariant to the scene's scale and to rigid motions.  The arrangement is stable
when :math:`E` < ``threshold`` (``constants.ENERGY_THRESHOLD`` = 1e-5, see there why not
the paper's 1e-3); a body is stable when its own share of :math:`E` is below it.
Infeasibility is not an error: it shows as a large :math:`E` and the verdict *unstable*.

Backends
--------
``nnls``: dense non-negative least squares (``scipy.optimize.nnls``) per independent
group of bodies (connected through free-free contacts).
``qp``: the same problem as a sparse convex QP in lifted form,
:math:`\min \tfrac12\|r\|^2` s.t. :math:`\tilde D\lambda - r = \tilde b,\ \lambda \ge 0`,
solved through its dual by Clarabel (interior point), group by group.
``auto`` works per independent group: it first tries a *load path* certificate
(:func:`load_path`: loads carried from the top body down, one 6-row NNLS per body, a
body that cannot carry what was put on it balanced jointly with the bodies that loaded
it; an exact solution proves E = 0), then a frictionless certificate, then picks ``nnls`` for
groups with few unknowns and ``qp`` otherwise.  Tests check that the backends agree.
A caller that checks many similar arrangements (the search) passes ``solve_cache``: a
group whose sub-problem digest (its column blocks, their layout, body heights and
right-hand side) was seen before reuses that solution, which is exactly what a new
solve would return.  ``D`` itself is assembled lazily from the column blocks.

The side-friction trap
----------------------
Plain statics lets two boxes that merely touch along vertical faces squeeze each other
with arbitrarily large normal forces whose friction then holds a box up: a box
"wedged" between two columns by side friction alone is statically admissible, yet with
no preload nothing produces that squeeze, and both MuJoCo and PyBullet drop it.  We
remove friction from *side contacts*: face-to-face interfaces (>= 3 vertices), and edge
contacts along a line steeper than 45 degrees (two upright boxes slightly yawed against
each other touch along a vertical edge), whose normal is within 15 degrees of
horizontal (``constants.SIDE_CONTACT_MAX_NZ``) and that are not fixed.  They still push
(normal force), so lateral bracing works; corners and edges along flatter lines keep
friction, so a plank leaning with its edge on a wall keeps the ladder limit :math:`\tan\theta = (1-\mu^2)/(2\mu)` (20.0 degrees for mu = 0.7).  That
exception needs the body to stand on something: a body that no contact pushes upward
(:func:`hanging_contacts`) gets no friction on its corner and edge side contacts either
(a box held at 45 degrees by one edge on the wall and one on a desk's side, squeezed by
the desk standing on the floor: statics accepted it, both engines drop it 0.5 m).  Pass
``side_friction=True`` to get plain statics.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp

from .constants import (
    DEFAULT_MU,
    ENERGY_THRESHOLD,
    FRICTION_PYRAMID_EDGES,
    GRAVITY,
    ROBUST_THRESHOLD_REL,
    SIDE_CONTACT_MAX_NZ,
)
from .contacts import ContactSet, cross, find_contacts
from .errors import InputError
from .model import Arrangement, is_support_id

log = logging.getLogger(__name__)

#: groups with at most this many unknowns are solved by dense NNLS under ``auto``
NNLS_MAX_COLUMNS = 400
#: systems with at most this many matrix entries are sliced densely (small scenes)
DENSE_MAX_ENTRIES = 2_000_000


@dataclass(frozen=True)
class BodyResidual:
    """Per-cuboid diagnostics (a cuboid of a fused group reports its group's values)."""

    id: str
    stable: bool
    residual_force: float  #: N, norm of the unbalanced force on its body
    residual_torque: float  #: N m, norm of the unbalanced torque about the body's COM
    energy: float  #: the body's share of E
    anchored: bool = False
    group: int = -1


@dataclass(frozen=True)
class StabilityResult:
    """Outcome of :func:`check_stability` (an unstable arrangement is a normal answer)."""

    stable: bool
    energy: float
    threshold: float
    status: str  #: "ok", "interpenetration"
    bodies: tuple[BodyResidual, ...]
    backend: str
    mu: float
    n_contacts: int = 0
    penetrations: tuple[tuple[str, str, float], ...] = ()
    #: (M,) scale-free load carried by each contact of the ContactSet (0: not needed here)
    contact_load: np.ndarray | None = None

    @property
    def unstable_ids(self) -> list[str]:
        return [b.id for b in self.bodies if not b.stable]

    def to_json(self) -> dict:
        return {
            "stable": self.stable, "energy": self.energy, "threshold": self.threshold,
            "status": self.status, "backend": self.backend, "mu": self.mu,
            "contacts": self.n_contacts,
            "bodies": [{"id": b.id, "stable": b.stable, "residual_force": b.residual_force,
                        "residual_torque": b.residual_torque, "energy": b.energy,
                        "anchored": b.anchored} for b in self.bodies],
            "penetrations": [{"a": a, "b": b, "depth": d} for a, b, d in self.penetrations],
        }


# ------------------------------------------------------------------------- bodies
@dataclass(frozen=True)
class Bodies:
    """Rigid bodies of an arrangement: cuboids merged through ``fixed`` contacts.

    ``of_node[k]`` is the body of node ``k`` (cuboids then supports); anchored bodies
    (fused to a support, and the supports themselves) have ``anchored[g]`` True.
    """

    of_node: np.ndarray  # (K + S,) int
    anchored: np.ndarray  # (G,) bool
    mass: np.ndarray  # (G,)
    com: np.ndarray  # (G, 3)
    size: np.ndarray  # (G,) characteristic length L_g


def fixed_node_pairs(arr: Arrangement, contacts: ContactSet) -> list[tuple[int, int]]:
    """Node index pairs of the listed ``fixed`` contacts; each must touch geometrically."""
    node = {name: k for k, name in enumerate(contacts.names)}
    touching = contacts.lookup()
    out = []
    for idx, c in enumerate(arr.contacts):
        if c.type != "fixed":
            continue
        if c.key not in touching:
            raise InputError(f"contacts[{idx}]: {c.a!r} and {c.b!r} are listed as fixed but do "
                             "not touch (fix the geometry or remove the contact)")
        out.append((node[c.a], node[c.b]))
    return out


def build_bodies(arr: Arrangement, fixed: list[tuple[int, int]]) -> Bodies:
    """Union-find of cuboids over fixed pairs; mass, COM and size of each body."""
    K, S = len(arr.cuboids), len(arr.supports)
    key = (K, S, tuple(fixed))
    grouping = _BODY_GROUPING.get(key)
    if grouping is None:
        grouping = _group_bodies(K, S, fixed)
        if len(_BODY_GROUPING) >= 256:
            _BODY_GROUPING.clear()
        _BODY_GROUPING[key] = grouping
    of_node, anchored, G = grouping
    masses = arr.masses
    mass = np.bincount(of_node[:K], weights=masses, minlength=G)
    com = np.stack([np.bincount(of_node[:K], weights=masses * arr.centers[:, d], minlength=G)
                    for d in range(3)], axis=1) / np.maximum(mass, 1e-300)[:, None]
    corners = arr.corners
    dist = np.linalg.norm(corners - com[of_node[:K]][:, None, :], axis=2).max(axis=1) if K else []
    size = np.zeros(G)
    np.maximum.at(size, of_node[:K], dist)
    return Bodies(of_node, anchored.copy(), mass, com, size)


#: body grouping of recent (cuboid count, support count, fixed pairs): the same input
#: (a refinement's variants, a search's nodes) gives the same union-find
_BODY_GROUPING: dict[tuple, tuple[np.ndarray, np.ndarray, int]] = {}


def _group_bodies(K: int, S: int, fixed) -> tuple[np.ndarray, np.ndarray, int]:
    """(body of each node, anchored flag of each body, body count) of the union-find."""
    parent = list(range(K + S))

    def find(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for a, b in fixed:
        ra, rb = find(a), find(b)
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    roots = np.array([find(k) for k in range(K + S)])
    # all supports form one anchored body
    sup_roots = set(roots[K:].tolist())
    if S:
        is_sup = np.zeros(K + S, bool)
        is_sup[list(sup_roots)] = True
        roots = np.where(is_sup[roots], K + S, roots)
    uniq, of_node = np.unique(roots, return_inverse=True)
    G = len(uniq)
    anchored = np.zeros(G, bool)
    if S:
        anchored[of_node[K:]] = True
    of_node.setflags(write=False)
    return of_node, anchored, G


# ------------------------------------------------------------------------- system
#: cosines and sines of the friction pyramid's edge angles 2 pi j / E
_PYRAMID_COS = np.cos(2 * np.pi * np.arange(FRICTION_PYRAMID_EDGES) / FRICTION_PYRAMID_EDGES)
_PYRAMID_SIN = np.sin(2 * np.pi * np.arange(FRICTION_PYRAMID_EDGES) / FRICTION_PYRAMID_EDGES)


@dataclass(frozen=True)
class EquilibriumSystem:
    """The scale-free system ``D lambda = b`` with bookkeeping to read it back.

    ``D`` rows: 6 per free body (force x y z, torque x y z); columns: one per pyramid
    edge per interface vertex (``col_vertex`` maps columns to contact vertices, and
    ``col_dir`` holds each column's unit-free direction ``g``).  Search reuses the
    system and drops the columns of contacts it switches off (``column_mask``).
    """

    _D: sp.csc_matrix | None  # assembled from ``blocks`` on first use (see ``D``)
    b: np.ndarray
    free: np.ndarray  # (F,) body index of each free body (row block)
    row_scale: np.ndarray  # (6F,) multiply residual rows to get N / N m
    col_vertex: np.ndarray
    col_contact: np.ndarray
    col_dir: np.ndarray
    contact_bodies: np.ndarray  # (M, 2) body of a and b for each contact (-1 if internal)
    blocks: np.ndarray  # (ncol, 2, 6) scaled coefficients of each column on its two bodies
    col_row: np.ndarray  # (ncol, 2) free-body row block of each side, -1 when anchored
    free_height: np.ndarray  # (F,) COM height of each free body
    #: arrays derived on first use (see ``entries``, ``half_pyramid``), shared with the
    #: copies that differ in ``b`` (tilted gravity)
    _shared: dict = field(default_factory=dict, repr=False, compare=False)

    def entries(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Flat row indices, column indices and values of the entries of ``D``."""
        if "entries" not in self._shared:
            c_idx, s_idx = np.nonzero(self.col_row >= 0)
            rows = (6 * self.col_row[c_idx, s_idx])[:, None] + np.arange(6)
            self._shared["entries"] = (rows.ravel(), c_idx, self.blocks[c_idx, s_idx])
        return self._shared["entries"]

    def components(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """:func:`_components` of this system (shared by systems of one topology)."""
        if "components" not in self._shared:
            self._shared["components"] = _components(self)
        return self._shared["components"]

    def grouping(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:func:`_body_columns` of this system (shared by systems of one topology)."""
        if "grouping" not in self._shared:
            self._shared["grouping"] = _body_columns(self)
        return self._shared["grouping"]

    def half_pyramid(self) -> np.ndarray:
        """(ncol,) bool: every other edge of each friction pyramid (an inscribed square)
        and the single column of each frictionless vertex: a subset of the columns, so a
        solution over them solves the whole problem too."""
        if "half" not in self._shared:
            cv = self.col_vertex
            n = len(cv)
            starts = np.r_[0, np.nonzero(cv[1:] != cv[:-1])[0] + 1] if n else np.zeros(0, int)
            per = np.diff(np.r_[starts, n])
            j = np.arange(n) - np.repeat(starts, per)
            self._shared["half"] = (np.repeat(per, per) == 1) | (j % 2 == 0)
        return self._shared["half"]

    @property
    def D(self) -> sp.csc_matrix:
        """(6F, ncol) the scaled equilibrium matrix (assembled lazily: certificates that
        work body by body never need it)."""
        if self._D is None:
            rows, c_idx, coef = self.entries()
            D = sp.csc_matrix((coef.ravel(), (rows, np.repeat(c_idx, 6))),
                              shape=(6 * len(self.free), len(self.col_vertex)))
            object.__setattr__(self, "_D", D)
        return self._D

    def residual(self, lam: np.ndarray) -> np.ndarray:
        """(6F,) ``D lambda - b``."""
        if self._D is not None or self.blocks is None:
            return self.D @ lam - self.b
        rows, c_idx, coef = self.entries()
        w = coef * lam[c_idx, None]
        return np.bincount(rows, weights=w.ravel(), minlength=6 * len(self.free)) - self.b


def hanging_contacts(contacts: ContactSet, bodies: Bodies, active: np.ndarray) -> np.ndarray:
    """(M,) bool: contacts of a free body that nothing pushes upward (no active contact
    whose normal into it points up by more than ``SIDE_CONTACT_MAX_NZ``).

    Such a body could hang only from friction at its side contacts, and friction there
    needs a squeeze that nothing without preload provides (a box wedged by two edges
    between a desk's side and the wall; see "The side-friction trap").  A body standing
    on something (a plank on the floor leaning on a wall) keeps the friction of its
    corner and edge contacts: its own weight presses them.
    """
    M = contacts.count
    if not M:
        return np.zeros(0, bool)
    ga = bodies.of_node[contacts.a]
    gb = bodies.of_node[contacts.b]
    nz = contacts.normal[:, 2]  # into a
    G = len(bodies.mass)
    held = np.zeros(G, bool)
    held[ga[active & (nz > SIDE_CONTACT_MAX_NZ)]] = True
    held[gb[active & (-nz > SIDE_CONTACT_MAX_NZ)]] = True
    hanging = ~held & ~bodies.anchored
    return active & (hanging[ga] | hanging[gb])


def build_system(arr: Arrangement, contacts: ContactSet, bodies: Bodies, mu: float,
                 side_friction: bool = False, fixed_contacts: np.ndarray | None = None
                 ) -> EquilibriumSystem:
    """Assemble the sparse equilibrium matrix from index arrays (no Python loop over rows)."""
    G = len(bodies.mass)
    free = np.nonzero(~bodies.anchored)[0]
    row_of_body = -np.ones(G, int)
    row_of_body[free] = np.arange(len(free))
    M = contacts.count
    ga = bodies.of_node[contacts.a] if M else np.zeros(0, int)
    gb = bodies.of_node[contacts.b] if M else np.zeros(0, int)
    active = (ga != gb) & ~(bodies.anchored[ga] & bodies.anchored[gb])
    contact_bodies = np.stack([np.where(active, ga, -1), np.where(active, gb, -1)], axis=1) \
        if M else np.zeros((0, 2), int)

    nverts = contacts.n_vertices
    horizontal = np.abs(contacts.normal[:, 2]) < SIDE_CONTACT_MAX_NZ if M else np.zeros(0, bool)
    # an edge contact along a vertical line (two upright boxes a little yawed against each
    # other) is the same trap as a face-to-face one; an edge along a horizontal line (a
    # plank's end against a wall) keeps its friction
    upright_edge = np.zeros(M, bool)
    if M:
        V = contacts.vertices
        if nverts.min() > 0:  # vertices come grouped by contact: reduce each run
            starts = np.r_[0, np.cumsum(nverts)[:-1]]
            span = np.maximum.reduceat(V, starts, axis=0) - np.minimum.reduceat(V, starts, axis=0)
        else:
            lo = np.full((M, 3), np.inf)
            hi = np.full((M, 3), -np.inf)
            np.minimum.at(lo, contacts.vertex_contact, V)
            np.maximum.at(hi, contacts.vertex_contact, V)
            span = np.where(np.isfinite(hi - lo), hi - lo, 0.0)
        upright_edge = (nverts == 2) & (span[:, 2] > np.hypot(span[:, 0], span[:, 1]))
    no_friction = horizontal & ((nverts >= 3) | upright_edge)
    # ... and so do the corner and edge side contacts of a body that nothing pushes up
    no_friction |= horizontal & hanging_contacts(contacts, bodies, active)
    if side_friction:
        no_friction[:] = False
    if fixed_contacts is not None:
        no_friction &= ~fixed_contacts

    # the index structure (columns, their bodies and rows, the components) depends only
    # on which nodes touch through how many vertices, which contacts have friction and
    # how cuboids group into bodies: shared by every system with the same topology
    import hashlib

    h = hashlib.blake2b(digest_size=20)
    for part in (contacts.a, contacts.b, contacts.vertex_contact, no_friction,
                 bodies.of_node, bodies.anchored):
        h.update(np.ascontiguousarray(part).tobytes())
        h.update(b"|")
    key = h.digest()
    topo = _TOPOLOGY.get(key)
    if topo is None:
        topo = _topology(contacts, bodies, G, active, ga, gb, no_friction)
        if len(_TOPOLOGY) >= TOPOLOGY_CACHE_MAX:
            _TOPOLOGY.clear()
        _TOPOLOGY[key] = topo
    free, row_of_body, contact_bodies, col_vertex, j, m, fric, c_idx, s_idx, gu, col_row, b, \
        shared = topo
    dirs = contacts.normal[m] + (fric * mu)[:, None] * (
        _PYRAMID_COS[j][:, None] * contacts.tangent_u[m]
        + _PYRAMID_SIN[j][:, None] * contacts.tangent_v[m])
    p = contacts.vertices[col_vertex]

    ncol = len(col_vertex)
    W = bodies.mass * GRAVITY
    # blocks[c, side] = the 6 scaled equilibrium coefficients of column c on body side
    # (both sides at once: side 0 is body a, pushed along +dir; side 1 is b, along -dir)
    blocks = np.zeros((ncol, 2, 6))
    if len(c_idx):
        du = np.where((s_idx == 0)[:, None], 1.0, -1.0) * dirs[c_idx]
        torque = cross(p[c_idx] - bodies.com[gu], du)
        blocks[c_idx, s_idx, :3] = du / W[gu][:, None]
        blocks[c_idx, s_idx, 3:] = torque / (W[gu] * bodies.size[gu])[:, None]
    Wf, WLf = W[free], W[free] * bodies.size[free]  # force rows in weights, torque rows
    row_scale = np.stack([Wf, Wf, Wf, WLf, WLf, WLf], axis=1).ravel()
    return EquilibriumSystem(None, b, free, row_scale, col_vertex, m, dirs, contact_bodies, blocks,
                             col_row, bodies.com[free, 2], dict(shared))


#: topologies of recent systems (see :func:`build_system`), cleared beyond this many
TOPOLOGY_CACHE_MAX = 256
_TOPOLOGY: dict[bytes, tuple] = {}


def _topology(contacts: ContactSet, bodies: Bodies, G: int, active, ga, gb, no_friction
              ) -> tuple:
    """The index arrays of :func:`build_system` (read-only, shared between systems) and
    the derived structures that depend on nothing else (components, body columns)."""
    free = np.nonzero(~bodies.anchored)[0]
    row_of_body = -np.ones(G, int)
    row_of_body[free] = np.arange(len(free))
    M = contacts.count
    contact_bodies = np.stack([np.where(active, ga, -1), np.where(active, gb, -1)], axis=1) \
        if M else np.zeros((0, 2), int)
    # columns: for every vertex of an active contact, E pyramid edges (or 1 normal column)
    E = FRICTION_PYRAMID_EDGES
    vc = contacts.vertex_contact
    vmask = active[vc] if len(vc) else np.zeros(0, bool)
    verts = np.nonzero(vmask)[0]
    nf = no_friction[vc[verts]]
    n_cols = np.where(nf, 1, E)
    col_vertex = np.repeat(verts, n_cols)
    j = np.arange(len(col_vertex)) - np.repeat(np.cumsum(n_cols) - n_cols, n_cols)
    m = vc[col_vertex]
    fric = ~no_friction[m]
    col_row = -np.ones((len(col_vertex), 2), int)
    g2 = contact_bodies[m]
    use = g2 >= 0
    use[use] = ~bodies.anchored[g2[use]]
    c_idx, s_idx = np.nonzero(use)
    gu = g2[c_idx, s_idx]
    col_row[c_idx, s_idx] = row_of_body[gu]
    b = np.zeros(6 * len(free))
    b[6 * np.arange(len(free)) + 2] = 1.0  # contacts must lift each body's weight
    out = (free, row_of_body, contact_bodies, col_vertex, j, m, fric, c_idx, s_idx, gu,
           col_row, b)
    for a in out:
        a.setflags(write=False)
    probe = EquilibriumSystem(None, b, free, None, col_vertex, m, None, contact_bodies, None,
                              col_row, None)
    shared = {"components": _components(probe), "grouping": _body_columns(probe),
              "half": probe.half_pyramid()}
    return (*out, shared)


# ------------------------------------------------------------------------- solvers
def _components(system: EquilibriumSystem) -> list[tuple[np.ndarray, np.ndarray]]:
    """Independent groups: (row indices, column indices) of each connected block.

    Two free bodies are connected when a column acts on both (a contact between them).
    """
    F = len(system.free)
    if F == 0:
        return []
    cr = system.col_row
    both = (cr[:, 0] >= 0) & (cr[:, 1] >= 0)
    # union-find over the distinct body pairs (few; cheaper than a sparse graph here)
    parent = list(range(F))

    def find(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    codes = np.unique(cr[both, 0] * F + cr[both, 1])
    for x, y in zip((codes // F).tolist(), (codes % F).tolist()):
        rx, ry = find(x), find(y)
        if rx != ry:
            parent[max(rx, ry)] = min(rx, ry)
    _, label = np.unique([find(x) for x in range(F)], return_inverse=True)
    ncomp = int(label.max()) + 1
    col_body = np.where(cr[:, 0] >= 0, cr[:, 0], cr[:, 1])
    col_label = np.where(col_body >= 0, label[np.maximum(col_body, 0)], -1)
    order = np.argsort(col_label, kind="stable")
    bounds = np.searchsorted(col_label[order], np.arange(ncomp + 1))
    by_label = np.argsort(label, kind="stable")  # bodies of each component, in order
    body_bounds = np.searchsorted(label[by_label], np.arange(ncomp + 1))
    out = []
    for c in range(ncomp):
        bodies_c = by_label[body_bounds[c]:body_bounds[c + 1]]
        rows = (6 * bodies_c[:, None] + np.arange(6)).ravel()
        out.append((rows, order[bounds[c]:bounds[c + 1]]))
    return out


def _normal_only(D: np.ndarray, b: np.ndarray, col_vertex: np.ndarray,
                 tol: float = 1e-10) -> np.ndarray | None:
    """An exact solution using normal forces only (one column per vertex), or None.

    The mean of a vertex's pyramid columns is its normal direction, so a frictionless
    equilibrium is one with equal weights on a vertex's columns.  It has an eighth of
    the unknowns: a cheap certificate of E = 0 before the full problem.  ``D`` is dense
    with the columns of each vertex contiguous.
    """
    from scipy.optimize import nnls

    if len(col_vertex) == 0:
        return None if np.linalg.norm(b) > tol else np.zeros(0)
    starts = np.r_[0, np.nonzero(np.diff(col_vertex))[0] + 1]
    per = np.diff(np.r_[starts, len(col_vertex)]).astype(float)
    Dn = np.add.reduceat(D, starts, axis=1) / per
    x, res = nnls(Dn, b, maxiter=50 * max(len(starts), 10))
    if res > tol:
        return None
    return np.repeat(x / per, per.astype(int))


def _solve_nnls(D: np.ndarray, b: np.ndarray) -> np.ndarray:
    from scipy.optimize import nnls

    if D.shape[1] == 0:
        return np.zeros(0)
    x, _ = nnls(np.asarray(D), b, maxiter=50 * max(D.shape[1], 10))
    return x


def _solve_qp(D: sp.spmatrix, b: np.ndarray) -> np.ndarray:
    """Solve eq. 3 through its dual QP with Clarabel; falls back to ``lsq_linear``.

    The Lagrange dual of ``min 1/2 ||D x - b||^2, x >= 0`` is
    ``min_y 1/2 ||y||^2 + b.y  s.t.  D^T y >= 0`` with ``y* = D x* - b`` (the residual)
    and ``x*`` the multipliers of the constraints.  It has only 6 unknowns per body
    (measured: 3x faster than the lifted primal on brick walls).
    """
    n, m = D.shape[1], D.shape[0]
    if n == 0:
        return np.zeros(0)
    try:
        import clarabel
    except ImportError:  # pragma: no cover - dependency declared
        clarabel = None
    if clarabel is not None:
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        settings.tol_gap_abs = 1e-12
        settings.tol_gap_rel = 1e-12
        settings.tol_feas = 1e-11
        solver = clarabel.DefaultSolver(sp.identity(m, format="csc"), np.asarray(b, float),
                                        (-D.T).tocsc(), np.zeros(n),
                                        [clarabel.NonnegativeConeT(n)], settings)
        sol = solver.solve()
        if str(sol.status) in ("Solved", "AlmostSolved"):
            return np.maximum(np.asarray(sol.z), 0.0)
        log.warning("clarabel status %s; falling back to lsq_linear", sol.status)
    from scipy.optimize import lsq_linear

    return np.maximum(lsq_linear(D, b, bounds=(0, np.inf), tol=1e-12).x, 0.0)


def _body_columns(system: EquilibriumSystem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Columns acting on each free body, grouped with one sort.

    Returns ``(cols, side, starts)``: the columns (and the side, 0 or 1, on which they act)
    of free body ``r`` are ``cols[starts[r]:starts[r + 1]]``.
    """
    cols_all, side_all = np.nonzero(system.col_row >= 0)
    body_all = system.col_row[cols_all, side_all]
    order = np.argsort(body_all, kind="stable")
    starts = np.searchsorted(body_all[order], np.arange(len(system.free) + 1))
    return cols_all[order], side_all[order], starts


def load_path(system: EquilibriumSystem, column_mask: np.ndarray | None = None,
              tol: float = 1e-10, bodies: np.ndarray | None = None,
              grouping: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
              max_cluster: int | None = None, memo: dict | None = None,
              proof: list | None = None, normal_first: bool = True) -> np.ndarray | None:
    """A zero-residual certificate by carrying loads top-down, or None.

    Free bodies are taken from the highest centre of mass down.  Each body's weight
    plus the forces already fixed by the bodies above it must be balanced by its
    remaining contacts (with lower bodies and supports): a 6-row NNLS per body.  If
    every body balances exactly, the concatenated forces solve ``D lambda = b`` with
    ``lambda >= 0``, which proves E = 0 (stable) without a global solve.  Stacks, walls
    and furniture resting on the floor pass; structures that need a lower body to be
    held by an upper one (counterweights) return None and go to the global solvers.

    The per-body choice is arbitrary where a body has more supports than it needs, and
    a choice can load a lower body with more than it can carry (a slab braced between a
    wall and a neighbour by a large couple) although another choice would do.  When a
    body fails, the bodies that loaded it are therefore merged with it into a *cluster*
    that is balanced jointly (one NNLS over the cluster's rows: its internal forces are
    free again), the bodies processed since the earliest of them are taken back, and the
    pass resumes from there (the bodies still to come that the loaders also press on join
    the cluster at once).  Clusters grow up to ``max_cluster`` bodies
    (``LOAD_PATH_MAX_CLUSTER``) in at most ``LOAD_PATH_MAX_MERGES`` merges; beyond that the
    certificate gives up (None) and the global solvers decide.  Whatever
    the merging, the result is a ``lambda >= 0`` that balances every body to ``tol``,
    so the certificate stays exact.

    ``bodies`` (free-body row blocks) restricts the pass to one independent component
    (its columns act only on its own bodies and on anchored ones, so its certificate is
    independent of the rest); the returned vector is then only meaningful on the
    component's columns.  ``grouping`` is :func:`_body_columns` of the system, reused.
    ``memo`` (a dict kept by the caller) maps a digest of one body's problem (its unknown
    columns' coefficients, their grouping into vertices and its right-hand side) to the
    NNLS answer, so the bodies that a change elsewhere leaves alone are not solved again
    (exact: equal problems have equal answers).

    A body that fails on its own and misses by more than :data:`LOAD_PATH_FLOOR`
    (squared) even with every one of its contacts free (:func:`_body_floor`) ends the
    pass at once: every cluster it would join must balance its rows too, to ``tol``, so
    none can, and the answer is None as after the merges.  Its floor is appended to
    ``proof`` (a list kept by the caller): the component's E is at least that much.
    ``normal_first`` False: each unit is balanced with friction at once (a certificate
    for tilted gravity, where normal forces alone rarely balance a body).
    """
    from scipy.optimize import nnls

    if system.blocks is None:
        return None
    max_cluster = LOAD_PATH_MAX_CLUSTER if max_cluster is None else max_cluster
    ncol = len(system.col_vertex)
    lam = np.zeros(ncol)
    owner = -np.ones(ncol, int)  # position of the unit that set each column
    done = np.zeros(len(system.free), bool)
    usable = np.ones(ncol, bool) if column_mask is None else column_mask
    cols_all, side_all, starts = _body_columns(system) if grouping is None else grouping
    rows_of = np.arange(len(system.free)) if bodies is None else np.asarray(bodies)
    units = [[int(r)] for r in rows_of[np.argsort(-system.free_height[rows_of], kind="stable")]]
    i = merges = 0
    while i < len(units):
        unit = units[i]
        if len(unit) == 1:
            ok = _balance_body(system, unit[0], lam, owner, i, done, usable, cols_all, side_all,
                               starts, tol, nnls, memo, normal_first)
        else:
            ok = _balance_cluster(system, unit, lam, owner, i, done, usable, cols_all, side_all,
                                  starts, tol, nnls, memo, normal_first)
        if ok:
            done[unit] = True
            i += 1
            continue
        if len(unit) == 1 and max(tol * tol, LOAD_PATH_FLOOR) < (
                floor := _body_floor(system, unit[0], column_mask,
                                     (cols_all, side_all, starts))):
            if proof is not None:
                proof.append(floor)
            return None  # no cluster with this body can balance it
        # merge the unit with the units of the bodies that loaded it, and resume there
        c = np.concatenate([cols_all[starts[r]:starts[r + 1]] for r in unit])
        sd = np.concatenate([side_all[starts[r]:starts[r + 1]] for r in unit])
        keep = usable[c]
        other = system.col_row[c[keep], 1 - sd[keep]]
        loaders = set(other[(other >= 0) & done[np.maximum(other, 0)]].tolist())
        if not loaders:
            return None
        pos = {r: k for k, u in enumerate(units[:i]) for r in u}
        merge = sorted({pos[r] for r in loaders})
        # the bodies that the loaders also load, still to come, join too (books standing
        # in a shelf whose fused top rests on them would otherwise fail one by one)
        later = {r for u in units[i + 1:] for r in u}
        lc = np.concatenate([cols_all[starts[r]:starts[r + 1]] for r in loaders])
        ls = np.concatenate([side_all[starts[r]:starts[r + 1]] for r in loaders])
        loaded = system.col_row[lc, 1 - ls]
        loaded = set(loaded[loaded >= 0].tolist()) & later
        merge += sorted({k for k, u in enumerate(units[i + 1:], start=i + 1) if loaded & set(u)})
        cluster = sorted(set(unit).union(*(units[k] for k in merge)))
        merges += 1
        if len(cluster) > max_cluster or merges > LOAD_PATH_MAX_MERGES:
            return None
        j = merge[0]
        for u in units[j:i]:
            done[u] = False
        undo = owner >= j
        lam[undo] = 0.0
        owner[undo] = -1
        rest = [u for k, u in enumerate(units[j:], start=j) if k not in merge and k != i]
        units = units[:j] + [cluster] + rest
        i = j
    return lam


#: largest cluster of bodies that :func:`load_path` balances jointly before giving up
LOAD_PATH_MAX_CLUSTER = 12
#: and the most merges it tries
LOAD_PATH_MAX_MERGES = 2
#: a body missing equilibrium by more than this (squared, scaled) with all its contacts
#: free ends :func:`load_path` (far above the certificate's tolerance squared, 1e-20)
LOAD_PATH_FLOOR = 1e-8
#: body problems remembered by :func:`load_path` (the memo is cleared beyond this)
LOAD_PATH_MEMO_MAX = 20000


def _balance_body(system, r, lam, owner, pos, done, usable, cols_all, side_all, starts, tol,
                  nnls, memo: dict | None = None, normal_first: bool = True) -> bool:
    """Balance free body ``r`` with its contacts to bodies not yet done (see load_path)."""
    c = cols_all[starts[r]:starts[r + 1]]
    sd = side_all[starts[r]:starts[r + 1]]
    keep = usable[c]
    c, sd = c[keep], sd[keep]
    other = system.col_row[c, 1 - sd]
    known = (other >= 0) & done[np.maximum(other, 0)]
    coef = system.blocks[c, sd]  # (k, 6)
    rhs = system.b[6 * r:6 * r + 6] - coef[known].T @ lam[c[known]]
    cu, coef_u = c[~known], coef[~known]
    if len(cu) == 0:
        return bool(np.linalg.norm(rhs) <= tol)
    # 1) normal forces only (the mean of a vertex's pyramid edges is its normal): passes
    #    no friction down, so lower bodies are not loaded sideways by arbitrary choices
    n_vert, inv = _group_ids(system.col_vertex[cu])
    key = None
    if memo is not None:
        import hashlib

        h = hashlib.blake2b(b"" if normal_first else b"friction", digest_size=20)
        for part in (coef_u, inv, rhs, np.float64(tol)):
            h.update(np.ascontiguousarray(part).tobytes())
        key = h.digest()
        hit = memo.get(key, memo)
        if hit is not memo:
            if hit is None:
                return False
            lam[cu] = hit
            owner[cu] = pos
            return True
    x = None
    if normal_first:
        per_vert = np.bincount(inv, minlength=n_vert)
        normal_coef = np.zeros((n_vert, 6))
        np.add.at(normal_coef, inv, coef_u)
        normal_coef /= per_vert[:, None]
        x = _exact_nnls(normal_coef.T, rhs, tol, nnls)
        if x is not None:
            x = (x / per_vert)[inv]
    if x is None:  # 2) with friction
        x = _exact_nnls(coef_u.T, rhs, tol, nnls)
    if key is not None:
        if len(memo) >= LOAD_PATH_MEMO_MAX:
            memo.clear()
        memo[key] = x
    if x is None:
        return False
    lam[cu] = x
    owner[cu] = pos
    return True


def _group_ids(values: np.ndarray) -> tuple[int, np.ndarray]:
    """``(len(u), inverse)`` of ``u, inverse = np.unique(values, return_inverse=True)``,
    by counting changes when ``values`` is non-decreasing (a body's or a component's
    columns come in column order, so their vertices do)."""
    if len(values) and np.all(values[1:] >= values[:-1]):
        inv = np.empty(len(values), np.intp)
        inv[0] = 0
        np.cumsum(values[1:] != values[:-1], out=inv[1:])
        return int(inv[-1]) + 1, inv
    u, inv = np.unique(values, return_inverse=True)
    return len(u), inv


def _exact_nnls(A: np.ndarray, b: np.ndarray, tol: float, nnls) -> np.ndarray | None:
    """``x >= 0`` with ``||A x - b|| <= tol`` found by NNLS, or None.  The residual is
    recomputed: scipy's reported one can be 0 for a solve that stopped early."""
    x, _ = nnls(A, b, maxiter=200 * max(A.shape[1], 10))
    return x if np.linalg.norm(A @ x - b) <= tol else None


def _balance_cluster(system, unit, lam, owner, pos, done, usable, cols_all, side_all, starts,
                     tol, nnls, memo: dict | None = None, normal_first: bool = True) -> bool:
    """Balance the bodies of ``unit`` jointly (forces between them are unknowns too).

    ``memo`` as for :func:`_balance_body`: the cluster's matrix, vertex grouping and
    right-hand side determine its answer."""
    local = {r: k for k, r in enumerate(unit)}
    c = np.concatenate([cols_all[starts[r]:starts[r + 1]] for r in unit])
    sd = np.concatenate([side_all[starts[r]:starts[r + 1]] for r in unit])
    blk = np.concatenate([np.full(starts[r + 1] - starts[r], local[r]) for r in unit])
    keep = usable[c]
    c, sd, blk = c[keep], sd[keep], blk[keep]
    other = system.col_row[c, 1 - sd]
    known = (other >= 0) & done[np.maximum(other, 0)]
    coef = system.blocks[c, sd]  # (k, 6) on the body of block blk
    n_rows = 6 * len(unit)
    rhs = np.concatenate([system.b[6 * r:6 * r + 6] for r in unit])
    kn = np.nonzero(known)[0]
    np.subtract.at(rhs, (6 * blk[kn])[:, None] + np.arange(6),
                   coef[kn] * lam[c[kn]][:, None])
    un = np.nonzero(~known)[0]
    if len(un) == 0:
        return bool(np.linalg.norm(rhs) <= tol)
    cu, col_idx = np.unique(c[un], return_inverse=True)  # internal columns appear twice
    A = np.zeros((n_rows, len(cu)))
    np.add.at(A, ((6 * blk[un])[:, None] + np.arange(6), col_idx[:, None]), coef[un])
    # 1) normal forces only, 2) with friction (as for one body)
    n_vert, inv = _group_ids(system.col_vertex[cu])
    key = None
    if memo is not None:
        import hashlib

        h = hashlib.blake2b(b"cluster" if normal_first else b"cluster-friction",
                            digest_size=20)
        for part in (A, inv, rhs, np.float64(tol)):
            h.update(np.ascontiguousarray(part).tobytes())
        key = h.digest()
        hit = memo.get(key, memo)
        if hit is not memo:
            if hit is None:
                return False
            lam[cu] = hit
            owner[cu] = pos
            return True
    x = None
    if normal_first:
        per_vert = np.bincount(inv, minlength=n_vert)
        An = np.zeros((n_rows, n_vert))
        np.add.at(An, (slice(None), inv), A)
        An /= per_vert
        x = _exact_nnls(An, rhs, tol, nnls)
        if x is not None:
            x = (x / per_vert)[inv]
    if x is None:
        x = _exact_nnls(A, rhs, tol, nnls)
    if key is not None:
        if len(memo) >= LOAD_PATH_MEMO_MAX:
            memo.clear()
        memo[key] = x
    if x is None:
        return False
    lam[cu] = x
    owner[cu] = pos
    return True


def _component_digest(system: EquilibriumSystem, rows: np.ndarray, cols: np.ndarray) -> bytes:
    """Digest of the matrix side of one component's sub-problem (right-hand side excluded).

    The sub-problem is fully determined by the coefficients of its columns on its bodies
    (``blocks``; ``D`` is assembled from them), which local body each column acts on, how
    columns group into contact vertices, the bodies' heights (the order of the load
    path) and the right-hand side (added by :func:`solve_energy`).  Equal digests mean an
    identical sub-problem, so a cached solution is exactly what a solve would return.
    """
    import hashlib

    bodies_c = rows[::6] // 6
    cr = system.col_row[cols]
    local = np.where(cr >= 0, np.searchsorted(bodies_c, np.maximum(cr, 0)), -1)
    _, vgroup = _group_ids(system.col_vertex[cols])
    h = hashlib.blake2b(digest_size=20)
    h.update(f"{len(rows)}|{len(cols)}|{system.blocks is None}".encode())
    for part in (system.free_height[bodies_c], local, vgroup):
        h.update(np.ascontiguousarray(part).tobytes())
    if system.blocks is not None:
        h.update(np.ascontiguousarray(system.blocks[cols]).tobytes())
    else:
        h.update(system.D[rows][:, cols].toarray().tobytes())
    return h.digest()


def solve_energy(system: EquilibriumSystem, backend: str = "auto",
                 column_mask: np.ndarray | None = None, *,
                 components: list[tuple[np.ndarray, np.ndarray]] | None = None,
                 cache: dict | None = None, digests: dict | None = None,
                 unstable_bound: float | None = None, certificate: bool = False,
                 expect_unstable: bool = False) -> tuple[np.ndarray, str]:
    """Minimise eq. 3 component by component; return (lambda over all columns, backend used).

    Independent components (free bodies connected through free-free contacts, see
    :func:`_components`) are solved separately: under ``auto`` each first tries the load
    path certificate, then the frictionless certificate, then dense NNLS or the QP.
    ``components`` may be passed when several right-hand sides share one system (tilted
    gravity).  ``cache`` (a dict kept by the caller, e.g. the search) maps a digest of a
    component's sub-problem (:func:`_component_digest` and the right-hand side) to its solution, so a node that
    changes one box re-solves only the components that box touches.  ``digests`` maps
    ``id(cols)`` of each passed component to its :func:`_component_digest` (shared by
    several right-hand sides); it is only used when ``column_mask`` is None.

    ``unstable_bound`` (verdicts only): a component whose load path fails and one of whose
    bodies cannot balance to within ``unstable_bound`` even with every one of its contacts
    free (:func:`_body_cannot_balance`, a lower bound on E) is not solved: its forces are
    left at zero (backend "bound"), so the E computed from the result is >= the bound too
    but is not the minimum.  Only the verdict of such a result is meaningful.

    ``certificate`` (only whether E is below the threshold matters, as for tilted gravity):
    a component is first tried with the load path over half of each friction pyramid
    (:meth:`EquilibriumSystem.half_pyramid`); when that balances every body, its forces
    solve the whole problem to the load path's tolerance (E is about zero, which any
    solve would find below the threshold) and are kept without the full pass.

    ``expect_unstable`` (a hint, as in refining an unstable arrangement): a component
    that would go to dense NNLS is solved by it first; when that minimum is clearly
    above zero (:data:`LOAD_PATH_FLOOR`, optimality checked) no certificate of a zero
    residual can succeed, so the answer is that NNLS solution, as the full order gives.
    """
    if backend not in ("auto", "nnls", "qp"):
        raise ValueError(f"backend must be auto, nnls or qp, got {backend!r}")
    lam = np.zeros(len(system.col_vertex))
    used = set()
    comps = system.components() if components is None else components
    dense = Dr = grouping = None
    for rows, cols in comps:
        if column_mask is not None:
            cols = cols[column_mask[cols]]
            digests = None
        key = None
        if cache is not None:
            import hashlib

            d = digests.get(id(cols)) if digests is not None else None
            if d is None:
                d = _component_digest(system, rows, cols)
            h = hashlib.blake2b(d, digest_size=20)
            h.update(backend.encode())
            h.update(np.ascontiguousarray(system.b[rows]).tobytes())
            key = h.digest()
            hit = cache.get(key)
            if hit is None and unstable_bound is not None:
                hit = cache.get(key + b"|bound")
            if hit is None and certificate:
                hit = cache.get(key + b"|half")
            if hit is not None:
                lam[cols] = hit[0]
                used.add(hit[1])
                continue
        how, floor = None, 0.0
        sliced = system.blocks is not None and \
            6 * len(system.free) * len(system.col_vertex) <= DENSE_MAX_ENTRIES
        sub_dense = None
        if (expect_unstable and sliced and backend == "auto" and unstable_bound is None
                and column_mask is None and len(cols) <= NNLS_MAX_COLUMNS):
            sub_dense = _dense_block(system, rows, cols)
            x = _solve_nnls(sub_dense, system.b[rows])
            if _clear_miss(sub_dense, x, system.b[rows]):
                if key is not None:
                    cache[key] = (x, "nnls")
                used.add("nnls")
                lam[cols] = x
                continue
        if backend == "auto" and system.blocks is not None:
            if grouping is None:
                grouping = system.grouping()
            memo = None if cache is None else cache.setdefault("load_path_memo", {})
            if certificate and column_mask is None:
                x = load_path(system, system.half_pyramid(), bodies=rows[::6] // 6,
                              grouping=grouping, memo=memo, normal_first=False)
                if x is not None:
                    x = x[cols]
                    if key is not None:
                        cache[key + b"|half"] = (x, "load-path")
                    used.add("load-path")
                    lam[cols] = x
                    continue
            proof: list[float] = []
            x = load_path(system, column_mask, bodies=rows[::6] // 6, grouping=grouping,
                          memo=memo, proof=proof)
            floor = max(proof, default=0.0)  # E of this component is at least this
            if x is not None:
                x, how = x[cols], "load-path"
            elif unstable_bound is not None and (
                    floor >= 10 * unstable_bound or _body_cannot_balance(
                        system, rows[::6] // 6, column_mask, grouping, unstable_bound)):
                x, how = np.zeros(len(cols)), "bound"
                if key is not None:
                    cache[key + b"|bound"] = (x, how)
                used.add(how)
                lam[cols] = x
                continue
        if how is None:
            if sliced:
                dense = True  # each component's block is sliced from ``blocks``
            elif dense is None and Dr is None:
                if system.D.shape[0] * system.D.shape[1] <= DENSE_MAX_ENTRIES:
                    dense = system.D.toarray()
                else:
                    Dr = system.D.tocsr()
            if dense is True and sub_dense is None:
                sub_dense = _dense_block(system, rows, cols)
            x, how = _solve_component(None if dense is True else dense, Dr, system, rows, cols,
                                      backend, exact_possible=floor <= LOAD_PATH_FLOOR,
                                      sub_dense=sub_dense)
        if key is not None:
            cache[key] = (x, how)
        used.add(how)
        lam[cols] = x
    if used == {"load-path"}:
        return lam, "load-path"
    return lam, "+".join(sorted(used)) or "none"


def _clear_miss(A: np.ndarray, x: np.ndarray, b: np.ndarray) -> bool:
    """Whether NNLS answer ``x`` of ``min ||A x - b||`` leaves more than
    :data:`LOAD_PATH_FLOOR` (squared) and satisfies the optimality conditions (gradient
    >= 0, zero where ``x`` > 0, up to round-off): then no ``x >= 0`` balances to the
    certificates' tolerance."""
    res = A @ x - b
    if res @ res <= LOAD_PATH_FLOOR:
        return False
    g = A.T @ res
    slack = 1e-9 * (1.0 + (np.abs(A).max() if A.size else 0.0) * (np.linalg.norm(b) + 1.0))
    return bool(g.min(initial=0.0) >= -slack and np.all(np.abs(g[x > 0]) <= slack))


def _body_cannot_balance(system: EquilibriumSystem, bodies: np.ndarray,
                         column_mask: np.ndarray | None, grouping, bound: float) -> bool:
    """True when some body's equilibrium misses by at least ``bound`` (squared, scaled)
    even with every one of its contacts free: a proof that E >= ``bound``.

    Body ``g``'s rows involve only its own columns, so for any ``lambda >= 0`` its share
    of E is at least ``min_{x >= 0} ||D_g x - b_g||^2`` (a 6-row NNLS, :func:`_body_floor`),
    trusted when it beats the bound ten times over.
    """
    return any(_body_floor(system, r, column_mask, grouping) >= 10 * bound for r in bodies)


def _body_floor(system: EquilibriumSystem, r: int, column_mask: np.ndarray | None,
                grouping) -> float:
    """``min_{x >= 0} ||D_r x - b_r||^2`` of free body ``r`` with every one of its contacts
    free (a lower bound on its share of E under any forces), or 0 when the NNLS answer
    fails the optimality conditions (gradient >= 0, zero where ``x`` > 0, up to
    round-off) and so proves nothing."""
    from scipy.optimize import nnls

    cols_all, side_all, starts = grouping
    c = cols_all[starts[r]:starts[r + 1]]
    sd = side_all[starts[r]:starts[r + 1]]
    if column_mask is not None:
        keep = column_mask[c]
        c, sd = c[keep], sd[keep]
    b = system.b[6 * r:6 * r + 6]
    if len(c) == 0:
        return float(b @ b)
    A = system.blocks[c, sd].T  # (6, k)
    x, _ = nnls(A, b, maxiter=200 * max(len(c), 10))
    res = A @ x - b
    g = A.T @ res
    slack = 1e-9 * (1.0 + np.abs(A).max() * (np.linalg.norm(b) + 1.0))
    optimal = g.min() >= -slack and np.all(np.abs(g[x > 0]) <= slack)
    return float(res @ res) if optimal else 0.0


def _dense_block(system: EquilibriumSystem, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``D[rows][:, cols]`` of one component as a dense array, straight from ``blocks``
    (the same entries as the assembled matrix: each column acts on two different bodies,
    so no entry is a sum)."""
    bodies_c = rows[::6] // 6
    cr = system.col_row[cols]
    out = np.zeros((len(rows), len(cols)))
    for side in (0, 1):
        use = np.nonzero(cr[:, side] >= 0)[0]
        local = np.searchsorted(bodies_c, cr[use, side])
        out[(6 * local)[:, None] + np.arange(6), use[:, None]] = system.blocks[cols[use], side]
    return out


def _solve_component(dense, Dr, system, rows, cols, backend, exact_possible: bool = True,
                     sub_dense: np.ndarray | None = None) -> tuple[np.ndarray, str]:
    """Solve one component by the frictionless certificate, dense NNLS or the QP
    (``exact_possible`` False: a body is known to miss equilibrium, so the certificate,
    which needs a zero residual, is skipped).  The component's matrix comes as
    ``sub_dense``, or is sliced from the whole ``dense`` one or the sparse ``Dr``."""
    if sub_dense is not None or dense is not None:
        sub_dense = dense[np.ix_(rows, cols)] if sub_dense is None else sub_dense
        sub = sp.csc_matrix(sub_dense) if len(cols) > NNLS_MAX_COLUMNS else None
    else:
        sub = Dr[rows][:, cols].tocsc()
        sub_dense = sub.toarray() if len(cols) <= 4 * NNLS_MAX_COLUMNS else None
    rhs = system.b[rows]
    choice = backend
    if choice == "auto" and sub_dense is not None:
        x = _normal_only(sub_dense, rhs, system.col_vertex[cols]) if exact_possible else None
        if x is not None:
            return x, "normal"
        choice = "nnls" if len(cols) <= NNLS_MAX_COLUMNS else "qp"
    if choice == "auto":
        choice = "qp"
    if choice == "nnls":
        x = _solve_nnls(sub_dense if sub_dense is not None else sub.toarray(), rhs)
    else:
        x = _solve_qp(sub if sub is not None else sp.csc_matrix(sub_dense), rhs)
    return x, choice


# ------------------------------------------------------------------------- entry point
def check_stability(arr: Arrangement, mu: float = DEFAULT_MU, threshold: float | None = None,
                    backend: str = "auto", side_friction: bool = False,
                    contacts: ContactSet | None = None, tilt_deg: float = 0.0,
                    solve_cache: dict | None = None, verdict_only: bool = False,
                    expect_unstable: bool = False, summary_only: bool = False
                    ) -> StabilityResult:
    """Static equilibrium of ``arr`` under gravity (see the module docstring).

    Parameters
    ----------
    arr : Arrangement
        Its ``fixed`` contacts fuse bodies; all other touching pairs are found from the
        geometry by :func:`pipeline.contacts.find_contacts`.
    mu : float
        Friction coefficient.
    threshold : float, optional
        Stability threshold on E (default ``constants.ENERGY_THRESHOLD``).
    backend : {"auto", "nnls", "qp"}
    side_friction : bool
        Allow friction on vertical face-to-face contacts (plain statics; see the trap).
    contacts : ContactSet, optional
        Precomputed contacts of ``arr``.
    tilt_deg : float
        When > 0, also require equilibrium with gravity tilted by this angle towards
        +-x and +-y (a robustness margin used by the search), to within
        ``threshold * ROBUST_THRESHOLD_REL``: the plain threshold lets a flat body balance
        on a knife edge pass a 2 degree tilt (a 32 cm book half over its support: E = 5e-6
        under the tilt; both engines topple it).
    solve_cache : dict, optional
        Solutions of independent components by digest of their sub-problem, kept by the
        caller across calls (see :func:`solve_energy`); results are identical with or
        without it.
    verdict_only : bool
        Only ``stable`` is needed (the search's nodes): a component that a single body
        proves unstable (its miss with every contact free already exceeds the threshold,
        ``solve_energy(unstable_bound=...)``) is not solved.  ``stable`` is exact; when it
        is False, ``energy`` and the per-body values are then not the minimum.
    expect_unstable : bool
        A hint that the arrangement (refinement's variants) mostly misses equilibrium:
        upright components are solved by NNLS before the certificates, which are skipped
        when it leaves a clear residual (``solve_energy``).  Results are identical.
    summary_only : bool
        Only ``stable``, ``energy`` and ``status`` are needed (refinement's finite
        differences): ``bodies`` is left empty and ``contact_load`` None; the rest is as
        without.

    Returns
    -------
    StabilityResult
        ``stable`` False with ``status`` "interpenetration" when boxes overlap beyond
        the contact tolerance.
    """
    if not np.isfinite(mu) or mu < 0:
        raise InputError(f"--mu: friction coefficient must be a non-negative number, got {mu}")
    threshold = ENERGY_THRESHOLD if threshold is None else float(threshold)
    contacts = find_contacts(arr) if contacts is None else contacts
    fixed_pairs = fixed_node_pairs(arr, contacts)
    bodies = build_bodies(arr, fixed_pairs)
    fixed_mask = np.zeros(contacts.count, bool)
    lookup = contacts.lookup()
    for c in arr.contacts:
        if c.type == "fixed":
            fixed_mask[lookup[c.key]] = True
    system = build_system(arr, contacts, bodies, mu, side_friction, fixed_mask)
    comps = system.components()
    digests = None if solve_cache is None else \
        {id(cols): _component_digest(system, rows, cols) for rows, cols in comps}
    bound = threshold if verdict_only else None
    lam, used = solve_energy(system, backend, components=comps, cache=solve_cache,
                             digests=digests, unstable_bound=bound,
                             expect_unstable=expect_unstable)
    if summary_only:  # E summed as _result sums it, without the per-body records
        energy = _energy(bodies, system, lam)
        result = StabilityResult(energy < threshold and not contacts.penetrations, energy,
                                 threshold, "interpenetration" if contacts.penetrations
                                 else "ok", (), used, mu, contacts.count,
                                 contacts.penetrations, None)
    else:
        result = _result(arr, contacts, bodies, system, lam, threshold, used, mu)
    if tilt_deg > 0 and result.stable:
        # robustness: the arrangement must also stand when gravity leans by tilt_deg
        # towards +-x and +-y (rules out knife-edge solutions such as a table on two
        # diagonal legs, which a volume-minimising search would otherwise pick)
        t = np.radians(tilt_deg)
        F = len(system.free)
        for hx, hy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            b = system.b.copy()
            b[6 * np.arange(F) + 0] = -np.sin(t) * hx
            b[6 * np.arange(F) + 1] = -np.sin(t) * hy
            b[6 * np.arange(F) + 2] = np.cos(t)
            tilted = replace(system, b=b)
            tthr = threshold * ROBUST_THRESHOLD_REL
            lam_t, used_t = solve_energy(tilted, backend, components=comps, cache=solve_cache,
                                         digests=digests,
                                         unstable_bound=None if bound is None else tthr,
                                         certificate=True)
            if _energy(bodies, tilted, lam_t) < tthr:
                continue  # (the full result is only built when it is the answer)
            res_t = _result(arr, contacts, bodies, tilted, lam_t, tthr, used_t, mu)
            if not res_t.stable:
                if summary_only:
                    res_t = replace(res_t, bodies=(), contact_load=None)
                return replace(res_t, status="not robust")
    return result


def _energy(bodies, system, lam) -> float:
    """E of a solution, summed exactly as :func:`_result` sums it."""
    resid = system.residual(lam)
    F = len(system.free)
    body_energy = np.zeros(len(bodies.mass))
    body_energy[system.free] = (resid.reshape(F, 6) ** 2).sum(axis=1) if F else 0.0
    return float(body_energy.sum())


def _result(arr, contacts, bodies, system, lam, threshold, used, mu) -> StabilityResult:
    resid = system.residual(lam)
    F = len(system.free)
    per_row = resid.reshape(F, 6) if F else np.zeros((0, 6))
    body_energy = np.zeros(len(bodies.mass))
    body_energy[system.free] = (per_row ** 2).sum(axis=1)
    phys = (resid * system.row_scale).reshape(F, 6) if F else np.zeros((0, 6))
    rforce = np.zeros(len(bodies.mass))
    rtorque = np.zeros(len(bodies.mass))
    rforce[system.free] = np.linalg.norm(phys[:, :3], axis=1)
    rtorque[system.free] = np.linalg.norm(phys[:, 3:], axis=1)
    energy = float(body_energy.sum())
    e, rf, rt = body_energy.tolist(), rforce.tolist(), rtorque.tolist()
    anchored = bodies.anchored.tolist()
    out = [BodyResidual(c.id, e[g] < threshold, rf[g], rt[g], e[g], anchored[g], g)
           for c, g in zip(arr.cuboids, bodies.of_node[:len(arr.cuboids)].tolist())]
    status = "interpenetration" if contacts.penetrations else "ok"
    stable = energy < threshold and not contacts.penetrations
    load = np.bincount(system.col_contact, weights=lam, minlength=contacts.count) \
        if len(lam) else np.zeros(contacts.count)
    return StabilityResult(stable, energy, threshold, status, tuple(out), used, mu,
                           contacts.count, contacts.penetrations, load)


def contact_force_newtons(arr: Arrangement, mu: float = DEFAULT_MU,
                          side_friction: bool = False) -> tuple[ContactSet, np.ndarray]:
    """Physical contact forces (N) at every interface vertex of a solved arrangement.

    Returns the contact set and ``forces (V, 3)``: the force that node ``b`` applies
    to node ``a`` at each vertex.  Used by tests (forces must sum to the weight).
    """
    contacts = find_contacts(arr)
    bodies = build_bodies(arr, fixed_node_pairs(arr, contacts))
    fixed_mask = np.zeros(contacts.count, bool)
    lookup = contacts.lookup()
    for c in arr.contacts:
        if c.type == "fixed":
            fixed_mask[lookup[c.key]] = True
    system = _unscaled(build_system(arr, contacts, bodies, mu, side_friction, fixed_mask))
    lam, _ = solve_energy(system, "auto")
    forces = np.zeros((len(contacts.vertices), 3))
    np.add.at(forces, system.col_vertex, lam[:, None] * system.col_dir)
    return contacts, forces


def _unscaled(system: EquilibriumSystem) -> EquilibriumSystem:
    """The same system in newtons (rows multiplied back by their scale)."""
    S = sp.diags(system.row_scale)
    return replace(system, _D=(S @ system.D).tocsc(), b=system.b * system.row_scale,
                   row_scale=np.ones_like(system.row_scale), blocks=None, _shared={})


__all__ = ["check_stability", "StabilityResult", "BodyResidual", "build_bodies", "build_system",
           "solve_energy", "EquilibriumSystem", "contact_force_newtons", "is_support_id"]
