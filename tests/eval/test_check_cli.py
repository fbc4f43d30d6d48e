"""``unseen check``: verdicts, exit codes, JSON contract, one-line errors; lazy start-up."""

import json
import subprocess
import sys

import pytest

from pipeline.arrangement_io import write_arrangement
from tests.conftest import overhang_scene

UNSEEN = [sys.executable, "-m", "eval.cli"]


def _run(*args, timeout=120):
    return subprocess.run(UNSEEN + list(args), capture_output=True, text=True, timeout=timeout)


@pytest.fixture
def stable_file(tmp_path):
    p = tmp_path / "stable.json"
    write_arrangement(overhang_scene(0.3), p)
    return p


@pytest.fixture
def unstable_file(tmp_path):
    p = tmp_path / "unstable.json"
    write_arrangement(overhang_scene(0.7), p)
    return p


def test_analytic_exit_codes_and_table(stable_file, unstable_file):
    ok = _run("check", str(stable_file))
    assert ok.returncode == 0, ok.stderr
    assert "analytic: STABLE" in ok.stdout
    bad = _run("check", str(unstable_file))
    assert bad.returncode == 1
    assert "analytic: UNSTABLE" in bad.stdout
    top = next(line for line in bad.stdout.splitlines() if line.startswith("top"))
    assert "MOVES" in top


def test_json_contract(unstable_file):
    out = _run("check", str(unstable_file), "--json")
    assert out.returncode == 1
    data = json.loads(out.stdout)
    assert data["arrangement"] == str(unstable_file)
    assert data["agree"] is True
    a = data["engines"]["analytic"]
    assert a["stable"] is False and a["energy"] > a["threshold"]
    bodies = {b["id"]: b for b in a["bodies"]}
    assert bodies["top"]["stable"] is False and bodies["base"]["stable"] is True
    assert bodies["top"]["residual_torque"] > 0


def test_all_engines_agree_on_a_clear_case(unstable_file):
    out = _run("check", str(unstable_file), "--engine", "all", "--json", timeout=300)
    assert out.returncode == 1, out.stderr
    data = json.loads(out.stdout)
    assert set(data["engines"]) == {"analytic", "mujoco", "pybullet"}
    assert data["agree"] is True
    for name in ("mujoco", "pybullet"):
        top = next(b for b in data["engines"][name]["bodies"] if b["id"] == "top")
        assert top["stable"] is False and top["rotation_deg"] > 20


@pytest.mark.parametrize("content, needle", [
    ("{not json", "not valid JSON"),
    ('{"format": "unseen.arrangement", "version": 1, "cuboids": [{"id": "a", "center": [0, 0, 0],'
     ' "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "size": [1, 0, 1]}]}',
     "cuboids[0].size: must be 3 positive numbers"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, content, needle):
    p = tmp_path / "bad.json"
    p.write_text(content)
    out = _run("check", str(p))
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in out.stderr


def test_missing_file_and_bad_mu(tmp_path, stable_file):
    out = _run("check", str(tmp_path / "nope.json"))
    assert out.returncode == 2 and "no such file" in out.stderr
    out = _run("check", str(stable_file), "--mu", "-1")
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1


def test_help_imports_no_heavy_library():
    code = ("import sys\nfrom eval.cli import main\n"
            "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
            "heavy = [m for m in ('numpy', 'scipy', 'mujoco', 'pybullet', 'open3d', 'cv2', 'trimesh')"
            " if m in sys.modules]\nprint('HEAVY', heavy)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert "HEAVY []" in out.stdout, out.stdout + out.stderr
    assert "check" in out.stdout and "synth" in out.stdout


def test_pybullet_prints_no_banner(stable_file):
    """PyBullet's C extension announces its build time when imported; nothing of it shows."""
    out = _run("check", str(stable_file), "--engine", "pybullet", "--json")
    assert out.returncode == 0 and out.stderr == ""
    assert json.loads(out.stdout)["engines"]["pybullet"]["stable"] is True


def test_threshold_must_be_finite_and_positive(stable_file):
    for bad in ("-1", "nan", "inf", "0"):
        out = _run("check", str(stable_file), "--threshold", bad)
        assert out.returncode == 2 and out.stderr.count("\n") == 1
        assert "--threshold: must be a finite positive energy" in out.stderr
