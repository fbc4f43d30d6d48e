"""Benchmark datasets (``unseen dataset make``): the plan, the files, the loader, BOP."""

from __future__ import annotations

import hashlib
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from eval.cli import main
from pipeline.errors import InputError
from synth_scenes import dataset as ds
from synth_scenes.bop import read_bop_scene


def _tree(root: Path) -> dict[str, str]:
    """Relative path -> SHA-256 of every file except the run's own records and timings."""
    return {p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file() and ".run" not in p.parts}


# ------------------------------------------------------------------------------ plan
def test_plan_seeds_families_and_stratified_splits():
    cfg = ds.DatasetConfig(families=("stack", "table", "room"), n=30, first_seed=500,
                           split=(0.8, 0.1, 0.1))
    plans = ds.plan(cfg)
    assert [p.seed for p in plans] == list(range(500, 530))
    assert [p.family for p in plans[:4]] == ["stack", "table", "room", "stack"]
    assert len({p.id for p in plans}) == 30
    for fam in cfg.families:  # every family split 8 / 1 / 1
        splits = [p.split for p in plans if p.family == fam]
        assert (splits.count("train"), splits.count("val"), splits.count("test")) == (8, 1, 1)
    assert ds.plan(cfg) == plans  # a pure function


def test_a_scene_does_not_change_with_n():
    base = ds.DatasetConfig(families=("stack", "room"), views=(1, 3), scale=(0.8, 1.2),
                            options={"stack": {"n_boxes": (3, 8)},
                                     "room": {"n_objects": (2, 5)}})
    small = ds.plan(replace(base, n=10))
    large = ds.plan(replace(base, n=40))
    for a, b in zip(small, large):
        assert (a.id, a.seed, a.views, a.scale, a.options) == (b.id, b.seed, b.views, b.scale,
                                                              b.options)
    assert {p.views for p in large} == {1, 2, 3}
    assert all(0.8 <= p.scale <= 1.2 for p in large)
    assert all(3 <= p.options["n_boxes"] <= 8 for p in large if p.family == "stack")
    assert all(set(p.options) == {"n_objects"} for p in large if p.family == "room")


def test_style_choices_are_drawn_per_scene_and_made(tmp_path):
    (tmp_path / "k.toml").write_text("[families.table]\nstyle = ['pedestal', 'three_legs']\n"
                                     "[families.chair]\narms = [true]\n")
    cfg = replace(ds.read_config(tmp_path / "k.toml"), families=("table", "chair"), n=12)
    plans = ds.plan(cfg)
    styles = {p.options["style"] for p in plans if p.family == "table"}
    assert styles == {"pedestal", "three_legs"}
    assert all(p.options == {"arms": True} for p in plans if p.family == "chair")
    from synth_scenes.registry import make

    parts = {"pedestal": 3, "three_legs": 4}  # top + column + foot; top + 3 legs
    for sp in (p for p in plans if p.family == "table"):
        arr = make("table", np.random.default_rng(sp.seed), **sp.options)
        assert sum(c.object == "table0" for c in arr.cuboids) == parts[sp.options["style"]]
    with pytest.raises(InputError, match=r"\[families.chair\] arms: expected a list of"):
        ds.config_from_mapping({"families": {"chair": {"arms": ["yes"]}}}, "k.toml")


def test_proportions_replace_the_generators_ranges(tmp_path):
    (tmp_path / "k.yaml").write_text("proportions: {table: {height: [0.5, 0.52]}, "
                                     "chair: {width: [0.55, 0.6]}}\n")
    cfg = replace(ds.read_config(tmp_path / "k.yaml"), families=("table", "chair"), n=6)
    from synth_scenes.registry import make

    for sp in ds.plan(cfg):
        arr = make(sp.family, np.random.default_rng(sp.seed), **sp.options)
        own = [c for c in arr.cuboids if c.object == f"{sp.family}0"]
        top = max(float(c.center[2] + c.size[2] / 2) for c in own)
        if sp.family == "table":
            assert 0.5 - 1e-9 <= top <= 0.52 + 1e-9
    default = make("table", np.random.default_rng(0))
    same = make("table", np.random.default_rng(0), proportions=None)
    assert np.array_equal(default.centers, same.centers)
    with pytest.raises(InputError, match=r"\[proportions.table\] legs: unknown length"):
        ds.config_from_mapping({"proportions": {"table": {"legs": [1, 2]}}}, "k.yaml")
    with pytest.raises(InputError, match=r"\[proportions.table\] height"):
        ds.config_from_mapping({"proportions": {"table": {"height": [0.9, 0.5]}}}, "k.yaml")


