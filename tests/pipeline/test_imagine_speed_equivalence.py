"""Speed-ups of the stages after the search that must not change answers: the glue
relaxation with shared solutions and contacts gives what plain checks give."""

from __future__ import annotations

import numpy as np
import pytest

import pipeline.refine as refine_mod
import pipeline.stability as stability
from pipeline.imagine import relax_fixed
from pipeline.model import Arrangement, Contact, ObservedBox, Support, box, ground
from pipeline.stability import check_stability


def _observed(c):
    return c.with_(observed=ObservedBox(c.center, c.size))


def _plain(monkeypatch) -> None:
    """Every stability check from scratch: no contacts passed in, no shared solutions,
    full solves (the reference the cached paths must equal)."""
    real = stability.check_stability

    def plain(arr, mu=0.7, threshold=None, backend="auto", side_friction=False, contacts=None,
              tilt_deg=0.0, solve_cache=None, verdict_only=False):
        return real(arr, mu=mu, threshold=threshold, backend=backend,
                    side_friction=side_friction, tilt_deg=tilt_deg)

    monkeypatch.setattr(stability, "check_stability", plain)
    monkeypatch.setattr(refine_mod, "check_stability", plain)


def _decks() -> Arrangement:
    """Two deck boards glued end to end, each on one pillar (cantilevers), a box on one:
    the joint between the decks is tried, growths fail and refinement takes steps."""
    p0 = _observed(box("p0", (0.0, 0.0, 0.3), (0.2, 0.24, 0.6), object="pillar0"))
    p1 = _observed(box("p1", (0.0, 2.2, 0.3), (0.2, 0.24, 0.6), object="pillar1"))
    d0 = _observed(box("d0", (0.0, 0.5, 0.63), (0.2, 1.2, 0.06), object="deck0"))
    d1 = _observed(box("d1", (0.0, 1.7, 0.63), (0.2, 1.2, 0.06), object="deck1"))
    bx = _observed(box("bx", (0.0, 1.5, 0.7), (0.08, 0.09, 0.08), object="box0"))
    contacts = (Contact("d0", "d1", "fixed"), Contact("d0", "p0"), Contact("d1", "p1"),
                Contact("bx", "d1"), Contact("p0", "ground"), Contact("p1", "ground"))
    return Arrangement((p0, p1, d0, d1, bx), (ground(),), contacts)


def _overhang() -> Arrangement:
    lower = _observed(box("lo", (0, 0, 0.2), (0.4, 0.4, 0.4), object="o1"))
    upper = _observed(box("up", (0, -0.23, 0.5), (0.3, 0.2, 0.2), object="o2"))
    return Arrangement((lower, upper), (ground(),),
                       (Contact("lo", "ground"), Contact("lo", "up", "fixed")))


def _board() -> Arrangement:
    wall = Support("wall:0", (0, 0.5, 0), (0, -1, 0))
    board = _observed(box("board", (0, 0.35, 1.5), (0.6, 0.3, 0.03), object="shelf"))
    return Arrangement((board,), (ground(), wall), (Contact("board", "wall:0", "fixed"),))


@pytest.mark.parametrize("make", [_decks, _overhang, _board])
def test_relax_fixed_with_shared_work_equals_plain_checks(make, monkeypatch):
    arr = make()
    fast = relax_fixed(arr)
    _plain(monkeypatch)
    slow = relax_fixed(arr)
    assert fast[1:] == slow[1:]
    assert fast[0].contacts == slow[0].contacts
    for a, b in zip(fast[0].cuboids, slow[0].cuboids, strict=True):
        assert a.id == b.id
        np.testing.assert_array_equal(a.center, b.center)
        np.testing.assert_array_equal(a.size, b.size)


def test_cluster_load_path_from_the_memo_equals_a_fresh_pass(monkeypatch):
    from tests.pipeline.test_search_speed_equivalence import _shelf, _systems

    calls = []
    real = stability._balance_cluster

    def spy(*args):
        memo = args[-1]
        n = None if memo is None else len(memo)
        out = real(*args)
        if memo is not None:
            calls.append(len(memo) == n)  # True: answered from the memo
        return out

    monkeypatch.setattr(stability, "_balance_cluster", spy)
    rng = np.random.default_rng(2)
    for arr in (_shelf(4), _shelf(3, rng), _shelf(5, rng)):
        memo: dict = {}
        for system in _systems(arr):
            fresh = stability.load_path(system)
            first = stability.load_path(system, memo=memo)
            calls.clear()
            again = stability.load_path(system, memo=memo)
            assert calls and all(calls)  # every cluster came from the memo
            for lam in (first, again):
                assert (lam is None) == (fresh is None)
                if fresh is not None:
                    np.testing.assert_array_equal(lam, fresh)


def test_load_path_floor_gives_the_answers_of_the_full_pass(monkeypatch):
    """A body that cannot balance with all its contacts free ends the load path early
    and skips the frictionless certificate: the same solutions as without."""
    from tests.conftest import overhang_scene
    from tests.pipeline.test_search_speed_equivalence import _random_scene, _systems

    rng = np.random.default_rng(21)
    scenes = [_random_scene(rng) for _ in range(20)]
    scenes += [overhang_scene(0.3), overhang_scene(0.7), _board(), _decks(), _overhang()]
    scenes += [_decks().with_(contacts=tuple(c for c in _decks().contacts if c.type != "fixed"))]
    out, on = {}, stability.LOAD_PATH_FLOOR
    for floor in (on, np.inf):
        monkeypatch.setattr(stability, "LOAD_PATH_FLOOR", floor)
        proofs, res = [], []
        for arr in scenes:
            for system in _systems(arr):
                for rows, _cols in stability._components(system):
                    proof: list = []
                    lam = stability.load_path(system, bodies=rows[::6] // 6, proof=proof)
                    res.append(None if lam is None else lam.copy())
                    proofs += proof
                lam, used = stability.solve_energy(system)
                res += [lam.copy(), used]
            full = check_stability(arr, tilt_deg=2.0)
            res.append((full.stable, full.energy, full.backend))
        out[floor] = (res, proofs)
    (fast, proofs), (slow, none) = out[on], out[np.inf]
    assert proofs and not none  # the floor ended some passes
    assert len(fast) == len(slow)
    for a, b in zip(fast, slow, strict=True):
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b)
        else:
            assert a == b
