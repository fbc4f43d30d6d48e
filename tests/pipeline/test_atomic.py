"""Atomic file output never turns a device, a named pipe or a socket into a file."""

from __future__ import annotations

import os
import socket
import stat

import pytest

from pipeline import atomic
from pipeline.errors import InputError


def test_a_regular_file_is_replaced_whole(tmp_path):
    p = tmp_path / "out.txt"
    p.write_text("old")
    atomic.write_text(p, "new")
    assert p.read_text() == "new"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["out.txt"]  # no temporary left


def test_a_named_pipe_stays_a_pipe(tmp_path):
    # renaming a finished temporary file onto a FIFO (or onto /dev/null, as root) would
    # replace it by a regular file: refused in one line, the pipe untouched
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match=r"pipe: is a named pipe; outputs are written to "
                                         r"regular files"):
        atomic.write_text(fifo, "report")
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert [x.name for x in tmp_path.iterdir()] == ["pipe"]


def test_a_socket_stays_a_socket(tmp_path):
    path = tmp_path / "s"
    with socket.socket(socket.AF_UNIX) as s:
        s.bind(str(path))
        with pytest.raises(InputError, match="is a socket"):
            atomic.write_bytes(path, b"x")
        assert stat.S_ISSOCK(os.lstat(path).st_mode)


def test_dev_null_is_refused_not_replaced():
    before = os.stat("/dev/null")
    with pytest.raises(InputError, match="/dev/null: is a device"):
        atomic.write_text("/dev/null", "report")
    after = os.stat("/dev/null")
    assert stat.S_ISCHR(after.st_mode) and after.st_rdev == before.st_rdev