def test_deal_is_exact_for_any_n():
    for n in range(0, 60):
        counts = ds._deal(n, (0.8, 0.1, 0.1))
        assert sum(counts) == n
        assert all(abs(c - n * p) < 1 for c, p in zip(counts, (0.8, 0.1, 0.1)))


@pytest.mark.parametrize("text, needle", [
    ("[camera]\nfocus = 3\n", "[camera] focus: unknown key"),
    ("[scan]\nviews = [3, 1]\n", "[scan] views"),
    ("[scan]\nnoise = 'loud'\n", "[scan] noise"),
    ("[families.table]\nn_boxes = [1, 2]\n", "[families.table] n_boxes: unknown option"),
    ("[families.stack]\nn_boxes = [0, 400]\n", "[families.stack] n_boxes"),
    ("[scene]\nscale = [0.1, 1]\n", "[scene] scale"),
    ("[lights]\nsun = 1\n", "[lights]: unknown section"),
    ("[camera\n", "not valid TOML"),
])
def test_config_errors_name_the_key(tmp_path, text, needle):
    path = tmp_path / "knobs.toml"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        ds.read_config(path)
    assert needle in str(err.value) and str(path) in str(err.value)
    assert "\n" not in str(err.value)


def test_config_toml_and_yaml_agree(tmp_path):
    (tmp_path / "k.toml").write_text(
        "[camera]\ndistance = [1.5, 3.0]\nheight = [0.5, 1.8]\n[scan]\nviews = [1, 2]\n"
        "noise = 'none'\n[scene]\nscale = [0.9, 1.1]\n[families.room]\nn_objects = [3, 6]\n")
    (tmp_path / "k.yaml").write_text(
        "camera: {distance: [1.5, 3.0], height: [0.5, 1.8]}\nscan: {views: [1, 2], "
        "noise: none}\nscene: {scale: [0.9, 1.1]}\nfamilies: {room: {n_objects: [3, 6]}}\n")
    a, b = ds.read_config(tmp_path / "k.toml"), ds.read_config(tmp_path / "k.yaml")
    assert a == b
    assert a.camera == {"distance": (1.5, 3.0), "height": (0.5, 1.8)}
    assert a.noise == "none" and a.views == (1, 2) and a.options == {"room": {"n_objects": (3, 6)}}


def test_scaled_scene_keeps_contacts_and_verdict():
    from pipeline.contacts import find_contacts
    from pipeline.stability import check_stability
    from synth_scenes.registry import make
    from synth_scenes.truth import scaled

    arr = make("table", np.random.default_rng(3))
    big = scaled(arr, 1.7)
    np.testing.assert_allclose(big.sizes, 1.7 * arr.sizes)
    np.testing.assert_allclose(big.centers, 1.7 * arr.centers)
    pairs = lambda a: {tuple(sorted(p)) for p in find_contacts(a).pairs}  # noqa: E731
    assert pairs(big) == pairs(arr)
    assert check_stability(big).stable == check_stability(arr).stable


# ------------------------------------------------------------------------ the files
@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """Three scenes, one with two views, made through the command line, with BOP."""
    out = tmp_path_factory.mktemp("ds") / "data"
    rc = main(["dataset", "make", "--out", str(out), "--families", "stack,chair,table",
               "--n", "3", "--views", "1-2", "--split", "1/1/1", "--first-seed", "7", "--bop"])
    assert rc == 0
    return out


