"""The contract every prior keeps (docs/DESIGN.md, "Priors beyond the paper").

Each prior states its principle and declares frozen parameters; every edit any prior
proposes passes one gate, :func:`pipeline.priors.gate.accept`.  Here the gate's promise is
checked on every edit it accepts, over seeded random scenes rendered by an independent
ray caster: nothing entered deeper than before, no added volume a view saw empty, and
after the search the arrangement still stands.  And the gate is shown bad edits built by
hand, which it must refuse.
"""

from __future__ import annotations

import dataclasses
import re
import sys

import numpy as np
import pytest

from pipeline.boxops import box_samples
from pipeline.camera import Intrinsics, look_at
from pipeline.contacts import find_contacts
from pipeline.errors import InputError
from pipeline.evidence import FREE_FRACTION_MAX, DepthView, Evidence
from pipeline.extend import candidate_edges
from pipeline.model import Arrangement, Contact, ObservedBox, Support, box, ground
from pipeline.priors import (
    BY_NAME,
    PRIORS,
    STAGES,
    Context,
    Edit,
    EditLog,
    ImagineConfig,
    Prior,
    gate,
    run_stage,
)
from pipeline.search import finalize
from pipeline.stability import check_stability
from synth_scenes.registry import family_names
from tests.pipeline.test_imagine import _depth_of_boxes

# --------------------------------------------------------------------------------------
# 1. what each prior declares


def _module(prior):
    return sys.modules[prior.apply.__module__]


#: A scene named in a docstring: a family with a number (``sofa-1001``, ``stack18``), any
#: ``name-1234`` seed, or a table of the evaluation.
_SCENE = re.compile(r"\b(?:" + "|".join(map(re.escape, family_names()))
                    + r")[-_ ]?\d+|\b[a-z_]+-\d{3,}\b|\bTable \d", re.IGNORECASE)


def test_the_scene_pattern_catches_what_it_must():
    for bad in ("as on sofa-1001 of the benchmark", "stack18 of Table 3", "room_1003",
                "wall_shelf-1000", "seen in Table 1"):
        assert _SCENE.search(bad), bad
    for ok in ("a sofa's back", "two books 1 cm deep", "within 45 degrees of the view",
               "at most 0.5 of its width", "Kinect v1"):
        assert not _SCENE.search(ok), ok


@pytest.mark.parametrize("prior", PRIORS, ids=lambda p: p.name)
def test_every_prior_states_its_principle_and_declares_frozen_parameters(prior):
    module = _module(prior)
    # the principle: the module docstring's first paragraph, not empty, and the
    # docstring names no scene that motivated it
    doc = module.__doc__ or ""
    first = " ".join(doc.strip().split("\n\n")[0].split())
    assert first and prior.principle == first, prior.name
    assert len(first.split()) >= 5, first
    found = _SCENE.search(doc)
    assert found is None, f"{prior.name}: names a scene ({found.group(0)!r})"
    # the parameters: the module's frozen dataclass ``Params``, every field with a default
    params_cls = module.Params
    assert dataclasses.is_dataclass(params_cls) and isinstance(prior.params, params_cls)
    assert params_cls.__dataclass_params__.frozen, prior.name
    for f in dataclasses.fields(params_cls):
        assert (f.default is not dataclasses.MISSING
                or f.default_factory is not dataclasses.MISSING), f"{prior.name}.{f.name}"
    assert params_cls() == prior.params  # the prior runs at the defaults
    fields = dataclasses.fields(params_cls)
    if fields:
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(prior.params, fields[0].name, getattr(prior.params, fields[0].name))
    # a stage, and an apply that proposes (a generator function)
    assert prior.stage in STAGES
    assert callable(prior.apply) and module.PRIOR is prior


def test_prior_names_are_unique_and_run_stage_by_stage():
    names = [p.name for p in PRIORS]
    assert len(set(names)) == len(names)
    assert set(BY_NAME) == set(names) and all(BY_NAME[p.name] is p for p in PRIORS)
    order = [STAGES.index(p.stage) for p in PRIORS]
    assert order == sorted(order)  # the declared order is stage by stage
    assert {p.stage for p in PRIORS} == set(STAGES)


# --------------------------------------------------------------------------------------
# 2. the gate's contract on every edit it accepts, over random scenes

