"""The model repository: valid GLB files with an index, every kind and variant, upright,
sized as their parameters say; the variant of a generated object read back from its boxes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from synth_scenes import objects
from synth_scenes.models import (
    GENERATOR_VARIANTS,
    VARIANTS,
    make_models,
    variant_of,
    write_repository,
)


@pytest.fixture(scope="module")
def repo(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("models")
    write_repository(folder, make_models(np.random.default_rng(3), 6), seed=3)
    return folder


def test_index_lists_every_kind_and_variant(repo: Path) -> None:
    index = json.loads((repo / "index.json").read_text())
    assert index["format"] == "unseen.models" and index["units"] == "m"
    entries = index["models"]
    assert len(entries) == 6 * len(VARIANTS)
    got = {(e["kind"], e["variant"]) for e in entries}
    assert got == {(k, v) for k, vs in VARIANTS.items() for v in vs}
    assert all((repo / e["file"]).is_file() and e["up"] == "y" for e in entries)
    assert len({e["file"] for e in entries}) == len(entries)


def test_glb_files_are_upright_and_sized_as_their_params(repo: Path) -> None:
    import trimesh

    from pipeline.retrieve import load_repository

    index = json.loads((repo / "index.json").read_text())["models"]
    for e in index:
        raw = trimesh.load(repo / e["file"], force="mesh")
        # glTF is y up: the model's height is the file's y extent, its floor y = 0
        lo, hi = raw.bounds
        assert lo[1] == pytest.approx(0.0, abs=1e-6)
        np.testing.assert_allclose(hi - lo, np.array(e["extents"])[[0, 2, 1]], atol=1e-5)
    models = load_repository(repo)
    for e, m in zip(index, models, strict=True):
        assert (m.kind, m.variant, m.file) == (e["kind"], e["variant"], e["file"])
        ext = m.hi - m.lo
        np.testing.assert_allclose(ext, e["extents"], atol=1e-5)
        assert m.lo[2] == pytest.approx(0.0, abs=1e-6)                  # stands on z = 0
        mid = (m.lo + m.hi) / 2                 # about the origin (a sofa's back is behind)
        assert abs(mid[0]) < 1e-6 and abs(mid[1]) < 0.25 * ext[1]
        p = e["params"]
        if e["kind"] in ("table", "desk"):
            np.testing.assert_allclose(ext, [p["width"], p["depth"], p["height"]], atol=1e-5)
        elif e["kind"] == "chair":
            w = p["width"]
            np.testing.assert_allclose(ext, [w, p["depth"], p["height"] + p["back_height"]],
                                       atol=1e-5)
        elif e["kind"] == "shelf":
            np.testing.assert_allclose(ext, [p["width"], p["depth"], p["height"]], atol=1e-5)
            assert e["variant"] == f"boards{p['boards']}"
        elif e["kind"] == "sofa":
            assert ext[2] == pytest.approx(max(p["back_height"], p.get("arm_height", 0)), abs=1e-5)
            assert ext[1] == pytest.approx(p["depth"] + p["back"], abs=1e-5)


def test_pedestal_and_leg_counts_differ_in_the_floor_footprint(repo: Path) -> None:
    """Three legs, four legs and a pedestal touch the floor in 3, 4 and 1 places."""
    from scipy.ndimage import label

    from pipeline.retrieve import load_repository

    models = load_repository(repo, kinds=("table",))
    for m in models:
        on_floor = m.grid[:, :, 0]
        n = label(on_floor)[1]
        want = {"four_legs": 4, "three_legs": 3, "pedestal": 1}[m.variant]
        assert n == want, (m.file, m.variant, n)


def _parts(group, kind: str):
    sel = [p for p in group.parts if p.label == kind]
    return (np.array([p.center for p in sel]), np.array([p.rotation for p in sel]),
            np.array([p.size for p in sel]))


@pytest.mark.parametrize("seed", range(8))
def test_variant_of_reads_the_generator_style(seed: int) -> None:
    rng = np.random.default_rng(seed)
    wide = objects.WIDE
    chair = objects.chair(rng, wide["chair"])
    c = _parts(chair, "chair")
    assert variant_of("chair", *c) == {6: "board", 8: "posts"}[len(c[0])]
    table = objects.table(rng, 0, wide["table"])
    assert variant_of("table", *_parts(table, "table")) == "four_legs"
    desk = objects.desk(rng, wide["desk"])
    d = _parts(desk, "desk")
    drawer = d[2][2, 0] > 0.1      # the third part: second panel or drawer block
    assert variant_of("desk", *d) == ("drawers" if drawer else "panels")
    shelf = objects.shelf(rng, wide["shelf"])
    s = _parts(shelf, "shelf")
    assert variant_of("shelf", *s) == f"boards{len(s[0]) - 2}"
    assert variant_of("shelf", *s) in GENERATOR_VARIANTS["shelf"]
    assert variant_of("sofa", *_parts(objects.sofa(rng, wide["sofa"]), "sofa")) == "arms"


@pytest.mark.parametrize("seed", range(3))
def test_default_styles_draw_what_the_generator_always_drew(seed: int) -> None:
    from pipeline.arrangement_io import dumps
    from synth_scenes.families import make_chair, make_sofa, make_table

    def same(fn, **kw):
        return dumps(fn(np.random.default_rng(seed))) == \
            dumps(fn(np.random.default_rng(seed), **kw))

    assert same(make_table, style="four_legs") and same(make_table, style=None)
    assert same(make_chair, arms=False) and same(make_sofa, arms=True)


@pytest.mark.parametrize("family, options, variants", [
    ("table", {"style": "three_legs"}, {"three_legs"}),
    ("table", {"style": "pedestal"}, {"pedestal"}),
    ("chair", {"arms": True}, {"board_arms", "posts_arms"}),
    ("sofa", {"arms": False}, {"no_arms"}),
])
@pytest.mark.parametrize("seed", range(4))
def test_styled_objects_touch_where_listed_and_read_back(family: str, options: dict,
                                                        variants: set, seed: int) -> None:
    from pipeline.retrieve import object_groups
    from synth_scenes.registry import make
    from synth_scenes.truth import validate

    arr = make(family, np.random.default_rng(seed), **options)
    v = validate(arr, engines=(), analytic=False)
    assert v.contacts_ok, v.details["contacts"]
    cubs = object_groups(arr)[f"{family}0"]
    got = variant_of(family, np.array([c.center for c in cubs]),
                     np.array([c.rotation for c in cubs]), np.array([c.size for c in cubs]))
    assert got in variants
