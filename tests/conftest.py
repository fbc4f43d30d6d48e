"""Shared fixtures and scene builders for the test suite."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

os.environ.setdefault("MUJOCO_GL", "egl")

# Property tests draw the same cases on every run (CI stays reproducible); explore with
# HYPOTHESIS_PROFILE=explore, and pin what it finds as a test of its own.
settings.register_profile("repeatable", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "repeatable"))

from pipeline.model import (  # noqa: E402
    Arrangement,
    Contact,
    Cuboid,
    Support,
    box,
    box_corners,
    ground,
    rotation_about_axis,
)

REPO = Path(__file__).resolve().parents[1]
REAL_DATA = REPO.parent / "shared" / "data" / "real"


def overhang_scene(fraction: float, yaw: float = 0.0) -> Arrangement:
    """A 1 m cube on the ground with a 1 x 1 x 0.2 slab on top shifted by ``fraction`` of its length."""
    return Arrangement((box("base", (0, 0, 0.5), (1, 1, 1)),
                        box("top", (fraction, 0, 1.1), (1, 1, 0.2), yaw=yaw)), (ground(),))


def leaning_plank(theta_deg: float, length: float = 1.0, thickness: float = 0.02,
                  width: float = 0.3) -> Arrangement:
    """A plank at ``theta_deg`` from the floor, its bottom edge on the ground, top edge on wall x = 0."""
    th = np.radians(theta_deg)
    d = np.array([-np.cos(th), 0.0, np.sin(th)])
    y = np.array([0.0, 1.0, 0.0])
    R = np.stack([d, y, np.cross(d, y)], axis=1)
    size = np.array([length, width, thickness])
    c = box_corners(np.zeros((1, 3)), R[None], size[None])[0]
    center = np.array([-c[:, 0].min(), 0.0, -c[:, 2].min()])
    wall = Support("wall:0", np.zeros(3), np.array([1.0, 0.0, 0.0]))
    return Arrangement((Cuboid("plank", center, R, size),), (ground(), wall))


def slanted_clamp(phi_deg: float) -> Arrangement:
    """A board (0.1 x 0.3 x 0.4 m) tilted ``phi_deg`` about y, clamped in the air between
    two tilted 0.3 x 0.4 x 2 m jaws glued to the ground: its two big faces touch the jaws'
    faces exactly, and their normal points ``phi_deg`` below and above horizontal."""
    R = rotation_about_axis(np.array([0.0, 1.0, 0.0]), np.radians(phi_deg))
    x, z = R[:, 0], R[:, 2]
    mid = np.array([0.0, 0.0, 0.7])
    size = np.array([0.3, 0.4, 2.0])
    lift = np.abs(R[2]) @ (size / 2)  # a jaw's centre height when its lowest edge is on the floor
    jaws = []
    for name, side in (("jaw0", -1.0), ("jaw1", 1.0)):
        base = mid + side * (0.05 + 0.15) * x
        # slid along its own axis until its lowest edge is on the floor
        jaws.append(Cuboid(name, base + (lift - base[2]) / R[2, 2] * z, R, size))
    board = Cuboid("board", mid, R, np.array([0.1, 0.3, 0.4]))
    return Arrangement((*jaws, board), (ground(),),
                       (Contact("jaw0", "ground", "fixed"), Contact("jaw1", "ground", "fixed")))


@pytest.fixture
def real_data() -> Path:
    if not REAL_DATA.is_dir():
        pytest.skip(f"real scans not present at {REAL_DATA}")
    return REAL_DATA
