"""Speed-ups of the stages after the search that must not change answers: the glue
relaxation with shared solutions and contacts gives what plain checks give."""

from __future__ import annotations

import numpy as np
import pytest

import pipeline.load_path as load_path_mod
import pipeline.refine as refine_mod
import pipeline.stability as stability
from pipeline.model import Arrangement, Contact, ObservedBox, Support, box, ground
from pipeline.stability import check_stability
from tests.pipeline.priors_util import relax_fixed, run


def _observed(c):
    return c.with_(observed=ObservedBox(c.center, c.size))


def _plain(monkeypatch) -> None:
    """Every stability check from scratch: no contacts passed in, no shared solutions,
    no hints, full solves (the reference the cached paths must equal)."""
    real = stability.check_stability

    def plain(arr, mu=0.7, threshold=None, backend="auto", side_friction=False, contacts=None,
              tilt_deg=0.0, **_hints):
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
    from pipeline.search import finalize

    # as the search leaves it (the glue relaxation runs after it: the gate then judges
    # each edit with its contacts), with the contacts listed above
    given = make()
    arr = finalize(given.with_(contacts=()), [c for c in given.contacts if c.type == "fixed"])
    assert sorted((c.key, c.type) for c in arr.contacts) == \
        sorted((c.key, c.type) for c in given.contacts)
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
        memo = args[12]  # (system, unit, ..., tol, nnls, memo, normal_first)
        n = None if memo is None else len(memo)
        out = real(*args)
        if memo is not None:
            calls.append(len(memo) == n)  # True: answered from the memo
        return out

    monkeypatch.setattr(load_path_mod, "_balance_cluster", spy)  # where load_path calls it
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
        for mod in (stability, load_path_mod):  # read by the load path and the solver
            monkeypatch.setattr(mod, "LOAD_PATH_FLOOR", floor)
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


def test_changed_pairs_are_the_candidate_pairs_with_a_changed_box():
    from eval.benchmarks.search import rooms
    from pipeline.contacts import candidate_pairs, changed_pairs

    arr = rooms(56, 3)
    C, R, S = arr.centers, arr.rotations, arr.sizes
    tol = np.full(len(C), 0.003)
    i, j = candidate_pairs(C, R, S, tol)
    rng = np.random.default_rng(3)
    for n in (1, 2, 5, 20, len(C)):
        changed = np.zeros(len(C), bool)
        changed[rng.choice(len(C), n, replace=False)] = True
        sel = changed[i] | changed[j]
        a, b = changed_pairs(C, R, S, tol, changed)
        np.testing.assert_array_equal(a, i[sel])
        np.testing.assert_array_equal(b, j[sel])


def test_group_ids_equal_numpy_unique():
    rng = np.random.default_rng(4)
    for n in (1, 2, 9, 200):
        for values in (np.sort(rng.integers(0, 30, n)), rng.integers(0, 30, n)):
            u, inv = np.unique(values, return_inverse=True)
            count, ids = stability._group_ids(values)
            assert count == len(u)
            np.testing.assert_array_equal(ids, inv)


def test_with_keeps_the_cuboid_views_only_for_the_same_cuboids():
    from eval.benchmarks.search import rooms

    arr = rooms(30, 1)
    views = (arr.centers, arr.sizes, arr.masses, arr.corners)
    same = arr.with_(contacts=(Contact(arr.ids[0], arr.ids[1], "fixed"),))
    assert all(a is b for a, b in zip(views, (same.centers, same.sizes, same.masses,
                                                same.corners), strict=True))
    grown = arr.cuboids[0].with_(size=arr.cuboids[0].size * 2)
    other = arr.with_(cuboids=(grown, *arr.cuboids[1:]))
    np.testing.assert_array_equal(other.sizes[0], grown.size)
    np.testing.assert_array_equal(other.masses[1:], arr.masses[1:])
    assert other.masses[0] == 8 * arr.masses[0]


def _reference_cost(group, assignment, upto=None):
    """The search's cost as first written (one option at a time, numpy sizes)."""
    n = len(assignment) if upto is None else upto
    fixed = apart = 0
    for e, o, i in zip(group.edges[:n], group.options[:n], assignment[:n], strict=True):
        f, a, _ = group._cost(e, o[i])
        fixed += f
        apart += a
    exts = {}
    for o, i in zip(group.options[:n], assignment[:n], strict=True):
        for x in o[i].extensions:
            k = (x.box, x.axis, x.side)
            exts[k] = max(exts.get(k, (0.0, x))[0], x.length), x
    vol = 0.0
    for (k_box, axis, _side), (length, _x) in exts.items():
        s = group.full.sizes[k_box]
        other = [k for k in range(3) if k != axis]
        vol += length * s[other[0]] * s[other[1]]
    return fixed, group.pieces(assignment, n), apart, vol


