"""The equilibrium system of an arrangement: rigid bodies, contact forces, the matrix ``D``.

:func:`build_bodies` merges fused cuboids into rigid bodies (anchored when fused to a
support); :func:`build_system` writes, per body, the six balance rows of the contact forces
at every interface vertex (each force a non-negative mix of the edges of an inscribed
friction pyramid; no friction on side contacts, see :mod:`pipeline.stability`) and of the
weight, scale free.  :mod:`pipeline.stability` solves it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .constants import FRICTION_PYRAMID_EDGES, GRAVITY, SIDE_CONTACT_MAX_NZ
from .contacts import ContactSet, cross
from .errors import InputError
from .model import Arrangement


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
    force_unit: float  # newtons per unit of lambda (see :func:`force_unit`)
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
    unit = force_unit(W[free])
    # blocks[c, side] = the 6 scaled equilibrium coefficients of column c on body side
    # (both sides at once: side 0 is body a, pushed along +dir; side 1 is b, along -dir)
    blocks = np.zeros((ncol, 2, 6))
    if len(c_idx):
        du = np.where((s_idx == 0)[:, None], 1.0, -1.0) * dirs[c_idx]
        torque = cross(p[c_idx] - bodies.com[gu], du)
        blocks[c_idx, s_idx, :3] = du * (unit / W[gu])[:, None]
        blocks[c_idx, s_idx, 3:] = torque * (unit / (W[gu] * bodies.size[gu]))[:, None]
    Wf, WLf = W[free], W[free] * bodies.size[free]  # force rows in weights, torque rows
    row_scale = np.stack([Wf, Wf, Wf, WLf, WLf, WLf], axis=1).ravel()
    return EquilibriumSystem(None, b, free, row_scale, unit, col_vertex, m, dirs, contact_bodies,
                             blocks, col_row, bodies.com[free, 2], dict(shared))


def force_unit(weights: np.ndarray) -> float:
    """The force that one unit of ``lambda`` stands for: the geometric mean of the free
    bodies' weights (N; 1 when there are none).

    Rows are balanced in units of each body's own weight; measuring the contact forces in
    a weight of the same scene keeps the columns of ``D`` near 1 at any scale (at 100x a
    column in newtons is about 1e-9 of its row, and NNLS then stops short)."""
    w = weights[weights > 0]
    return float(np.exp(np.log(w).mean())) if len(w) else 1.0


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
    probe = EquilibriumSystem(None, b, free, None, 1.0, col_vertex, m, None, contact_bodies, None,
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