def test_manifest_matches_files_and_every_scene_stands(small):
    lines = [json.loads(x) for x in (small / "manifest.jsonl").read_text().splitlines()]
    assert [r["id"] for r in lines] == ["stack-000007", "chair-000008", "table-000009"]
    # one scene per family: stratified dealing gives each to the largest split
    assert [r["split"] for r in lines] == ["train"] * 3
    for r in lines:
        folder = small / r["path"]
        assert r["files"] == ds.file_hashes(folder)
        assert r["stands"] == {"analytic": True, "mujoco": True, "pybullet": True}
        scene = json.loads((folder / "scene.json").read_text())
        assert scene["meta"]["validation"]["engines"] == {"mujoco": True, "pybullet": True}
        assert scene["meta"]["seed"] == r["seed"] and scene["meta"]["family"] == r["family"]
        assert r["counts"]["cuboids"] == len(scene["cuboids"])
        assert r["counts"]["contacts"] == len(scene["contacts"])
    assert ds.Dataset(small).verify() == []
    card = (small / "DATASET.md").read_text()
    assert "| stack | 1 |" in card and "unseen dataset make --out" in card
    assert (small / "stats.png").stat().st_size > 5000


def test_same_scene_as_unseen_synth(small, tmp_path):
    """Scene i is 'unseen synth FAMILY --seed SEED' with the same options."""
    rec = json.loads((small / "manifest.jsonl").read_text().splitlines()[0])
    rc = main(["synth", rec["family"], "--out", str(tmp_path / "one"), "--seed", str(rec["seed"]),
               "--views", str(rec["parameters"]["views"])])
    assert rc == 0
    synth = ds.file_hashes(tmp_path / "one")
    synth.pop("manifest.json")  # the output folder's own inventory
    assert synth == rec["files"]


def test_loader_and_bop_export_agree(small):
    data = ds.Dataset(small)
    assert len(data) == 3 and len(ds.Dataset(small, split="train")) == 3
    assert len(ds.Dataset(small, split="val")) == 0 and len(ds.Dataset(small, family="chair")) == 1
    n_views = 0
    for s in data:
        bop = read_bop_scene(small / "bop" / s.split / f"{s.record['index']:06d}")
        assert sorted(bop) == list(range(len(s.views)))
        arr = s.arrangement
        for im, view in enumerate(s.views):
            n_views += 1
            b = bop[im]
            np.testing.assert_array_equal(b["depth"], view.depth)
            assert view.depth.max() > 0.3
            ids = set(np.unique(view.instance)) - {0}
            for k in range(1, len(arr.cuboids) + 1):
                np.testing.assert_array_equal(b["masks"][k], view.instance == k)
                np.testing.assert_allclose(b["poses"][k], s.poses[k - 1], atol=1e-9)
                np.testing.assert_allclose(b["sizes"][k], s.sizes[k - 1], atol=1e-12)
            assert ids <= set(b["masks"])
        assert all(t in ("touch", "fixed") for _, _, t in s.graph)
        assert len(s.graph) == len(arr.contacts)
    assert n_views >= 4  # views 1-2 over three scenes drew at least one second view


def test_resume_remakes_only_what_is_missing(small, tmp_path):
    import shutil

    copy = tmp_path / "copy"
    shutil.copytree(small, copy)
    before = _tree(copy)
    rec = json.loads((copy / "manifest.jsonl").read_text().splitlines()[1])
    shutil.rmtree(copy / rec["path"])
    rc = main(["dataset", "make", "--out", str(copy), "--families", "stack,chair,table",
               "--n", "3", "--views", "1-2", "--split", "1/1/1", "--first-seed", "7", "--bop"])
    assert rc == 0
    timing = json.loads((copy / ".run" / "timing.json").read_text())
    assert timing["n_resumed"] == 2 and list(timing["task_seconds"]) == [rec["id"]]
    after = _tree(copy)
    assert after.pop("DATASET.md") and before.pop("DATASET.md")  # it names --out
    assert after == before


def test_verify_names_a_changed_file(small, tmp_path, capsys):
    import shutil

    copy = tmp_path / "copy"
    shutil.copytree(small, copy)
    rec = json.loads((copy / "manifest.jsonl").read_text().splitlines()[2])
    depth = copy / rec["path"] / "scan" / "depth.png"
    depth.write_bytes(depth.read_bytes()[:-8] + b"\0" * 8)
    assert main(["dataset", "verify", str(copy)]) == 1
    err = capsys.readouterr().err
    assert f"{rec['path']}/scan/depth.png: hash differs" in err


