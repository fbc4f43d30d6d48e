"""The Kinect v1 noise model: each term against its formula, and switchable."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pipeline.camera import Intrinsics
from simulate.noise import (
    TERMS,
    KinectNoise,
    apply_noise,
    axial_sigma,
    incidence_angle,
    lateral_sigma_px,
    projector_shadow,
    quantize_depth,
)

INTR = Intrinsics.kinect_v1()


def frontal(z: float, intr: Intrinsics = INTR) -> np.ndarray:
    return np.full((intr.height, intr.width), z, dtype=np.float32)


def box_before_wall(z_box: float = 1.0, z_wall: float = 2.0, half: int = 60) -> np.ndarray:
    """A fronto-parallel square at ``z_box`` in front of a wall at ``z_wall``."""
    d = frontal(z_wall)
    cv, cu = 240, 320
    d[cv - half:cv + half, cu - half:cu + half] = z_box
    return d


def tilted_plane(angle_deg: float, z0: float = 2.0, intr: Intrinsics = INTR) -> np.ndarray:
    """Depth of the plane through (0, 0, z0) whose normal is tilted ``angle`` about the y axis."""
    a = np.deg2rad(angle_deg)
    n = np.array([np.sin(a), 0.0, -np.cos(a)])
    v, u = np.mgrid[0:intr.height, 0:intr.width]
    ray = np.stack([(u - intr.cx) / intr.fx, (v - intr.cy) / intr.fy, np.ones(u.shape)], -1)
    t = (np.array([0, 0, z0]) @ n) / (ray @ n)
    return t.astype(np.float32)


def test_axial_sigma_matches_nguyen_formula_by_hand():
    # theta <= 60 deg: 0.0012 + 0.0019 (z - 0.4)^2
    assert axial_sigma(1.0, 0.0) == pytest.approx(0.0012 + 0.0019 * 0.36)
    assert axial_sigma(3.0, np.deg2rad(60)) == pytest.approx(0.0012 + 0.0019 * 2.6**2)
    # theta = 70 deg, z = 1.0: + 0.0001 * theta^2 / (pi/2 - theta)^2 = 0.0001 * (70/20)^2
    assert axial_sigma(1.0, np.deg2rad(70)) == pytest.approx(0.0012 + 0.0019 * 0.36
                                                             + 0.0001 * 3.5**2)
    assert axial_sigma(4.0, np.deg2rad(70)) == pytest.approx(0.0012 + 0.0019 * 3.6**2
                                                             + 0.0001 / 2 * 3.5**2)
    assert lateral_sigma_px(0.0) == pytest.approx(0.8)
    assert lateral_sigma_px(np.deg2rad(45)) == pytest.approx(0.8 + 0.035)


@pytest.mark.parametrize("z", [0.8, 1.5, 2.5, 3.5])
def test_axial_noise_std_follows_formula(z):
    model = KinectNoise.only("axial")
    noisy = apply_noise(frontal(z), INTR, np.random.default_rng(1), model)
    resid = noisy.astype(float) - z
    want = axial_sigma(z, 0.0)
    # 307200 samples: the sample std is within 1 % of sigma (plus float32 rounding)
    assert np.std(resid) == pytest.approx(want, rel=0.01)
    assert abs(np.mean(resid)) < 4 * want / np.sqrt(resid.size) + 1e-6


def test_axial_noise_grows_with_incidence_angle():
    model = KinectNoise.only("axial")
    stds = []
    for ang in (0.0, 50.0, 70.0):
        d = tilted_plane(ang)
        noisy = apply_noise(d, INTR, np.random.default_rng(2), model)
        _, th = incidence_angle(d, INTR)
        ok = np.isfinite(th)
        # normalised residuals are standard normal when sigma uses the per-pixel angle
        r = (noisy[ok] - d[ok]) / axial_sigma(d[ok], th[ok])
        assert np.std(r) == pytest.approx(1.0, abs=0.02)
        stds.append(np.std(noisy[ok] - d[ok]))
    assert stds[0] < stds[1] < stds[2]


def test_incidence_angle_of_a_tilted_plane():
    d = tilted_plane(50.0)
    n, th = incidence_angle(d, INTR)
    # at the principal point the viewing ray is the optical axis: theta = tilt
    assert np.rad2deg(th[240, 320]) == pytest.approx(50.0, abs=0.2)
    a = np.deg2rad(50.0)
    assert np.allclose(n[240, 320], [np.sin(a), 0, -np.cos(a)], atol=5e-3)  # faces the camera


def test_quantisation_steps_in_eighth_disparity():
    d = tilted_plane(40.0)
    q = apply_noise(d, INTR, np.random.default_rng(0), KinectNoise.only("quantization"))
    fb = INTR.fx * 0.075
    disp = fb / q.astype(float)
    # every depth is an exact 1/8-pixel disparity (up to float32 rounding of the depth)
    assert np.abs(disp * 8 - np.rint(disp * 8)).max() < 1e-3
    # the step between neighbouring levels near 2 m is z^2 / (8 f b)
    levels = np.unique(quantize_depth(np.linspace(1.95, 2.05, 5000), INTR.fx, 0.075))
    step = np.diff(levels).mean()
    assert step == pytest.approx(2.0**2 / (8 * fb), rel=0.02)
    # rounding error is at most half a step
    assert np.abs(q - d).max() <= 0.5 * (d.max() ** 2) / (8 * fb) * 1.05


@pytest.mark.parametrize("baseline", [0.075, -0.075])
def test_projector_shadow_on_the_projector_side_only(baseline):
    z_box, z_wall, half = 1.0, 2.0, 60
    d = box_before_wall(z_box, z_wall, half)
    shadow = projector_shadow(d, INTR, baseline)
    assert not shadow[d == z_box].any()  # the occluder is never in its own shadow
    rows = np.arange(240 - half, 240 + half)
    width = INTR.fx * abs(baseline) * (1 / z_box - 1 / z_wall)  # disparity difference, px
    # shadowed columns of a row through the box: a band of ~width px beside the box,
    # left of it when the projector is to the right (+x), right of it otherwise
    v, u = np.nonzero(shadow)
    assert set(np.unique(v)) == set(rows)
    if baseline > 0:
        assert u.max() == 320 - half - 1
        assert abs(u.min() - (320 - half - width)) <= 1.0
    else:
        assert u.min() == 320 + half
        assert abs(u.max() - (320 + half - 1 + width)) <= 1.0
    assert abs(shadow.sum() / len(rows) - width) <= 1.0
    # through apply_noise the shadowed pixels read zero and nothing else does
    model = replace(KinectNoise.only("shadows"), baseline=baseline)
    out = apply_noise(d, INTR, np.random.default_rng(0), model)
    assert ((out == 0) == shadow).all()


def test_dropout_only_at_grazing_angles_and_out_of_range():
    model = KinectNoise.only("dropout")
    near = apply_noise(tilted_plane(30.0), INTR, np.random.default_rng(0), model)
    assert (near > 0).all()
    d = tilted_plane(76.0, z0=1.5)
    out = apply_noise(d, INTR, np.random.default_rng(0), model)
    _, th = incidence_angle(d, INTR)
    deg = np.rad2deg(np.nan_to_num(th))
    gone = (out == 0) & (d >= model.min_depth) & (d <= model.max_depth)
    assert gone.any()
    assert deg[gone].min() >= model.grazing_start_deg
    # the dropped fraction follows the linear ramp between 70 and 80 degrees
    band = (deg > 74) & (deg < 76) & (d >= 0.4) & (d <= 6.0)
    assert gone[band].mean() == pytest.approx(0.5, abs=0.06)
    assert (out[(d < 0.4) | (d > 6.0)] == 0).all()


def test_lateral_noise_moves_edges_not_flat_interiors():
    d = box_before_wall()
    out = apply_noise(d, INTR, np.random.default_rng(3), KinectNoise.only("lateral"))
    changed = out != d
    assert changed.any()
    # only pixels within a few sigma_L (0.8 px) of the box outline change
    v, u = np.nonzero(changed)
    edge_dist = np.abs(np.maximum(np.abs(v - 239.5), np.abs(u - 319.5)) - 60)
    assert edge_dist.max() <= 5, edge_dist.max()
    # values are only ever the two depths present (a resampling, not a blend)
    assert set(np.unique(out)) <= {np.float32(1.0), np.float32(2.0)}


def test_flying_pixels_only_at_depth_edges_and_between_surfaces():
    d = box_before_wall()
    out = apply_noise(d, INTR, np.random.default_rng(4), KinectNoise.only("flying_pixels"))
    fly = (out != d)
    assert fly.sum() > 100
    v, u = np.nonzero(fly)
    ring = np.abs(np.maximum(np.abs(v - 239.5), np.abs(u - 319.5)) - 60)
    assert ring.max() <= 1.0  # the two pixel rings on either side of the outline
    assert ((out[fly] > 1.0) & (out[fly] < 2.0)).all()
    # about half the edge pixels fly (flying_prob = 0.5)
    assert fly.sum() / (2 * 4 * 120) == pytest.approx(0.5, abs=0.08)


def test_all_off_is_identity_and_seeded():
    d = box_before_wall()
    assert (apply_noise(d, INTR, np.random.default_rng(0), KinectNoise.none()) == d).all()
    a = apply_noise(d, INTR, np.random.default_rng(7))
    b = apply_noise(d, INTR, np.random.default_rng(7))
    c = apply_noise(d, INTR, np.random.default_rng(8))
    assert a.tobytes() == b.tobytes()
    assert a.tobytes() != c.tobytes()
    assert a.dtype == np.float32


def test_switching_a_term_off_keeps_the_other_draws():
    """Each term has its own child generator: dropping shadows only zeroes fewer pixels."""
    d = box_before_wall()
    full = apply_noise(d, INTR, np.random.default_rng(5), KinectNoise())
    no_shadow = apply_noise(d, INTR, np.random.default_rng(5), KinectNoise(shadows=False))
    sh = projector_shadow(d, INTR)
    assert (full[~sh] == no_shadow[~sh]).all()
    assert (full[sh] == 0).all() and (no_shadow[sh] > 0).mean() > 0.9


@pytest.mark.parametrize("term", TERMS)
def test_each_term_changes_the_image(term):
    d = tilted_plane(76.0, z0=1.5) if term == "dropout" else box_before_wall()
    out = apply_noise(d, INTR, np.random.default_rng(0), KinectNoise.only(term))
    assert (out != d).any()


def test_only_rejects_unknown_terms():
    with pytest.raises(ValueError, match="unknown noise terms"):
        KinectNoise.only("gaussian")


def test_rendered_shadow_falls_beside_the_occluder_on_the_wall():
    """Through the renderer: a box 1 m in front of a wall at 2 m casts its projector shadow
    on the wall, immediately left of the box (projector to the camera's right)."""
    import os

    os.environ.setdefault("MUJOCO_GL", "egl")
    from pipeline.model import Arrangement, box
    from simulate.scan import render

    arr = Arrangement((box("box", (0.0, 0.0, 1.0), (0.3, 0.3, 0.3)),
                       box("wall", (0.0, 0.0, 2.05), (6.0, 6.0, 0.1))))
    f = render(arr, INTR, np.eye(4))
    shadow = projector_shadow(f.depth, INTR, 0.075)
    assert shadow.any()
    assert (f.instance[shadow] == 2).all()  # only wall pixels
    width = INTR.fx * 0.075 * (1 / 0.85 - 1 / 2.0)  # front face at z = 0.85
    v, u = np.nonzero(shadow)
    box_left = np.array([np.nonzero(f.instance[r] == 1)[0].min() for r in np.unique(v)])
    left_of = dict(zip(np.unique(v), box_left, strict=True))
    gap = np.array([left_of[r] for r in v]) - u  # 1 .. width pixels left of the box
    assert gap.min() >= 1 and gap.max() <= np.ceil(width) + 1
