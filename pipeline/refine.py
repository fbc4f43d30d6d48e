r"""Refining cuboid parameters under contact constraints (paper section 4.3, eq. 4).

With the contact graph fixed, the stability energy :math:`E` is lowered by moving one
cuboid at a time.  Each cuboid's parameters are its centre and its full extents
(rotation kept); the numerical gradient of :math:`E` is taken for the cuboids of the
bodies that carry residual energy, the cuboid with the largest gradient norm is
chosen, and its step :math:`-\alpha \nabla E / \|\nabla E\|` is projected by a small QP

.. math::  \min_\delta \|\delta - \delta_0\|^2 \quad \text{s.t.} \quad
           J_c\,\delta = 0 \;(\text{every touching face stays touching}),\quad
           G\,\delta \le h \;(\text{the box keeps containing its observed box}),

solved with qpsolvers (OSQP, or Clarabel).  For a contact with unit normal :math:`n`
the gap along :math:`n` is linear in the centres and extents,
:math:`g = n\cdot(c_a - c_b) - \tfrac12\sum_k |n\cdot r_{a,k}| s_{a,k} -
\tfrac12\sum_k |n\cdot r_{b,k}| s_{b,k}` (the second box term is absent for a
support), which gives the rows of :math:`J_c`.  A step is kept only when it lowers E
(halving :math:`\alpha` up to 6 times); refinement stops when E is below a hundredth
of the threshold or after ``max_steps``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import workclock
from .contacts import ContactSet, find_contacts, update_contacts, update_contacts_of_one
from .errors import InputError
from .model import Arrangement, Cuboid
from .stability import check_stability


@dataclass(frozen=True)
class RefineResult:
    arrangement: Arrangement
    energy_before: float
    energy_after: float
    steps: int
    evaluations: int


def _with_params(arr: Arrangement, k: int, center: np.ndarray, size: np.ndarray) -> Arrangement:
    c = arr.cuboids[k]
    cubs = list(arr.cuboids)
    cubs[k] = Cuboid(c.id, center, c.rotation, np.maximum(size, 1e-4), c.density, c.object,
                     c.observed, c.extra)
    return arr.with_(cuboids=tuple(cubs)).inherit_views(arr)


#: the per-refinement cache of component solutions is cleared beyond this many entries
SOLVE_CACHE_MAX = 4096


class _Evaluator:
    """E of variants of one arrangement that differ from a base in a cuboid or two.

    Exact reuse, so results equal plain ``check_stability(arr, ...)``: contacts are
    updated from the base's (:func:`pipeline.contacts.update_contacts` equals
    :func:`pipeline.contacts.find_contacts`), and components of the equilibrium that a
    move leaves unchanged take their solution from a digest-keyed cache
    (``check_stability(solve_cache=...)``).
    """

    def __init__(self, arr: Arrangement, mu: float, tilt_deg: float,
                 contacts: ContactSet | None = None, cache: dict | None = None) -> None:
        self.mu, self.tilt_deg = mu, tilt_deg
        self.cache: dict[bytes, tuple] = {} if cache is None else cache
        self.rebase(arr, find_contacts(arr) if contacts is None else contacts)

    def rebase(self, arr: Arrangement, contacts: ContactSet) -> None:
        self.base, self.base_contacts = arr, contacts

    def contacts(self, arr: Arrangement) -> ContactSet:
        if arr is self.base:
            return self.base_contacts
        return update_contacts(arr, self.base, self.base_contacts)

    def variants(self, arrs: list[Arrangement], k: int) -> list[ContactSet]:
        """Contacts of variants of the base that differ in cuboid ``k`` (one batch)."""
        return update_contacts_of_one(arrs, self.base, self.base_contacts, k)

    def __call__(self, arr: Arrangement, cs: ContactSet | None = None, summary: bool = False
                 ) -> tuple[float, object, ContactSet]:
        """(E, stability result, contacts) of ``arr``; ``summary``: only E is needed."""
        cs = self.contacts(arr) if cs is None else cs
        if len(self.cache) > SOLVE_CACHE_MAX:
            self.cache.clear()
        try:
            res = check_stability(arr, mu=self.mu, tilt_deg=self.tilt_deg, contacts=cs,
                                  solve_cache=self.cache, expect_unstable=True,
                                  summary_only=summary)
        except InputError:  # a fixed pair pulled apart
            return float("inf"), None, cs
        if res.status != "ok":
            return float("inf"), res, cs
        return res.energy, res, cs


def _energy(arr: Arrangement, mu: float, tilt_deg: float = 0.0) -> tuple[float, object]:
    try:
        res = check_stability(arr, mu=mu, tilt_deg=tilt_deg)
    except InputError:  # a fixed pair pulled apart
        return float("inf"), None
    if res.status != "ok":
        return float("inf"), res
    return res.energy, res


def _constraints(arr: Arrangement, k: int, cs: ContactSet | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Equality rows (touching contacts of box k) and containment inequalities (G, h)."""
    cs = find_contacts(arr) if cs is None else cs
    c = arr.cuboids[k]
    rows = []
    for m in range(cs.count):
        a, b = int(cs.a[m]), int(cs.b[m])
        if k not in (a, b):
            continue
        n = cs.normal[m] if a == k else -cs.normal[m]  # pointing into box k
        row = np.zeros(6)
        row[:3] = n
        row[3:] = -0.5 * np.abs(c.rotation.T @ n)
        rows.append(row)
    A = np.array(rows) if rows else np.zeros((0, 6))
    G, h = [], []
    if c.observed is not None:
        R = c.rotation
        lo = R.T @ c.observed.center - c.observed.size / 2
        hi = R.T @ c.observed.center + c.observed.size / 2
        local = R.T @ c.center
        for ax in range(3):
            # (local + d_local) + (s + ds)/2 >= hi  ->  -d_local - ds/2 <= local + s/2 - hi
            g = np.zeros(6)
            g[:3] = -R[:, ax]
            g[3 + ax] = -0.5
            G.append(g)
            h.append(local[ax] + c.size[ax] / 2 - hi[ax])
            g = np.zeros(6)
            g[:3] = R[:, ax]
            g[3 + ax] = -0.5
            G.append(g)
            h.append(c.size[ax] / 2 - local[ax] + lo[ax])
    return A, np.array(G) if G else np.zeros((0, 6)), np.maximum(np.array(h), 0.0) if h else np.zeros(0)


