"""``unseen regress record|verify``: a folder of scans is recorded, verified unchanged, and
fails naming the scan and the figure when a box is moved on purpose.

The scans are built here with known geometry: point clouds of boxes on a floor (the
visible top and two sides of each box, per-point instance ids), and one synthetic scene
directory with its ground truth.  Each pipeline run takes about a second.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from eval import regress
from eval.cli import main
from pipeline.errors import InputError

#: (centre, size) of the boxes of the "stack" cloud: a box on a box, and one beside them.
STACK = (((0.0, 0.0, 0.15), (0.4, 0.4, 0.3)),
         ((0.0, 0.0, 0.4), (0.3, 0.3, 0.2)),
         ((0.6, 0.3, 0.1), (0.2, 0.3, 0.2)))
#: The top box pushed 0.35 m sideways, off the box it stood on.
STACK_MOVED = (STACK[0], ((0.35, 0.0, 0.4), (0.3, 0.3, 0.2)), STACK[2])
#: Two boxes side by side.
PAIR = (((-0.3, 0.0, 0.125), (0.3, 0.3, 0.25)), ((0.25, 0.1, 0.2), (0.25, 0.2, 0.4)))


def _grid(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    u, v = np.meshgrid(a, b)
    return u.ravel(), v.ravel()


def box_cloud(boxes, step: float = 0.01) -> tuple[np.ndarray, np.ndarray]:  # noqa: ANN001
    """Points of a 2 m floor and of each box's top, -x and -y faces; instance k+1 per box."""
    g = np.arange(-1.0, 1.0, 2 * step)
    fx, fy = _grid(g, g)
    pts, inst = [np.c_[fx, fy, np.zeros_like(fx)]], [np.zeros(fx.size, np.int64)]
    for k, (c, s) in enumerate(boxes):
        c, h = np.asarray(c, float), np.asarray(s, float) / 2
        ax, ay, az = (np.arange(-h[i], h[i] + 1e-9, step) for i in range(3))
        u, v = _grid(ax, ay)
        faces = [np.c_[u, v, np.full(u.size, h[2])]]
        u, w = _grid(ax, az)
        faces.append(np.c_[u, np.full(u.size, -h[1]), w])
        v, w = _grid(ay, az)
        faces.append(np.c_[np.full(v.size, -h[0]), v, w])
        p = np.concatenate(faces) + c
        pts.append(p)
        inst.append(np.full(len(p), k + 1))
    return np.concatenate(pts), np.concatenate(inst)


def write_cloud(path: Path, boxes) -> None:  # noqa: ANN001
    from simulate.scan import write_ply

    pts, inst = box_cloud(boxes)
    write_ply(path, pts, instance=inst)


def digest(folder: Path) -> dict[str, str]:
    """SHA-256 of every file under ``folder`` (relative path -> hex)."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def scans(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder of three scans (two clouds, a scene directory) and one file that is none."""
    pytest.importorskip("mujoco")
    from synth_scenes.scene_dir import make_scene_dir

    d = tmp_path_factory.mktemp("scans") / "my_scans"
    d.mkdir()
    write_cloud(d / "stack.ply", STACK)
    write_cloud(d / "pair.ply", PAIR)
    made = make_scene_dir("stack", d / "scene", seed=4, noise="none", n_boxes=3)
    assert made.truth.status == "ok"
    (d / "notes.txt").write_text("not a scan\n")
    return d


@pytest.fixture(scope="module")
def recorded(scans: Path) -> tuple[Path, str]:
    """``record`` run once on the folder (MuJoCo verdicts too); (folder, its stderr)."""
    before = digest(scans)
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        rc = main(["regress", "record", str(scans), "--engine", "mujoco"])
    assert rc == 0, err.getvalue()
    after = digest(scans)
    assert after.pop(regress.RECORD_NAME)
    assert after == before  # record adds its file and touches nothing else
    return scans, err.getvalue()


def _copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


