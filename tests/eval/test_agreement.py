"""The agreement suite: tables, plot and disagreements from a small run; counting logic."""

from __future__ import annotations

import argparse
import csv
import io
import json
from pathlib import Path

import pytest

from eval.suites import agreement
from pipeline.arrangement_io import read_arrangement

pytest.importorskip("mujoco")
pytest.importorskip("pybullet")


def _rec(a: bool, m: bool, p: bool, margin=None, energy=1e-30) -> dict:  # noqa: ANN001
    r = {"margin": margin, "analytic": {"stable": a, "energy": energy, "threshold": 1e-5},
         "mujoco": {"stable": m}, "pybullet": {"stable": p}}
    r["near"] = agreement.near_threshold(r)
    return r


def test_counting() -> None:
    recs = [_rec(True, True, True), _rec(False, False, True), _rec(True, False, False),
            _rec(True, False, True, margin=0.01), _rec(False, True, True, energy=3e-5)]
    assert [r["near"] for r in recs] == [False, False, False, True, True]
    s = agreement.summarize(recs)
    assert (s["n"], s["n_outside"], s["n_band"]) == (5, 3, 2)
    am = s["pairs"]["analytic-mujoco"]
    assert am["outside"] == {"ss": 1, "su": 1, "us": 0, "uu": 1}
    assert am["agree_outside"] == pytest.approx(2 / 3)
    assert s["pairs"]["mujoco-pybullet"]["outside"] == {"ss": 1, "su": 0, "us": 1, "uu": 1}
    assert s["pairs"]["analytic-pybullet"]["band"] == {"ss": 1, "su": 0, "us": 1, "uu": 0}


def test_small_run_writes_everything(tmp_path: Path) -> None:
    stream = io.StringIO()
    args = argparse.Namespace(out=tmp_path, seed=3, n=6, workers=1, dask=None, quick=False,
                              stream=stream)
    assert agreement.run(args) == 0
    for name in ("agreement.md", "agreement.csv", "agreement_by_kind.md", "cases.csv",
                 "agreement.png", "summary.json"):
        assert (tmp_path / name).stat().st_size > 0
    assert "analytic-mujoco" in stream.getvalue()
    rows = list(csv.DictReader((tmp_path / "cases.csv").open()))
    assert len(rows) == 6
    s = json.loads((tmp_path / "summary.json").read_text())
    for pair in s["pairs"].values():
        assert sum(pair["outside"].values()) == s["n_outside"]
        assert sum(pair["band"].values()) == s["n_band"]
    disagree = {r["id"] for r in rows if len({r["analytic"], r["mujoco"], r["pybullet"]}) > 1}
    saved = {p.stem for p in (tmp_path / "disagreements").glob("*.json")}
    assert saved == disagree
    for p in (tmp_path / "disagreements").glob("*.json"):
        arr = read_arrangement(p)  # a valid arrangement.json for `unseen check`
        assert set(arr.meta["verdicts"]) == {"analytic", "mujoco", "pybullet"}
    # rerun resumes from the task records and gives the same tables
    first = (tmp_path / "agreement.csv").read_bytes()
    assert agreement.run(args) == 0
    assert (tmp_path / "agreement.csv").read_bytes() == first


@pytest.mark.slow
def test_agreement_outside_the_band_at_least_99_percent(tmp_path: Path) -> None:
    """The issue's target on 200 arrangements (the README quotes the 500-case run)."""
    args = argparse.Namespace(out=tmp_path, seed=0, n=200, workers=2, dask=None, quick=False,
                              stream=io.StringIO())
    assert agreement.run(args) == 0
    s = json.loads((tmp_path / "summary.json").read_text())
    for name, pair in s["pairs"].items():
        assert pair["agree_outside"] >= 0.99, (name, pair)
    assert s["n_band"] < 0.1 * s["n"]
