"""Initial cuboids of objects hanging on a wall (section 4.1 on a rendered scan)."""

from __future__ import annotations

import os

import numpy as np
import pytest


def _yaw_mod_90(R: np.ndarray) -> float:
    h = R[:, int(np.argmin(np.abs(R[2])))]
    return float(np.degrees(np.arctan2(h[1], h[0])) % 90.0)


def test_a_wall_shelf_seen_at_a_slant_is_fitted_square_to_its_wall(tmp_path):
    # wall_shelf seed 32, one Kinect view: three shelves on brackets on one wall (seed 5
    # before the generator was widened; there the normals of two voted for yaws 15-17
    # degrees off the wall: depth steps across a board face the camera).  Each shelf
    # hangs (nothing of it near the floor) within centimetres of the wall, so its parts
    # take the wall's yaw.  The truth's wall is the reference.
    if os.environ.get("MUJOCO_GL") not in ("egl", "osmesa"):
        pytest.skip("rendering needs MUJOCO_GL=egl or osmesa (make test sets it)")
    from eval.suites._scenes import initial_from_dir, make_scene

    made = make_scene("wall_shelf", 32, tmp_path / "s", views=1)
    wall = next(s for s in made.truth.arrangement.supports if s.id == "wall:0")
    wall_yaw = float(np.degrees(np.arctan2(wall.normal[1], wall.normal[0])) % 90.0)
    _, initial, _ = initial_from_dir(made.path)
    parts = [c for c in initial.cuboids if c.object.startswith("wall_shelf")]
    assert len({c.object for c in parts}) == 3 and len(parts) == 9
    for c in parts:
        off = (_yaw_mod_90(c.rotation) - wall_yaw + 45.0) % 90.0 - 45.0
        assert abs(off) < 1.0, (c.id, off)