INTR = Intrinsics(320, 240, 262.5, 262.5, 159.5, 119.5)  # Kinect's field of view, halved


def _seen(c):
    return c.with_(observed=ObservedBox(c.center, c.size))


def _view(truth, eye, target=(0.0, 0.3, 0.4)) -> DepthView:
    T = look_at(np.asarray(eye, float), np.asarray(target, float))
    return DepthView(_depth_of_boxes(truth, T, INTR, far=8.0), INTR, T)


def _table(rng, x, y, name):
    """A table (top on four legs) in truth; as fitted, the top and the two or three legs
    nearest the camera (y < its centre), the legs' tops up to 2 cm under the top."""
    w, d, h = rng.uniform(0.5, 0.7), rng.uniform(0.35, 0.45), rng.uniform(0.5, 0.7)
    top = box(f"{name}_top", (x, y, h + 0.015), (w, d, 0.03), object=name)
    legs = [box(f"{name}_leg{k}", (x + sx * (w / 2 - 0.03), y + sy * (d / 2 - 0.03), h / 2),
                (0.04, 0.04, h), object=name)
            for k, (sx, sy) in enumerate(((-1, -1), (1, -1), (-1, 1), (1, 1)))]
    keep = 3 if rng.random() < 0.5 else 2
    fitted = [top]
    for leg in legs[:keep]:
        gap = rng.uniform(0.0, 0.02)
        fitted.append(leg.with_(center=leg.center - [0, 0, gap / 2],
                                size=leg.size - [0, 0, gap]))
    return [top, *legs], fitted


def _stack(rng, x, y, name):
    """A crate on a crate; as fitted the upper one floats up to 4 cm above the lower, or
    reaches up to 1 cm into it."""
    a, b = rng.uniform(0.25, 0.4), rng.uniform(0.2, 0.3)
    low = box(f"{name}_low", (x, y, a / 2), (a, a, a), object=f"{name}_low",
              yaw=rng.uniform(-0.3, 0.3))
    up = box(f"{name}_up", (x + rng.uniform(-0.03, 0.03), y, a + b / 2), (b, b, b),
             object=f"{name}_up", yaw=rng.uniform(-0.3, 0.3))
    dz = rng.uniform(-0.01, 0.04)
    return [low, up], [low, up.with_(center=up.center + [0, 0, dz])]


def _slab(rng, x, y, name):
    """A block seen face-on: fitted as its front, 1 cm deep."""
    w, d, h = rng.uniform(0.2, 0.4), rng.uniform(0.15, 0.3), rng.uniform(0.3, 0.6)
    block = box(name, (x, y, h / 2), (w, d, h), object=name)
    front = box(name, (x, y - d / 2 + 0.005, h / 2), (w, 0.01, h), object=name)
    return [block], [front]


def _monitor(rng, x, y, name):
    """A monitor: a foot, a neck hidden behind the screen, a screen hanging above the
    foot; the neck is not fitted."""
    g = rng.uniform(0.08, 0.15)
    foot = box(f"{name}_foot", (x, y, 0.01), (0.22, 0.14, 0.02), object=name)
    neck = box(f"{name}_neck", (x, y + 0.01, 0.02 + (g + 0.02) / 2), (0.04, 0.03, g + 0.02),
               object=name)
    screen = box(f"{name}_screen", (x, y, 0.02 + g + 0.15), (0.55, 0.03, 0.3), object=name)
    return [foot, neck, screen], [foot, screen]


def _desk(rng, x, y, name):
    """A desk: a top on two side panels; the far one seen as a strip at its front."""
    w, d, h = 1.0, 0.5, rng.uniform(0.65, 0.75)
    top = box(f"{name}_top", (x, y, h + 0.015), (w, d, 0.03), object=name)
    near = box(f"{name}_near", (x - w / 2 + 0.01, y, h / 2), (0.02, d, h), object=name)
    far = box(f"{name}_far", (x + w / 2 - 0.01, y, h / 2), (0.02, d, h), object=name)
    s = rng.uniform(0.08, 0.2)
    strip = box(f"{name}_far", (x + w / 2 - 0.01, y - d / 2 + s / 2, h / 2 + 0.1),
                (0.02, s, h - 0.2), object=name)
    pts = {top.id: 4000, near.id: 1500, far.id: 60}
    fitted = [c.with_(extra={"points": pts[c.id]}) for c in (top, near, strip)]
    return [top, near, far], fitted


