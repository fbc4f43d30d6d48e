"""Progress on stderr: a bar on a terminal, a plain line every 30 s into a pipe or log."""

from __future__ import annotations

import io

import pytest

import pipeline.progress as progress
from pipeline.progress import PLAIN_EVERY, Progress


class Clock:
    """A stand-in for ``time.perf_counter`` that moves only when told."""

    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def clock(monkeypatch) -> Clock:
    c = Clock()
    monkeypatch.setattr(progress.time, "perf_counter", c)
    return c


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_into_a_log_a_line_every_30_s_and_one_at_the_end(clock):
    log = io.StringIO()
    with Progress(10, "pool", stream=log) as bar:
        for step in range(10):
            clock.t += 7.0  # 7 s a task: lines after the 5th (35 s) and the 10th (70 s)
            bar.update()
            if step == 3:
                assert log.getvalue() == ""  # 28 s: nothing yet
    assert log.getvalue().splitlines() == [
        "pool: 5/10 after 35 s", "pool: 10/10 after 70 s", "pool: 10/10 after 70 s done"]
    assert "\r" not in log.getvalue()
    assert PLAIN_EVERY == 30.0


def test_work_shorter_than_30_s_prints_nothing(clock):
    log = io.StringIO()
    with Progress(None, "unseen run", stream=log) as bar:
        for _ in range(5):
            clock.t += PLAIN_EVERY / 6
            bar.update(note="search")
    assert log.getvalue() == ""


def test_switched_off_it_is_silent_however_long(clock):
    log = io.StringIO()
    with Progress(3, "pool", stream=log, enabled=False) as bar:
        for _ in range(3):
            clock.t += 100.0
            bar.update()
    assert log.getvalue() == ""


def test_on_a_terminal_the_bar_is_redrawn_in_place(clock):
    tty = Terminal()
    with Progress(4, "bench", stream=tty) as bar:
        for _ in range(4):
            clock.t += 40.0
            bar.update()
    text = tty.getvalue()
    assert text.startswith("\rbench [") and text.endswith("\n")
    assert "4/4" in text and "after" not in text  # no plain lines on a terminal
