"""``unseen bench`` with tiny fake sections: document, plot, failing section, --only."""

from __future__ import annotations

import sys
import types

import pytest

from eval.benchmarks import BenchTable, median_time
from eval.cli import main
from eval.commands import bench


def _tiny_run(quick: bool) -> list[BenchTable]:
    sizes = [10, 100] if quick else [10, 100, 1000]
    times = [median_time(lambda n=n: sum(range(n)), repeats=3) for n in sizes]
    rows = [[n, t] for n, t in zip(sizes, times, strict=True)]
    return [BenchTable("sum of range", ["n", "median s"], rows, note="tiny fake",
                       series={"sum": list(zip(sizes, times, strict=True))}),
            BenchTable("no series", ["a"], [["x"]])]


def _broken_run(quick: bool) -> list[BenchTable]:
    raise RuntimeError("solver exploded")


@pytest.fixture
def sections(monkeypatch):
    for name, fn, title in (("aa_tiny", _tiny_run, "Tiny section"),
                            ("bb_broken", _broken_run, "Broken section")):
        mod = types.ModuleType(f"eval.benchmarks.{name}")
        mod.TITLE = title
        mod.run = fn
        monkeypatch.setitem(sys.modules, mod.__name__, mod)
    monkeypatch.setattr(bench, "section_names", lambda: ["aa_tiny", "bb_broken"])


def test_bench_document_plot_and_failed_section(sections, tmp_path, capsys):
    out = tmp_path / "b"
    assert main(["bench", "--out", str(out), "--quick"]) == 1  # one section failed
    cap = capsys.readouterr()
    doc = (out / "bench.md").read_text()
    assert cap.out == doc
    assert "## Machine" in doc and "| CPU |" in doc and "| Python |" in doc and "numpy" in doc
    assert "Sections: 1 ok, 1 failed (bb_broken)." in doc
    assert "## Tiny section" in doc and "### sum of range" in doc and "| 100 |" in doc
    assert "## Broken section (FAILED)" in doc and "RuntimeError: solver exploded" in doc
    assert doc.index("## Tiny section") < doc.index("## Broken section")
    assert "section bb_broken failed" in cap.err
    png = (out / "bench.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"


def test_bench_only_selects_and_all_ok_exits_0(sections, tmp_path, capsys):
    out = tmp_path / "b"
    assert main(["bench", "--out", str(out), "--quick", "--only", "aa_tiny"]) == 0
    doc = capsys.readouterr().out
    assert "Tiny section" in doc and "Broken" not in doc
    assert "Sections: 1 ok, 0 failed." in doc
    assert bench.plot([bench.run_section("aa_tiny", True)], tmp_path / "p.png") == 1


def test_bench_unknown_section_exit_2(sections, tmp_path, capsys):
    assert main(["bench", "--out", str(tmp_path / "b"), "--only", "nope"]) == 2
    err = capsys.readouterr().err.strip()
    assert "unknown section(s) nope" in err and "aa_tiny" in err and "\n" not in err


def test_bench_section_import_error_is_a_failed_section():
    r = bench.run_section("does_not_exist_anywhere", quick=True)
    assert not r.ok and r.error.startswith("ModuleNotFoundError")
