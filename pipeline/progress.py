"""A minimal progress bar on stderr; a plain line now and then when stderr is no terminal.

Long work (searches, suites, settling many scenes) takes a ``progress`` callable or
wraps an iterable with :func:`track`.  On a terminal the bar is redrawn in place; into a
pipe or a CI log a line is written only once work has run :data:`PLAIN_EVERY` seconds,
and then every as many seconds (a log shows that a long suite is alive and how far it
got; work shorter than that, a test's, prints nothing).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Iterable, Iterator
from typing import TextIO, TypeVar

T = TypeVar("T")

#: Seconds between two plain progress lines when stderr is not a terminal.
PLAIN_EVERY = 30.0


class Progress:
    """``with Progress(total, "settling") as p: ... p.update()``; draws at most 10 times a second."""

    def __init__(self, total: int | None, label: str, stream: TextIO | None = None,
                 enabled: bool | None = None) -> None:
        self.total = total
        self.label = label
        self.stream = stream or sys.stderr
        tty = self.stream.isatty()
        self.enabled = tty if enabled is None else enabled
        #: plain lines (no terminal, and not switched off or on by the caller)
        self.plain = enabled is None and not tty
        self.count = 0
        self.start = time.perf_counter()
        self._last = 0.0
        self._last_plain = self.start
        self._plain_lines = 0

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        if self.enabled:
            self._draw(final=True)
            self.stream.write("\n")
            self.stream.flush()
        elif self._plain_lines:
            self._line("done")

    def _line(self, note: str = "") -> None:
        """One plain progress line (no terminal)."""
        elapsed = time.perf_counter() - self.start
        done = f"{self.count}/{self.total}" if self.total else f"{self.count}"
        self.stream.write(f"{self.label}: {done} after {elapsed:.0f} s{' ' + note if note else ''}\n")
        self.stream.flush()
        self._plain_lines += 1

    def update(self, n: int = 1, note: str = "") -> None:
        self.count += n
        now = time.perf_counter()
        if self.plain and now - self._last_plain >= PLAIN_EVERY:
            self._last_plain = now
            self._line(note)
        if self.enabled and (now - self._last > 0.1 or (self.total and self.count >= self.total)):
            self._last = now
            self._draw(note=note)

    def _draw(self, final: bool = False, note: str = "") -> None:
        elapsed = time.perf_counter() - self.start
        if self.total:
            frac = min(1.0, self.count / self.total)
            bar = "#" * int(30 * frac) + "-" * (30 - int(30 * frac))
            text = f"\r{self.label} [{bar}] {self.count}/{self.total} {elapsed:5.1f}s {note}"
        else:
            text = f"\r{self.label} {self.count} {elapsed:5.1f}s {note}"
        self.stream.write(text[:120])
        self.stream.flush()


def track(items: Iterable[T], label: str, total: int | None = None,
          enabled: bool | None = None) -> Iterator[T]:
    """Iterate ``items`` while drawing a progress bar."""
    if total is None:
        try:
            total = len(items)  # type: ignore[arg-type]
        except TypeError:
            total = None
    with Progress(total, label, enabled=enabled) as bar:
        for item in items:
            yield item
            bar.update()