def _books(rng, x, y, name):
    """Three books standing on a board, fitted as a zigzag that overlaps along the row."""
    board = box(f"{name}_board", (x, y, 0.3), (0.6, 0.3, 0.02), object=name)
    support = box(f"{name}_leg", (x, y, 0.145), (0.1, 0.1, 0.29), object=name)
    truth, fitted = [board, support], [board, support]
    for k in range(3):
        bx = x - 0.06 + 0.04 * k
        book = box(f"{name}_b{k}", (bx, y, 0.31 + 0.12), (0.04, 0.2, 0.24), object=f"{name}_b{k}")
        truth.append(book)
        fy = y - 0.07 + (0.05 if k == 1 else 0.0)
        fitted.append(box(book.id, (bx + rng.uniform(-0.006, 0.006), fy, 0.43),
                          (0.05, 0.04, 0.24), object=book.object))
    return truth, fitted


GROUPS = (_table, _stack, _slab, _monitor, _desk, _books)


def _complete_scene(seed: int):
    """Three random groups in a row before a camera: (fitted arrangement, evidence)."""
    rng = np.random.default_rng(seed)
    truth, fitted = [], []
    makers = rng.choice(len(GROUPS), size=3, replace=False)
    for slot, m in zip((-1.2, 0.0, 1.2), makers, strict=True):
        t, f = GROUPS[int(m)](rng, slot + rng.uniform(-0.1, 0.1), rng.uniform(0.1, 0.5),
                              f"g{int(m)}")
        truth += t
        fitted += f
    # a fit a little too big: one box reaches 5-15 mm further towards +x
    k = int(rng.integers(len(fitted)))
    grow = rng.uniform(0.005, 0.015)
    c = fitted[k]
    fitted[k] = c.with_(center=c.center + c.rotation[:, 0] * grow / 2,
                        size=c.size + np.array([grow, 0.0, 0.0]))
    eye = (rng.uniform(-0.8, 0.8), -3.2, rng.uniform(1.0, 2.0))
    view = _view(truth, eye)
    arr = Arrangement(tuple(_seen(c) for c in fitted), (ground(),))
    return arr, Evidence((view,))


