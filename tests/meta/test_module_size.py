"""Issue 20's size limits: ``pipeline/imagine.py`` is an orchestrator (at most 400
lines) and no module of ``pipeline/`` runs past 900 lines; a file that grows past them
holds something that should be a named part of its own."""

from __future__ import annotations

from pathlib import Path

PIPELINE = Path(__file__).resolve().parents[2] / "pipeline"


def _lines(path: Path) -> int:
    return len(path.read_text(encoding="utf-8").splitlines())


def test_imagine_is_an_orchestrator():
    assert _lines(PIPELINE / "imagine.py") <= 400


def test_no_pipeline_module_runs_past_900_lines():
    long = {str(p.relative_to(PIPELINE)): _lines(p) for p in PIPELINE.rglob("*.py")
            if _lines(p) > 900}
    assert long == {}
