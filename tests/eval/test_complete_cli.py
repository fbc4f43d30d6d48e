"""``unseen complete``: bad input, and a synthetic pair end to end."""

from __future__ import annotations

import json

import numpy as np
import pytest

from eval.cli import main


@pytest.mark.parametrize(("argv", "message"), [
    (["missing_scan", "--template", "{tmp}"], "PARTIAL missing_scan: no such file or folder"),
    (["{tmp}", "--template", "nope"], "--template nope: no such file or folder"),
    (["{tmp}", "--template", "{tmp}", "--height-tol", "-1"], "--height-tol: must be a length"),
    (["{tmp}", "--template", "{tmp}", "--icp-distance", "nan"], "--icp-distance"),
    (["{tmp}", "--template", "{tmp}", "--budget", "0"], "--budget"),
])
def test_bad_input_exit_2_one_line(tmp_path, capsys, argv, message):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    code = main(["complete", *argv, "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2
    assert message in err and err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_unknown_edge_pairs_exit_2_one_line(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["complete", str(tmp_path), "--template", str(tmp_path), "--out",
              str(tmp_path / "o"), "--edge-pairs", "some"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "--edge-pairs" in err and "'matched'" in err
    assert err.count("\n") == 1 and not (tmp_path / "o").exists()


def test_help_has_an_example(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["complete", "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert "unseen complete" in out and "--template" in out and "--transfer" in out


def read_ply(path):
    data = path.read_bytes()
    head, _, body = data.partition(b"end_header\n")
    n = int([ln for ln in head.decode().splitlines() if ln.startswith("element vertex")][0]
            .split()[-1])
    rec = np.frombuffer(body, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"),
                                     ("green", "u1"), ("blue", "u1"), ("source", "u1")],
                        count=n)
    return np.stack([rec["x"], rec["y"], rec["z"]], 1).astype(float), rec["source"]


@pytest.fixture(scope="module")
def chair_pair(tmp_path_factory):
    """A chair seen once and another chair (other proportions) seen from eight views, some
    from low down (under the seat), as the completion suite scans its templates."""
    from synth_scenes.scene_dir import make_scene_dir

    root = tmp_path_factory.mktemp("pair")
    partial = make_scene_dir("chair", root / "partial", seed=3)
    template = make_scene_dir("chair", root / "template", seed=7, views=8,
                              view_ranges={"height": (0.1, 1.9)})
    assert partial.truth.status == "ok" and template.truth.status == "ok"
    return partial, template


def test_end_to_end_coverage_improves(chair_pair, tmp_path, capsys):
    from eval.suites.completion import TAU, cloud_figures, surface_samples
    from pipeline.complete import parts_of

    partial, template = chair_pair
    out = tmp_path / "done"
    code = main(["complete", str(partial.path), "--template", str(template.path),
                 "--out", str(out), "--stage", "initial", "--json"])
    cap = capsys.readouterr()
    assert code == 0, cap.err
    line = json.loads(cap.out.strip().splitlines()[-1])
    assert line["matched"] >= 4
    for name in ("completed.ply", "transform.json", "completion.png", "report.md",
                 "manifest.json"):
        assert (out / name).is_file(), name
    rec = json.loads((out / "transform.json").read_text())
    T = np.array(rec["T_partial_template"])
    assert T.shape == (4, 4) and np.allclose(T[:3, :3].T @ T[:3, :3], np.eye(3))
    assert rec["matching"] and rec["alignment"]["icp"]["fitness"] > 0.5
    assert rec["config"]["edge_pairs"] == "all" and len(rec["alignment"]["edge_pair"]) == 2
    pts, source = read_ply(out / "completed.ply")
    assert set(np.unique(source)) == {0, 1}
    truth = partial.truth.arrangement
    name = rec["objects"]["partial"]
    samples = surface_samples(truth, name)
    tparts = parts_of([c for c in truth.cuboids if c.object == name])
    before = cloud_figures(pts[source == 0], samples, tparts, TAU)
    after = cloud_figures(pts, samples, tparts, TAU)
    assert after["coverage"] > before["coverage"] + 0.15
    assert after["coverage"] > 0.75
    assert after["completeness"] < before["completeness"]


def test_unknown_object_exit_2(chair_pair, tmp_path, capsys):
    partial, template = chair_pair
    code = main(["complete", str(partial.path), "--template", str(template.path),
                 "--out", str(tmp_path / "o"), "--stage", "initial", "--object", "sofa9"])
    err = capsys.readouterr().err
    assert code == 2 and "partial object 'sofa9': not in the scan" in err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "o" / "completed.ply").exists()


@pytest.mark.slow
def test_completion_suite_quick(tmp_path):
    """``unseen eval completion --quick``: one chair pair, its tables, plot and picture."""
    import csv

    assert main(["eval", "completion", "--out", str(tmp_path), "--quick"]) == 0
    rows = list(csv.DictReader((tmp_path / "completion.csv").open()))
    assert [r["family"] for r in rows] == ["chair", "all"]
    r = rows[0]
    assert float(r["coverage completed"]) > float(r["coverage partial"]) + 0.15
    for name in ("completion.md", "completion.png", "pairs.csv"):
        assert (tmp_path / name).is_file()
    assert list((tmp_path / "pictures").glob("chair-*.png"))


def test_a_poor_alignment_is_named_a_warning():
    # below POOR_FITNESS of the partial points near the aligned template, the run says
    # the completion is not to be trusted; at or above it, nothing is said
    from eval.commands.complete import POOR_FITNESS, _poor_fit

    assert _poor_fit({"fitness": POOR_FITNESS}) is None
    assert _poor_fit({}) is None
    w = _poor_fit({"fitness": POOR_FITNESS - 0.01})
    assert w is not None and "ICP fitness 0.09" in w and "not to be trusted" in w
