"""A box turned within its one seen face (pipeline.fit.face_turn_frame): a board standing
on its corner and leaning sideways on a block, seen face-on, is fitted turned; an upright
board is not.  Frames are ray-cast by tests/pipeline/rgbd_fixtures.py."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from pipeline.model import rotation_about_axis
from pipeline.run import RunConfig, load, run_scan

sys.path.insert(0, str(Path(__file__).parent))
from rgbd_fixtures import raycast, write_frame  # noqa: E402

EYE, TARGET = (0.0, -1.5, 0.6), (0.0, 0.0, 0.25)
Y = np.array([0.0, 1.0, 0.0])


def _board(turn_deg: float):
    """A 40 x 4 x 30 cm board facing the camera (thin along y), turned about y by
    ``turn_deg``, its lowest corner on the floor."""
    R = rotation_about_axis(Y, np.radians(turn_deg))
    size = np.array([0.4, 0.04, 0.3])
    corners = (np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
               * size / 2) @ R.T
    return np.array([0.0, 0.0, -corners[:, 2].min()]), R, size


def _fitted(tmp_path, turn_deg: float):
    boxes = [_board(turn_deg)]
    frame = raycast(boxes, EYE, TARGET)
    scan = load(write_frame(frame, tmp_path / f"f{turn_deg}"))
    res = run_scan(scan, RunConfig(stage="initial"))
    board = max(res.arrangement.cuboids, key=lambda c: c.extra.get("points", 0))
    return board


@pytest.mark.parametrize("turn", [25.0, 40.0])
def test_a_board_standing_on_its_corner_is_fitted_turned(tmp_path, turn):
    b = _fitted(tmp_path, turn)
    assert b.extra.get("slanted")
    # its long axis makes the true angle with the horizontal (within 3 degrees)
    R = b.rotation
    k = int(np.argmax(b.size))
    axis = R[:, k]
    angle = np.degrees(np.arcsin(min(1.0, abs(axis[2]))))
    assert abs(angle - turn) < 3.0, (angle, b.size)
    assert np.allclose(sorted(b.size), [0.04, 0.3, 0.4], atol=0.03), b.size


def test_an_upright_board_stays_upright(tmp_path):
    b = _fitted(tmp_path, 0.0)
    assert not b.extra.get("slanted")
    assert abs(b.rotation[2, 2]) > 0.999 or abs(b.rotation[2, :]).max() > 0.999