# ---------------------------------------------------------------------------- record
def test_record_file_holds_the_results(recorded: tuple[Path, str]) -> None:
    folder, err = recorded
    assert "skipped (not a scan unseen run takes): notes.txt" in err
    text = (folder / regress.RECORD_NAME).read_text()
    data = json.loads(text)
    assert data["format"] == "unseen.regress" and data["version"] == 1
    assert data["run"] == {"seed": 0, "budget": 10.0, "engines": ["mujoco"]}
    assert list(data["scans"]) == ["pair.ply", "scene", "stack.ply"]
    # no absolute paths, no timings; one box per line
    assert str(folder) not in text and "/tmp" not in text and "seconds" not in text
    stack = data["scans"]["stack.ply"]
    assert text.count('{"id": "b') == sum(len(e["boxes"]) for e in data["scans"].values())
    # the boxes are the boxes of the cloud (sizes and heights from the geometry above)
    by_object = {b["object"]: b for b in stack["boxes"]}
    assert set(by_object) == {"inst1", "inst2", "inst3"}
    for k, (c, s) in enumerate(STACK):
        b = by_object[f"inst{k + 1}"]
        assert np.allclose(sorted(b["size"]), sorted(s), atol=0.011)
        assert b["center"][2] == pytest.approx(c[2], abs=0.011)
        assert np.allclose(np.asarray(b["rotation"]) @ np.asarray(b["rotation"]).T, np.eye(3),
                           atol=1e-4)
    ids = {o: b["id"] for o, b in by_object.items()}
    edges = {tuple(e) for e in stack["contacts"]}
    lower, upper, side = ids["inst1"], ids["inst2"], ids["inst3"]
    assert tuple(sorted((lower, upper))) + ("touch",) in edges
    assert (lower, "ground", "touch") in edges and (side, "ground", "touch") in edges
    assert stack["verdicts"] == {"analytic": True, "mujoco": True} and stack["fixed"] == 0
    assert "truth" not in stack
    scene = data["scans"]["scene"]
    assert set(scene["truth"]) == {"f1", "size"} and 0.0 <= scene["truth"]["f1"] <= 1.0
    assert set(scene["verdicts"]) == {"analytic", "mujoco"}
    # the file is its own canonical form: read and written back, the same bytes
    assert regress.dumps(regress.read_record(folder / regress.RECORD_NAME)) == text


def test_record_refuses_to_overwrite(recorded: tuple[Path, str], capsys) -> None:  # noqa: ANN001
    folder, _ = recorded
    before = (folder / regress.RECORD_NAME).read_bytes()
    assert main(["regress", "record", str(folder)]) == 2
    err = capsys.readouterr().err
    assert "already recorded" in err and "--update" in err and err.count("\n") == 1
    assert (folder / regress.RECORD_NAME).read_bytes() == before


def test_update_keeps_the_recorded_engines(recorded: tuple[Path, str], tmp_path: Path) -> None:
    # recorded with --engine mujoco: --update without --engine records MuJoCo's verdicts
    # again (as README's "after an intended change" says), --engine analytic drops them
    folder = _copy(recorded[0], tmp_path / "scans")
    path = folder / regress.RECORD_NAME
    assert json.loads(path.read_text())["run"]["engines"] == ["mujoco"]
    with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
        assert main(["regress", "record", str(folder), "--update"]) == 0
        data = json.loads(path.read_text())
        assert data["run"]["engines"] == ["mujoco"]
        assert all("mujoco" in e["verdicts"] for e in data["scans"].values())
        assert main(["regress", "record", str(folder), "--update", "--engine", "analytic"]) == 0
    assert json.loads(path.read_text())["run"]["engines"] == []


@pytest.mark.parametrize(("argv", "message"), [
    (["verify", "{d}", "--report", "{d}/stack.ply"], "--report {d}/stack.ply: is the input"),
    (["verify", "{d}", "--junit", "{d}/scene/scene.json"], "is inside the input scene"),
    (["verify", "{d}", "--report", "{d}/" + regress.RECORD_NAME], "is the input"),
    (["record", "{d}", "--update", "--expected", "{d}/scene/scene.json"], "inside the input"),
])
def test_outputs_never_go_over_the_inputs(recorded: tuple[Path, str], tmp_path: Path,
                                          capsys, argv, message) -> None:  # noqa: ANN001
    # a report, a JUnit file or a record written over a scan (or inside one), or a report
    # over the record, is refused before any work and every input stays byte-identical
    folder = _copy(recorded[0], tmp_path / "scans")
    before = digest(folder)
    rc = main(["regress", *[a.format(d=folder) for a in argv]])
    err = capsys.readouterr().err
    assert rc == 2 and message.format(d=folder) in err and err.count("\n") == 1, err
    assert digest(folder) == before


