"""The renderers against analytic ray casting and against each other."""

from __future__ import annotations

import os

import numpy as np
import pytest

from pipeline.camera import Intrinsics, look_at
from pipeline.model import Arrangement, Support, box, ground, rotation_about_axis

os.environ.setdefault("MUJOCO_GL", "egl")


def _rays_world(intr: Intrinsics, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Origin (3,) and world directions (H, W, 3) with unit camera-z component."""
    v, u = np.mgrid[0:intr.height, 0:intr.width]
    d = np.stack([(u - intr.cx) / intr.fx, (v - intr.cy) / intr.fy, np.ones(u.shape)], -1)
    return T[:3, 3], d @ T[:3, :3].T


def _raycast_boxes(arr: Arrangement, intr: Intrinsics, T: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Independent truth: slab-method ray casting of the cuboids and the support planes.

    Returns depth (H, W) (camera z of the first hit, inf = none) and the instance ids.
    """
    o, d = _rays_world(intr, T)
    best = np.full(d.shape[:2], np.inf)
    inst = np.zeros(d.shape[:2], np.uint16)
    for s in arr.supports:  # planes (infinite: the drawn slabs are 50 m wide)
        dn = d @ s.normal
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -s.signed_distance(o[None])[0] / dn
        t = np.where((dn < 0) & (t > 0), t, np.inf)
        inst[t < best] = 0
        best = np.minimum(best, t)
    for k, c in enumerate(arr.cuboids):
        ol = (o - c.center) @ c.rotation  # ray in the box frame
        dl = d @ c.rotation
        h = c.size / 2
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (-h - ol) / dl
            t2 = (h - ol) / dl
        tmin = np.nanmax(np.minimum(t1, t2), axis=-1)
        tmax = np.nanmin(np.maximum(t1, t2), axis=-1)
        hit = (tmax >= tmin) & (tmin > 0)
        t = np.where(hit, tmin, np.inf)
        inst[t < best] = k + 1
        best = np.minimum(best, t)
    return best, inst  # t is the camera z because the ray's camera-z component is 1


@pytest.fixture(scope="module")
def scene() -> Arrangement:
    tilt = rotation_about_axis(np.array([1.0, 1.0, 0.0]), 0.5)
    return Arrangement(
        (box("a", (0, 0, 0.25), (0.5, 0.5, 0.5), object="crate"),
         box("b", (0, 0, 0.6), (0.3, 0.25, 0.2), yaw=0.3, object="crate"),
         box("c", (0.65, 0.2, 0.15), (0.3, 0.2, 0.3), yaw=0.4),
         box("d", (-0.4, 0.6, 0.5), (0.2, 0.3, 0.15), rotation=tilt)),
        (ground(), Support("wall:0", np.array([0.0, 1.2, 0.0]), np.array([0.0, -1.0, 0.0]))))


# an off-centre principal point and fx != fy, so the frustum code is really exercised
ODD = Intrinsics(320, 240, 280.0, 300.0, 150.3, 131.7)


@pytest.mark.parametrize("intr", [Intrinsics.kinect_v1(), ODD], ids=["kinect", "odd"])
def test_mujoco_depth_and_ids_equal_ray_casting(scene, intr):
    from simulate.render_mujoco import render_mujoco

    T = look_at([1.8, -1.4, 1.3], [0.0, 0.1, 0.3])
    color, depth, inst = render_mujoco(scene, intr, T)
    assert color.shape == (intr.height, intr.width, 3) and color.dtype == np.uint8
    assert depth.dtype == np.float32 and inst.dtype == np.uint16
    truth, truth_inst = _raycast_boxes(scene, intr, T)
    # ids: only pixels whose ray grazes an edge may differ
    agree = (inst == truth_inst).mean()
    assert agree > 0.998, agree
    assert set(np.unique(inst)) == {0, 1, 2, 3, 4}
    same = (inst == truth_inst) & (depth > 0) & (truth < 8.0)
    err = np.abs(depth[same] - truth[same])
    assert same.sum() > 0.9 * depth.size
    assert np.median(err) < 2e-6
    assert err.max() < 1e-4, err.max()


def test_mujoco_frontal_plane_is_constant_depth():
    """A box face square to the optical axis at 1.234 m reads 1.234 m on every pixel."""
    from simulate.render_mujoco import render_mujoco

    arr = Arrangement((box("wall", (0, 0, 1.234 + 0.05), (4.0, 4.0, 0.1)),))
    T = np.eye(4)  # camera at the origin looking along +z
    _, depth, inst = render_mujoco(arr, Intrinsics.kinect_v1(), T)
    assert (inst == 1).all()
    assert np.abs(depth - 1.234).max() < 1e-5


def test_background_reads_zero_depth():
    from simulate.render_mujoco import render_mujoco

    arr = Arrangement((box("a", (0, 0, 2.0), (0.2, 0.2, 0.2)),))
    _, depth, inst = render_mujoco(arr, ODD, np.eye(4))
    assert (depth[inst == 0] == 0).all()
    assert ((depth > 0) == (inst == 1)).all()
    # the front face at z = 1.9, centred on the optical axis: pixels within its projection
    v, u = np.nonzero(inst == 1)
    half_u = ODD.fx * 0.1 / 1.9
    assert abs(u.min() - (ODD.cx - half_u)) <= 1 and abs(u.max() - (ODD.cx + half_u)) <= 1


def test_pybullet_agrees_with_mujoco(scene):
    from simulate.render_mujoco import render_mujoco
    from simulate.render_pybullet import render_pybullet

    intr = Intrinsics.kinect_v1()
    T = look_at([1.6, -1.7, 1.2], [0.0, 0.2, 0.3])
    _, dm, im = render_mujoco(scene, intr, T)
    _, dp, ip = render_pybullet(scene, intr, T)
    ids = (im == ip).mean()
    assert ids > 0.99, ids
    both = (im == ip) & (dm > 0) & (dp > 0) & (dm < 8)
    err = np.abs(dm - dp)[both]
    assert np.median(err) < 1e-4, np.median(err)  # well under 1 mm
    assert np.percentile(err, 99) < 1e-3


def test_pybullet_pixel_shift_is_needed_and_right(scene):
    """The measured (u, v + 1) corner sampling: with the shift the floor depth is exact,
    without it a tilted floor is off by millimetres."""
    from simulate.render_pybullet import PIXEL_SHIFT, PybulletRenderer

    intr = ODD
    T = look_at([1.5, -1.2, 1.4], [0.0, 0.0, 0.0])
    truth, truth_inst = _raycast_boxes(scene, intr, T)
    with PybulletRenderer(scene) as r:
        errs = {}
        for shift in [PIXEL_SHIFT, (0.0, 0.0)]:
            _, d, inst = r.render(intr, T, shift=shift)
            ok = (inst == truth_inst) & (d > 0) & (truth < 4)
            errs[shift] = float(np.median(np.abs(d - truth)[ok]))
    assert errs[PIXEL_SHIFT] < 5e-5
    assert errs[(0.0, 0.0)] > 1e-3


def test_colours_distinct_per_cuboid_and_object(scene):
    from simulate.render_mujoco import cuboid_colors, render_mujoco

    rgb = cuboid_colors(scene)
    assert len(np.unique(np.round(rgb, 3), axis=0)) == len(scene.cuboids)
    intr = Intrinsics.kinect_v1()
    color, _, inst = render_mujoco(scene, intr, look_at([1.8, -1.4, 1.3], [0, 0.1, 0.3]))
    # the two parts of one object differ in the image (mean colour differs clearly)
    m1 = color[inst == 1].reshape(-1, 3).mean(axis=0)
    m2 = color[inst == 2].reshape(-1, 3).mean(axis=0)
    assert np.abs(m1 - m2).max() > 15


def test_renderer_reuse_many_views(scene):
    from simulate.render_mujoco import MujocoRenderer

    intr = Intrinsics(160, 120, 140.0, 140.0, 79.5, 59.5)
    with MujocoRenderer(scene, intr.width, intr.height) as r:
        for az in np.linspace(-2.8, 0.6, 4):  # all in front of the wall at y = 1.2
            eye = np.array([2.2 * np.cos(az), 2.2 * np.sin(az) - 0.5, 1.2])
            T = look_at(eye, [0, 0.1, 0.3])
            _, d, inst = r.render(intr, T)
            truth, tinst = _raycast_boxes(scene, intr, T)
            ok = (inst == tinst) & (d > 0) & (truth < 8)
            assert (inst == tinst).mean() > 0.99
            assert np.abs(d - truth)[ok].max() < 1e-4
        with pytest.raises(ValueError, match="intrinsics"):
            r.render(Intrinsics.kinect_v1(), T)


def test_shared_context_interleaved_renderers_are_independent(scene):
    """Renderers share one GL context per image size; interleaving them changes nothing."""
    from simulate.render_mujoco import MujocoRenderer

    intr = Intrinsics(160, 120, 140.0, 140.0, 79.5, 59.5)
    T = look_at([1.8, -1.4, 1.3], [0.0, 0.1, 0.3])
    other = Arrangement(tuple(box(f"o{k}", (0.3 * k - 1, 0.2, 0.1), (0.2, 0.2, 0.2))
                              for k in range(70)), (ground(),))  # grows the geom pool
    with MujocoRenderer(scene, intr.width, intr.height) as a:
        first = a.render(intr, T)
        with MujocoRenderer(other, intr.width, intr.height) as b:
            b_img = b.render(intr, T)
            again = a.render(intr, T)
    assert len(np.unique(b_img[2])) > 5 and b_img[2].max() <= len(other.cuboids)
    for x, y in zip(first, again, strict=True):
        assert x.tobytes() == y.tobytes()
