"""Random arrangements: seeded, in contact exactly where listed, margins from closed forms."""

from __future__ import annotations

import zlib

import numpy as np
import pytest

from pipeline.arrangement_io import dumps
from pipeline.contacts import find_contacts
from pipeline.stability import check_stability
from synth_scenes.random_arrangements import (
    KINDS,
    ladder_limit_deg,
    leaning_plank,
    overhang,
    random_arrangement,
    with_yaw,
    yawed_on_edge,
)


def test_same_seed_same_arrangements() -> None:
    a = [dumps(random_arrangement(np.random.default_rng(11))) for _ in range(2)]
    assert a[0] == a[1]
    r1, r2 = np.random.default_rng(5), np.random.default_rng(5)
    assert [dumps(random_arrangement(r1)) for _ in range(20)] == \
           [dumps(random_arrangement(r2)) for _ in range(20)]
    assert dumps(random_arrangement(np.random.default_rng(6))) != \
           dumps(random_arrangement(np.random.default_rng(7)))


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_listed_contacts_are_exactly_the_touching_pairs(kind: str) -> None:
    rng = np.random.default_rng(zlib.crc32(kind.encode()))
    for _ in range(12):
        arr = random_arrangement(rng, kind)
        assert arr.meta["kind"] == kind
        found = find_contacts(arr)
        assert not found.penetrations
        assert {tuple(sorted(p)) for p in found.pairs} == {c.key for c in arr.contacts}


def test_kinds_cover_stable_and_unstable_and_near_threshold() -> None:
    rng = np.random.default_rng(0)
    arrs = [random_arrangement(rng) for _ in range(120)]
    assert {a.meta["kind"] for a in arrs} == set(KINDS)
    verdicts = [check_stability(a).stable for a in arrs]
    assert 0.3 < np.mean(verdicts) < 0.85
    margins = np.array([a.meta["margin"] for a in arrs if a.meta["margin"] is not None])
    assert np.mean(np.abs(margins) < 0.1) > 0.15  # many cases close to tipping


def test_stack_margin_sign_matches_statics_outside_a_narrow_band() -> None:
    """The closed-form stack margin and the equilibrium solver agree on the verdict."""
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(80):
        arr = random_arrangement(rng, str(rng.choice(["stack", "overhang", "counterweight"])))
        m = arr.meta["margin"]
        if abs(m) < 0.01:
            continue
        assert check_stability(arr).stable == (m > 0), (arr.meta, dumps(arr))
        checked += 1
    assert checked > 60


def test_builders_closed_forms() -> None:
    assert overhang(0.49).meta["margin"] == pytest.approx(np.arctan(0.02))
    assert yawed_on_edge(0.003).meta["margin"] == pytest.approx(-np.arctan(0.06))
    assert ladder_limit_deg(0.7) == pytest.approx(20.0160, abs=1e-4)  # atan(0.51 / 1.4)
    # thick plank: moments about the floor contact, by hand for t / L = 0.08
    assert ladder_limit_deg(0.7, 0.08) == pytest.approx(
        np.degrees(np.arctan(0.51 / (1.4 + 1.49 * 0.08))), abs=1e-12)
    # the column tips as a whole about its base edge: atan(0.05 / 0.5), COM 0.5 m up
    from synth_scenes.random_arrangements import column

    assert column(10).meta["margin"] == pytest.approx(np.arctan(0.1))
    plank = leaning_plank(23.0)
    c = plank.cuboids[0]
    corners = c.corners()
    assert corners[:, 0].min() == pytest.approx(0.0, abs=1e-12)  # on the wall x = 0
    assert corners[:, 2].min() == pytest.approx(0.0, abs=1e-12)  # on the ground
    long_axis = c.rotation[:, 2]
    assert np.degrees(np.arcsin(long_axis[2])) == pytest.approx(23.0)
    turned = with_yaw(overhang(0.3), 0.7)
    assert check_stability(turned).stable and not check_stability(with_yaw(overhang(0.7), 0.7)).stable
