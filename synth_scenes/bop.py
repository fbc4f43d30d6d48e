"""Write a dataset's scenes in the BOP layout, for detection and 6D pose tools.

BOP (Hodan et al., the Benchmark for 6D Object Pose Estimation) keeps one folder per
scene with one image id per camera view::

    bop/camera.json                      the default camera (first view of the first scene)
    bop/<split>/<scene:06d>/rgb/<im:06d>.png          8-bit RGB
    bop/<split>/<scene:06d>/depth/<im:06d>.png        16-bit, depth_scale 1.0 -> millimetres
    bop/<split>/<scene:06d>/mask_visib/<im:06d>_<gt:06d>.png   255 where object gt is seen
    bop/<split>/<scene:06d>/scene_camera.json   per image: cam_K, depth_scale, cam_R_w2c,
                                                cam_t_w2c (mm)
    bop/<split>/<scene:06d>/scene_gt.json       per image: [{obj_id, cam_R_m2c, cam_t_m2c
                                                (mm), obj_size_mm, name, object}, ...]
    bop/<split>/<scene:06d>/scene_gt_info.json  per image: [{bbox_visib, px_count_visib,
                                                px_count_valid}, ...]
    bop/<split>/<scene:06d>/scene_source.json   the dataset scene this folder came from

Conventions that differ from BOP's datasets, because every scene here is made of its own
boxes: ``obj_id`` is the cuboid's instance id in its scene (``k`` = ``scene.json``
cuboid ``k-1``, as in ``instance.png``), and its model is a box centred at the model
origin with edges along the model axes, of the size ``obj_size_mm`` (so no ``models/``
folder is needed).  ``cam_R_m2c`` is row-major, translations are in millimetres, as in
BOP.  Amodal masks (``mask/``) and the amodal pixel counts are not written: the sensor
renders what is visible.  Scene folders are numbered by the scene's ``index`` in the
manifest.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from pipeline import atomic


def _pose_blocks(T_world_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World-to-camera rotation and translation (metres) of a camera-to-world pose."""
    R_wc = T_world_cam[:3, :3]
    return R_wc.T, -R_wc.T @ T_world_cam[:3, 3]


def _floats(a: np.ndarray) -> list:
    return [float(x) for x in np.asarray(a, dtype=float).ravel()]


