"""The regression suite fails (exit 1) when a stored expectation is made impossible to meet,
passes within its tolerance, and its stored expectations cover every case."""

from __future__ import annotations

import argparse
import io
import json
from pathlib import Path

import pytest

from eval.suites import regression
from pipeline.errors import InputError

pytest.importorskip("mujoco")

CASE = "stack-1000"


def _run(out: Path, expected: Path, update: bool = False) -> tuple[int, str]:
    stream = io.StringIO()
    args = argparse.Namespace(out=out, seed=0, n=None, workers=1, dask=None, quick=False,
                              only=[CASE], expected=expected, update=update, stream=stream)
    return regression.run(args), stream.getvalue()


@pytest.fixture(scope="module")
def measured(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    """One run of the case, its figures written as an expectation file by --update."""
    tmp = tmp_path_factory.mktemp("regression")
    exp = tmp / "expected.json"
    rc, text = _run(tmp / "out", exp, update=True)
    assert rc == 0 and "expectations written" in text
    figures = json.loads(exp.read_text())["cases"][CASE]
    assert set(figures) == {"f1", "stands", "agree", "fixed"}
    return tmp, figures


def _with(tmp: Path, name: str, figures: dict) -> Path:
    path = tmp / name
    path.write_text(json.dumps({"cases": {CASE: figures}}))
    return path


def test_unchanged_expectation_passes(measured: tuple[Path, dict]) -> None:
    tmp, fig = measured
    rc, text = _run(tmp / "out", _with(tmp, "same.json", fig))   # resumed: no rerun
    assert rc == 0 and "no regression" in text


def test_within_tolerance_passes(measured: tuple[Path, dict]) -> None:
    tmp, fig = measured
    slack = {**fig, "f1": fig["f1"] + 0.5 * regression.F1_TOL}
    assert _run(tmp / "out", _with(tmp, "slack.json", slack))[0] == 0


@pytest.mark.parametrize("flip", [{"f1": 1.05}, {"fixed": -1}, {"stands": 2}, {"agree": 2}])
def test_flipped_expectation_fails(measured: tuple[Path, dict], flip: dict) -> None:
    tmp, fig = measured
    (name,) = flip
    rc, text = _run(tmp / "out", _with(tmp, f"flip_{name}.json", {**fig, **flip}))
    assert rc == 1
    assert "REGRESSED" in text and f"{CASE}: {name}" in text


def test_f1_drop_beyond_tolerance_fails(measured: tuple[Path, dict]) -> None:
    tmp, fig = measured
    rc, _ = _run(tmp / "out", _with(tmp, "drop.json",
                                    {**fig, "f1": fig["f1"] + 2 * regression.F1_TOL}))
    assert rc == 1


def test_stored_expectations_cover_every_case() -> None:
    data = json.loads(regression.EXPECTED.read_text())
    assert set(data["cases"]) == {c[0] for c in regression.CASES}
    for fig in data["cases"].values():
        assert 0.0 <= fig["f1"] <= 1.0 and fig["stands"] in (0, 1) and fig["agree"] in (0, 1)
        assert fig["fixed"] >= 0


def test_unknown_case_is_bad_input(tmp_path: Path) -> None:
    args = argparse.Namespace(out=tmp_path, seed=0, n=None, workers=1, dask=None, quick=False,
                              only=["nope"], expected=None, update=False, stream=io.StringIO())
    with pytest.raises(InputError, match="--only"):
        regression.run(args)