@pytest.mark.parametrize(("damage", "message"), [
    (lambda d: (d / "manifest.jsonl").write_text(""),
     "manifest.jsonl: lists 0 scenes; dataset.json made 3"),
    (lambda d: (d / "manifest.jsonl").write_text(
        "\n".join((d / "manifest.jsonl").read_text().splitlines()[:2]) + "\n"),
     "manifest.jsonl: lists 2 scenes; dataset.json made 3"),
    (lambda d: (d / "dataset.json").unlink(), "dataset.json: missing, or not the configuration"),
    (lambda d: (d / "dataset.json").write_text("[]"), "dataset.json: missing, or not the"),
    (lambda d: (d / "train" / "stack-000099").mkdir(),
     "train/stack-000099: a scene folder the manifest does not list"),
    # the BOP export is checked against the hashes written with it
    (lambda d: (d / "bop" / "train" / "000000" / "scene_gt.json").write_text("{}"),
     "bop/train/000000/scene_gt.json: hash differs from bop_manifest.json"),
    (lambda d: (d / "bop" / "train" / "000000" / "scene_gt.json").unlink(),
     "bop/: files differ from bop_manifest.json (missing ['train/000000/scene_gt.json']"),
    (lambda d: (d / "bop_manifest.json").unlink(), "bop/: no readable bop_manifest.json"),
])
def test_verify_judges_the_dataset_as_a_whole(small, tmp_path, capsys, damage, message):
    # a manifest emptied or cut short, a configuration gone, a scene folder it does not
    # list: each fails verify (exit 1), naming what is wrong; the intact copy passes
    import shutil

    copy = tmp_path / "copy"
    shutil.copytree(small, copy)
    assert main(["dataset", "verify", str(copy)]) == 0
    capsys.readouterr()
    damage(copy)
    assert main(["dataset", "verify", str(copy)]) == 1
    assert message in capsys.readouterr().err


def test_a_failed_scene_exits_1_and_the_rest_is_written(tmp_path, monkeypatch, capsys):
    real = ds.make_scene

    def flaky(sp, cfg, root):  # noqa: ANN001
        if sp.family == "chair":
            raise RuntimeError("a deliberately broken scene")
        return real(sp, cfg, root)

    monkeypatch.setattr(ds, "make_scene", flaky)
    rc = main(["dataset", "make", "--out", str(tmp_path / "d"), "--families", "stack,chair",
               "--n", "2", "--first-seed", "3"])
    assert rc == 1
    err = capsys.readouterr().err
    assert "1 of 2 tasks failed; first: chair-000004: RuntimeError: a deliberately broken" in err
    lines = (tmp_path / "d" / "manifest.jsonl").read_text().splitlines()
    assert [json.loads(x)["id"] for x in lines] == ["stack-000003"]


@pytest.mark.parametrize("argv, needle", [
    (["--n", "0"], "--n: must be from 1"),
    (["--split", "80/20"], "--split '80/20'"),
    (["--views", "0-2"], "--views '0-2'"),
    (["--families", "table,boat"], "unknown boat"),
])
def test_bad_flags_exit_2_with_one_line(tmp_path, capsys, argv, needle):
    out = tmp_path / "d"
    assert main(["dataset", "make", "--out", str(out), *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_refuses_a_folder_of_other_files(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("mine")
    assert main(["dataset", "make", "--out", str(tmp_path), "--n", "1"]) == 2
    assert "a folder of other files" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]


@pytest.mark.slow
def test_two_workers_give_byte_identical_scenes(tmp_path):
    argv = ["dataset", "make", "--families", "all", "--n", "10", "--first-seed", "40"]
    assert main([*argv, "--out", str(tmp_path / "one")]) == 0
    assert main([*argv, "--out", str(tmp_path / "two"), "--workers", "2"]) == 0
    one, two = _tree(tmp_path / "one"), _tree(tmp_path / "two")
    one.pop("DATASET.md")
    card = two.pop("DATASET.md")
    assert one == two and card
