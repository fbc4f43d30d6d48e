"""The depth denoising of section 4.1's points (pipeline.initial.segment_median_depth)."""

from __future__ import annotations

import numpy as np

from pipeline.initial import nan_median_last, segment_median_depth


def _plane(H=60, W=80, z0=3.0, slope=0.02):
    """A plane receding by ``slope`` metres per image row: (H, W) depth."""
    return z0 + slope * np.arange(H)[:, None] + np.zeros((H, W))


def test_noise_on_a_face_is_cut_more_than_twice_without_bias():
    rng = np.random.default_rng(0)
    truth = _plane()
    noisy = truth + rng.normal(0.0, 0.014, truth.shape)  # Kinect sigma at 3 m
    label = np.zeros(truth.shape, np.int64)
    out = segment_median_depth(noisy, label)
    inner = (slice(2, -2), slice(2, -2))
    rms_in = np.sqrt(np.mean((noisy - truth)[inner] ** 2))
    rms_out = np.sqrt(np.mean((out - truth)[inner] ** 2))
    assert rms_out < rms_in / 2.5
    assert abs(np.mean((out - truth)[inner])) < 0.002


def test_the_far_edge_of_a_receding_face_is_not_pulled_towards_the_camera():
    # a plain window median at the segment's last row sees only nearer rows and pulls
    # the edge forward by about two rows' worth of depth (4 cm here); the symmetric
    # pairs keep it where it is
    truth = _plane(slope=0.02)
    label = np.full(truth.shape, -1, np.int64)
    label[10:40] = 0  # the face covers rows 10..39, background around it
    out = segment_median_depth(truth, label)
    np.testing.assert_allclose(out[10:40], truth[10:40], atol=1e-12)


def test_segments_do_not_mix_and_pixels_without_reading_or_label_stay():
    rng = np.random.default_rng(1)
    depth = np.where(np.arange(80)[None, :] < 40, 2.0, 3.5) + np.zeros((60, 80))
    depth = depth + rng.normal(0.0, 0.01, depth.shape)
    label = np.where(np.arange(80)[None, :] < 40, 0, 1) + np.zeros((60, 80), np.int64)
    depth[5, 5] = 0.0  # no reading
    label[50, 60] = -1  # floor / wall / unsegmented
    out = segment_median_depth(depth, label)
    assert out[5, 5] == 0.0 and out[50, 60] == depth[50, 60]
    a, b = out[:, :40], out[:, 40:]
    assert a[a > 0].max() < 2.1 and b.min() > 3.4  # nothing of one segment in the other


def test_nan_median_matches_numpy_on_rows_with_any_number_of_readings():
    import warnings

    rng = np.random.default_rng(3)
    a = rng.normal(size=(40, 30, 13))
    a[rng.random(a.shape) < 0.5] = np.nan
    a[0, 0] = np.nan  # no reading at all
    a[1, 1, 1:] = np.nan  # one
    a[2, 2, 2:] = np.nan  # two: the mean of both
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        want = np.nanmedian(a, axis=-1)
    got = nan_median_last(a)
    assert np.array_equal(got, want, equal_nan=True)
    assert np.isnan(got[0, 0]) and got[1, 1] == a[1, 1, 0]
    assert got[2, 2] == (a[2, 2, 0] + a[2, 2, 1]) / 2
