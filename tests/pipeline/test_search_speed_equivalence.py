"""Speed-ups that must not change answers: the cluster load-path certificate and the
incremental energy evaluator of refinement."""

from dataclasses import replace

import numpy as np
import pytest

from pipeline.contacts import find_contacts
from pipeline.model import Arrangement, Contact, Cuboid, box, ground
from pipeline.refine import _energy, _Evaluator
from pipeline.stability import (
    _components,
    build_bodies,
    build_system,
    check_stability,
    fixed_node_pairs,
    load_path,
    solve_energy,
)


def _shelf(n_books: int, rng: np.random.Generator | None = None) -> Arrangement:
    """A fused shelf (bottom, top, side) with books standing between its boards, each
    book touching both boards: the shelf, processed first (its centre of mass is higher),
    may rest its top on the books, which then cannot balance one by one."""
    H, T = 0.5, 0.02
    cubs = [box("bottom", (0, 0, T / 2), (0.8, 0.3, T)),
            box("top", (0, 0, T + H + T / 2), (0.8, 0.3, T)),
            box("left", (-0.4 - T / 2, 0, (H + 2 * T) / 2), (T, 0.3, H + 2 * T))]
    x = -0.4
    for k in range(n_books):
        w = 0.03 + 0.01 * (k % 3) if rng is None else float(rng.uniform(0.02, 0.06))
        y = 0.0 if rng is None else float(rng.uniform(-0.02, 0.02))
        cubs.append(box(f"book{k}", (x + w / 2, y, T + H / 2), (w, 0.25, H)))
        x += w
    fixed = (Contact("bottom", "left", "fixed"), Contact("left", "top", "fixed"))
    return Arrangement(tuple(cubs), (ground(),), fixed)


def _systems(arr: Arrangement, tilt_deg: float = 2.0):
    """The equilibrium system of ``arr`` under upright gravity and the four tilts."""
    cs = find_contacts(arr)
    bodies = build_bodies(arr, fixed_node_pairs(arr, cs))
    lookup = cs.lookup()
    fixed = np.zeros(cs.count, bool)
    for c in arr.contacts:
        if c.type == "fixed":
            fixed[lookup[c.key]] = True
    base = build_system(arr, cs, bodies, 0.7, False, fixed)
    F = len(base.free)
    t = np.radians(tilt_deg)
    out = [base]
    for hx, hy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        b = base.b.copy()
        b[6 * np.arange(F) + 0] = -np.sin(t) * hx
        b[6 * np.arange(F) + 1] = -np.sin(t) * hy
        b[6 * np.arange(F) + 2] = np.cos(t)
        out.append(replace(base, b=b))
    return out


def _qp_energy(system) -> float:
    lam, _ = solve_energy(system, "qp")
    r = system.D @ lam - system.b
    return float(r @ r)


def test_cluster_certificate_proves_books_in_a_shelf_where_body_by_body_fails():
    arr = _shelf(4)
    for system in _systems(arr):
        assert load_path(system, max_cluster=1) is None  # body by body: the books fail
        lam = load_path(system)
        assert lam is not None
        assert lam.min() >= 0
        # independent check of the certificate on the assembled matrix
        assert np.linalg.norm(system.D @ lam - system.b) < 1e-9
        assert _qp_energy(system) < 1e-12  # the interior-point QP agrees: E = 0
    assert check_stability(arr, tilt_deg=2.0).stable
    assert check_stability(arr, tilt_deg=2.0, backend="qp").stable


def _random_scene(rng: np.random.Generator) -> Arrangement:
    """Random stacks beside random shelves: stable and unstable cases."""
    if rng.random() < 0.5:
        arr = _shelf(int(rng.integers(2, 7)), rng)
        if rng.random() < 0.5:  # a box on top, possibly overhanging
            s = rng.uniform(0.1, 0.4, 3)
            top = arr.cuboids[1]
            z = top.center[2] + top.size[2] / 2 + s[2] / 2
            arr = arr.with_(cuboids=arr.cuboids + (box("cap", (rng.uniform(-0.5, 0.5), 0, z), s),))
        return arr
    cubs, z, x = [], 0.0, 0.0
    for k in range(int(rng.integers(2, 6))):
        size = rng.uniform(0.2, 0.6, 3)
        x += rng.uniform(-0.6, 0.6) * size[0] if k else 0.0
        cubs.append(box(f"b{k}", (x, rng.uniform(-0.05, 0.05), z + size[2] / 2), size,
                        yaw=rng.uniform(0, 0.6)))
        z += size[2]
    return Arrangement(tuple(cubs), (ground(),))