def _project(delta0: np.ndarray, A: np.ndarray, G: np.ndarray, h: np.ndarray) -> np.ndarray | None:
    from qpsolvers import solve_qp

    kwargs = {}
    if len(A):
        kwargs.update(A=A, b=np.zeros(len(A)))
    if len(G):
        kwargs.update(G=G, h=h)
    import scipy.sparse as sp

    kwargs = {k: (sp.csc_matrix(v) if k in ("A", "G") else v) for k, v in kwargs.items()}
    x = solve_qp(sp.identity(6, format="csc"), -delta0, solver="clarabel", **kwargs)
    return None if x is None else np.asarray(x)


def refine(arr: Arrangement, mu: float = 0.7, max_steps: int = 20, threshold: float | None = None,
           tilt_deg: float = 0.0, deadline: float | None = None,
           contacts: ContactSet | None = None, solve_cache: dict | None = None
           ) -> RefineResult:
    """Lower the stability energy of ``arr`` keeping its contacts (see module docstring).

    Steps stop once the energy is below a hundredth of ``threshold`` (the stability
    threshold on the energy; None: :data:`pipeline.constants.ENERGY_THRESHOLD`).

    With ``tilt_deg`` > 0 the energy is that of the first tilt of gravity by that angle
    under which the arrangement fails (``check_stability(tilt_deg=...)``): the result then
    stands with a margin.  ``deadline`` (a :func:`pipeline.workclock.now` value) stops the steps
    early; the best arrangement so far is returned.  ``contacts`` (those of ``arr``) and
    ``solve_cache`` (component solutions kept by the caller, see ``check_stability``)
    only save work.
    """

    from .constants import ENERGY_THRESHOLD

    threshold = ENERGY_THRESHOLD if threshold is None else float(threshold)
    energy = _Evaluator(arr, mu, tilt_deg, contacts, solve_cache)
    E0, res, _ = energy(arr)
    evals = 1
    E = E0
    steps = 0
    scale = arr.scale_length()
    h_fd = 1e-3 * scale
    while steps < max_steps and np.isfinite(E) and E > threshold / 100:
        if deadline is not None and workclock.now() > deadline:
            break
        # cuboids of bodies that carry energy worth lowering (round-off residues of
        # 1e-30 do not: each hot cuboid costs twelve evaluations)
        hot = [k for k, b in enumerate(res.bodies) if b.energy > threshold / 100]
        best = None
        for k in hot:
            if best is not None and deadline is not None and workclock.now() > deadline:
                break
            c = arr.cuboids[k]
            x0 = np.concatenate([c.center, c.size])
            grad = np.zeros(6)
            moves, trials = [], []
            for p in range(6):
                for sgn in (1, -1):
                    x = x0.copy()
                    x[p] += sgn * h_fd
                    moves.append((p, sgn))
                    trials.append(_with_params(arr, k, x[:3], x[3:]))
            for (p, sgn), trial, cs in zip(moves, trials, energy.variants(trials, k),
                                           strict=True):
                e, _, _ = energy(trial, cs, summary=True)
                evals += 1
                grad[p] += sgn * (e if np.isfinite(e) else E) / (2 * h_fd)
            if best is None or np.linalg.norm(grad) > np.linalg.norm(best[1]):
                best = (k, grad)
        if best is None or np.linalg.norm(best[1]) == 0:
            break
        k, grad = best
        A, G, hh = _constraints(arr, k, energy.contacts(arr))
        c = arr.cuboids[k]
        improved = False
        alpha = 0.05 * scale
        for _ in range(6):
            delta = _project(-alpha * grad / np.linalg.norm(grad), A, G, hh)
            if delta is None:
                break
            trial = _with_params(arr, k, c.center + delta[:3], c.size + delta[3:])
            e, r, cs = energy(trial)
            evals += 1
            if e < E:
                arr, E, res, improved = trial, e, r, True
                energy.rebase(trial, cs)
                break
            alpha /= 2
        steps += 1
        if not improved:
            break
    return RefineResult(arr, E0, E, steps, evals)
