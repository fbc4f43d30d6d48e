"""``unseen export``: files written atomically and reproducibly, bad input exits 2."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from eval.cli import main
from pipeline.arrangement_io import write_arrangement
from pipeline.model import Arrangement, Contact, box, ground

pytest.importorskip("mujoco")


@pytest.fixture
def arrangement_file(tmp_path: Path) -> Path:
    arr = Arrangement((box("seat", (0, 0, 0.45), (0.5, 0.5, 0.05), object="chair"),
                       box("leg <&>", (0, 0, 0.2125), (0.05, 0.05, 0.425), object="chair"),
                       box('cup "a"', (0.1, 0.1, 0.525), (0.08, 0.08, 0.1))),
                      (ground(),),
                      (Contact("seat", "leg <&>", "fixed"), Contact("leg <&>", "ground"),
                       Contact('cup "a"', "seat")))
    path = tmp_path / "arrangement.json"
    write_arrangement(arr, path)
    return path


def _digest(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def test_export_writes_every_file_reproducibly(arrangement_file: Path, tmp_path: Path,
                                               capsys) -> None:
    before = arrangement_file.read_bytes()
    assert main(["export", str(arrangement_file), "--out", str(tmp_path / "a"), "--json"]) == 0
    written = json.loads(capsys.readouterr().out)
    assert set(written) == {"mjcf", "urdf", "urdf:urdf/world.urdf", "urdf:urdf/body0.urdf",
                            "urdf:urdf/body1.urdf", "glb"}
    assert main(["export", str(arrangement_file), "--out", str(tmp_path / "b")]) == 0
    assert _digest(tmp_path / "a") == _digest(tmp_path / "b")  # byte-identical
    assert arrangement_file.read_bytes() == before  # input untouched
    assert not list((tmp_path / "a").glob(".*"))  # no temporary files left behind

    import mujoco
    import trimesh

    model = mujoco.MjModel.from_xml_path(str(tmp_path / "a" / "scene.xml"))
    assert model.nbody == 3  # world, the fused chair, the cup
    scene = trimesh.load(tmp_path / "a" / "arrangement.glb")
    assert {"seat", "leg <&>", 'cup "a"', "support:ground"} <= set(scene.geometry)
    # glTF is y-up: the chair's height (z in the arrangement) is the file's y extent
    assert scene.bounds[1, 1] == pytest.approx(0.575, abs=1e-6)
    seat = scene.geometry["seat"].visual.face_colors[0]
    leg = scene.geometry["leg <&>"].visual.face_colors[0]
    cup = scene.geometry['cup "a"'].visual.face_colors[0]
    assert np.array_equal(seat, leg) and not np.array_equal(seat, cup)  # colour per object


def test_constraint_welds(arrangement_file: Path, tmp_path: Path) -> None:
    import mujoco

    assert main(["export", str(arrangement_file), "--out", str(tmp_path / "c"),
                 "--welds", "constraint"]) == 0
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "c" / "scene.xml"))
    assert model.nbody == 4 and model.neq == 1


def test_bad_input_exits_2(tmp_path: Path, capsys) -> None:
    assert main(["export", str(tmp_path / "missing.json"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "missing.json" in err and "Traceback" not in err and err.count("\n") == 1
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "unseen.arrangement", "version": 1, "cuboids": [{"id": "a"}]}')
    assert main(["export", str(bad), "--out", str(tmp_path / "o")]) == 2
    assert "cuboids[0]" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
