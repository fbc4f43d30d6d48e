"""The units step: clouds of implausible extent rescaled by a power of ten (noted),
depth scans refused naming the flags, coincident points refused, --scale obeyed."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.errors import InputError
from pipeline.scan_io import ScanInput
from pipeline.units import extent, to_metres


def cloud(n: int = 2000, size: float = 3.0, seed: int = 0) -> ScanInput:
    pts = np.random.default_rng(seed).uniform(0, size, (n, 3))
    return ScanInput(points=pts, source="cloud.ply")


def test_a_plausible_cloud_is_kept_as_it_is():
    scan = cloud()
    out, s, note = to_metres(scan)
    assert out is scan and s == 1.0 and note is None


@pytest.mark.parametrize("s_in", [1e-3, 1e-2, 1e2, 1e3])
def test_an_implausible_cloud_comes_back_to_the_same_metres(s_in):
    scan = cloud()
    small = ScanInput(points=scan.points * s_in, source="cloud.ply")
    out, s, note = to_metres(small)
    assert s == pytest.approx(1.0 / s_in, rel=1e-12) and "scaled by" in note
    np.testing.assert_allclose(out.points, scan.points, rtol=1e-12)
    assert 1.0 <= extent(out.points) < 10.0


def test_a_depth_scan_of_implausible_extent_is_refused_naming_the_flags():
    scan = cloud(size=200.0)
    scan = ScanInput(points=scan.points, depth=np.ones((4, 4)), source="depth.png")
    with pytest.raises(InputError, match=r"depth\.png: the scan is .* m across.*--depth-scale"
                                         r".*--scale"):
        to_metres(scan)


def test_an_explicit_scale_wins_and_scales_depth_and_pose():
    T = np.eye(4)
    T[:3, 3] = (1000.0, 0.0, 500.0)
    scan = ScanInput(points=cloud(size=3000.0).points, depth=np.full((2, 2), 2000.0),
                     T_world_cam=T, source="mm")
    out, s, note = to_metres(scan, 0.001)
    assert s == 0.001 and "(--scale)" in note
    np.testing.assert_allclose(out.depth, 2.0)
    np.testing.assert_allclose(out.T_world_cam[:3, 3], (1.0, 0.0, 0.5))
    np.testing.assert_allclose(out.T_world_cam[:3, :3], np.eye(3))
    with pytest.raises(InputError, match="--scale"):
        to_metres(scan, -1.0)


def test_coincident_points_are_refused():
    scan = ScanInput(points=np.tile([[0.5, 0.25, 1.0]], (1000, 1)), source="same.ply")
    with pytest.raises(InputError, match="all 1000 points coincide"):
        to_metres(scan)


@pytest.mark.parametrize("s_in, s_out", [(1e-6, 1e6), (1e6, 1e-6), (1e-7, None), (1e7, None)])
def test_the_automatic_unit_obeys_the_range_of_scale(s_in, s_out):
    # the cloud is 5 units across times s_in: the factor that makes it 1-10 m is 1 / s_in,
    # accepted within --scale's range (1e-6 to 1e6), refused with one line beyond it
    scan = ScanInput(points=cloud().points * s_in, source="far.ply")
    if s_out is not None:
        assert to_metres(scan)[1] == pytest.approx(s_out, rel=1e-12)
        return
    with pytest.raises(InputError, match=r"far\.ply: the cloud is .* units across; no unit "
                                         r"from 1e-06 to 1e\+06 m"):
        to_metres(scan)
