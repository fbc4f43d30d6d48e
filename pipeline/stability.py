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
each other touch along a vertical edge), whose normal is within 30 degrees of
horizontal (``constants.SIDE_CONTACT_MAX_NZ``: faces that steep hold nothing by the
friction a body's weight presses on them, for any mu below 1.73) and that are not
fixed.  They still push
(normal force), so lateral bracing works; corners and edges along flatter lines keep
friction, so a plank leaning with its edge on a wall keeps the ladder limit :math:`\tan\theta = (1-\mu^2)/(2\mu)` (20.0 degrees for mu = 0.7).  That
exception needs the body to stand on something: a body that no contact pushes upward
(:func:`hanging_contacts`) gets no friction on its corner and edge side contacts either
(a box held at 45 degrees by one edge on the wall and one on a desk's side, squeezed by
the desk standing on the floor: statics accepted it, both engines drop it 0.5 m).  Pass
``side_friction=True`` to get plain statics.  What is left of the trap: a body clamped
between two parallel faces less steep than 60 degrees is still held by a squeeze (both
engines let it slide); telling that squeeze from the weight of a body resting on it
needs the contacts' compliance, which the rigid statics does not model.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from . import workclock
from .constants import (
    DEFAULT_MU,
    ENERGY_THRESHOLD,
    ROBUST_THRESHOLD_REL,
)
from .contacts import ContactSet, find_contacts
from .equilibrium import (  # noqa: F401  (re-exported: the equilibrium system's names)
    _BODY_GROUPING,
    _TOPOLOGY,
    Bodies,
    EquilibriumSystem,
    _body_columns,
    _components,
    build_bodies,
    build_system,
    fixed_node_pairs,
    hanging_contacts,
)
from .errors import InputError
from .load_path import (  # noqa: F401  (re-exported)
    LOAD_PATH_FLOOR,
    _balance_cluster,
    _body_floor,
    _group_ids,
    load_path,
)
from .model import Arrangement, Contact, is_support_id  # noqa: F401  (re-exported)

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
    workclock.charge_stability(len(arr.cuboids))
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


#: A contact carries load in the statics' solution when its load exceeds this share of
#: the largest one (the rest is the solver's rounding).
LOAD_SHARE_MIN = 1e-6


def load_carrying(arr: Arrangement, mu: float = DEFAULT_MU, threshold: float | None = None
                  ) -> tuple[ContactSet, StabilityResult, np.ndarray]:
    """The contacts of ``arr``, the statics' verdict, and per contact whether it carries
    load in the solution (more than :data:`LOAD_SHARE_MIN` of the largest load; none when
    the solve gave no loads)."""
    cs = find_contacts(arr)
    res = check_stability(arr, mu=mu, threshold=threshold, contacts=cs)
    load = res.contact_load if res.contact_load is not None else np.zeros(cs.count)
    top = float(np.max(load)) if len(load) else 0.0
    return cs, res, load > LOAD_SHARE_MIN * top


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


def glue_reasons(arr: Arrangement, mu: float = DEFAULT_MU, tilt_deg: float = 2.0
                 ) -> list[tuple[Contact, list[str], bool]]:
    """Why each glue joint is there: every ``fixed`` contact between different objects
    or with a support, the boxes that cannot be held when it alone is loosened to a plain
    touch, and (when those are none) whether the result then still stands with gravity
    tilted by ``tilt_deg`` (the margin the search demands of every explanation).

    The search takes a ``fixed`` joint between different objects only as a last resort
    (it minimises their number first); this names, per joint, what it holds."""
    objects = {c.id: c.object or c.id for c in arr.cuboids}
    out = []
    for k, c in enumerate(arr.contacts):
        if c.type != "fixed" or (c.a in objects and c.b in objects
                                 and objects[c.a] == objects[c.b]):
            continue
        loose = list(arr.contacts)
        loose[k] = Contact(c.a, c.b, "touch")
        loosened = arr.with_(contacts=tuple(loose))
        res = check_stability(loosened, mu=mu)
        margin = res.stable and check_stability(loosened, mu=mu, tilt_deg=tilt_deg).stable
        out.append((c, [] if res.stable else res.unstable_ids, bool(margin)))
    return out


def _unscaled(system: EquilibriumSystem) -> EquilibriumSystem:
    """The same system in newtons (rows multiplied back by their scale, columns by the
    force unit, so that ``lambda`` is in newtons too)."""
    S = sp.diags(system.row_scale)
    return replace(system, _D=(S @ system.D / system.force_unit).tocsc(),
                   b=system.b * system.row_scale, row_scale=np.ones_like(system.row_scale),
                   force_unit=1.0, blocks=None, _shared={})


__all__ = ["check_stability", "load_carrying", "LOAD_SHARE_MIN", "StabilityResult",
           "BodyResidual", "build_bodies", "build_system", "solve_energy", "EquilibriumSystem",
           "contact_force_newtons", "is_support_id", "glue_reasons"]
