"""Objects apart without labels: a cluster of a depth image is split at concave creases
and depth steps (pipeline.segment.split_clusters), never at a convex box's own edges.

Frames are ray-cast by tests/pipeline/rgbd_fixtures.py (independent of the project's
sensor), every box painted one colour, and read back without an instance mask, as a
user's depth frame arrives; the truth is the ray-caster's per-pixel box id.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from pipeline.model import rotation_about_z
from pipeline.run import RunConfig, initial, load

sys.path.insert(0, str(Path(__file__).parent))
from rgbd_fixtures import raycast, write_frame  # noqa: E402

EYE, TARGET = (0.2, -1.6, 1.3), (0.0, 0.1, 0.35)


def _objects(tmp_path, boxes, eye=EYE, target=TARGET):
    """(per point object label, per point true box id (0 none)) of a one-colour frame."""
    frame = raycast(boxes, eye, target)
    frame.color[:] = 150  # one colour everywhere: only geometry can separate objects
    scan = load(write_frame(frame, tmp_path / "frame"))
    _, rep = initial(scan, RunConfig(seed=0))
    truth = frame.instance[scan.pixels[:, 0], scan.pixels[:, 1]]
    return rep["labels"], truth, rep["objects"]


def _main_objects(labels, truth, boxes=(1, 2)):
    """The object holding most of each true box's points, and that share."""
    out = []
    for k in boxes:
        lab = labels[(truth == k) & (labels >= 0)]
        counts = np.bincount(lab)
        out.append((int(np.argmax(counts)), counts.max() / len(lab)))
    return out


def _purity(labels, truth):
    """Per object, the share of its points that belong to its majority box."""
    out = []
    for k in np.unique(labels[labels >= 0]):
        t = truth[labels == k]
        out.append(np.bincount(t).max() / len(t))
    return out


def test_a_box_standing_on_a_box_of_the_same_colour_is_two_objects(tmp_path):
    # the top box is set back, so the lower box's top face meets its front concavely
    boxes = [(np.array([0.0, 0.1, 0.25]), np.eye(3), np.array([0.6, 0.5, 0.5])),
             (np.array([0.05, 0.2, 0.65]), rotation_about_z(0.3), np.array([0.3, 0.25, 0.3]))]
    labels, truth, names = _objects(tmp_path, boxes)
    (a, share_a), (b, share_b) = _main_objects(labels, truth)
    assert a != b and share_a > 0.9 and share_b > 0.9
    assert min(_purity(labels, truth)) > 0.8


def test_a_low_box_pushed_against_a_tall_one_is_cut_where_they_meet(tmp_path):
    # the low box's back face touches the tall box's front face: one proximity cluster
    boxes = [(np.array([0.0, 0.35, 0.4]), np.eye(3), np.array([0.5, 0.3, 0.8])),
             (np.array([0.05, 0.05, 0.15]), np.eye(3), np.array([0.4, 0.3, 0.3]))]
    labels, truth, names = _objects(tmp_path, boxes)
    (a, share_a), (b, share_b) = _main_objects(labels, truth)
    assert a != b and share_a > 0.9 and share_b > 0.9
    assert min(_purity(labels, truth)) > 0.9


@pytest.mark.parametrize("yaw", [0.4, 0.8])
def test_one_box_seen_on_three_faces_stays_one_object(tmp_path, yaw):
    # must not act: the faces of one convex box meet in convex creases only
    boxes = [(np.array([0.0, 0.1, 0.3]), rotation_about_z(yaw), np.array([0.5, 0.4, 0.6]))]
    labels, truth, names = _objects(tmp_path, boxes)
    assert len(names) == 1, names


@pytest.mark.parametrize("yaw", [0.4, 0.8])
def test_a_shaded_box_seen_on_three_faces_stays_one_object(tmp_path, yaw):
    # must not act: its faces differ in brightness (the ray-caster shades each face
    # differently), not in kind
    boxes = [(np.array([0.0, 0.1, 0.3]), rotation_about_z(yaw), np.array([0.5, 0.4, 0.6]))]
    frame = raycast(boxes, EYE, TARGET)
    scan = load(write_frame(frame, tmp_path / "frame"))
    _, rep = initial(scan, RunConfig(seed=0))
    assert len(rep["objects"]) == 1, rep["objects"]



def _ridge(deg: float):
    """Two boxes side by side on the floor, each turned ``deg`` degrees, their fronts
    meeting in a ridge towards the camera (a convex edge, as a box's own edges are)."""
    size = np.array([0.4, 0.3, 0.5])
    ridge = np.array([0.0, -0.05, 0.25])
    out = []
    for sign in (-1.0, 1.0):
        R = rotation_about_z(np.radians(sign * deg))
        corner = np.array([-sign * size[0] / 2, -size[1] / 2, 0.0])  # front corner at the ridge
        out.append((ridge - R @ corner, R, size))
    return out


@pytest.mark.parametrize("painted", [True, False])
def test_two_boxes_whose_fronts_meet_in_a_ridge_are_two_objects_when_painted_apart(
        tmp_path, painted):
    """Two boxes side by side, turned 15 degrees each way, their fronts meeting in a
    convex ridge towards the camera, as two faces of one box would (at 30 degrees, not
    square): no concave crease, no depth step.  Painted differently (the ray-caster's
    colour per box) they are two objects; painted one colour nothing separates them and
    the cluster stays whole.  The strip of each front within the plane tolerance of the
    other (a few cm along the ridge) goes with the other, so each object holds about
    three quarters of its box."""
    boxes = _ridge(15.0)
    frame = raycast(boxes, (0.1, -1.6, 0.4), (0.0, 0.1, 0.3))
    if not painted:
        frame.color[:] = 150
    scan = load(write_frame(frame, tmp_path / "frame"))
    _, rep = initial(scan, RunConfig(seed=0))
    labels = rep["labels"]
    truth = frame.instance[scan.pixels[:, 0], scan.pixels[:, 1]]
    (a, share_a), (b, share_b) = _main_objects(labels, truth)
    if painted:
        assert len(rep["objects"]) == 2, rep["objects"]
        assert a != b and share_a > 0.65 and share_b > 0.65
        assert min(_purity(labels, truth)) > 0.75
    else:
        assert len(rep["objects"]) == 1, rep["objects"]