def _settle_scene(seed: int):
    """Stable groups as the search leaves them (finalized with their glue): books with
    hidden gaps, a box glued over an edge to another object, a table with a leg seen at
    its top and glued, cushions grown to the floor, a shelf hung on a wall.  Returns
    (arrangement, evidence, context)."""
    rng = np.random.default_rng(seed)
    cubs, glue = [], []
    # three books on the floor with hidden gaps between them
    x = -1.6
    for k in range(3):
        cubs.append(_seen(box(f"book{k}", (x + 0.02, 0.0, 0.15), (0.04, 0.2, 0.3),
                              object=f"book{k}")))
        x += 0.04 + rng.uniform(0.003, 0.015)
    # a box on another, hanging over its front edge, glued (another object)
    over = rng.uniform(0.02, 0.05)
    cubs += [_seen(box("lo", (-0.8, 0.0, 0.2), (0.4, 0.4, 0.4), object="lo")),
             _seen(box("up", (-0.8, -0.2 - over, 0.5), (0.3, 0.2, 0.2), object="up"))]
    glue.append(Contact("lo", "up", "fixed"))
    # a table whose fourth leg was seen over its top 20 cm only, glued to the top
    h = 0.7
    cubs.append(_seen(box("top", (0.3, 0.0, h + 0.02), (0.8, 0.5, 0.04), object="table")))
    for k, (sx, sy) in enumerate(((-1, -1), (1, -1), (-1, 1), (1, 1))):
        c = (0.3 + sx * 0.37, sy * 0.22)
        leg = (box(f"leg{k}", (*c, h / 2), (0.05, 0.05, h), object="table") if k < 3 else
               box(f"leg{k}", (*c, h - 0.1), (0.05, 0.05, 0.2), object="table"))
        cubs.append(_seen(leg))
        glue.append(Contact(f"leg{k}", "top", "fixed"))
    # two cushions seen at their tops, grown to the floor by the search, beside a back
    cubs.append(_seen(box("back", (1.5, 0.5, 0.425), (1.2, 0.2, 0.85), object="sofa")))
    for k, s in enumerate((-1, 1)):
        c = box(f"cushion{k}", (1.5 + s * 0.3, 0.1, 0.225), (0.6, 0.6, 0.45),
                object=f"cushion{k}")
        cubs.append(c.with_(observed=ObservedBox(c.center + [0, 0, 0.18], [0.6, 0.6, 0.09])))
    glue.append(Contact("back", "cushion0", "fixed"))
    # a board hung on the wall y = 1.2, a bracket under it 2 cm short of the wall
    wall = Support("wall:0", np.array([0.0, 1.2, 0.0]), np.array([0.0, -1.0, 0.0]))
    cubs += [_seen(box("board", (-0.6, 1.05, 1.2), (0.8, 0.3, 0.02), object="ws")),
             _seen(box("br0", (-0.9, 1.1, 1.13), (0.025, 0.2, 0.12), object="ws")),
             _seen(box("br1", (-0.3, 1.08, 1.13), (0.025, 0.16, 0.12), object="ws"))]
    glue += [Contact("board", "wall:0", "fixed"), Contact("board", "br0", "fixed"),
             Contact("board", "br1", "fixed")]
    initial = Arrangement(tuple(cubs), (ground(), wall))
    final = finalize(initial, glue)
    # the true scene: the books touching, the table's fourth leg down to the floor, the
    # bracket on the wall (the view saw none of the gaps)
    true = {"leg3": box("leg3", (0.67, 0.22, h / 2), (0.05, 0.05, h)),
            "br1": box("br1", (-0.3, 1.1, 1.13), (0.025, 0.2, 0.12))}
    true.update({f"book{k}": box(f"book{k}", (-1.58 + 0.04 * k, 0.0, 0.15), (0.04, 0.2, 0.3))
                 for k in range(3)})
    truth = [true.get(c.id, c) for c in cubs]
    view = _view(truth, (rng.uniform(-0.5, 0.5), -3.0, rng.uniform(0.8, 1.4)))
    ctx = Context(initial, tuple(candidate_edges(initial)), 0.7, None)
    return final, Evidence((view,)), ctx


class _Spy:
    """Every call of the gate: (arrangement, edit, evidence, ctx, stage, verdict)."""

    def __init__(self):
        self.calls = []
        self.real = gate.accept

    def __call__(self, arr, edit, evidence, ctx=None, stage="complete"):
        v = self.real(arr, edit, evidence, ctx, stage)
        self.calls.append((arr, edit, evidence, ctx, stage, v))
        return v


@dataclasses.dataclass(frozen=True)
class _NoParams:
    pass


def _fuzz(stage: str, seed: int):
    """A prior of ``stage`` that proposes random edits, good and bad, for the gate to
    judge: a face of a box pushed out or in by up to 15 cm, a new box anywhere over the
    scene, a box taken away."""
    rng = np.random.default_rng(seed)

    def apply(arr, evidence, p, ctx):
        for n in range(14):
            kind = int(rng.integers(3))
            c = arr.cuboids[int(rng.integers(len(arr.cuboids)))]
            if kind == 0:
                axis, sign = int(rng.integers(3)), float(rng.choice((-1.0, 1.0)))
                length = float(rng.uniform(-0.5, 1.0)) * min(0.15, 0.4 * float(c.size[axis]))
                u = c.rotation[:, axis] * sign
                size = c.size.copy()
                size[axis] += length
                edit = Edit((c.with_(center=c.center + u * length / 2, size=size),),
                            f"fuzz: {c.id} face {axis}{sign:+.0f} by {100 * length:.0f} cm")
            elif kind == 1:
                lo, hi = arr.centers.min(axis=0) - 0.3, arr.centers.max(axis=0) + 0.3
                centre = rng.uniform(lo, hi)
                size = rng.uniform(0.05, 0.3, 3)
                centre[2] = max(centre[2], size[2] / 2 + 0.01)
                edit = Edit((box(f"fuzz{stage}{n}", centre, size, object=f"fuzz{n}"),),
                            "fuzz: a new box")
            else:
                edit = Edit((), f"fuzz: {c.id} taken away", removed=(c.id,))
            v = yield edit
            if v.ok:
                arr = v.arrangement

    return Prior(f"fuzz_{stage}", stage, _NoParams(), apply, "Random edits.")


