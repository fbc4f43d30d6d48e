"""The load-path certificate: loads carried from the top body down, one small NNLS per body.

Exact: when every body balances its own weight and the loads put on it by the bodies it
carries, the energy is zero and the arrangement stands; :func:`load_path` returns the
contact forces that show it (or where the path breaks), and :mod:`pipeline.stability`
falls back to the full solve only there.
"""

from __future__ import annotations

import numpy as np

from .equilibrium import EquilibriumSystem, _body_columns  # noqa: F401


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
