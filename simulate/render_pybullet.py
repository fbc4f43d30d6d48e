"""PyBullet TinyRenderer backend (``DIRECT``, no GL): RGB, metric depth, instance ids.

The second, independent renderer the MuJoCo one is checked against.  Each cuboid is a
static multibody with one box visual shape; supports are large thin grey boxes, as in
:mod:`simulate.render_mujoco`.

Pixel-centre quirk (measured, see ``tests/simulate/test_render.py``): in pixel-corner
coordinates (OpenCV pixel ``(u, v)`` covers ``[u, u + 1] x [v, v + 1]``) TinyRenderer
samples pixel ``(u, v)`` at ``(u, v + 1)``, its lower-left corner, instead of its centre
``(u + 0.5, v + 0.5)``.  An OpenCV camera with principal point ``(cx, cy)`` is therefore
rendered with a projection whose principal point is moved by :data:`PIXEL_SHIFT`
``= (-0.5, +0.5)`` (the "cx = W/2, cy = H/2 - 1" rule, in pixel-corner terms, for a
centred camera).  Without it a tilted plane is
off by millimetres (median 5 mm for a 1-2 m floor) and ids disagree along edges; with it
the depth agrees with MuJoCo to 5 micrometres (median) and ids on 100 % of pixels.
"""

from __future__ import annotations

import numpy as np

from pipeline.camera import Intrinsics, invert
from pipeline.model import Arrangement

from .render_mujoco import scene_boxes

#: Near and far clipping planes of the projection, metres.  TinyRenderer's float32 depth
#: buffer resolves about ``6e-8 z^2 / ZNEAR``: 0.005 mm at 3 m with 0.1 m (a Kinect sees
#: nothing nearer than 0.4 m anyway).
ZNEAR = 0.1
ZFAR = 60.0

#: (du, dv): where TinyRenderer samples OpenCV pixel (u, v) (centre at integers), minus
#: (u, v): the pixel's lower-left corner.  Measured by rendering tilted planes and fitting the shift that zeroes the depth
#: error (``test_pybullet_pixel_shift``).
PIXEL_SHIFT = (-0.5, 0.5)


def _quat_xyzw_from_matrix(R: np.ndarray) -> list[float]:
    """PyBullet's x y z w quaternion of a rotation matrix (the one place it is converted)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(np.asarray(R, float)).as_quat().tolist()


def projection_matrix(intr: Intrinsics, near: float = ZNEAR, far: float = ZFAR,
                      shift: tuple[float, float] = PIXEL_SHIFT) -> np.ndarray:
    """OpenGL projection (4, 4) of OpenCV intrinsics for TinyRenderer.

    Pixel ``u`` spans ``[u - 0.5, u + 0.5]``; the image spans ``[-0.5, W - 0.5]``.
    ``shift`` is added to the principal point to undo TinyRenderer's sampling offset.
    """
    W, H = intr.width, intr.height
    cx = intr.cx + shift[0]
    cy = intr.cy + shift[1]
    P = np.zeros((4, 4))
    P[0, 0] = 2 * intr.fx / W
    P[0, 2] = 1 - 2 * (cx + 0.5) / W
    P[1, 1] = 2 * intr.fy / H
    P[1, 2] = 2 * (cy + 0.5) / H - 1
    P[2, 2] = -(far + near) / (far - near)
    P[2, 3] = -2 * far * near / (far - near)
    P[3, 2] = -1.0
    return P


def view_matrix(T_world_cam: np.ndarray) -> np.ndarray:
    """OpenGL view matrix (4, 4): world -> GL camera (x right, y up, z backwards)."""
    return np.diag([1.0, -1.0, -1.0, 1.0]) @ invert(np.asarray(T_world_cam, float))


class PybulletRenderer:
    """Renders one arrangement from many cameras in its own ``DIRECT`` client."""

    def __init__(self, arr: Arrangement, colors: np.ndarray | None = None) -> None:
        from .pybullet_import import pybullet

        p = pybullet()
        self._p = p
        self.client = p.connect(p.DIRECT)
        boxes = scene_boxes(arr, colors)
        self._lookup: dict[int, int] = {}
        for c, R, h, rgb, inst in zip(boxes["center"], boxes["rotation"], boxes["half"],
                                      boxes["rgb"], boxes["instance"], strict=True):
            self._add_box(c, R, h, (*rgb, 1.0), int(inst))
        self._maxid = max(self._lookup, default=0)
        self._table = np.zeros(self._maxid + 2, dtype=np.uint16)
        for uid, inst in self._lookup.items():
            self._table[uid] = inst

    def _add_box(self, center, R, half, rgba, inst: int) -> None:
        p = self._p
        vis = p.createVisualShape(p.GEOM_BOX, halfExtents=[float(h) for h in half],
                                  rgbaColor=[float(x) for x in rgba], physicsClientId=self.client)
        uid = p.createMultiBody(baseMass=0, baseVisualShapeIndex=vis,
                                basePosition=[float(x) for x in center],
                                baseOrientation=_quat_xyzw_from_matrix(R),
                                physicsClientId=self.client)
        self._lookup[uid] = inst

    def __enter__(self) -> PybulletRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self.client is not None:
            self._p.disconnect(physicsClientId=self.client)
            self.client = None

    def render(self, intr: Intrinsics, T_world_cam: np.ndarray,
               shift: tuple[float, float] = PIXEL_SHIFT
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Render one view; same outputs as :meth:`simulate.render_mujoco.MujocoRenderer.render`."""
        p = self._p
        V = view_matrix(T_world_cam)
        P = projection_matrix(intr, shift=shift)
        _, _, rgba, zbuf, seg = p.getCameraImage(
            intr.width, intr.height, viewMatrix=V.T.ravel().tolist(),
            projectionMatrix=P.T.ravel().tolist(), renderer=p.ER_TINY_RENDERER,
            shadow=0,
            lightDirection=[-0.35, -0.25, 1.0], lightColor=[1, 1, 1],
            lightAmbientCoeff=0.55, lightDiffuseCoeff=0.45, lightSpecularCoeff=0.0,
            physicsClientId=self.client)
        H, W = intr.height, intr.width
        color = np.asarray(rgba, dtype=np.uint8).reshape(H, W, 4)[..., :3].copy()
        zb = np.asarray(zbuf, dtype=np.float64).reshape(H, W)
        seg = np.asarray(seg, dtype=np.int64).reshape(H, W)
        hit = seg >= 0
        # OpenGL depth buffer in [0, 1] -> eye-space z.
        depth = ZFAR * ZNEAR / (ZFAR - (ZFAR - ZNEAR) * zb)
        depth = np.where(hit, depth, 0.0).astype(np.float32)
        instance = self._table[np.clip(seg, -1, self._maxid + 1)]
        instance[~hit] = 0
        return color, depth, instance


def render_pybullet(arr: Arrangement, intr: Intrinsics, T_world_cam: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One-shot :meth:`PybulletRenderer.render` (own DIRECT client, disconnected after)."""
    with PybulletRenderer(arr) as r:
        return r.render(intr, T_world_cam)
