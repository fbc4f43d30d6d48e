"""Output folders: replaced whole, locked, never mixed, even when a run is killed midway;
``--mu`` reaches the scene files and ``meta``; outputs do not depend on the input's path."""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from eval.cli import main
from pipeline.arrangement_io import read_arrangement, write_arrangement
from pipeline.model import Arrangement, box, ground
from pipeline.outdir import MANIFEST

UNSEEN = [sys.executable, "-m", "eval.cli"]


def complete(folder: Path) -> dict:
    """The folder's manifest, after checking it lists exactly the files there, byte for byte."""
    manifest = json.loads((folder / MANIFEST).read_text())
    listed = {e["path"]: e["sha256"] for e in manifest["files"]}
    present = {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
               for p in folder.rglob("*") if p.is_file() and p.name != MANIFEST}
    assert listed == present
    return listed


def towers(n: int) -> Arrangement:
    """n free cubes side by side on the ground: n free bodies."""
    return Arrangement(tuple(box(f"c{i}", (2.0 * i, 0, 0.5), (1, 1, 1)) for i in range(n)),
                       (ground(),))


def test_export_removes_files_the_new_scene_does_not_have(tmp_path, capsys):
    big, small = tmp_path / "big.json", tmp_path / "small.json"
    write_arrangement(towers(3), big)
    write_arrangement(towers(1), small)
    out = tmp_path / "out"
    assert main(["export", str(big), "--out", str(out)]) == 0
    assert (out / "urdf" / "body2.urdf").is_file()
    assert main(["export", str(small), "--out", str(out)]) == 0
    files = complete(out)
    assert sorted(files) == ["arrangement.glb", "scene.urdf", "scene.xml", "urdf/body0.urdf",
                             "urdf/world.urdf"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.json", "out", "small.json"]


def test_another_commands_results_are_refused_not_replaced(tmp_path, capsys):
    # the manifest names the command that wrote the folder: the same command replaces
    # it, another one (synth over an export) is refused before any work, the folder intact
    arr = tmp_path / "a.json"
    write_arrangement(towers(2), arr)
    out = tmp_path / "out"
    assert main(["export", str(arr), "--out", str(out)]) == 0
    assert json.loads((out / MANIFEST).read_text())["command"] == "export"
    before = complete(out)
    assert main(["export", str(arr), "--out", str(out)]) == 0  # the same command: replaced
    assert complete(out) == before
    capsys.readouterr()
    assert main(["synth", "stack", "--out", str(out), "--seed", "1"]) == 2
    err = capsys.readouterr().err
    assert "holds the results of unseen export, which unseen synth would replace" in err
    assert err.count("\n") == 1 and complete(out) == before


def test_a_second_command_on_a_locked_folder_is_refused(tmp_path, capsys):
    src = tmp_path / "a.json"
    write_arrangement(towers(2), src)
    out = tmp_path / "out"
    assert main(["export", str(src), "--out", str(out)]) == 0
    before = complete(out)
    fd = os.open(out, os.O_RDONLY | os.O_DIRECTORY)
    fcntl.flock(fd, fcntl.LOCK_EX)  # what a running command holds
    try:
        capsys.readouterr()
        assert main(["export", str(src), "--out", str(out), "--mu", "0.3"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "another unseen command is writing this folder" in err[0]
    finally:
        os.close(fd)
    assert complete(out) == before


@pytest.fixture(scope="module")
def stack_scene(tmp_path_factory) -> Path:
    from synth_scenes.scene_dir import make_scene_dir

    out = tmp_path_factory.mktemp("stack") / "scene"
    made = make_scene_dir("stack", out, seed=3, noise="none", n_boxes=3)
    assert made.truth.status == "ok"
    return out


def test_results_never_go_inside_an_input_folder(stack_scene, tmp_path, capsys):
    # a result folder inside the scan's folder would change the input: refused, one
    # line, and the scan folder keeps exactly its files
    scene = tmp_path / "scene"
    shutil.copytree(stack_scene, scene)
    before = sorted(p.relative_to(scene).as_posix() for p in scene.rglob("*"))
    assert main(["run", str(scene), "--out", str(scene / "result"), "--stage", "initial"]) == 2
    err = capsys.readouterr().err
    assert "lies inside the input" in err and err.count("\n") == 1
    assert sorted(p.relative_to(scene).as_posix() for p in scene.rglob("*")) == before


def test_a_run_killed_midway_leaves_the_old_complete_set(stack_scene, tmp_path, capsys):
    out = tmp_path / "out"
    args = ["run", str(stack_scene), "--stage", "initial", "--out", str(out)]
    assert main(args) == 0
    old = complete(out)
    # a second run (another seed: other bytes) killed as soon as it writes its first file
    proc = subprocess.Popen(UNSEEN + args + ["--seed", "7"], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None:
        if any(any(t.iterdir()) for t in tmp_path.glob(".out.tmp-*")):
            break
        time.sleep(0.002)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert proc.returncode == -signal.SIGKILL, "the run ended before it could be killed"
    assert complete(out) == old
    # the next run replaces the folder whole and clears what the killed one left
    assert main(args + ["--seed", "7"]) == 0
    assert complete(out) != old
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_outputs_do_not_depend_on_the_input_path(stack_scene, tmp_path, capsys):
    other = tmp_path / "elsewhere" / "deeper" / "scene"
    shutil.copytree(stack_scene, other)
    for k, src in enumerate((stack_scene, other)):
        assert main(["run", str(src), "--stage", "initial", "--out", str(tmp_path / f"r{k}")]) == 0
    a, b = (tmp_path / "r0" / "arrangement.json"), (tmp_path / "r1" / "arrangement.json")
    assert a.read_bytes() == b.read_bytes()
    assert read_arrangement(a).meta["source"] == "scene/scan/depth.png"


def test_mu_reaches_the_scene_files_meta_export_and_check(stack_scene, tmp_path, capsys):
    out = tmp_path / "r"
    assert main(["run", str(stack_scene), "--out", str(out), "--mu", "0.4",
                 "--budget", "2"]) in (0, 1)
    arr = read_arrangement(out / "arrangement.json")
    assert arr.meta["mu"] == 0.4 and arr.meta["input_scale"] == 1.0
    assert read_arrangement(out / "initial.json").meta["mu"] == 0.4
    assert 'friction="0.4 ' in (out / "scene.xml").read_text()
    assert '<lateral_friction value="0.632455532034"/>' in (out / "scene.urdf").read_text()
    # export takes the file's mu unless told otherwise
    exp = tmp_path / "exp"
    assert main(["export", str(out / "arrangement.json"), "--out", str(exp)]) == 0
    assert 'friction="0.4 ' in (exp / "scene.xml").read_text()
    assert main(["export", str(out / "arrangement.json"), "--out", str(exp),
                 "--mu", "0.9"]) == 0
    assert 'friction="0.9 ' in (exp / "scene.xml").read_text()


def test_check_takes_mu_from_meta_and_the_flag_wins():
    from eval.commands.check import file_mu

    arr = towers(1).with_(meta={"mu": 0.25})
    assert file_mu(arr, None) == 0.25
    assert file_mu(arr, 0.6) == 0.6
    assert file_mu(towers(1), None) == 0.7


@pytest.mark.parametrize("argv", [
    ["run", "{S}", "--out", "{T}/ro/out"],
    ["export", "{S}", "--out", "{T}/ro/out"],
    ["synth", "demo", "--out", "{T}/ro/out"],
    ["demo", "--out", "{T}/ro/out"],
])
def test_a_read_only_parent_is_refused_before_any_work(argv, tmp_path, capsys, monkeypatch):
    """Root may write anywhere, so the read-only folder is simulated through os.access."""
    src = tmp_path / "a.json"
    write_arrangement(towers(1), src)
    (tmp_path / "ro").mkdir()
    real_access = os.access
    monkeypatch.setattr("pipeline.outdir.os.access",
                        lambda p, mode: False if Path(p).name == "ro" else real_access(p, mode))
    code = main([a.format(S=src, T=tmp_path) for a in argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "is not writable" in err[0], err
    assert list((tmp_path / "ro").iterdir()) == []
