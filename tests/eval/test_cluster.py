"""Scale-out on a real cluster (issue 24 item 4).

Workers started the usual way (``dask scheduler``, ``dask worker``) inherit nothing from
us: no ``MUJOCO_GL``, no thread settings.  Every task must prepare its own process.  The
slow test starts a scheduler and two workers as separate processes on 127.0.0.1 with
those variables removed, runs a small suite (and ``dataset make``) through them, and
compares with a serial run.  The default run keeps the cheap part: a fresh process with
no ``MUJOCO_GL`` that settles a scene in MuJoCo *before* it renders one (the order in
which a worker used to fail) must render.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
#: Variables a worker started by hand does not have.
STRIPPED = ("MUJOCO_GL", "PYOPENGL_PLATFORM", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS",
            "MKL_NUM_THREADS", "DISPLAY")


def _bare_env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in STRIPPED}
    env["PYTHONPATH"] = str(ROOT)
    return env


def test_fresh_process_settles_then_renders_without_mujoco_gl():
    code = (
        "import os\n"
        "assert 'MUJOCO_GL' not in os.environ\n"
        "from simulate.engines import settle\n"
        "import numpy as np\n"
        "from synth_scenes.demo import make_demo\n"
        "arr = make_demo(np.random.default_rng(0))\n"
        "res = settle(arr, 'mujoco')\n"
        "from simulate.scan import scan_arrangement\n"
        "scan = scan_arrangement(arr, rng=np.random.default_rng(0), noise='none')\n"
        "d = scan.frames[0].depth\n"
        "print(os.environ['MUJOCO_GL'], res.stable, int((d > 0).sum()))\n")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=_bare_env(),
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    backend, stable, pixels = proc.stdout.split()
    assert backend in ("egl", "osmesa")
    assert stable == "True"
    assert int(pixels) > 1000  # a real depth image, not a black frame


def test_a_failed_task_makes_eval_exit_1(tmp_path, monkeypatch, capsys):
    """A suite with a failed task exits 1, says how many failed and prints the first
    error, though its table of the other tasks is written."""
    import eval.suites._scenes as scenes
    from eval.cli import main

    real = scenes.scene_task

    def flaky(rng, **kw):  # noqa: ANN001 - the task signature
        if kw["views"] == 1:
            raise ValueError("a deliberately broken scene")
        return real(rng=rng, **kw)

    monkeypatch.setattr(scenes, "scene_task", flaky)
    rc = main(["eval", "table1", "--quick", "--out", str(tmp_path / "t1")])
    err = capsys.readouterr().err
    assert rc == 1
    lines = [ln for ln in err.splitlines() if "tasks failed" in ln]
    assert len(lines) == 1, err
    assert "ValueError: a deliberately broken scene" in lines[0]
    assert lines[0].startswith("unseen eval table1: 1 of 2 tasks failed; first: stack-1000-v1: ")
    assert (tmp_path / "t1" / "table1.md").is_file()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_for(port: int, seconds: float) -> None:
    end = time.time() + seconds
    while time.time() < end:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.2)
    raise TimeoutError(f"nothing listens on {port} after {seconds} s")


@pytest.fixture
def cluster(tmp_path):
    """``dask scheduler`` and ``dask worker --nworkers 2`` as separate processes, started
    from a clean environment in a folder that is not the repository."""
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = _bare_env()
    logs = tmp_path / "logs"
    logs.mkdir()
    procs = []
    try:
        procs.append(subprocess.Popen(
            [str(BIN / "dask"), "scheduler", "--host", "127.0.0.1", "--port", str(port),
             "--no-dashboard"], cwd=logs, env=env,
            stdout=open(logs / "scheduler.log", "w"), stderr=subprocess.STDOUT))
        _wait_for(port, 60)
        procs.append(subprocess.Popen(
            [str(BIN / "dask"), "worker", address, "--nworkers", "2", "--nthreads", "1",
             "--no-dashboard"], cwd=logs, env=env,
            stdout=open(logs / "worker.log", "w"), stderr=subprocess.STDOUT))
        from distributed import Client

        with Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=90)
        yield address
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()


def _unseen(*argv: str) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    return subprocess.run([str(BIN / "unseen"), *argv], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=900)


@pytest.mark.slow
def test_suite_on_separate_scheduler_and_workers_matches_serial(tmp_path, cluster):
    serial = _unseen("eval", "table1", "--quick", "--out", str(tmp_path / "serial"))
    assert serial.returncode == 0, serial.stderr[-2000:]
    remote = _unseen("eval", "table1", "--quick", "--out", str(tmp_path / "dask"),
                     "--dask", cluster)
    assert remote.returncode == 0, remote.stderr[-2000:]
    for name in ("table1.md", "table1.csv", "table1_physics.csv"):
        assert (tmp_path / "dask" / name).read_bytes() == (tmp_path / "serial" / name).read_bytes()
    timing = json.loads((tmp_path / "dask" / "timing.json").read_text())
    assert timing["backend"] == f"dask {cluster}" and timing["n_failed"] == 0


@pytest.mark.slow
def test_dataset_on_separate_scheduler_and_workers_matches_serial(tmp_path, cluster):
    from synth_scenes.dataset import file_hashes

    argv = ["dataset", "make", "--families", "stack,table,chair,shelf", "--n", "4",
            "--views", "1-2", "--first-seed", "21"]
    serial = _unseen(*argv, "--out", str(tmp_path / "serial"))
    assert serial.returncode == 0, serial.stderr[-2000:]
    remote = _unseen(*argv, "--out", str(tmp_path / "dask"), "--dask", cluster)
    assert remote.returncode == 0, remote.stderr[-2000:]
    assert f"on dask {cluster}" in remote.stdout
    for name in ("manifest.jsonl", "dataset.json", "stats.png"):
        assert (tmp_path / "dask" / name).read_bytes() == (tmp_path / "serial" / name).read_bytes()
    a, b = file_hashes(tmp_path / "serial"), file_hashes(tmp_path / "dask")
    assert {k: v for k, v in a.items() if not k.startswith((".run/", "DATASET"))} == \
        {k: v for k, v in b.items() if not k.startswith((".run/", "DATASET"))}