def test_search_cost_equals_the_reference_on_random_assignments():
    from eval.benchmarks.search import occluded, rooms
    from pipeline.extend import candidate_edges
    from pipeline.search import SearchStats, _Group, _groups

    arr, _ = run("overlaps", occluded(rooms(30, seed=1001), np.random.default_rng(1)))
    rng = np.random.default_rng(5)
    checked = 0
    for boxes, edges in _groups(len(arr.cuboids), candidate_edges(arr)):
        group = _Group(arr, boxes, edges, 0.7, None, SearchStats())
        for _ in range(20):
            assignment = tuple(int(rng.integers(len(o))) for o in group.options)
            for upto in (None, len(assignment) // 2):
                assert group.cost(assignment, upto) == _reference_cost(group, assignment, upto)
                checked += 1
    assert checked > 20


def test_half_pyramid_certificate_gives_the_tilt_verdicts_of_the_full_solve(monkeypatch):
    """Tilted gravity only needs a verdict: a load path over half of each friction
    pyramid that balances every body proves it; the answers equal the full solves'."""
    from tests.pipeline.test_search_speed_equivalence import _random_scene, _room_variants, _shelf

    rng = np.random.default_rng(8)
    scenes = [_random_scene(rng) for _ in range(20)] + [_shelf(4), _shelf(6, rng)]
    scenes += [v.with_(contacts=()) for v in _room_variants(6, 4)[1]]
    real = stability.solve_energy
    used = []

    def spy(*args, certificate=False, **kwargs):
        used.append(certificate)
        return real(*args, certificate=certificate, **kwargs)

    def without(*args, certificate=False, **kwargs):
        return real(*args, **kwargs)

    out = {}
    for name, fn in (("with", spy), ("without", without)):
        monkeypatch.setattr(stability, "solve_energy", fn)
        cache: dict = {}
        out[name] = [check_stability(arr, tilt_deg=2.0, solve_cache=cache, verdict_only=quick)
                     for arr in scenes for quick in (False, True)]
    assert any(used)  # the tilts went through the certificate
    for a, b in zip(out["with"], out["without"], strict=True):
        assert (a.stable, a.status, a.unstable_ids) == (b.stable, b.status, b.unstable_ids)
        if a.stable:  # the answer is the upright one, untouched
            assert a.energy == b.energy and a.backend == b.backend
            np.testing.assert_array_equal(a.contact_load, b.contact_load)


def test_expect_unstable_hint_gives_identical_results():
    """NNLS before the certificates, kept when it leaves a clear residual: the same
    result as the full order, on stable and unstable arrangements."""
    from tests.conftest import overhang_scene
    from tests.pipeline.test_search_speed_equivalence import _random_scene

    rng = np.random.default_rng(17)
    scenes = [_random_scene(rng) for _ in range(20)]
    scenes += [overhang_scene(f) for f in (0.2, 0.45, 0.55, 0.8)] + [_decks(), _board()]
    shortcut = 0
    for arr in scenes:
        for tilt in (0.0, 2.0):
            plain = check_stability(arr, tilt_deg=tilt)
            hinted = check_stability(arr, tilt_deg=tilt, expect_unstable=True)
            assert (plain.stable, plain.energy, plain.status, plain.backend) == \
                (hinted.stable, hinted.energy, hinted.status, hinted.backend)
            assert plain.bodies == hinted.bodies
            np.testing.assert_array_equal(plain.contact_load, hinted.contact_load)
            shortcut += plain.energy > 1e-3
    assert shortcut > 5


def test_contacts_of_one_box_variants_in_one_batch_equal_one_by_one():
    from eval.benchmarks.search import rooms
    from pipeline.contacts import find_contacts, update_contacts, update_contacts_of_one
    from pipeline.refine import _with_params

    rng = np.random.default_rng(6)
    fields = ("a", "b", "normal", "tangent_u", "tangent_v", "vertices", "vertex_contact", "gap")
    checked = 0
    for arr in (_decks(), rooms(30, 2)):
        cs = find_contacts(arr)
        scale = arr.scale_length()
        for k in rng.choice(len(arr.cuboids), min(5, len(arr.cuboids)), replace=False):
            c = arr.cuboids[k]
            x0 = np.concatenate([c.center, c.size])
            variants = []
            for h in (1e-3 * scale, 0.1 * scale, -0.3 * scale):
                for p in range(6):
                    x = x0.copy()
                    x[p] += h
                    variants.append(_with_params(arr, k, x[:3], x[3:]))
            variants.append(arr)  # unchanged: answered on its own
            for v, got in zip(variants, update_contacts_of_one(variants, arr, cs, k),
                              strict=True):
                ref = update_contacts(v, arr, cs)
                for f in fields:
                    np.testing.assert_array_equal(getattr(got, f), getattr(ref, f))
                assert got.penetrations == ref.penetrations
                checked += 1
    assert checked > 100


def test_inherited_views_equal_fresh_ones():
    from eval.benchmarks.search import rooms

    arr = rooms(30, 4)
    _ = arr.corners  # computed on the base
    cubs = list(arr.cuboids)
    for k in (0, 7, 19):
        c = cubs[k]
        cubs[k] = c.with_(center=c.center + 0.01, size=c.size * 1.1)
    derived = arr.with_(cuboids=tuple(cubs)).inherit_views(arr)
    fresh = arr.with_(cuboids=tuple(cubs))
    for name in ("centers", "rotations", "sizes", "corners"):
        np.testing.assert_array_equal(getattr(derived, name), getattr(fresh, name))
        assert not getattr(derived, name).flags.writeable


def test_summary_only_checks_give_the_full_stable_energy_and_status():
    from tests.conftest import overhang_scene
    from tests.pipeline.test_search_speed_equivalence import _random_scene

    rng = np.random.default_rng(23)
    scenes = [_random_scene(rng) for _ in range(15)] + [overhang_scene(0.55), _decks()]
    for arr in scenes:
        for tilt in (0.0, 2.0):
            full = check_stability(arr, tilt_deg=tilt)
            short = check_stability(arr, tilt_deg=tilt, summary_only=True)
            assert (short.stable, short.energy, short.status, short.backend) == \
                (full.stable, full.energy, full.status, full.backend)
            assert short.bodies == () and short.contact_load is None


def test_same_object_pair_edges_are_those_of_all_pairs():
    from eval.benchmarks.search import occluded, rooms
    from pipeline.extend import MAX_EXTENSION_REL, pair_edges

    arr = occluded(rooms(56, seed=1001), np.random.default_rng(1))
    max_ext = MAX_EXTENSION_REL * arr.scale_length()
    every = [e for e in pair_edges(arr, max_ext) if e.same_object]
    assert every and pair_edges(arr, max_ext, same_object=True) == every


def test_remembered_body_grouping_equals_a_fresh_union_find():
    from tests.pipeline.test_search_speed_equivalence import _shelf

    arr = _shelf(4)
    cs = find_contacts_of(arr)
    fixed = stability.fixed_node_pairs(arr, cs)
    stability._BODY_GROUPING.clear()
    fresh = stability.build_bodies(arr, fixed)
    again = stability.build_bodies(arr, fixed)  # from the remembered grouping
    assert stability._BODY_GROUPING
    for f in ("of_node", "anchored", "mass", "com", "size"):
        np.testing.assert_array_equal(getattr(fresh, f), getattr(again, f))


def find_contacts_of(arr):
    from pipeline.contacts import find_contacts

    return find_contacts(arr)


def test_systems_from_a_remembered_topology_equal_fresh_ones():
    from pipeline.contacts import find_contacts
    from tests.pipeline.test_search_speed_equivalence import _room_variants

    base, variants = _room_variants(2, 3)
    for arr in (base, *variants):
        arr = arr.with_(contacts=())
        cs = find_contacts(arr)
        bodies = stability.build_bodies(arr, [])
        stability._TOPOLOGY.clear()
        fresh = stability.build_system(arr, cs, bodies, 0.7)
        again = stability.build_system(arr, cs, bodies, 0.7)  # topology remembered
        assert stability._TOPOLOGY
        for f in ("b", "free", "row_scale", "col_vertex", "col_contact", "col_dir",
                  "contact_bodies", "blocks", "col_row", "free_height"):
            np.testing.assert_array_equal(getattr(fresh, f), getattr(again, f))
        fresh_comps = stability._components(fresh)
        assert len(again.components()) == len(fresh_comps)
        for (r1, c1), (r2, c2) in zip(again.components(), fresh_comps, strict=True):
            np.testing.assert_array_equal(r1, r2)
            np.testing.assert_array_equal(c1, c2)
