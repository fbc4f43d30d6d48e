"""Incremental contacts and cached component solves equal the full computations."""

import numpy as np
import pytest

from pipeline.contacts import find_contacts, update_contacts
from pipeline.model import Arrangement, Cuboid, box, ground
from pipeline.stability import check_stability


def _room(seed: int) -> Arrangement:
    """A ground-truth synthetic room (many touching pairs)."""
    from eval.benchmarks.search import rooms

    return rooms(30, seed)


def _edit(arr: Arrangement, rng: np.random.Generator, n: int) -> Arrangement:
    """Grow ``n`` random cuboids by random amounts along random local axes."""
    cubs = list(arr.cuboids)
    for k in rng.choice(len(cubs), size=n, replace=False):
        c = cubs[k]
        axis = int(rng.integers(3))
        grow = float(rng.uniform(-0.2, 0.3)) * c.size[axis]
        size = c.size.copy()
        size[axis] += grow
        center = c.center + c.rotation[:, axis] * grow / 2 * rng.choice([-1.0, 1.0])
        cubs[k] = Cuboid(c.id, center, c.rotation, size, c.density, c.object, c.observed,
                         c.extra)
    return arr.with_(cuboids=tuple(cubs))


def _assert_same(a, b):
    assert a.names == b.names and a.n_cuboids == b.n_cuboids
    np.testing.assert_array_equal(a.a, b.a)
    np.testing.assert_array_equal(a.b, b.b)
    np.testing.assert_array_equal(a.vertex_contact, b.vertex_contact)
    for f in ("normal", "tangent_u", "tangent_v", "vertices", "gap"):
        np.testing.assert_allclose(getattr(a, f), getattr(b, f), rtol=0, atol=1e-12)
    assert [p[:2] for p in a.penetrations] == [p[:2] for p in b.penetrations]
    np.testing.assert_allclose([p[2] for p in a.penetrations], [p[2] for p in b.penetrations],
                               atol=1e-12)


@pytest.mark.parametrize("seed", [3, 11])
def test_update_contacts_equals_full_on_random_edits(seed):
    rng = np.random.default_rng(seed)
    base = _room(seed)
    base_cs = find_contacts(base)
    assert base_cs.count > 10
    seen_changes = 0
    for n in (1, 2, 3, 1, 4):
        arr = _edit(base, rng, n)
        full = find_contacts(arr)
        inc = update_contacts(arr, base, base_cs)
        _assert_same(inc, full)
        seen_changes += int(full.pairs != base_cs.pairs or len(full.penetrations)
                            != len(base_cs.penetrations))
        # chained: the edited one becomes the base of the next edit
        base, base_cs = arr, inc
    assert seen_changes > 0  # the edits did change the contact structure


def test_update_contacts_unchanged_returns_base_and_rejects_other_scenes():
    arr = Arrangement((box("a", (0, 0, 0.5), (1, 1, 1)), box("b", (0, 0, 1.5), (1, 1, 1))),
                      (ground(),))
    cs = find_contacts(arr)
    assert update_contacts(arr, arr, cs) is cs
    other = Arrangement((box("x", (0, 0, 0.5), (1, 1, 1)), box("b", (0, 0, 1.5), (1, 1, 1))),
                        (ground(),))
    with pytest.raises(ValueError):
        update_contacts(other, arr, cs)


def test_solve_cache_gives_identical_results():
    base = _room(5)
    rng = np.random.default_rng(5)
    cache: dict = {}
    for n in (0, 1, 2, 0):
        arr = _edit(base, rng, n) if n else base
        cs = find_contacts(arr)
        if cs.penetrations:
            continue
        plain = check_stability(arr, contacts=cs, tilt_deg=2.0)
        cached = check_stability(arr, contacts=cs, tilt_deg=2.0, solve_cache=cache)
        again = check_stability(arr, contacts=cs, tilt_deg=2.0, solve_cache=cache)
        for r in (cached, again):
            assert r.stable == plain.stable and r.status == plain.status
            assert r.energy == pytest.approx(plain.energy, abs=1e-12)
            np.testing.assert_allclose(r.contact_load, plain.contact_load, atol=1e-12)
    assert len(cache) > 0


def test_floating_shortcut_agrees_with_the_full_check():
    """Every assignment of the Figure 8 scene: quick verdicts equal full-check verdicts."""
    import itertools

    from pipeline.extend import candidate_edges
    from pipeline.search import SearchStats, _Group

    arr = Arrangement((box("A", (0, 0, 0.25), (1, 1, 0.5)),
                       box("B", (0.1, 0, 0.85), (0.6, 0.6, 0.3))), (ground(),))
    edges = candidate_edges(arr)
    quick = _Group(arr, [0, 1], edges, 0.7, None, SearchStats())
    full = _Group(arr, [0, 1], edges, 0.7, None, SearchStats())
    floating = 0
    for assignment in itertools.product(*(range(len(o)) for o in quick.options)):
        q_ok, q_res = quick.evaluate(assignment)
        f_ok, f_res = full.evaluate(assignment, quick=False)
        assert q_ok == f_ok
        if q_res == "floating":
            floating += 1
            assert f_res.energy >= 1.0  # a body with no contact carries its whole weight
    assert floating > 0


def test_prune_penetrating_matches_one_extension_at_a_time():
    from pipeline.contacts import pair_tolerance, sat_separation
    from pipeline.extend import MAX_EXTENSION_REL, pair_edges, prune_penetrating, support_edges

    arr = _room(7)
    arr = arr.with_(cuboids=tuple(c.with_(size=c.size * [1, 1, 0.8]) for c in arr.cuboids))
    me = MAX_EXTENSION_REL * arr.scale_length()
    edges = pair_edges(arr, me) + support_edges(arr, me)
    kept, rejected = prune_penetrating(arr, edges)
    C, R, S = arr.centers, arr.rotations, arr.sizes
    K = len(C)

    def penetrates(x) -> bool:  # the extension applied alone, against every other box
        off = np.zeros((3, 2))
        off[x.axis, x.side] = x.length
        size = S[x.box] + off.sum(axis=1)
        cen = C[x.box] + R[x.box] @ ((off[:, 1] - off[:, 0]) / 2.0)
        others = np.array([k for k in range(K) if k != x.box])
        n = len(others)
        tol = pair_tolerance(np.broadcast_to(size, (n, 3)), S[others])
        sep, _, _ = sat_separation(np.broadcast_to(cen, (n, 3)), np.broadcast_to(R[x.box], (n, 3, 3)),
                                   np.broadcast_to(size / 2, (n, 3)), C[others], R[others],
                                   S[others] / 2, tol)
        return bool(np.any(sep < -tol))

    expected = []
    n_rejected = 0
    for e in edges:
        keep = [o for o in e.options if not any(penetrates(x) for x in o.extensions)]
        n_rejected += len(e.options) - len(keep)
        if any(o.type != "none" for o in keep):
            expected.append((e.a, e.b, tuple(keep)))
    assert n_rejected == rejected and n_rejected > 0
    assert [(e.a, e.b, e.options) for e in kept] == expected