def _depths(arr: Arrangement) -> dict[tuple[str, str], float]:
    return {tuple(sorted((p, q))): float(d) for p, q, d in find_contacts(arr).penetrations}


def _check_accepted(arr, edit, evidence, ctx, stage, v):
    """The gate's promise for one accepted edit (independent of how it decided)."""
    after = v.arrangement
    for c in edit.boxes:  # the edit's boxes are in place, what it took away is gone
        np.testing.assert_array_equal(after.cuboid(c.id).size, c.size)
        np.testing.assert_array_equal(after.cuboid(c.id).center, c.center)
    assert not set(edit.removed) & set(after.ids)
    if stage == "prepare":
        return  # corrections of the fit itself: judged by the points they fit
    # 1. nothing entered: no box the edit changed overlaps another deeper than before
    assert gate.entered(arr, after, edit) is None
    before, now = _depths(arr), _depths(after)
    changed = set(edit.ids)
    for (p, q), d in now.items():
        if p in changed or q in changed:
            was = before.get((p, q), 0.0)
            for g in edit.removed:
                for pair in ((g, q), (p, g)):
                    was = max(was, before.get(tuple(sorted(pair)), 0.0))
            assert d <= was + 1e-6, (edit.reason, p, q, d, was)
    # 2. no added volume a view saw empty (a new box: none of it)
    assert gate.seen_empty(arr, edit, evidence) is None
    for c in edit.boxes:
        if c.id not in arr.index:
            assert evidence.free_fraction(box_samples(c)) <= FREE_FRACTION_MAX, edit.reason
    # 3. after the search, the arrangement with the edit stands
    if arr.stability is not None:
        assert after.stability is not None and after.stability.stable, edit.reason
        assert check_stability(after, mu=ctx.mu, threshold=ctx.threshold).stable, edit.reason


def _broken_rule(arr, edit, evidence, ctx, stage) -> int | None:
    """Which of the gate's rules a refused edit breaks (1, 2 or 3), found again: None
    when it breaks none (the gate refused it without cause)."""
    if stage == "prepare":
        return None
    trial = gate.apply_edit(arr, edit)
    if gate.entered(arr, trial, edit) is not None:
        return 1
    if gate.seen_empty(arr, edit, evidence) is not None:
        return 2
    if arr.stability is None:
        return None
    fixed = edit.fixed if edit.fixed is not None else tuple(
        c for c in arr.contacts if c.type == "fixed")
    try:
        cand = finalize(trial.with_(stability=None), list(fixed), mu=ctx.mu,
                        threshold=ctx.threshold)
        stands = check_stability(cand, mu=ctx.mu, threshold=ctx.threshold,
                                 tilt_deg=2.0).stable
    except InputError:  # a fixed pair no longer touches
        stands = False
    return None if stands else 3


def _audit(spy, report, rules=None):
    """Check every verdict of one scene's run; returns {prior: [accepted, rejected]} and
    counts the rules refused edits broke in ``rules``."""
    assert len(spy.calls) == len(report.edits)
    counts: dict[str, list[int]] = {}
    last = None
    for (arr, edit, evidence, ctx, stage, v), rec in zip(spy.calls, report.edits, strict=True):
        assert rec.accepted == v.ok and rec.boxes == edit.ids and rec.stage == stage
        if last is not None:  # each proposal is judged against what the last one left
            assert arr is last
        n = counts.setdefault(rec.prior, [0, 0])
        if v.ok:
            n[0] += 1
            _check_accepted(arr, edit, evidence, ctx, stage, v)
        else:
            n[1] += 1
            assert v.reason and v.arrangement is arr, rec  # refused, with the reason ...
            rule = _broken_rule(arr, edit, evidence, ctx, stage)
            assert rule is not None, rec  # ... and with cause
            if rules is not None:
                rules[rule] = rules.get(rule, 0) + 1
        last = v.arrangement
    return counts