def test_load_path_certificates_are_exact_and_verdicts_match_the_qp():
    rng = np.random.default_rng(5)
    outcomes = []
    for _ in range(25):
        arr = _random_scene(rng)
        for system in _systems(arr):
            for rows, cols in _components(system):
                lam = load_path(system, bodies=rows[::6] // 6)
                e_qp = _qp_energy(replace(system)) if lam is None else None
                if lam is not None:
                    assert lam[cols].min() >= 0
                    r = system.D[rows][:, cols] @ lam[cols] - system.b[rows]
                    assert np.linalg.norm(r) < 1e-9
                outcomes.append(lam is not None or e_qp < 1e-5)
        auto, qp = check_stability(arr, tilt_deg=2.0), check_stability(arr, tilt_deg=2.0,
                                                                       backend="qp")
        assert auto.stable == qp.stable
    assert 0 < sum(outcomes) < len(outcomes)  # both outcomes were exercised


def _room_variants(seed: int, n: int):
    from eval.benchmarks.search import rooms

    arr = rooms(30, seed)
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        cubs = list(arr.cuboids)
        k = int(rng.integers(len(cubs)))
        c = cubs[k]
        x = np.concatenate([c.center, c.size])
        x[int(rng.integers(6))] += float(rng.choice([-1, 1])) * 1e-3
        cubs[k] = Cuboid(c.id, x[:3], c.rotation, x[3:], c.density, c.object, c.observed,
                         c.extra)
        out.append(arr.with_(cuboids=tuple(cubs)))
    return arr, out


@pytest.mark.parametrize("tilt", [0.0, 2.0])
def test_refine_evaluator_equals_a_plain_check_on_every_variant(tilt):
    base, variants = _room_variants(4, 12)
    energy = _Evaluator(base, 0.7, tilt)
    e0, _, _ = energy(base)
    assert e0 == _energy(base, 0.7, tilt)[0]
    for arr in variants:
        e, _, cs = energy(arr)
        assert e == _energy(arr, 0.7, tilt)[0]  # bitwise: the reuse is exact
        assert cs.pairs == find_contacts(arr).pairs


def test_refine_evaluator_equals_a_plain_check_when_the_energy_is_not_zero():
    from tests.conftest import overhang_scene

    base = overhang_scene(0.6)
    energy = _Evaluator(base, 0.7, 0.0)
    assert energy(base)[0] == _energy(base, 0.7)[0] > 1e-3
    top = base.cuboids[1]
    for dx in (-0.2, -0.05, 0.05):
        moved = top.with_(center=top.center + [dx, 0, 0])
        arr = base.with_(cuboids=(base.cuboids[0], moved))
        e = energy(arr)[0]
        assert e == _energy(arr, 0.7)[0]
        assert (e > 1e-5) == (0.6 + dx > 0.5)  # tips exactly when the overhang passes half


def test_block_relaxation_gives_the_one_by_one_answer_with_fewer_checks(monkeypatch):
    from eval.benchmarks.search import occluded, rooms
    from pipeline.extend import candidate_edges
    from pipeline.priors import run_prior
    from pipeline.search import _Group, search

    arr, _ = run_prior("overlaps", occluded(rooms(30, seed=1001), np.random.default_rng(1)))
    edges = candidate_edges(arr)
    out = {}
    for block in (True, False):
        monkeypatch.setattr(_Group, "BLOCK_RELAX", block)
        out[block] = search(arr, edges, budget=60.0)
    a, b = out[True], out[False]
    assert a.choices == b.choices and a.n_fixed == b.n_fixed and a.stable and b.stable
    assert a.added_volume == b.added_volume
    assert [(c.a, c.b, c.type) for c in a.arrangement.contacts] == \
        [(c.a, c.b, c.type) for c in b.arrangement.contacts]
    assert a.stats.stability_checks < b.stats.stability_checks  # the blocks were used


def test_load_path_memo_returns_what_a_fresh_pass_returns():
    rng = np.random.default_rng(9)
    memo: dict = {}
    hits_possible = 0
    for _ in range(12):
        arr = _random_scene(rng)
        for system in _systems(arr):
            for rows, _cols in _components(system):
                fresh = load_path(system, bodies=rows[::6] // 6)
                for _rep in range(2):  # the second pass is answered from the memo
                    memo_lam = load_path(system, bodies=rows[::6] // 6, memo=memo)
                    assert (fresh is None) == (memo_lam is None)
                    if fresh is not None:
                        np.testing.assert_array_equal(memo_lam, fresh)
                hits_possible += 1
    assert hits_possible > 20 and len(memo) > 0


def test_verdict_only_gives_the_same_verdict_and_skips_solves_it_can_prove(monkeypatch):
    import pipeline.load_path as load_path_mod
    import pipeline.stability as stability

    rng = np.random.default_rng(13)
    floors = []
    real = load_path_mod._body_floor

    def spy(*args):
        floors.append(real(*args))
        return floors[-1]

    # the one-body bound, wherever it is taken: ending a load path, or proving a
    # component cannot balance
    for mod in (stability, load_path_mod):
        monkeypatch.setattr(mod, "_body_floor", spy)
    for _ in range(30):
        arr = _random_scene(rng)
        full = check_stability(arr, tilt_deg=2.0)
        fast = check_stability(arr, tilt_deg=2.0, verdict_only=True)
        assert fast.stable == full.stable
        if fast.stable:  # a stable answer is the full one
            assert fast.energy == full.energy
        else:
            assert fast.energy >= fast.threshold
    assert any(f >= 10 * 1e-5 for f in floors)  # the one-body bound was used