def write_bop_scene(sample, out: str | os.PathLike) -> None:  # noqa: ANN001 - dataset.Sample
    """Write one :class:`synth_scenes.dataset.Sample` as a BOP scene folder ``out``."""
    out = Path(out)
    for sub in ("rgb", "depth", "mask_visib"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    arr = sample.arrangement
    cams, gts, infos = {}, {}, {}
    for im, view in enumerate(sample.views):
        R_cw, t_cw = _pose_blocks(view.T_world_cam)
        cams[str(im)] = {"cam_K": _floats(view.K), "depth_scale": 1.0,
                         "cam_R_w2c": _floats(R_cw), "cam_t_w2c": _floats(1000.0 * t_cw)}
        _png(out / "rgb" / f"{im:06d}.png", view.color[..., ::-1])
        depth_mm = np.round(view.depth * 1000.0).astype(np.uint16)
        _png(out / "depth" / f"{im:06d}.png", depth_mm)
        entries, info = [], []
        for gt_idx, k in enumerate(range(1, len(arr.cuboids) + 1)):
            c = arr.cuboids[k - 1]
            R = R_cw @ c.rotation
            t = 1000.0 * (R_cw @ c.center + t_cw)
            entries.append({"obj_id": k, "cam_R_m2c": _floats(R), "cam_t_m2c": _floats(t),
                            "obj_size_mm": _floats(1000.0 * c.size), "name": c.id,
                            "object": c.object})
            mask = view.instance == k
            _png(out / "mask_visib" / f"{im:06d}_{gt_idx:06d}.png",
                 mask.astype(np.uint8) * 255)
            info.append({"bbox_visib": _bbox(mask), "px_count_visib": int(mask.sum()),
                         "px_count_valid": int((mask & (view.depth > 0)).sum())})
        gts[str(im)] = entries
        infos[str(im)] = info
    for name, body in (("scene_camera.json", cams), ("scene_gt.json", gts),
                       ("scene_gt_info.json", infos),
                       ("scene_source.json", {"id": sample.id, "path": sample.record["path"],
                                              "seed": sample.record.get("seed"),
                                              "family": sample.family})):
        atomic.write_text(out / name, json.dumps(body, indent=1) + "\n")


def _bbox(mask: np.ndarray) -> list[int]:
    """BOP's ``[x, y, width, height]`` of a mask, ``[-1, -1, -1, -1]`` when empty."""
    ys, xs = np.nonzero(mask)
    if len(xs) == 0:
        return [-1, -1, -1, -1]
    return [int(xs.min()), int(ys.min()), int(xs.max() - xs.min() + 1),
            int(ys.max() - ys.min() + 1)]


def _png(path: Path, image: np.ndarray) -> None:
    import cv2

    with atomic.atomic_path(path) as tmp:
        if not cv2.imwrite(str(tmp), np.ascontiguousarray(image)):
            raise OSError(f"cannot write {path}")


def bop_scene_dir(root: str | os.PathLike, record: Mapping) -> Path:
    """Where a manifest line's scene goes in the BOP export."""
    return Path(root) / "bop" / record["split"] / f"{int(record['index']):06d}"


def export_bop(root: str | os.PathLike, records: Iterable[Mapping] | None = None) -> int:
    """Write ``root/bop`` for the dataset at ``root`` (all scenes, or ``records``).

    Returns the number of scenes written.
    """
    from .dataset import Dataset

    ds = Dataset(root)
    wanted = None if records is None else {r["id"] for r in records}
    n = 0
    first = None
    for k in range(len(ds)):
        if wanted is not None and ds.records[k]["id"] not in wanted:
            continue
        sample = ds[k]
        write_bop_scene(sample, bop_scene_dir(root, sample.record))
        if first is None:
            first = sample.views[0]
        n += 1
    if first is not None:
        K = first.K
        h, w = first.depth.shape
        atomic.write_text(Path(root) / "bop" / "camera.json", json.dumps(
            {"cx": float(K[0, 2]), "cy": float(K[1, 2]), "fx": float(K[0, 0]),
             "fy": float(K[1, 1]), "width": int(w), "height": int(h), "depth_scale": 1.0},
            indent=1) + "\n")
    return n


def read_bop_scene(folder: str | os.PathLike) -> dict:
    """Read a BOP scene folder back: per image id, depth (metres), visible masks and the
    objects' world poses recovered from ``cam_*_m2c`` and ``cam_*_w2c``.

    Returns ``{im_id: {"depth": (H, W) float32, "masks": {obj_id: bool (H, W)},
    "poses": {obj_id: (4, 4) world pose}, "sizes": {obj_id: (3,) metres}}}``.
    """
    import cv2

    f = Path(folder)
    cams = json.loads((f / "scene_camera.json").read_text())
    gts = json.loads((f / "scene_gt.json").read_text())
    out = {}
    for im, cam in cams.items():
        i = int(im)
        depth = cv2.imread(str(f / "depth" / f"{i:06d}.png"), cv2.IMREAD_UNCHANGED)
        depth = depth.astype(np.float32) * float(cam["depth_scale"]) / 1000.0
        R_cw = np.array(cam["cam_R_w2c"]).reshape(3, 3)
        t_cw = np.array(cam["cam_t_w2c"]) / 1000.0
        masks, poses, sizes = {}, {}, {}
        for gt_idx, e in enumerate(gts[im]):
            m = cv2.imread(str(f / "mask_visib" / f"{i:06d}_{gt_idx:06d}.png"),
                           cv2.IMREAD_UNCHANGED)
            masks[e["obj_id"]] = m > 127
            R_mc = np.array(e["cam_R_m2c"]).reshape(3, 3)
            t_mc = np.array(e["cam_t_m2c"]) / 1000.0
            T = np.eye(4)
            T[:3, :3] = R_cw.T @ R_mc
            T[:3, 3] = R_cw.T @ (t_mc - t_cw)
            poses[e["obj_id"]] = T
            sizes[e["obj_id"]] = np.array(e["obj_size_mm"]) / 1000.0
        out[i] = {"depth": depth, "masks": masks, "poses": poses, "sizes": sizes}
    return out
