"""A minimal progress bar on stderr, silent when stderr is not a terminal.

Long work (searches, suites, settling many scenes) takes a ``progress`` callable or
wraps an iterable with :func:`track`; nothing is printed in tests or pipes.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Iterable, Iterator
from typing import TextIO, TypeVar

T = TypeVar("T")


class Progress:
    """``with Progress(total, "settling") as p: ... p.update()``; draws at most 10 times a second."""

    def __init__(self, total: int | None, label: str, stream: TextIO | None = None,
                 enabled: bool | None = None) -> None:
        self.total = total
        self.label = label
        self.stream = stream or sys.stderr
        self.enabled = self.stream.isatty() if enabled is None else enabled
        self.count = 0
        self.start = time.perf_counter()
        self._last = 0.0

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        if self.enabled:
            self._draw(final=True)
            self.stream.write("\n")
            self.stream.flush()

    def update(self, n: int = 1, note: str = "") -> None:
        self.count += n
        now = time.perf_counter()
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
