"""The same verdict at every unit of length: analytic statics, MuJoCo and PyBullet on the
demo scene (stands) and a 70 % overhang (falls) scaled from 0.001x to 1000x; the engines'
budget, progress lines and refusals."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.errors import InputError
from pipeline.model import Arrangement, Cuboid, Support
from pipeline.stability import check_stability
from simulate import settling
from simulate.engines import settle
from tests.conftest import overhang_scene

pytest.importorskip("mujoco")
pytest.importorskip("pybullet")

ALL_SCALES = (0.001, 0.01, 0.1, 1.0, 10.0, 100.0, 1000.0)
QUICK_SCALES = (0.001, 1.0, 1000.0)


def scaled(arr: Arrangement, s: float) -> Arrangement:
    return arr.with_(
        cuboids=tuple(Cuboid(c.id, c.center * s, c.rotation, c.size * s, c.density, c.object)
                      for c in arr.cuboids),
        supports=tuple(Support(p.id, p.point * s, p.normal) for p in arr.supports))


@pytest.fixture(scope="module")
def demo_scene() -> Arrangement:
    from synth_scenes.truth import sample_scene

    gt = sample_scene("demo", np.random.default_rng(2), seed=2)
    assert gt.status == "ok"
    return gt.arrangement


def verdicts(arr: Arrangement) -> dict[str, bool]:
    out = {"analytic": check_stability(arr).stable}
    for engine in ("mujoco", "pybullet"):
        r = settle(arr, engine)
        assert r.status == "ok"
        out[engine] = r.stable
    return out


def _check_scale(demo_scene: Arrangement, s: float) -> None:
    assert verdicts(scaled(demo_scene, s)) == {"analytic": True, "mujoco": True,
                                               "pybullet": True}
    assert verdicts(scaled(overhang_scene(0.7), s)) == {"analytic": False, "mujoco": False,
                                                        "pybullet": False}


@pytest.mark.parametrize("s", QUICK_SCALES)
def test_same_verdicts_at_every_scale(demo_scene, s):
    _check_scale(demo_scene, s)


@pytest.mark.slow
@pytest.mark.parametrize("s", sorted(set(ALL_SCALES) - set(QUICK_SCALES)))
def test_same_verdicts_at_every_scale_sweep(demo_scene, s):
    _check_scale(demo_scene, s)


def test_motions_come_back_in_the_scenes_own_units():
    small = settle(scaled(overhang_scene(0.7), 0.001), "mujoco")
    unit = settle(overhang_scene(0.7), "mujoco")
    assert small.length_scale == 1000.0 and unit.length_scale == 1.0
    top = {b.id: b for b in small.bodies}["top"]
    top1 = {b.id: b for b in unit.bodies}["top"]
    # the same motion in millimetres: within float noise of a thousandth of the 1x one
    assert top.translation == pytest.approx(top1.translation / 1000, rel=1e-6)
    assert top.rotation_deg == pytest.approx(top1.rotation_deg, rel=1e-6)
    assert small.to_json()["length_scale"] == 1000.0 and "length_scale" not in unit.to_json()


def test_engine_frame_is_the_identity_in_range_and_a_power_of_ten_outside():
    arr = overhang_scene(0.3)
    assert settling.engine_frame(arr) == (arr, 1.0, 1.0)
    s_arr, s, r = settling.engine_frame(scaled(arr, 1e-3))
    assert (s, r) == (1000.0, 1.0)
    np.testing.assert_allclose(s_arr.sizes, arr.sizes, rtol=1e-12)
    light = arr.with_(cuboids=tuple(c.with_(density=0.05) for c in arr.cuboids))
    assert settling.engine_frame(light)[1:] == (1.0, 1e5)
    with pytest.raises(InputError, match="cannot simulate edges from"):
        settling.engine_frame(arr.with_(cuboids=(arr.cuboids[0].with_(size=np.array(
            [1e-7, 1.0, 1.0])),)))


def test_budget_refuses_early_with_the_estimate():
    with pytest.raises(InputError, match=r"mujoco: settling 2 cuboids would take about \d+ s, "
                                         r"more than the budget of 0.0001 s"):
        settle(overhang_scene(0.3), "mujoco", budget=1e-4)
    assert settle(overhang_scene(0.3), "mujoco", budget=600).stable


@pytest.mark.parametrize("engine", ["mujoco", "pybullet"])
def test_progress_lines_are_drawn(engine, monkeypatch):
    monkeypatch.setattr(settling, "PROGRESS_EVERY", 0.0)
    lines: list[str] = []
    settle(overhang_scene(0.3), engine, progress=lines.append)
    assert lines and all(line.startswith(f"{engine}: ") and " steps, " in line
                         for line in lines)
