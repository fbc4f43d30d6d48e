"""refine() stops at a hundredth of the stability threshold it is given (issue 20)."""

import numpy as np

from pipeline.model import Arrangement, Contact, ObservedBox, box, ground
from pipeline.refine import refine
from pipeline.stability import check_stability


def _overhang() -> Arrangement:
    # a top box overhanging its base by 55 % of its length (E well above 1e-5)
    base = box("base", (0, 0, 0.5), (1, 1, 1))
    top = box("top", (0.55, 0, 1.1), (1, 1, 0.2))
    top = top.with_(observed=ObservedBox(np.array([0.8, 0, 1.1]), np.array([0.4, 1, 0.2])))
    return Arrangement((base, top), (ground(),), (Contact("base", "ground"),
                                                  Contact("base", "top")))


def test_refine_takes_no_step_when_the_energy_is_already_below_the_given_threshold():
    arr = _overhang()
    e0 = check_stability(arr).energy
    assert e0 > 1e-5  # unstable at the default threshold
    # a threshold a hundred times the energy: nothing to lower
    lazy = refine(arr, max_steps=20, threshold=200 * e0)
    assert lazy.steps == 0 and lazy.energy_after == lazy.energy_before == e0
    assert lazy.arrangement is arr
    # the default threshold refines
    eager = refine(arr, max_steps=20)
    assert eager.steps >= 1 and eager.energy_after < e0 / 10


def test_refine_stops_once_below_a_hundredth_of_the_given_threshold():
    # the first step leaves E = 2e-9: below 1e-5 / 100 (the default stops there), not
    # below 1e-7 / 100 (a stricter threshold takes a second step, to round-off)
    arr = _overhang()
    default = refine(arr, max_steps=20)
    assert default.steps == 1 and 1e-9 < default.energy_after < 1e-7
    strict = refine(arr, max_steps=20, threshold=1e-7)
    assert strict.steps == 2 and strict.energy_after < 1e-20
