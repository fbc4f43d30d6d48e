"""``unseen synth``: exit codes, messages, JSON summary, scene directory, reproducibility."""

from __future__ import annotations

import json

import pytest

from eval.cli import main


def test_kinds_match_the_registry():
    from eval.commands.synth import KINDS
    from synth_scenes.registry import family_names

    assert KINDS == family_names()


def test_help_lists_families(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["synth", "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for kind in ("stack", "wall_shelf", "room", "--n-boxes", "--views", "--noise"):
        assert kind in out


@pytest.mark.parametrize(("argv", "message"), [
    (["castle"], "unknown scene family 'castle'"),
    (["stack", "--views", "0"], "--views: must be from 1 to 64"),
    (["stack", "--n-boxes", "0"], "--n-boxes: must be from 1 to 200"),
    (["table", "--n-boxes", "3"], "--n-boxes: not an option of family 'table'"),
    (["stack", "--seed", "-1"], "--seed"),
])
def test_bad_input_exit_2_one_line(tmp_path, capsys, argv, message):
    code = main(["synth", *argv, "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2
    assert message in err and err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_out_is_a_file(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["synth", "chair", "--out", str(f)]) == 2
    assert "not a folder" in capsys.readouterr().err


def test_writes_scene_dir_and_json(tmp_path, capsys):
    pytest.importorskip("mujoco")
    from pipeline.arrangement_io import read_arrangement

    out = tmp_path / "s"
    code = main(["synth", "stack", "--out", str(out), "--seed", "4", "--n-boxes", "4",
                 "--noise", "none", "--json"])
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    arr = read_arrangement(out / "scene.json")
    assert summary["status"] == "ok" and summary["cuboids"] == len(arr.cuboids) == 4
    assert summary["contacts"] == len(arr.contacts)
    assert summary["validation"]["engines"] == {"mujoco": True, "pybullet": True}
    assert (out / "scan" / "depth.png").is_file() and (out / "scan" / "points.ply").is_file()
    # same command again: byte-identical files, the plain-text summary line
    out2 = tmp_path / "s2"
    assert main(["synth", "stack", "--out", str(out2), "--seed", "4", "--n-boxes", "4",
                 "--noise", "none"]) == 0
    assert capsys.readouterr().out.startswith(f"wrote {out2}: stack, 4 cuboids")
    for f in sorted(p for p in out.rglob("*") if p.is_file()):
        assert f.read_bytes() == (out2 / f.relative_to(out)).read_bytes(), f


def test_no_valid_scene_exits_1(tmp_path, capsys, monkeypatch):
    import synth_scenes.truth as truth

    monkeypatch.setattr(truth, "validate",
                        lambda arr, *a, **k: truth.Validation(False, True, False, {}))
    code = main(["synth", "chair", "--out", str(tmp_path / "x"), "--max-attempts", "2"])
    assert code == 1
    assert "no valid chair scene in 2 attempts" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()
