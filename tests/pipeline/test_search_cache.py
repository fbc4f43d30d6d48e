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
