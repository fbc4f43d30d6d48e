"""Benchmark sections for ``unseen bench``.

Each module here is one section: it defines ``TITLE: str`` and
``run(quick: bool) -> list[BenchTable]``.  ``unseen bench`` runs every section and
prints/writes the tables (medians over repeats, with the machine description).
Timings live here, never in unit tests.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field


@dataclass(frozen=True)
class BenchTable:
    """One Markdown table: ``columns`` headers, ``rows`` of cells, an optional ``note``."""

    title: str
    columns: list[str]
    rows: list[list]
    note: str = ""
    #: optional series for the time-vs-size plot: {label: [(size, seconds), ...]}
    series: dict[str, list[tuple[float, float]]] = field(default_factory=dict)

    def markdown(self) -> str:
        def fmt(v: object) -> str:
            if isinstance(v, float):
                return f"{v:.4g}"
            return str(v)

        lines = [f"### {self.title}", "", "| " + " | ".join(self.columns) + " |",
                 "|" + "---|" * len(self.columns)]
        lines += ["| " + " | ".join(fmt(v) for v in row) + " |" for row in self.rows]
        if self.note:
            lines += ["", self.note]
        return "\n".join(lines) + "\n"


def median_time(fn: Callable[[], object], repeats: int = 5, warmup: int = 1) -> float:
    """Median wall time of ``fn()`` in seconds over ``repeats`` runs after ``warmup`` runs."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)