@pytest.mark.parametrize(("edit", "message"), [
    (lambda e: e["truth"].__setitem__("f1", "high"), "truth.f1: expected a finite number"),
    (lambda e: e["boxes"][0].__setitem__("size", [0.1, float("nan"), 0.1]),
     "boxes[0].size: expected 3 finite positive numbers"),
    (lambda e: e["verdicts"].__setitem__("bullet", True), "verdicts: 'bullet'"),
])
def test_a_corrupt_record_is_bad_input(recorded: tuple[Path, str], tmp_path: Path, capsys,
                                       edit, message) -> None:  # noqa: ANN001
    folder = _copy(recorded[0], tmp_path / "scans")
    path = folder / regress.RECORD_NAME
    data = json.loads(path.read_text())
    edit(data["scans"]["scene"])
    path.write_text(json.dumps(data))
    assert main(["regress", "verify", str(folder)]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err, err


@pytest.mark.parametrize(("key", "value"), [("seed", -1), ("budget", 1e300)])
def test_a_record_run_out_of_range_is_bad_input(recorded: tuple[Path, str], tmp_path: Path,
                                                capsys, key, value) -> None:  # noqa: ANN001
    folder = _copy(recorded[0], tmp_path / "scans")
    path = folder / regress.RECORD_NAME
    data = json.loads(path.read_text())
    data["run"][key] = value
    path.write_text(json.dumps(data))
    assert main(["regress", "verify", str(folder)]) == 2
    assert f"run.{key}:" in capsys.readouterr().err


# ---------------------------------------------------------------------------- verify
def test_verify_unchanged_passes(recorded: tuple[Path, str], tmp_path: Path, capsys) -> None:  # noqa: ANN001
    folder, _ = recorded
    before = digest(folder)
    junit, report = tmp_path / "regress.xml", tmp_path / "out" / "regress.md"
    rc = main(["regress", "verify", str(folder), "--junit", str(junit), "--report", str(report)])
    out = capsys.readouterr()
    assert rc == 0, out.err
    assert out.out.startswith("3 scans: 3 passed, 0 dropped, 0 failed, 0 skipped: PASS")
    assert digest(folder) == before  # inputs and the record untouched
    suite = ET.parse(junit).getroot().find("testsuite")
    assert (suite.get("tests"), suite.get("failures"), suite.get("errors")) == ("3", "0", "0")
    assert [c.get("name") for c in suite.iter("testcase")] == ["pair.ply", "scene", "stack.ply"]
    md = report.read_text()
    assert "3 scans: 3 passed, 0 dropped, 0 failed, 0 skipped: **PASS**" in md
    assert "DROP" not in md and "Nothing changed." in md
    assert "| stack.ply | f1 (record) | 1.000 | 1.000 | 0.05 | pass |" in md
    assert "| stack.ply | moved (record) | 0.000 | 0.000 | 0.05 m | pass |" in md
    assert "| scene | f1 (truth) |" in md and "| scene | stands:mujoco | yes | yes |" in md
    assert "Not scans (skipped): notes.txt" in md


def test_verify_fails_naming_scan_and_figure_when_a_box_moved(
        recorded: tuple[Path, str], tmp_path: Path, capsys) -> None:  # noqa: ANN001
    folder = _copy(recorded[0], tmp_path / "scans")
    write_cloud(folder / "stack.ply", STACK_MOVED)  # the top box pushed off its support
    junit, report = tmp_path / "regress.xml", tmp_path / "regress.md"
    rc = main(["regress", "verify", str(folder), "--junit", str(junit), "--report", str(report)])
    out = capsys.readouterr()
    assert rc == 1
    assert "1 of 3 scans dropped, 0 failed" in out.err
    line = next(ln for ln in out.err.splitlines() if "stack.ply" in ln)
    assert "stack.ply: f1 " in line and "< 1.00 - 0.05 (vs record)" in line
    assert "pair.ply" not in out.err and "scene:" not in out.err
    # JUnit: one failure, on stack.ply, naming the figure and its numbers
    suite = ET.parse(junit).getroot().find("testsuite")
    assert (suite.get("tests"), suite.get("failures"), suite.get("errors")) == ("3", "1", "0")
    cases = {c.get("name"): c for c in suite.iter("testcase")}
    failure = cases["stack.ply"].find("failure")
    assert failure is not None and failure.get("message").startswith("f1 ")
    f1_now = float(failure.get("message").split()[1])
    assert f1_now < 0.95
    assert all(cases[n].find("failure") is None for n in ("pair.ply", "scene"))
    # the report: the dropped row, and what changed (the moved box's contacts)
    md = report.read_text()
    assert f"| stack.ply | f1 (record) | 1.000 | {f1_now:.3f} | 0.05 | **DROP** |" in md
    assert "| pair.ply | f1 (record) | 1.000 | 1.000 | 0.05 | pass |" in md
    changes = md.split("## Changes", 1)[1]
    assert "### stack.ply" in changes and "### pair.ply" not in changes
    assert "contact lost:" in changes and "contact gained:" in changes


def test_verify_errors_are_cases_not_silence(recorded: tuple[Path, str], tmp_path: Path,
                                             capsys) -> None:  # noqa: ANN001
    """A scan that fails to run and a recorded scan that is gone are errors; a scan never
    recorded is skipped; the scans that still run pass."""
    folder = _copy(recorded[0], tmp_path / "scans")
    (folder / "pair.ply").write_bytes(b"ply\nformat ascii 1.0\nelement vertex 1\n"
                                      b"property float x\nproperty float y\nproperty float z\n"
                                      b"end_header\n0 0 0\n")
    shutil.rmtree(folder / "scene")
    write_cloud(folder / "new.ply", PAIR)
    junit = tmp_path / "r.xml"
    rc = main(["regress", "verify", str(folder), "--junit", str(junit)])
    out = capsys.readouterr()
    assert rc == 1
    assert "0 of 4 scans dropped, 2 failed" in out.err
    assert "not recorded, skipped: new.ply" in out.err
    assert "pair.ply: failed to run:" in out.err
    assert "scene: recorded but not found" in out.err
    suite = ET.parse(junit).getroot().find("testsuite")
    assert (suite.get("tests"), suite.get("failures"), suite.get("errors"),
            suite.get("skipped")) == ("4", "0", "2", "1")
    cases = {c.get("name"): c for c in suite.iter("testcase")}
    assert cases["pair.ply"].find("error") is not None
    assert cases["new.ply"].find("skipped") is not None
    assert list(cases["stack.ply"]) == [cases["stack.ply"].find("system-out")]  # passed


def test_a_refused_scan_is_recorded_as_refused(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    """record: exit 1, how many failed, the first error, and the others recorded; verify
    skips a scan refused then and now, and passes."""
    write_cloud(tmp_path / "ok.ply", PAIR)
    (tmp_path / "bad.ply").write_bytes(b"ply\nformat ascii 1.0\nelement vertex 1\n"
                                       b"property float x\nproperty float y\n"
                                       b"property float z\nend_header\n0 0 0\n")
    assert main(["regress", "record", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "1 of 2 scans failed to run (recorded as refused); first: bad.ply: " in err
    text = (tmp_path / regress.RECORD_NAME).read_text()
    scans = json.loads(text)["scans"]
    assert set(scans["bad.ply"]) == {"error"} and "boxes" in scans["ok.ply"]
    assert str(tmp_path) not in text  # the error names the scan, not where it lies
    assert main(["regress", "verify", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "2 scans: 1 passed, 0 dropped, 0 failed, 1 skipped: **PASS**" in out
    assert "| bad.ply | - | - | - | - | skipped: refused when recorded and now:" in out


# ---------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(("argv", "message"), [
    (["verify", "{missing}"], "no such folder"),
    (["verify", "{file}"], "not a folder"),
    (["verify", "{empty}"], "no expectation file"),
    (["verify", "{broken}"], "not a readable JSON file"),
    (["verify", "{other}"], "not an expectation file"),
    (["verify", "{empty}", "--f1-tol", "-0.1"], "--f1-tol -0.1: expected a value >= 0"),
    (["verify", "{empty}", "--size-tol", "abc"], "--size-tol 'abc': expected a number"),
    (["verify", "{empty}", "--fixed-tol", "1.5"], "--fixed-tol '1.5': expected an integer"),
    (["verify", "{empty}", "--report", "{empty}"], "is a folder"),
    (["verify", "{empty}", "--workers", "0"], "--workers: must be at least 1"),
    (["record", "{empty}"], "no scans here"),
    (["record", "{missing}"], "no such folder"),
])
def test_bad_input_exits_2_with_one_line(tmp_path: Path, capsys, argv, message) -> None:  # noqa: ANN001
    paths = {"missing": tmp_path / "nope", "file": tmp_path / "f.txt", "empty": tmp_path / "e",
             "broken": tmp_path / "b", "other": tmp_path / "o"}
    paths["file"].write_text("x")
    for k in ("empty", "broken", "other"):
        paths[k].mkdir()
    (paths["broken"] / regress.RECORD_NAME).write_text("{not json")
    (paths["other"] / regress.RECORD_NAME).write_text('{"format": "unseen.arrangement"}')
    before = digest(tmp_path)
    rc = main(["regress", *[a.format(**paths) for a in argv]])
    err = capsys.readouterr().err
    assert rc == 2
    assert message in err and err.count("\n") == 1 and "Traceback" not in err
    assert digest(tmp_path) == before


# ---------------------------------------------------------------------------- figures
def _entry(boxes, contacts, verdicts=None, fixed=0, truth=None) -> dict:  # noqa: ANN001
    e = {"verdicts": verdicts or {"analytic": True, "mujoco": True}, "fixed": fixed}
    if truth is not None:
        e["truth"] = truth
    e["boxes"] = [{"id": i, "center": list(c), "size": list(s),
                   "rotation": np.eye(3).tolist()} for i, c, s in boxes]
    e["supports"] = [{"id": "ground", "point": [0, 0, 0], "normal": [0, 0, 1]}]
    e["contacts"] = [list(x) for x in contacts]
    return e


BOXES = [("b0", (0, 0, 0.15), (0.4, 0.4, 0.3)), ("b1", (0, 0, 0.4), (0.3, 0.3, 0.2))]
EDGES = [("b0", "b1", "touch"), ("b0", "ground", "touch")]
REC = _entry(BOXES, EDGES)


def _figs(now: dict, rec: dict = REC, **tol) -> tuple[dict, list[str]]:  # noqa: ANN001
    figures, changes = regress.compare(now, rec, regress.Tolerances(**tol))
    return {f.name: f for f in figures}, changes


def test_identical_entry_passes_every_figure() -> None:
    figs, changes = _figs(REC)
    assert {n: f.verdict for n, f in figs.items()} == {
        "f1": "pass", "size": "pass", "moved": "pass", "stands:analytic": "pass",
        "stands:mujoco": "pass", "agree": "pass", "fixed": "pass"}
    assert figs["f1"].now == 1.0 and figs["size"].now == 0.0 and figs["moved"].now == 0.0
    assert changes == []


def test_moved_box_within_and_beyond_tolerance() -> None:
    now = _entry([BOXES[0], ("b1", (0.03, 0, 0.4), (0.3, 0.3, 0.2))], EDGES)
    figs, changes = _figs(now, move=0.05)
    assert figs["moved"].now == pytest.approx(0.03) and figs["moved"].verdict == "pass"
    assert changes == ["box b1 moved 0.030 m"]
    figs, _ = _figs(now, move=0.02)
    assert figs["moved"].verdict == "drop"
    assert figs["moved"].message == "moved 0.030 m > 0.02 m (b1)"
    assert _figs(now, move=None)[0]["moved"].verdict == "info"


def test_size_error_is_relative_l1_of_matched_sides() -> None:
    now = _entry([BOXES[0], ("b1", (0, 0, 0.43), (0.3, 0.3, 0.26))], EDGES)
    figs, changes = _figs(now, size=0.05)
    assert figs["size"].now == pytest.approx(0.06 / 1.9, abs=1e-6)  # |0.26-0.2| / sum sides
    assert figs["size"].verdict == "pass"
    assert "box b1 resized 0.200 x 0.300 x 0.300 -> 0.260 x 0.300 x 0.300 m" in changes
    figs, _ = _figs(now, size=0.03)
    assert figs["size"].verdict == "drop" and figs["size"].message.startswith("size 0.032 > 0.000")


def test_retyped_contact_drops_typed_f1() -> None:
    now = _entry(BOXES, [("b0", "b1", "fixed"), ("b0", "ground", "touch")])
    figs, changes = _figs(now)
    assert figs["f1"].now == 0.5 and figs["f1"].verdict == "drop"
    assert figs["f1"].message == "f1 0.50 < 1.00 - 0.05 (vs record)"
    assert changes == ["contact retyped: b0 - b1 touch -> fixed"]
    assert _figs(now, f1=0.5)[0]["f1"].verdict == "pass"


def test_box_gone_loses_its_contacts() -> None:
    now = _entry([BOXES[0]], [("b0", "ground", "touch")])
    figs, changes = _figs(now)
    assert figs["f1"].now == pytest.approx(2 / 3) and figs["f1"].verdict == "drop"
    assert changes[0].startswith("box b1 removed (was 0.300 x 0.300 x 0.200 m at")
    assert "contact lost: b0 - b1 touch" in changes


def test_stands_modes() -> None:
    falls = _entry(BOXES, EDGES, verdicts={"analytic": True, "mujoco": False})
    figs, changes = _figs(falls)
    assert figs["stands:mujoco"].verdict == "drop"
    assert figs["stands:mujoco"].message == "stands:mujoco no (recorded yes)"
    assert figs["agree"].verdict == "drop" and "analytic yes, mujoco no" in figs["agree"].message
    assert "mujoco: stands -> falls" in changes
    assert {f.verdict for f in _figs(falls, stands="ignore")[0].values()} == {"pass", "info"}
    rec_falls = _entry(BOXES, EDGES, verdicts={"analytic": False, "mujoco": False})
    figs, _ = _figs(rec_falls, rec_falls)
    assert figs["stands:mujoco"].verdict == "pass"
    figs, _ = _figs(rec_falls, rec_falls, stands="required")
    assert figs["stands:mujoco"].message == "stands:mujoco no (required)"


def test_fixed_count_tolerance() -> None:
    rec = _entry(BOXES, EDGES, fixed=1)
    figs, _ = _figs(_entry(BOXES, EDGES, fixed=2), rec)
    assert figs["fixed"].verdict == "drop" and figs["fixed"].message == "fixed 2 > 1 + 0"
    assert _figs(_entry(BOXES, EDGES, fixed=2), rec, fixed=1)[0]["fixed"].verdict == "pass"
    assert _figs(_entry(BOXES, EDGES, fixed=0), rec)[0]["fixed"].verdict == "pass"


def test_truth_figures_judge_against_the_truth() -> None:
    rec = _entry(BOXES, EDGES, truth={"f1": 0.9, "size": 0.1})
    changed = _entry(BOXES, [("b0", "b1", "fixed"), ("b0", "ground", "touch")],
                     truth={"f1": 0.86, "size": 0.12})
    figs, _ = _figs(changed, rec)
    assert figs["f1"].verdict == "pass" and figs["f1"].versus == "truth"
    assert figs["f1 (record)"].verdict == "info" and figs["f1 (record)"].now == 0.5
    assert figs["size"].verdict == "pass" and figs["moved"].verdict == "info"
    worse = _entry(BOXES, EDGES, truth={"f1": 0.84, "size": 0.2})
    figs, _ = _figs(worse, rec)
    assert figs["f1"].message == "f1 0.84 < 0.90 - 0.05 (vs truth)"
    assert figs["size"].message == "size 0.200 > 0.100 + 0.05 (vs truth)"


def test_tolerances_are_checked() -> None:
    with pytest.raises(InputError, match="tolerance f1"):
        regress.Tolerances(f1=-1.0)
    with pytest.raises(InputError, match="tolerance stands"):
        regress.Tolerances(stands="maybe")
    assert regress.parse_tolerance("off", "--f1-tol") is None
    assert regress.parse_tolerance("3", "--fixed-tol", integer=True) == 3


def test_discover_lists_what_unseen_run_takes(tmp_path: Path) -> None:
    (tmp_path / "a.ply").write_text("ply")
    (tmp_path / "b.pcd").write_text("x")
    (tmp_path / "frame").mkdir()
    (tmp_path / "frame" / "depth.png").write_bytes(b"")
    (tmp_path / "scene" / "scan").mkdir(parents=True)
    (tmp_path / "scene" / "scan" / "depth.png").write_bytes(b"")
    (tmp_path / "scene" / "scene.json").write_text("{}")
    (tmp_path / "empty").mkdir()
    (tmp_path / "readme.md").write_text("x")
    (tmp_path / ".git").mkdir()
    (tmp_path / regress.RECORD_NAME).write_text("{}")
    scans, skipped = regress.discover(tmp_path)
    assert [(s.name, s.kind) for s in scans] == [("a.ply", "cloud"), ("b.pcd", "cloud"),
                                                ("frame", "rgbd"), ("scene", "scene")]
    assert skipped == ["empty", "readme.md"]


@pytest.mark.slow
def test_verify_output_is_the_same_with_workers(recorded: tuple[Path, str],
                                                tmp_path: Path) -> None:
    """Reports hold no timings: two verifies, serial and on two processes, same bytes."""
    folder, _ = recorded
    for k, workers in enumerate(("1", "2")):
        assert main(["regress", "verify", str(folder), "--workers", workers, "--junit",
                     str(tmp_path / f"{k}.xml"), "--report", str(tmp_path / f"{k}.md")]) == 0
    assert (tmp_path / "0.xml").read_bytes() == (tmp_path / "1.xml").read_bytes()
    assert (tmp_path / "0.md").read_bytes() == (tmp_path / "1.md").read_bytes()