def test_every_edit_the_gate_accepts_keeps_its_contract(monkeypatch):
    runner = sys.modules[run_stage.__module__]
    spy = _Spy()
    monkeypatch.setattr(runner, "accept", spy)  # the gate the runner calls
    config = ImagineConfig()
    totals: dict[str, list[int]] = {}
    rules: dict[int, int] = {}

    def tally(counts):
        for k, (a, r) in counts.items():
            t = totals.setdefault(k, [0, 0])
            t[0] += a
            t[1] += r

    for seed in range(6):  # before the search: prepare, then complete, as imagine runs them
        arr, evidence = _complete_scene(seed)
        # the real priors, then random edits (good and bad) for the gate to judge
        monkeypatch.setattr(runner, "PRIORS", PRIORS + (_fuzz("complete", seed),))
        report = EditLog()
        spy.calls.clear()
        ctx = Context()
        arr = run_stage("prepare", arr, evidence, ctx, config, report)
        run_stage("complete", arr, evidence.scaled_to(arr), ctx, config, report)
        tally(_audit(spy, report, rules))
    for seed in range(2):  # after the search: settle
        final, evidence, ctx = _settle_scene(seed)
        assert final.stability.stable
        assert check_stability(final, tilt_deg=2.0).stable  # stands with the search's margin
        monkeypatch.setattr(runner, "PRIORS", PRIORS + (_fuzz("settle", 10 + seed),))
        report = EditLog()
        spy.calls.clear()
        run_stage("settle", final, evidence, ctx, config, report)
        tally(_audit(spy, report, rules))
    # the scenes exercise the gate: most priors proposed, edits went both ways
    real = {p.name: p.stage for p in PRIORS}
    for stage, edits, priors in (("complete", 6, 4), ("settle", 4, 3)):
        mine = [n for n, st in real.items() if st == stage]
        assert sum(totals.get(n, [0, 0])[0] for n in mine) >= edits, totals
        assert sum(1 for n in mine if totals.get(n, [0, 0])[0]) >= priors, totals
    for stage in ("complete", "settle"):
        accepted, rejected = totals[f"fuzz_{stage}"]
        assert accepted >= 3 and rejected >= 3, totals
    assert all(rules.get(r, 0) >= 1 for r in (1, 2, 3)), rules  # each rule refused some


# --------------------------------------------------------------------------------------
# 3. the gate refuses bad edits built by hand


def _two_crates():
    a = _seen(box("a", (0.0, 0.0, 0.2), (0.4, 0.4, 0.4), object="a"))
    b = _seen(box("b", (0.45, 0.0, 0.2), (0.4, 0.4, 0.4), object="b"))  # 5 cm apart
    return Arrangement((a, b), (ground(),))


def _pushed(c, length):
    """``c`` with its +x face pushed out by ``length``."""
    return c.with_(center=c.center + [length / 2, 0, 0], size=c.size + [length, 0, 0])


def test_the_gate_refuses_an_edit_that_pushes_a_box_into_its_neighbour():
    arr = _two_crates()
    into = Edit((_pushed(arr.cuboid("a"), 0.08),), "a pushed 3 cm into b")
    for stage in ("complete", "settle"):
        v = gate.accept(arr, into, Evidence(), Context(), stage)
        assert not v.ok and v.arrangement is arr and "into" in v.reason, v.reason
    # ... and accepts the push that makes them just touch
    ok = Edit((_pushed(arr.cuboid("a"), 0.05),), "a pushed to b")
    v = gate.accept(arr, ok, Evidence(), Context(), "complete")
    assert v.ok and ("a", "b") in find_contacts(v.arrangement).lookup()
    # an overlap the fit already had may stay, as long as the edit does not deepen it
    fitted = arr.with_(cuboids=(_pushed(arr.cuboid("a"), 0.06), arr.cuboid("b")))
    taller = fitted.cuboid("b").with_(size=np.array([0.4, 0.4, 0.45]),
                                      center=np.array([0.45, 0.0, 0.225]))
    assert gate.accept(fitted, Edit((taller,), "b taller"), Evidence(), Context()).ok
    deeper = Edit((_pushed(fitted.cuboid("a"), 0.01),), "a 1 cm further into b")
    assert not gate.accept(fitted, deeper, Evidence(), Context()).ok
    # the prepare stage corrects the fit itself: the overlap rule is not its
    assert gate.accept(arr, into, Evidence(), Context(), "prepare").ok


