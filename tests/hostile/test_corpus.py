"""Replay the hostile-input corpus (``tests/hostile/corpus.py``) through the command line.

Every case must end with its exit code and exactly one line on stderr holding the
case's needle: no traceback, no warning, no hang (each case has 120 s), and nothing in
its scratch folder changed: every input byte-identical, no output folder, lock, temporary
folder or ``command.json`` left behind.  Cases run in this process through
``eval.cli.main`` (the subprocess start-up of 88 commands would cost a minute); stdout
and stderr are captured at the file-descriptor level, so C libraries printing there
are caught too.  The peak memory of the whole replay must stay under 4 GB.
"""

from __future__ import annotations

import hashlib
import os
import resource
import shutil
import signal
import stat
from pathlib import Path

import pytest

from tests.hostile.corpus import CASES

DATA = Path(__file__).resolve().parents[1] / "data" / "hostile"
PEAK_LIMIT_BYTES = 4 * 2**30


def snapshot(root: Path) -> dict[str, str]:
    """Relative path -> SHA-256 of every regular file (or its type for anything else)."""
    out = {}
    for p in sorted(root.rglob("*")):
        st = os.lstat(p)
        key = p.relative_to(root).as_posix()
        if stat.S_ISREG(st.st_mode):
            out[key] = hashlib.sha256(p.read_bytes()).hexdigest()
        else:
            out[key] = "dir" if stat.S_ISDIR(st.st_mode) else f"mode {stat.S_IFMT(st.st_mode)}"
    return out


def prepare(tmp: Path) -> dict[str, str]:
    """The case's scratch folder with every placeholder's target made."""
    shutil.copytree(DATA, tmp / "corpus")
    os.mkfifo(tmp / "pipe.json")
    (tmp / "plain.txt").write_text("not a folder\n")
    (tmp / "foreign").mkdir()
    (tmp / "foreign" / "notes.txt").write_text("mine\n")
    (tmp / "nested.json").write_text("[" * 200_000 + "]" * 200_000)
    return {"D": str(tmp / "corpus"), "T": str(tmp), "NESTED": str(tmp / "nested.json"),
            "FIFO": str(tmp / "pipe.json"), "ZERO": "/dev/zero", "FILE": str(tmp / "plain.txt"),
            "FOREIGN": str(tmp / "foreign")}


class Hang(Exception):
    pass


def _alarm(signum, frame):  # noqa: ARG001 - signal handler signature
    raise Hang("the command did not finish within 120 s")


@pytest.mark.parametrize("case_id, argv, code, needle", CASES, ids=[c[0] for c in CASES])
def test_hostile_input(case_id, argv, code, needle, tmp_path, capfd, monkeypatch):
    from eval.cli import main

    places = prepare(tmp_path)
    args = [a.format(**places) for a in argv]
    monkeypatch.setattr("sys.argv", ["unseen", *args])
    monkeypatch.chdir(tmp_path)
    before = snapshot(tmp_path)
    capfd.readouterr()
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(120)
    try:
        try:
            got = main(args)
        except SystemExit as exc:  # argparse
            got = exc.code
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    out, err = capfd.readouterr()
    lines = err.strip().splitlines()
    assert got == code, f"{case_id}: exit {got}, stderr: {err!r}"
    assert len(lines) == 1, f"{case_id}: stderr has {len(lines)} lines: {err!r}"
    assert "Traceback" not in err and needle in lines[0], f"{case_id}: {lines[0]!r}"
    assert snapshot(tmp_path) == before, f"{case_id}: the scratch folder changed"
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    assert peak < PEAK_LIMIT_BYTES, f"{case_id}: peak memory {peak / 2**30:.2f} GB"
