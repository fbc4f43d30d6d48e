import json

import numpy as np
import pytest

from pipeline.arrangement_io import dumps, read_arrangement, write_arrangement
from pipeline.errors import InputError
from pipeline.model import Arrangement, Contact, Support, box, ground


def _scene() -> Arrangement:
    return Arrangement(
        (box("b0", (0.1, 0.2, 0.5), (1.0, 1.0, 1.0), yaw=0.3, object="table0"),
         box("b1", (0.1 / 3, 0.2, 1.1), (0.7, 0.2, 0.2), density=750.5)),
        (ground(), Support("wall:0", (0, 2, 0), (0, -1, 0))),
        (Contact("b0", "ground", "touch"), Contact("b0", "b1", "fixed")),
        meta={"camera_pose": np.eye(4).tolist(), "note": "x"},
    )


def test_round_trip_is_exact(tmp_path):
    arr = _scene()
    p = tmp_path / "a.json"
    write_arrangement(arr, p)
    back = read_arrangement(p)
    assert back.ids == arr.ids
    np.testing.assert_array_equal(back.centers, arr.centers)  # bit-exact floats
    np.testing.assert_array_equal(back.rotations, arr.rotations)
    np.testing.assert_array_equal(back.sizes, arr.sizes)
    assert back.contacts == arr.contacts
    assert back.cuboids[0].object == "table0" and back.cuboids[1].density == 750.5
    assert back.meta == arr.meta
    text = p.read_text()
    write_arrangement(back, p)
    assert p.read_text() == text == dumps(arr)


def _write(tmp_path, data) -> str:
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(data) if not isinstance(data, str) else data)
    return str(p)


def _base() -> dict:
    return json.loads(dumps(_scene()))


@pytest.mark.parametrize("mutate, message", [
    (lambda d: d["cuboids"][1].__setitem__("size", [1, -1, 1]), r"cuboids\[1\]\.size: must be 3 positive numbers"),
    (lambda d: d["cuboids"][0].__setitem__("size", [1, 1]), r"cuboids\[0\]\.size: must be 3 positive numbers"),
    (lambda d: d["contacts"][1].__setitem__("b", "b9"), r"contacts\[1\]\.b: unknown id 'b9'"),
    (lambda d: d["cuboids"][0].__setitem__("rotation", [[1, 0, 0], [0, 1, 0], [0, 0.5, 1]]), r"cuboids\[0\]\.rotation: not a rotation"),
    (lambda d: d["cuboids"][0].__setitem__("rotation", [[-1, 0, 0], [0, 1, 0], [0, 0, 1]]), r"cuboids\[0\]\.rotation: not a rotation"),
    (lambda d: d["cuboids"][1].__setitem__("id", "b0"), r"cuboids\[1\]\.id: duplicate id 'b0'"),
    (lambda d: d.__setitem__("format", "other"), r"format: unknown format"),
    (lambda d: d.__setitem__("version", 7), r"version: unsupported version 7"),
    (lambda d: d["contacts"][0].__setitem__("type", "glued"), r"contacts\[0\]\.type: must be 'touch' or 'fixed'"),
    (lambda d: d["supports"][1].__setitem__("id", "floor"), r"supports\[1\]\.id"),
])
def test_bad_fields_are_named(tmp_path, mutate, message):
    data = _base()
    mutate(data)
    with pytest.raises(InputError, match=message):
        read_arrangement(_write(tmp_path, data))


def test_nan_and_infinity_rejected(tmp_path):
    for bad in (float("nan"), float("inf")):
        data = _base()
        data["cuboids"][0]["center"][0] = bad
        with pytest.raises(InputError, match=r"cuboids\[0\]\.center: .*NaN or infinity"):
            read_arrangement(_write(tmp_path, data))


def test_not_json_and_missing_file(tmp_path):
    with pytest.raises(InputError, match="not valid JSON"):
        read_arrangement(_write(tmp_path, "{nope"))
    with pytest.raises(InputError, match="no such file"):
        read_arrangement(tmp_path / "missing.json")


def test_write_is_atomic_and_leaves_no_temp_files(tmp_path):
    p = tmp_path / "out" / "a.json"
    write_arrangement(_scene(), p)
    assert sorted(x.name for x in p.parent.iterdir()) == ["a.json"]
