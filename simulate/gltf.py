"""Arrangement -> binary glTF (``.glb``) via trimesh, for any 3D viewer.

Every cuboid is a box mesh node named by its id, coloured by the object it belongs to
(cuboids of one object share a colour; a cuboid without ``object`` gets its own); every
support is a thin grey slab (``SUPPORT_SPAN`` x ``SUPPORT_SPAN`` scene extents, top face
on the plane).  glTF is y-up, so the scene is rotated by -90 degrees about x on export
(z-up world -> y-up file) as the glTF specification asks.
"""

from __future__ import annotations

import zlib

import numpy as np

from pipeline.model import Arrangement

from .bodies import scene_extent

SUPPORT_SPAN = 2.0
SUPPORT_THICKNESS = 0.01

#: A qualitative palette (matplotlib's tab10), RGBA 0-255.
PALETTE = np.array([
    [31, 119, 180], [255, 127, 14], [44, 160, 44], [214, 39, 40], [148, 103, 189],
    [140, 86, 75], [227, 119, 194], [188, 189, 34], [23, 190, 207], [127, 127, 127]],
    dtype=np.uint8)


def object_colors(arr: Arrangement) -> np.ndarray:
    """(K, 4) uint8 RGBA per cuboid: one palette colour per object, stable across runs."""
    keys = [c.object if c.object is not None else f"cuboid:{c.id}" for c in arr.cuboids]
    order = {k: i for i, k in enumerate(dict.fromkeys(keys))}
    idx = np.array([order[k] for k in keys], dtype=np.int64)
    # offset by a checksum of the first key so two scenes do not always start blue
    shift = zlib.crc32(keys[0].encode("utf-8")) % len(PALETTE) if keys else 0
    rgb = PALETTE[(idx + shift) % len(PALETTE)]
    return np.column_stack([rgb, np.full(len(idx), 255, np.uint8)])


def _transform(center: np.ndarray, R: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = center
    return T


def arrangement_scene(arr: Arrangement):
    """A ``trimesh.Scene`` of the arrangement (world frame, z up)."""
    import trimesh

    from .mjcf import _frame_from_normal

    scene = trimesh.Scene()
    colors = object_colors(arr)
    for c, rgba in zip(arr.cuboids, colors, strict=True):
        mesh = trimesh.creation.box(extents=c.size, transform=_transform(c.center, c.rotation))
        mesh.visual.face_colors = np.tile(rgba, (len(mesh.faces), 1))
        scene.add_geometry(mesh, node_name=c.id, geom_name=c.id)
    ext = scene_extent(arr)
    span, thick = SUPPORT_SPAN * ext, SUPPORT_THICKNESS * ext
    for s in arr.supports:
        R = _frame_from_normal(s.normal)
        mesh = trimesh.creation.box(extents=(span, span, thick),
                                    transform=_transform(s.point - s.normal * thick / 2, R))
        mesh.visual.face_colors = np.tile([170, 170, 170, 255], (len(mesh.faces), 1))
        scene.add_geometry(mesh, node_name=f"support:{s.id}", geom_name=f"support:{s.id}")
    return scene


def arrangement_glb(arr: Arrangement) -> bytes:
    """The ``.glb`` bytes of :func:`arrangement_scene`, converted to glTF's y-up frame."""
    scene = arrangement_scene(arr)
    z_up_to_y_up = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]])
    scene.apply_transform(z_up_to_y_up)
    return scene.export(file_type="glb")
