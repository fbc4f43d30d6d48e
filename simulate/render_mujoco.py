"""Offscreen MuJoCo renderer: RGB, exact metric depth and per-pixel instance ids.

The arrangement becomes a render-only MJCF (visual box geoms, no physics): one box per
cuboid with its own colour, and each support plane (ground, walls) as a large thin grey
box whose free face lies on the plane.  The OpenCV intrinsics are imposed exactly by
writing the OpenGL frustum of MuJoCo's scene camera after ``mjv_updateScene`` (so any
``fx, fy, cx, cy`` works, not only MuJoCo's symmetric ``fovy`` camera).

Depth is the camera-frame ``z`` (not the ray length), recovered by MuJoCo's reversed-Z
depth buffer (float32) in float64: exact to about a micrometre at a few metres.
Instance ids come from MuJoCo's segmentation pass: geom id -> cuboid index + 1, supports
and background 0.

Headless: ``MUJOCO_GL=egl`` (the default set here when unset), falling back to
``osmesa`` when EGL cannot create a context.
"""

from __future__ import annotations

import colorsys
import os
from collections.abc import Sequence

import numpy as np

from pipeline.camera import Intrinsics
from pipeline.model import Arrangement

#: Near and far clipping planes, metres (the model's ``statistic extent`` is pinned to 1).
ZNEAR = 0.02
ZFAR = 60.0

#: Half size of the slab drawn for a support plane, metres (in-plane), and its thickness.
SUPPORT_HALF = 25.0
SUPPORT_THICKNESS = 0.1

#: Support colours (RGB in [0, 1]): ground mid grey, walls light grey.
GROUND_RGB = (0.55, 0.55, 0.53)
WALL_RGB = (0.78, 0.77, 0.74)

_MJOBJ_GEOM = 5  # mujoco.mjtObj.mjOBJ_GEOM


def cuboid_colors(arr: Arrangement) -> np.ndarray:
    """Distinct colours per object and per cuboid.

    Objects (the ``object`` field; a cuboid without one is its own object) get hues
    spread by the golden ratio; the parts of one object share the hue and alternate in
    saturation and value, so image edges exist between objects *and* between parts.

    Returns
    -------
    rgb : (K, 3) float in [0, 1]
    """
    objects: dict[str, int] = {}
    part_of: dict[str, int] = {}
    out = np.zeros((len(arr.cuboids), 3))
    for k, c in enumerate(arr.cuboids):
        key = c.object if c.object is not None else f"\0{c.id}"
        obj = objects.setdefault(key, len(objects))
        part = part_of.get(key, 0)
        part_of[key] = part + 1
        hue = (0.07 + 0.61803398875 * obj) % 1.0
        sat = (0.70, 0.45, 0.85, 0.55)[part % 4]
        val = (0.90, 0.70, 0.80, 0.60)[(part // 2 + part) % 4]
        out[k] = colorsys.hsv_to_rgb(hue, sat, val)
    return out


def _quat_wxyz_from_matrix(R: np.ndarray) -> np.ndarray:
    """(4,) unit quaternion w x y z of a rotation matrix (MuJoCo's convention)."""
    import mujoco

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).ravel())
    return q