def test_the_gate_refuses_a_box_added_where_the_depth_view_saw_empty_space():
    arr = _two_crates()
    eye = (0.2, -3.0, 1.2)
    evidence = Evidence((_view(list(arr.cuboids), eye, target=(0.2, 0.0, 0.2)),))
    # a box floating in front of the crates, between them and the camera: seen through
    ghost = box("ghost", (0.2, -1.0, 0.4), (0.2, 0.2, 0.2), object="ghost")
    v = gate.accept(arr, Edit((ghost,), "a ghost"), evidence, Context(), "complete")
    assert not v.ok and v.arrangement is arr and "seen empty" in v.reason, v.reason
    # a crate grown towards the camera is seen through too ...
    front = arr.cuboid("a").with_(center=np.array([0.0, -0.1, 0.2]),
                                  size=np.array([0.4, 0.6, 0.4]))
    assert not gate.accept(arr, Edit((front,), "a towards the camera"), evidence).ok
    # ... while behind the crates (their shadow) nothing was seen: accepted
    hidden = box("hidden", (0.0, 0.4, 0.15), (0.2, 0.2, 0.3), object="hidden")
    v = gate.accept(arr, Edit((hidden,), "behind a"), evidence, Context(), "complete")
    assert v.ok and "hidden" in v.arrangement.index
    # without a depth view nothing is seen empty
    assert gate.accept(arr, Edit((ghost,), "a ghost"), Evidence(), Context()).ok


def test_after_the_search_the_gate_refuses_an_edit_that_removes_the_only_support():
    low = _seen(box("low", (0.0, 0.0, 0.2), (0.4, 0.4, 0.4), object="low"))
    up = _seen(box("up", (0.0, 0.0, 0.5), (0.3, 0.3, 0.2), object="up"))
    side = _seen(box("side", (0.6, 0.0, 0.15), (0.2, 0.2, 0.3), object="side"))
    arr = finalize(Arrangement((low, up, side), (ground(),)), [])
    assert arr.stability.stable
    ctx = Context()
    for edit in (Edit((), "low taken away", removed=("low",)),
                 Edit((low.with_(center=np.array([0.0, 0.0, 0.1]),
                                 size=np.array([0.4, 0.4, 0.2])),), "low cut to 20 cm"),
                 Edit((low.with_(center=np.array([0.0, 0.8, 0.2])),), "low moved away")):
        v = gate.accept(arr, edit, Evidence(), ctx, "settle")
        assert not v.ok and v.arrangement is arr and v.reason, edit.reason
        # before the search there is no verdict to keep: the same edit passes
        assert gate.accept(arr.with_(stability=None, contacts=()), edit, Evidence(), ctx,
                           "complete").ok
    # taking away a box that holds nothing up is accepted, and the verdict is new
    v = gate.accept(arr, Edit((), "side taken away", removed=("side",)), Evidence(), ctx,
                    "settle")
    assert v.ok and "side" not in v.arrangement.index and v.arrangement.stability.stable
    # glue listed by the edit holds what would otherwise fall
    over = up.with_(center=np.array([0.0, -0.3, 0.5]))
    hang = Edit((over,), "up slid over the edge", fixed=(Contact("low", "up", "fixed"),))
    assert not gate.accept(arr, Edit((over,), "up slid over the edge"), Evidence(), ctx,
                           "settle").ok
    v = gate.accept(arr, hang, Evidence(), ctx, "settle")
    assert v.ok and {c.key: c.type for c in v.arrangement.contacts}[
        Contact("low", "up").key] == "fixed"


def test_the_gate_refuses_an_edit_that_collapses_a_box_in_every_stage():
    arr = _two_crates()
    a = arr.cuboid("a")
    flat = a.with_(size=np.array([a.size[0], 3e-4, a.size[2]]))
    for stage in ("prepare", "complete", "settle"):
        v = gate.accept(arr, Edit((flat,), "a cut to a sheet"), Evidence(), Context(), stage)
        assert not v.ok and v.arrangement is arr and "thin" in v.reason, v.reason
    # just above the limit it is an ordinary edit
    thin = a.with_(size=np.array([a.size[0], 2 * gate.MIN_SIDE, a.size[2]]))
    assert gate.accept(arr, Edit((thin,), "a thinned"), Evidence(), Context(), "prepare").ok
