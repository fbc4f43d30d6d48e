"""``unseen check`` on many files: cases, order, exit codes, JSON lines, JUnit, workers, and
agreement with the agreement suite's own verdicts.

Fixtures are closed-form: a 1 x 1 x 0.2 slab on a 1 m cube tips when its centre is past
the cube's edge (overhang 0.5), so 0.3 stands and 0.7 falls in every check; a cube held
between two fixed columns by side friction alone is stable to plain statics with side
friction (``--side-friction``) and falls 0.25 m in both engines.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from eval import bulkcheck
from pipeline.arrangement_io import write_arrangement
from synth_scenes.random_arrangements import side_friction_trap
from tests.conftest import overhang_scene

UNSEEN = [sys.executable, "-m", "eval.cli"]
BAD_SIZE = "cuboids[1].size: must be 3 positive numbers"


def _run(*args, timeout=300):
    return subprocess.run(UNSEEN + [str(a) for a in args], capture_output=True, text=True,
                          timeout=timeout)


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    """a_stable, b_unstable, c_bad (a zero size), sub/d_trap; plus files that are not cases."""
    d = tmp_path / "cases"
    (d / "sub").mkdir(parents=True)
    write_arrangement(overhang_scene(0.3), d / "a_stable.json")
    write_arrangement(overhang_scene(0.7), d / "b_unstable.json")
    text = (d / "a_stable.json").read_text()
    assert text.count("[1.0, 1.0, 0.2]") == 1
    (d / "c_bad.json").write_text(text.replace("[1.0, 1.0, 0.2]", "[1.0, 0.0, 0.2]"))
    write_arrangement(side_friction_trap(), d / "sub" / "d_trap.json")
    (d / "manifest.json").write_text('{"format": "unseen.manifest", "version": 1, "files": []}')
    (d / ".a_stable.tmp.json").write_text("{half a fi")  # an atomic write in progress
    (d / "notes.txt").write_text("not json")
    return d


def _names(d: Path) -> list[str]:
    return [str(d / n) for n in ("a_stable.json", "b_unstable.json", "c_bad.json",
                                 "sub/d_trap.json")]


def test_folder_table_summary_and_exit_code(folder: Path) -> None:
    out = _run("check", folder)
    assert out.returncode == 1, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0].split()[:4] == ["file", "analytic", "worst", "residual"]
    rows = lines[1:5]
    assert [r.split()[0] for r in rows] == _names(folder)  # sorted, recursive, skips others
    assert rows[0].split()[1:3] == ["stable", "-"]
    assert rows[1].split()[1:4] == ["UNSTABLE", "top", "F"]
    assert rows[2].split()[1:3] == ["-", "-"] and rows[2].endswith(BAD_SIZE)
    assert rows[3].split()[1:3] == ["UNSTABLE", "mid"]  # no side friction: it falls
    assert "4 checked: 1 stable, 2 unstable, 0 disagree, 1 errors" in lines
    err = out.stderr.strip().splitlines()
    assert len(err) == 2 and "Traceback" not in out.stderr
    assert err[0].startswith("unseen check: skipped 1 JSON file") and "manifest.json" in err[0]
    assert err[1] == (f"unseen check: 3 of 4 failed (4 checked: 1 stable, 2 unstable, "
                      f"0 disagree, 1 errors); first error: {folder / 'c_bad.json'}: {BAD_SIZE}")
    # without a bad file, the first failing case is named
    out = _run("check", folder / "sub", folder / "b_unstable.json")
    assert out.returncode == 1
    assert out.stderr.startswith("unseen check: 2 of 2 failed (2 checked: 0 stable, 2 unstable, "
                                 f"0 disagree, 0 errors); first failure: "
                                 f"{folder / 'sub' / 'd_trap.json'}: unstable: analytic mid F ")


def test_json_lines_in_input_order_match_the_single_file_object(folder: Path) -> None:
    first = folder / "b_unstable.json"
    out = _run("check", first, folder, "--json")  # b given first, then again in the folder
    assert out.returncode == 1
    recs = [json.loads(line) for line in out.stdout.splitlines()]
    names = _names(folder)
    assert [r["arrangement"] for r in recs] == [names[1], names[0], names[2], names[3]]
    assert recs[2] == {"arrangement": names[2], "error": BAD_SIZE}
    assert [bulkcheck.outcome(r) for r in recs] == ["unstable", "stable", "error", "unstable"]
    # an analytic record is exactly the object of the single-file mode (no timings in it)
    single = _run("check", first, "--json")
    assert single.returncode == 1
    assert recs[0] == json.loads(single.stdout)
    assert all(line == bulkcheck.json_line(r) for line, r in zip(out.stdout.splitlines(), recs))


def _junit(path: Path) -> dict[str, ET.Element]:
    root = ET.parse(path).getroot()
    assert root.tag == "testsuite" and root.get("name") == "unseen check"
    cases = root.findall("testcase")
    assert all(c.get("classname") == "unseen.check" and c.get("time") is None for c in cases)
    return {"suite": root, **{c.get("name"): c for c in cases}}


def test_all_engines_workers_junit_and_disagreements(folder: Path, tmp_path: Path) -> None:
    common = [folder, "--engine", "all", "--side-friction"]
    one = _run("check", *common, "--json", "--junit", tmp_path / "w1.xml")
    two = _run("check", *common, "--json", "--junit", tmp_path / "w2.xml", "--workers", "2")
    assert one.returncode == two.returncode == 1, one.stderr + two.stderr
    assert one.stdout == two.stdout  # byte-identical JSON lines whatever the worker count
    assert (tmp_path / "w1.xml").read_bytes() == (tmp_path / "w2.xml").read_bytes()
    recs = [json.loads(line) for line in one.stdout.splitlines()]
    names = _names(folder)
    assert [r["arrangement"] for r in recs] == names
    assert [bulkcheck.outcome(r) for r in recs] == ["stable", "unstable", "error", "disagree"]
    trap = recs[3]["engines"]
    assert trap["analytic"]["stable"] and recs[3]["agree"] is False
    for engine in ("mujoco", "pybullet"):
        mid = next(b for b in trap[engine]["bodies"] if b["id"] == "mid")
        assert not trap[engine]["stable"] and mid["translation"] == pytest.approx(0.25, abs=0.01)
        assert "wall_time" not in trap[engine]

    j = _junit(tmp_path / "w1.xml")
    suite = j["suite"]
    assert (suite.get("tests"), suite.get("failures"), suite.get("errors")) == ("4", "2", "1")
    assert len(j[names[0]]) == 0  # passed: no child
    fail = j[names[1]].find("failure")
    assert fail.get("type") == "unstable" and fail.get("message").startswith(
        "unstable: analytic top F ")
    assert "mujoco top " in fail.get("message") and "pybullet top " in fail.get("message")
    assert j[names[2]].find("error").get("message") == BAD_SIZE
    assert j[names[2]].find("failure") is None
    fail = j[names[3]].find("failure")
    assert fail.get("type") == "disagree"
    assert fail.get("message").startswith(
        "engines disagree (analytic stable, mujoco unstable, pybullet unstable): mujoco mid 0.25")

    table = _run("check", *common)
    assert table.returncode == 1
    text = table.stdout
    assert "4 checked: 1 stable, 1 unstable, 1 disagree, 1 errors" in text
    assert "pairwise agreement: analytic-mujoco 2/3, analytic-pybullet 2/3, mujoco-pybullet 3/3" \
        in text
    section = text[text.index("disagreements (1):"):].splitlines()
    assert section[1].strip() == names[3]
    assert section[2].split()[:2] == ["analytic", "stable"]
    for line, engine in zip(section[3:5], ("mujoco", "pybullet")):
        assert line.split()[:5] == [engine, "UNSTABLE", "moved:", "mid", "0.25"]


def test_usage_errors_are_one_line_and_exit_2(folder: Path, tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "manifest.json").write_text('{"format": "unseen.manifest"}')
    for args, needle in [
        ((folder, tmp_path / "nope.json"), "nope.json: no such file or folder"),
        ((empty,), "no arrangement files found"),
        ((folder, "--workers", "0"), "--workers: must be at least 1"),
        ((folder, "--junit", tmp_path), "is a folder"),
    ]:
        out = _run("check", *args)
        assert out.returncode == 2, (args, out.stderr)
        err = out.stderr.strip().splitlines()
        assert needle in err[-1] and "Traceback" not in out.stderr, (args, out.stderr)
        assert out.stdout == ""


def test_one_file_with_junit_is_a_bulk_check(folder: Path, tmp_path: Path) -> None:
    """--junit turns even one bad file into a report (an error case, exit 1, not 2)."""
    out = _run("check", folder / "c_bad.json", "--junit", tmp_path / "r.xml")
    assert out.returncode == 1
    j = _junit(tmp_path / "r.xml")
    assert (j["suite"].get("tests"), j["suite"].get("errors")) == ("1", "1")
    assert j[str(folder / "c_bad.json")].find("error").get("message") == BAD_SIZE


def test_junit_carries_odd_names_and_messages() -> None:
    recs = [{"arrangement": "a\x01b\udcff.json", "error": "bad \x00 byte"},
            {"arrangement": "ok.json", "engines": {"analytic": {"stable": True, "bodies": []}},
             "agree": True}]
    root = ET.fromstring(bulkcheck.junit_xml(recs, ("analytic",)))
    cases = root.findall("testcase")
    assert cases[0].get("name") == "a\ufffdb\ufffd.json"
    assert cases[0].find("error").get("message") == "bad \ufffd byte"
    assert root.get("tests") == "2" and root.get("errors") == "1" and root.get("failures") == "0"


def _agreement_run(out: Path, n: int, workers: int = 1) -> list[dict]:
    from eval.suites import agreement

    args = argparse.Namespace(out=out, seed=3, n=n, workers=workers, dask=None, quick=False,
                              stream=io.StringIO())
    assert agreement.run(args) == 0
    return list(csv.DictReader((out / "cases.csv").open()))


def _same_verdicts(out: Path, rows: list[dict], workers: int) -> None:
    res = _run("check", out / "arrangements", "--engine", "all", "--json",
               "--workers", workers, "--junit", out / "check.xml")
    assert res.returncode in (0, 1), res.stderr
    recs = [json.loads(line) for line in res.stdout.splitlines()]
    assert [Path(r["arrangement"]).stem for r in recs] == [r["id"] for r in rows]
    for rec, row in zip(recs, rows):
        assert "error" not in rec, rec
        got = {e: int(v["stable"]) for e, v in rec["engines"].items()}
        assert got == {e: int(row[e]) for e in bulkcheck.ALL_ENGINES}, (row, rec)
        meta = json.loads(Path(rec["arrangement"]).read_text())["meta"]
        assert meta["verdicts"] == {e: bool(v) for e, v in got.items()}
    n_disagree = sum(len({r["analytic"], r["mujoco"], r["pybullet"]}) > 1 for r in rows)
    suite = _junit(out / "check.xml")["suite"]
    assert int(suite.get("tests")) == len(rows) and suite.get("errors") == "0"
    assert int(suite.get("failures")) == sum(
        not (r["analytic"] == r["mujoco"] == r["pybullet"] == "1") for r in rows)
    assert len(list((out / "disagreements").glob("*.json"))) == n_disagree


def test_agreement_suite_saves_every_case_and_bulk_check_gives_its_verdicts(
        tmp_path: Path) -> None:
    from eval.runner import load_records
    from eval.suites import agreement

    rows = _agreement_run(tmp_path, 6)
    saved = sorted(p.stem for p in (tmp_path / "arrangements").glob("*.json"))
    assert saved == [r["id"] for r in rows]
    # a record written before arrangements were kept is drawn again, identically
    for tid, rec in load_records(tmp_path).items():
        assert agreement._redraw(3, tid) == rec["result"]["arrangement"]
    _same_verdicts(tmp_path, rows, workers=1)


@pytest.mark.slow
def test_quick_agreement_run_checked_in_bulk_on_two_workers(tmp_path: Path) -> None:
    from eval.suites import agreement

    rows = _agreement_run(tmp_path, agreement.QUICK_N, workers=2)
    _same_verdicts(tmp_path, rows, workers=2)