def _support_frame(point: np.ndarray, normal: np.ndarray, anchor: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Centre and rotation of the slab drawn for a support plane.

    The slab's local z is the plane normal; its top face lies on the plane, centred on
    the projection of ``anchor`` (the scene centre) onto the plane.
    """
    n = normal / np.linalg.norm(normal)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, n)
    x /= np.linalg.norm(x)
    y = np.cross(n, x)
    foot = anchor - ((anchor - point) @ n) * n
    return foot - n * SUPPORT_THICKNESS / 2, np.stack([x, y, n], axis=1)


def scene_mjcf(arr: Arrangement, width: int = 640, height: int = 480,
               colors: np.ndarray | None = None) -> tuple[str, np.ndarray]:
    """A render-only MJCF of an arrangement.

    Parameters
    ----------
    arr : Arrangement
    width, height : int
        Largest image size the offscreen buffer must hold.
    colors : (K, 3) float in [0, 1], optional
        Per-cuboid colours (default :func:`cuboid_colors`).

    Returns
    -------
    xml : str
        The MJCF text (fixed float precision, so it is stable).
    instance_of_geom : (G,) uint16
        Instance id of every geom in compile order: cuboid index + 1, 0 for supports.
    """
    rgb = cuboid_colors(arr) if colors is None else np.asarray(colors, float)
    anchor = arr.centers.mean(axis=0) if arr.cuboids else np.zeros(3)

    def f(v: Sequence[float]) -> str:
        return " ".join(f"{x:.9g}" for x in v)

    geoms: list[str] = []
    inst: list[int] = []
    for s in arr.supports:
        c, R = _support_frame(s.point, s.normal, anchor)
        color = GROUND_RGB if s.id == "ground" else WALL_RGB
        geoms.append(f'<geom name="support_{len(inst)}" type="box" '
                     f'size="{f([SUPPORT_HALF, SUPPORT_HALF, SUPPORT_THICKNESS / 2])}" '
                     f'pos="{f(c)}" quat="{f(_quat_wxyz_from_matrix(R))}" rgba="{f(color)} 1"/>')
        inst.append(0)
    for k, cub in enumerate(arr.cuboids):
        geoms.append(f'<geom name="cuboid_{k}" type="box" size="{f(cub.size / 2)}" '
                     f'pos="{f(cub.center)}" quat="{f(_quat_wxyz_from_matrix(cub.rotation))}" '
                     f'rgba="{f(rgb[k])} 1"/>')
        inst.append(k + 1)
    xml = f"""<mujoco model="unseen_render">
  <compiler angle="radian"/>
  <statistic extent="1" center="0 0 0"/>
  <visual>
    <global offwidth="{int(width)}" offheight="{int(height)}"/>
    <map znear="{ZNEAR}" zfar="{ZFAR}"/>
    <quality shadowsize="0"/>
    <headlight ambient="0.35 0.35 0.35" diffuse="0.45 0.45 0.45" specular="0 0 0"/>
    <rgba haze="0 0 0 1"/>
  </visual>
  <worldbody>
    <light directional="true" dir="0.35 0.25 -1" diffuse="0.35 0.35 0.35" specular="0 0 0" castshadow="false"/>
    {chr(10).join('    ' + g for g in geoms).lstrip()}
  </worldbody>
</mujoco>
"""
    return xml, np.asarray(inst, dtype=np.uint16)


def _make_renderer(model, height: int, width: int):
    """A ``mujoco.Renderer``, trying EGL then OSMesa when ``MUJOCO_GL`` is unset or fails."""
    import mujoco

    try:
        return mujoco.Renderer(model, height, width)
    except Exception:
        if os.environ.get("MUJOCO_GL") == "osmesa":
            raise
        # The GL backend is chosen at import; a failed EGL context cannot be retried in
        # this process, so the caller sees the error with a hint.
        raise RuntimeError("MuJoCo could not create an offscreen GL context; set "
                           "MUJOCO_GL=egl or MUJOCO_GL=osmesa (Mesa) before starting") from None


class MujocoRenderer:
    """Renders one arrangement from many cameras (one GL context, reused).

    Use as a context manager or call :meth:`close`.  All frames must have the same
    size (the intrinsics passed to the constructor's ``width``/``height``).
    """

    def __init__(self, arr: Arrangement, width: int = 640, height: int = 480,
                 colors: np.ndarray | None = None) -> None:
        os.environ.setdefault("MUJOCO_GL", "egl")
        import mujoco

        xml, self.instance_of_geom = scene_mjcf(arr, width, height, colors)
        self.model = mujoco.MjModel.from_xml_string(xml)
        self.data = mujoco.MjData(self.model)
        mujoco.mj_forward(self.model, self.data)
        self.width, self.height = int(width), int(height)
        self._renderer = _make_renderer(self.model, self.height, self.width)
        self._lookup = np.zeros(self.model.ngeom + 1, dtype=np.uint16)  # index -1 -> 0
        self._lookup[: self.model.ngeom] = self.instance_of_geom

    def __enter__(self) -> MujocoRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def _set_camera(self, intr: Intrinsics, T_world_cam: np.ndarray) -> None:
        """Point MuJoCo's scene camera along the OpenCV camera with an exact frustum."""
        scene = self._renderer.scene
        T = np.asarray(T_world_cam, float)
        near = ZNEAR  # statistic extent is 1
        # Pixel u covers [u - 0.5, u + 0.5]: the image spans u in [-0.5, W - 0.5].
        left = (-0.5 - intr.cx) / intr.fx * near
        right = (intr.width - 0.5 - intr.cx) / intr.fx * near
        top = (intr.cy + 0.5) / intr.fy * near  # OpenGL y is up = -OpenCV y
        bottom = -(intr.height - 0.5 - intr.cy) / intr.fy * near
        for cam in (scene.camera[0], scene.camera[1]):
            cam.pos[:] = T[:3, 3]
            cam.forward[:] = T[:3, 2]
            cam.up[:] = -T[:3, 1]
            cam.frustum_center = (left + right) / 2
            cam.frustum_width = (right - left) / 2
            cam.frustum_bottom = bottom
            cam.frustum_top = top
            cam.frustum_near = near
            cam.frustum_far = ZFAR
            cam.orthographic = 0

    def render(self, intr: Intrinsics, T_world_cam: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Render one view.

        Parameters
        ----------
        intr : Intrinsics
            Must match the renderer's width and height.
        T_world_cam : (4, 4) float
            Camera-to-world, OpenCV camera frame.

        Returns
        -------
        color : (H, W, 3) uint8 RGB
        depth : (H, W) float32, metres along the optical axis, 0 = nothing hit
        instance : (H, W) uint16, cuboid index + 1, 0 = support or background
        """
        if (intr.width, intr.height) != (self.width, self.height):
            raise ValueError(f"intrinsics are {intr.width}x{intr.height}, the renderer was "
                             f"built for {self.width}x{self.height}")
        r = self._renderer
        r.disable_depth_rendering()
        r.disable_segmentation_rendering()
        r.update_scene(self.data)
        self._set_camera(intr, T_world_cam)
        color = r.render().copy()

        r.enable_segmentation_rendering()
        r.update_scene(self.data)
        self._set_camera(intr, T_world_cam)
        seg = r.render()
        geom = np.where(seg[..., 1] == _MJOBJ_GEOM, seg[..., 0], -1)
        instance = self._lookup[geom]
        hit = geom >= 0
        r.disable_segmentation_rendering()

        r.enable_depth_rendering()
        r.update_scene(self.data)
        self._set_camera(intr, T_world_cam)
        depth = r.render().astype(np.float32)
        r.disable_depth_rendering()
        depth[~hit | ~np.isfinite(depth) | (depth >= ZFAR * 0.999)] = 0.0
        return color, depth, instance


def render_mujoco(arr: Arrangement, intr: Intrinsics, T_world_cam: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One-shot :meth:`MujocoRenderer.render` (builds and frees a GL context)."""
    with MujocoRenderer(arr, intr.width, intr.height) as r:
        return r.render(intr, T_world_cam)
