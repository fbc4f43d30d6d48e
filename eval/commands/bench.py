"""``unseen bench --out DIR``: run every benchmark section and print one Markdown document."""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

from pipeline.outdir import out_arg

EPILOG = """\
Sections are the modules in eval/benchmarks/ (each has TITLE and run(quick) returning
tables).  The document (machine description, then each section's tables with medians)
goes to stdout and DIR/bench.md; DIR/bench.png plots time against problem size for
every table that has series.  A section that fails is reported with its error and the
others still run.  Exit 0, 1 when any section failed, 2 on bad input."""


@dataclass(frozen=True)
class SectionResult:
    """One section's outcome: its tables, or the error it raised."""

    name: str
    title: str
    ok: bool
    tables: list = field(default_factory=list)
    error: str = ""
    traceback: str = ""
    seconds: float = 0.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=out_arg, required=True, help="output folder (created)")
    parser.add_argument("--quick", action="store_true", help="small sizes, few repeats")
    parser.add_argument("--only", default=None, metavar="SECTION,...",
                        help="run only these sections (module names in eval/benchmarks)")


def section_names() -> list[str]:
    """The benchmark section modules in ``eval/benchmarks`` (not imported)."""
    import pkgutil

    import eval.benchmarks

    return sorted(m.name for m in pkgutil.iter_modules(eval.benchmarks.__path__)
                  if not m.name.startswith("_"))


def run_section(name: str, quick: bool) -> SectionResult:
    """Import and run one section; any exception becomes a failed result."""
    import importlib

    t0 = time.perf_counter()
    title = name
    try:
        module = importlib.import_module(f"eval.benchmarks.{name}")
        title = str(getattr(module, "TITLE", name))
        tables = list(module.run(quick))
        for t in tables:
            if not hasattr(t, "markdown"):
                raise TypeError(f"run() returned a {type(t).__name__}, expected BenchTable")
        return SectionResult(name, title, True, tables, seconds=time.perf_counter() - t0)
    except Exception as exc:  # noqa: BLE001 - a failing section is reported, the rest go on
        return SectionResult(name, title, False, [],
                             f"{type(exc).__name__}: {exc}".splitlines()[0][:500],
                             traceback.format_exc(), time.perf_counter() - t0)


def _read(path: str) -> str:
    try:
        with open(path, encoding="utf-8") as fh:
            return fh.read()
    except OSError:
        return ""


def machine() -> list[tuple[str, str]]:
    """(item, value) rows describing this machine and the package versions."""
    from eval.commands.evaluate import package_versions

    cpu = next((line.split(":", 1)[1].strip() for line in _read("/proc/cpuinfo").splitlines()
                if line.startswith("model name")), platform.processor() or platform.machine())
    mem = next((line.split()[1] for line in _read("/proc/meminfo").splitlines()
                if line.startswith("MemTotal:")), None)
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count() or 0
    rows = [("CPU", cpu), ("cores", f"{os.cpu_count()} logical, {usable} usable by this process"),
            ("RAM", f"{int(mem) / 2**20:.1f} GiB" if mem else "unknown"),
            ("OS", platform.platform()), ("Python", sys.version.split()[0])]
    versions = package_versions()
    try:
        from importlib.metadata import version

        versions["compas_cra"] = version("compas_cra")
    except Exception:  # noqa: BLE001 - optional
        versions["compas_cra"] = None
    rows.append(("packages", ", ".join(f"{k} {v}" for k, v in versions.items() if v)))
    return rows


def document(results: list[SectionResult], quick: bool) -> str:
    """The whole Markdown report."""
    stamp = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    lines = ["# unseen benchmark", "",
             f"{'Quick' if quick else 'Full'} run, {stamp}. Times are medians of repeated "
             "runs in seconds unless a table says otherwise.", "",
             "## Machine", "", "| item | value |", "|---|---|"]
    lines += [f"| {k} | {v} |" for k, v in machine()]
    failed = [r for r in results if not r.ok]
    lines += ["", f"Sections: {len(results) - len(failed)} ok, {len(failed)} failed"
                  + (f" ({', '.join(r.name for r in failed)})" if failed else "") + "."]
    if not results:
        lines += ["", "No benchmark sections found in eval/benchmarks/."]
    for r in results:
        lines += ["", f"## {r.title}" + ("" if r.ok else " (FAILED)"), "",
                  f"Section `{r.name}`, {r.seconds:.1f} s."]
        if not r.ok:
            lines += ["", f"Error: `{r.error}`", "", "```", r.traceback.rstrip(), "```"]
            continue
        for t in r.tables:
            lines += ["", t.markdown().rstrip()]
    return "\n".join(lines) + "\n"


def plot(results: list[SectionResult], path: Path) -> int:
    """Time against problem size, one panel per table with series; returns the panel count."""
    import math

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    from pipeline import atomic

    panels = [t for r in results if r.ok for t in r.tables if getattr(t, "series", None)]
    n = len(panels)
    cols = min(3, max(n, 1))
    rows = max(1, math.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(5.0 * cols, 3.8 * rows), squeeze=False)
    for ax in axes.flat[n:]:
        ax.axis("off")
    if n == 0:
        axes[0, 0].text(0.5, 0.5, "no timing series", ha="center", va="center")
    for ax, table in zip(axes.flat, panels, strict=False):
        positive = True
        for label, pts in table.series.items():
            pts = sorted(pts)
            xs = [p[0] for p in pts]
            ys = [p[1] for p in pts]
            positive &= all(x > 0 for x in xs) and all(y > 0 for y in ys)
            ax.plot(xs, ys, marker="o", label=label)
        if positive:
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.xaxis.set_minor_formatter(NullFormatter())
        sizes = sorted({p[0] for pts in table.series.values() for p in pts})
        if 0 < len(sizes) <= 10:  # label the measured sizes themselves
            ax.set_xticks(sizes, [f"{x:g}" for x in sizes])
        ax.set_title(table.title, fontsize=9)
        ax.set_xlabel(str(table.columns[0]) if table.columns else "problem size")
        ax.set_ylabel("seconds")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    with atomic.atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=100, metadata={"Software": None})
    plt.close(fig)
    return n


def run(args: argparse.Namespace) -> int:
    from pipeline import atomic
    from pipeline.errors import InputError
    from pipeline.outdir import check_results_folder
    from pipeline.progress import Progress

    check_results_folder(args.out, marker="bench.md", what="unseen bench")
    names = section_names()
    if args.only is not None:
        wanted = [s.strip() for s in args.only.split(",") if s.strip()]
        unknown = [s for s in wanted if s not in names]
        if unknown or not wanted:
            raise InputError(f"--only: unknown section(s) {', '.join(unknown) or '(none given)'}; "
                             f"available: {', '.join(names) or 'none'}")
        names = [s for s in names if s in wanted]
    if args.out.exists() and not args.out.is_dir():
        raise InputError(f"--out {args.out}: exists and is not a folder")
    args.out.mkdir(parents=True, exist_ok=True)
    results = []
    with Progress(len(names), "bench") as bar:
        for name in names:
            bar.update(0, note=name)
            results.append(run_section(name, args.quick))
            bar.update(note=name)
    doc = document(results, args.quick)
    atomic.write_text(args.out / "bench.md", doc)
    plot(results, args.out / "bench.png")
    sys.stdout.write(doc)
    for r in results:
        if not r.ok:
            print(f"unseen bench: section {r.name} failed: {r.error}", file=sys.stderr)
    return 0 if all(r.ok for r in results) else 1
