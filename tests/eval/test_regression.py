"""The regression suite is a folder of scans verified as ``unseen regress verify`` does: it
fails (exit 1) when a stored expectation is made impossible to meet, passes within its
tolerance, says how many cases failed to run, and its stored expectations cover every
case in the expectation file's format."""

from __future__ import annotations

import argparse
import copy
import io
import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from eval import regress
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
    """One run of the case, its record written as an expectation file by --update."""
    tmp = tmp_path_factory.mktemp("regression")
    exp = tmp / "expected.json"
    rc, text = _run(tmp / "out", exp, update=True)
    assert rc == 0 and "expectations written" in text
    data = json.loads(exp.read_text())
    assert data["tolerances"] == regression.TOLERANCES.to_json()
    entry = data["scans"][CASE]
    assert set(entry["truth"]) == {"f1", "size"} and set(entry["verdicts"]) == {"analytic",
                                                                              "mujoco"}
    # the case is materialized as a scene directory, with the record beside it
    scans = tmp / "out" / "scans"
    assert (scans / CASE / "scene.json").is_file() and (scans / CASE / "scan").is_dir()
    assert json.loads((scans / regress.RECORD_NAME).read_text()) == data
    return tmp, data


def _with(tmp: Path, name: str, data: dict, change) -> Path:  # noqa: ANN001
    body = copy.deepcopy(data)
    change(body["scans"][CASE])
    path = tmp / name
    path.write_text(json.dumps(body))
    return path


def test_unchanged_expectation_passes(measured: tuple[Path, dict]) -> None:
    tmp, data = measured
    rc, text = _run(tmp / "out", _with(tmp, "same.json", data, lambda e: None))  # resumed
    assert rc == 0 and "no regression" in text
    suite = ET.parse(tmp / "out" / "regression.xml").getroot().find("testsuite")
    assert (suite.get("tests"), suite.get("failures"), suite.get("errors")) == ("1", "0", "0")
    assert "1 passed, 0 dropped" in (tmp / "out" / "regress.md").read_text()


def test_within_tolerance_passes(measured: tuple[Path, dict]) -> None:
    tmp, data = measured
    path = _with(tmp, "slack.json", data,
                 lambda e: e["truth"].update(f1=e["truth"]["f1"] + 0.5 * regression.F1_TOL))
    assert _run(tmp / "out", path)[0] == 0


def _raise_f1(e: dict) -> None:
    e["truth"]["f1"] = 1.05


def _lower_fixed(e: dict) -> None:
    e["fixed"] = -1


def _add_engine(e: dict) -> None:
    e["verdicts"]["pybullet"] = True  # recorded as standing there, not measured now


@pytest.mark.parametrize(("change", "figure"), [(_raise_f1, "f1"), (_lower_fixed, "fixed"),
                                                (_add_engine, "stands:pybullet")])
def test_flipped_expectation_fails(measured: tuple[Path, dict], change, figure: str) -> None:  # noqa: ANN001
    tmp, data = measured
    rc, text = _run(tmp / "out", _with(tmp, f"flip_{figure}.json", data, change))
    assert rc == 1
    assert "REGRESSED" in text and f"{CASE}: {figure}" in text
    case = ET.parse(tmp / "out" / "regression.xml").getroot().find("testsuite/testcase")
    assert case.get("name") == CASE and case.find("failure").get("message").startswith(figure)


def test_f1_drop_beyond_tolerance_fails(measured: tuple[Path, dict]) -> None:
    tmp, data = measured
    path = _with(tmp, "drop.json", data,
                 lambda e: e["truth"].update(f1=e["truth"]["f1"] + 2 * regression.F1_TOL))
    assert _run(tmp / "out", path)[0] == 1


def test_a_failed_case_exits_1_and_says_so(tmp_path: Path, monkeypatch, capsys) -> None:  # noqa: ANN001
    import eval.suites._scenes as scenes

    def boom(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        raise RuntimeError("no scene today")

    monkeypatch.setattr(scenes, "make_scene", boom)
    rc, text = _run(tmp_path / "out", regression.EXPECTED)
    err = capsys.readouterr().err
    assert rc == 1
    assert f"1 of 1 cases failed to run; first: {CASE}: RuntimeError: no scene today" in err
    assert f"{CASE}: failed to run: RuntimeError: no scene today" in text


def test_stored_expectations_cover_every_case() -> None:
    record = regress.read_record(regression.EXPECTED)
    assert set(record.scans) == {c[0] for c in regression.CASES}
    assert record.engines == (regression.ENGINE,) and record.tolerances == regression.TOLERANCES
    for entry in record.scans.values():
        assert 0.0 <= entry["truth"]["f1"] <= 1.0
        assert set(entry["verdicts"]) == {"analytic", regression.ENGINE}
        assert entry["fixed"] >= 0 and entry["boxes"] and entry["contacts"]
    # the file is in its canonical form (an --update writes the same bytes)
    assert regress.dumps(record) == regression.EXPECTED.read_text()


def test_unknown_case_is_bad_input(tmp_path: Path) -> None:
    args = argparse.Namespace(out=tmp_path, seed=0, n=None, workers=1, dask=None, quick=False,
                              only=["nope"], expected=None, update=False, stream=io.StringIO())
    with pytest.raises(InputError, match="--only"):
        regression.run(args)


def test_old_expectation_file_is_bad_input(tmp_path: Path) -> None:
    old = tmp_path / "old.json"
    old.write_text(json.dumps({"cases": {CASE: {"f1": 1.0}}}))
    with pytest.raises(InputError, match="not an expectation file"):
        _run(tmp_path / "out", old)
