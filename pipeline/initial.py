"""From a scan to the initial cuboids (section 4.1): planes, objects, boxes, edge snapping.

``initial_cuboids(scan, rng=...)`` runs the stage and returns the arrangement (cuboids
with their source object, point count and observed box; ground and wall supports; no
contacts; ``meta.camera_pose`` the camera-to-world transform chosen) and a report
dict with the timing of every step and the counts.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from .camera import invert, project, transform
from .fit import CELL_REL, estimate_normals, fit_object, upright_rotation
from .model import Arrangement, Cuboid, ObservedBox
from .planes import find_frame, scene_scale
from .scan_io import ScanInput
from .segment import (
    MIN_INSTANCE_POINTS,
    flying_pixels,
    grabcut_scribbles,
    point_spacing,
    segment_objects,
)

SEGMENTATIONS = ("auto", "parts", "instance", "cluster")
#: An object needs at least this fraction of the scan's points (smaller clusters are specks).
MIN_OBJECT_FRACTION = 1e-3
#: Within this many pixels of an instance-mask border, a pixel whose depth differs from
#: the 5x5 median by more than ``MASK_DEPTH_REL`` of it is dropped (mixed/shifted depth).
MASK_ERODE_PX = 2
MASK_DEPTH_REL = 0.02
#: Radius of the neighbourhood a normal is estimated from, in cells.
NORMAL_RADIUS_CELLS = 4.0
#: Smallest voxel, metres (below the depth noise of any consumer sensor).
MIN_CELL = 0.002
#: Only boxes fitted to at least this many of their own points are snapped to the colour
#: image's edges: a smaller box's silhouette is a few pixels of noisy outline (and in
#: a cluttered room the snapping of dozens of such fragments cost seconds per frame).
EDGE_MIN_POINTS = 300


def _solid_test(scan: ScanInput, T_world_cam: np.ndarray, pix_label: np.ndarray,
                tol: float) -> Callable[[np.ndarray], np.ndarray]:
    """World points -> True where they are hidden behind a measured surface that is not
    a support plane (or where the sensor has no reading), i.e. where an object may be."""
    T_cw = invert(T_world_cam)
    depth = scan.depth
    intr = scan.intrinsics
    H, W = depth.shape

    def solid(points: np.ndarray) -> np.ndarray:
        uv, z = project(transform(T_cw, points), intr)
        u = np.round(uv[:, 0])
        v = np.round(uv[:, 1])
        inside = (z > 0) & (u >= 0) & (u < W) & (v >= 0) & (v < H)
        iu = np.where(inside, u, 0).astype(int)
        iv = np.where(inside, v, 0).astype(int)
        d = depth[iv, iu]
        lab = pix_label[iv, iu]
        hidden = (d <= 0) | ((z >= d - tol) & (lab != -2))
        return ~inside | hidden

    return solid


def _mask_border(scan: ScanInput) -> np.ndarray:
    """(n,) bool: points within ``MASK_ERODE_PX`` of an instance-mask border whose depth
    disagrees with the 5x5 median (mixed or shifted depth: only mask interiors are
    trusted); all False without an instance image."""
    if scan.instance_image is None or scan.pixels is None or scan.depth is None:
        return np.zeros(scan.n, dtype=bool)
    import cv2
    from scipy.ndimage import maximum_filter, minimum_filter

    img = scan.instance_image
    size = 2 * MASK_ERODE_PX + 1
    border = maximum_filter(img, size=size) != minimum_filter(img, size=size)
    med = cv2.medianBlur(scan.depth.astype(np.float32), 5).astype(float)
    bad = border & (np.abs(scan.depth - med) > MASK_DEPTH_REL * np.maximum(med, 1e-6))
    return bad[scan.pixels[:, 0], scan.pixels[:, 1]]


def _unreliable(view: ScanInput) -> np.ndarray:
    """(n,) bool: flying pixels and unreliable mask borders of one RGB-D frame."""
    if view.pixels is None or view.depth is None:
        return np.zeros(view.n, dtype=bool)
    fly = flying_pixels(view.depth)[view.pixels[:, 0], view.pixels[:, 1]]
    return fly | _mask_border(view)


def nan_median_last(a: np.ndarray) -> np.ndarray:
    """``np.nanmedian(a, axis=-1)`` (NaN where a row has no number), without the masked
    arrays numpy falls back on for short rows: the sorted row's middle value, or the
    mean of its two middle values."""
    s = np.sort(a, axis=-1)  # NaNs sort last
    n = np.isfinite(s).sum(axis=-1)
    lo = np.take_along_axis(s, np.maximum(n - 1, 0)[..., None] // 2, axis=-1)[..., 0]
    hi = np.take_along_axis(s, (n // 2)[..., None], axis=-1)[..., 0]
    return np.where(n > 0, np.where(n % 2 == 1, lo, (lo + hi) / 2), np.nan)


#: Half width (pixels) of the window of :func:`segment_median_depth`.
DEPTH_MEDIAN_RADIUS = 2


def segment_median_depth(depth: np.ndarray, label: np.ndarray,
                         radius: int = DEPTH_MEDIAN_RADIUS) -> np.ndarray:
    """Each pixel's depth replaced by a median over its ``(2 radius + 1)^2`` window of
    the same ``label`` (labels < 0 are left as they are).

    Depth noise moves a point along its pixel's ray only, by centimetres at 3-4 m: a book
    spine three pixels wide then spreads over a box several times its width.  The values
    taken are the pixel's own depth and the mean of each pair of pixels placed
    symmetrically about it (both with a reading and the same label): on a plane every
    such mean is the pixel's own true depth, so the median cuts the noise several times
    over without pulling a receding face's far edge towards the camera, as a plain
    window median does where the window runs off the segment.
    """
    H, W = depth.shape
    r = int(radius)
    d = np.pad(depth.astype(float), r, constant_values=0.0)
    lab = np.pad(label, r, constant_values=-1)

    def shifted(dv: int, du: int) -> tuple[np.ndarray, np.ndarray]:
        win = d[r + dv:r + dv + H, r + du:r + du + W]
        return win, (lab[r + dv:r + dv + H, r + du:r + du + W] == label) & (win > 0)

    offsets = [(dv, du) for dv in range(-r, r + 1) for du in range(-r, r + 1)
               if (dv, du) > (0, 0)]
    stack = np.full((H, W, len(offsets) + 1), np.nan)
    stack[..., 0] = np.where(depth > 0, depth, np.nan)
    for n, (dv, du) in enumerate(offsets, start=1):
        a, ok_a = shifted(dv, du)
        b, ok_b = shifted(-dv, -du)
        stack[..., n] = np.where(ok_a & ok_b, 0.5 * (a + b), np.nan)
    med = nan_median_last(stack)
    keep = (label >= 0) & (depth > 0) & np.isfinite(med)
    return np.where(keep, med, depth)


def initial_cuboids(scan: ScanInput, *, rng: np.random.Generator, cell_rel: float = CELL_REL,
                    edges: bool = True, segmentation: str = "auto",
                    progress: Callable[[str], None] | None = None,
                    ) -> tuple[Arrangement, dict]:
    """Run section 4.1 on a loaded scan.

    Parameters
    ----------
    scan : the input (see :mod:`pipeline.scan_io`)
    rng : the only source of randomness (RANSAC seeds)
    cell_rel : voxel size as a fraction of the scene diameter
    edges : snap boxes to Canny edges when a colour image exists
    segmentation : ``auto`` (per-part ids with a part -> object map as ``parts``, else
        instance ids as objects, else scribbles + GrabCut, else clustering), ``parts``,
        ``instance`` (require ids, one cluster per object) or ``cluster`` (ignore ids)
    progress : optional callable told the name of each step as it starts

    Returns
    -------
    arrangement : Arrangement
    report : dict with ``timings`` (step -> seconds), ``counts`` and ``notes``
    """
    from .errors import InputError

    if segmentation not in SEGMENTATIONS:
        raise InputError(f"--segmentation {segmentation!r}: expected one of {', '.join(SEGMENTATIONS)}")
    timings: dict[str, float] = {}
    notes = list(scan.notes)

    def step(name: str) -> float:
        if progress is not None:
            progress(name)
        return time.perf_counter()

    # ---- planes and world frame
    t = step("planes")
    camera = scan.pixels is not None and scan.intrinsics is not None
    pts = scan.points
    if len(pts) == 0 or not np.all(np.isfinite(pts)):
        raise InputError(f"{scan.source}: empty or non-finite point cloud")
    seg_ids = scan.instance if segmentation != "cluster" else None
    try:
        frame = find_frame(pts, rng, up=scan.up, T_world_input=scan.T_world_cam,
                           camera_frame=camera, floor_height=scan.floor_height,
                           object_points=None if seg_ids is None or not np.any(seg_ids > 0)
                           else np.asarray(seg_ids) > 0)
    except InputError as exc:  # what the scan lacks: name the scan (flags name themselves)
        if str(exc).startswith("--") or not scan.source:
            raise
        raise InputError(f"{scan.source}: {exc}") from None
    notes.extend(frame.notes)
    world = transform(frame.T_world_input, pts)
    timings["planes"] = time.perf_counter() - t

    # ---- objects
    t = step("segment")
    obj_mask = frame.labels == -1
    pix_label = None
    if camera:
        fly = flying_pixels(scan.depth)
        obj_mask &= ~fly[scan.pixels[:, 0], scan.pixels[:, 1]]
    elif scan.views:  # fused frames: drop what each frame's own image says is unreliable
        obj_mask &= ~np.concatenate([_unreliable(v) for v in scan.views])
    # the paper normalises the scene (its objects) to the unit sphere: the cell is relative
    # to the extent of what is not ground or wall
    diameter = scene_scale(world[obj_mask]) if obj_mask.sum() >= 100 else scene_scale(world)
    # ... but never finer than the sampling (a voxel must catch points on every surface)
    spacing = point_spacing(world[obj_mask]) if obj_mask.sum() >= 100 else 0.0
    min_cell = max(MIN_CELL, 1.5 * spacing)
    cell = max(cell_rel * diameter, min_cell)
    instance = scan.instance if segmentation != "cluster" else None
    if instance is not None and camera and scan.instance_image is not None:
        instance = np.where(_mask_border(scan), 0, instance)
    if segmentation == "instance" and (instance is None or not np.any(instance > 0)):
        raise InputError(f"{scan.source}: --segmentation instance but the input has no instance ids")
    parts = segmentation in ("auto", "parts") and instance is not None and bool(scan.instance_objects)
    if parts:
        # per-part ids with a part -> object map (a synthetic scene directory): one cluster per
        # part, named by its object, so the parts of one object stay separate boxes
        inst = instance
        obj_names_map = {int(k): nm for k, nm in scan.instance_objects.items()}
    elif instance is not None and scan.instance_objects:
        names_of = scan.instance_objects
        objs = sorted(set(names_of.values()))
        lut = np.zeros(int(max(names_of)) + 1, dtype=np.int64)
        for k, nm in names_of.items():
            lut[k] = objs.index(nm) + 1
        inst = np.where((instance > 0) & (instance < len(lut)), lut[np.clip(instance, 0, len(lut) - 1)], 0)
        obj_names_map = {i + 1: nm for i, nm in enumerate(objs)}
    else:
        inst, obj_names_map = instance, {}
    scribble_labels = None
    if (inst is None or not np.any(inst > 0)) and scan.scribbles is not None and scan.image is not None:
        allowed = np.zeros(scan.depth.shape, bool)
        allowed[scan.pixels[obj_mask, 0], scan.pixels[obj_mask, 1]] = True
        scribble_labels = grabcut_scribbles(scan.image, scan.depth, scan.scribbles, allowed)
    labels, names = segment_objects(world, obj_mask, cell, instance=inst, pixels=scan.pixels,
                                    scribble_labels=scribble_labels,
                                    min_points=max(30, int(MIN_OBJECT_FRACTION * len(world))),
                                    depth=scan.depth[scan.pixels[:, 0], scan.pixels[:, 1]]
                                    if camera else None)
    if camera and segmentation in ("auto", "cluster") and any(
            nm.startswith("cluster") for nm in names):
        from .segment import split_clusters

        labels, names = split_clusters(labels, names, world, frame.T_world_input[:3, 3],
                                       scan.pixels, scan.depth.shape,
                                       max(30, int(MIN_OBJECT_FRACTION * len(world))),
                                       frame.threshold, image=scan.image)
    if (labels >= 0).sum() >= 100:  # the cell from what was segmented (stray points gone)
        cell = max(cell_rel * scene_scale(world[labels >= 0]), min_cell)
    part_of = [int(nm[4:]) if parts and nm.startswith("inst") else None for nm in names]
    if obj_names_map:
        names = [obj_names_map.get(int(nm[4:]), nm) if nm.startswith("inst") else nm for nm in names]
    timings["segment"] = time.perf_counter() - t

    # ---- cuboids
    t = step("fit")
    T_world_cam = frame.T_world_input
    if camera and (labels >= 0).any():
        # depth noise along each pixel's ray, cut by a median within each segment
        lab_img = np.full(scan.depth.shape, -1, dtype=np.int64)
        lab_img[scan.pixels[:, 0], scan.pixels[:, 1]] = labels
        smooth = segment_median_depth(scan.depth, lab_img)
        sel = labels >= 0
        rows, cols = scan.pixels[sel, 0], scan.pixels[sel, 1]
        ratio = smooth[rows, cols] / scan.depth[rows, cols]
        world = world.copy()
        world[sel] = transform(T_world_cam, pts[sel] * ratio[:, None])
    if camera:
        pix_label = np.full(scan.depth.shape, -1, dtype=np.int64)
        pix_label[scan.pixels[:, 0], scan.pixels[:, 1]] = np.where(frame.labels >= 0, -2, labels)
    normals = np.zeros_like(world)
    seg = labels >= 0
    if seg.any():
        normals[seg] = estimate_normals(world[seg], NORMAL_RADIUS_CELLS * cell)
    # the parts of one object share its upright frame (more faces seen, one yaw); an
    # object of several parts (furniture) that reaches a wall stands square to it, as
    # a wall shelf hangs and a bookcase or a desk stands against one, unless its faces
    # and its footprint both say otherwise (pipeline.fit.upright_rotation)
    frames: dict[str, np.ndarray] = {}
    if parts:
        for nm in sorted(set(names)):
            ks = [k for k, n2 in enumerate(names) if n2 == nm]
            sel = np.isin(labels, ks)
            frames[nm] = upright_rotation(world[sel], normals[sel],
                                          frame.walls if len(ks) > 1 else ())
    boxes = []  # (object index, FittedBox)
    solid = _solid_test(scan, T_world_cam, pix_label, tol=cell) if camera else None
    for k in range(len(names)):
        sel = labels == k
        for b in fit_object(world[sel], cell, rng, solid=solid,
                            plane_threshold=max(cell, frame.threshold), normals=normals[sel],
                            rotation=frames.get(names[k]), single=part_of[k] is not None,
                            viewpoint=T_world_cam[:3, 3] if camera else None,
                            # a named part: one box, from as few points as its segment
                            # needed; a cluster's slab cover keeps slabs of 20 or more
                            min_points=MIN_INSTANCE_POINTS if part_of[k] is not None else 20):
            boxes.append((k, b))
    timings["fit"] = time.perf_counter() - t

    # ---- edge refinement
    refined = 0
    edge_infos = []
    if edges and camera and scan.image is not None and boxes:
        from .edges import edge_map, refine_box

        t = step("edges")
        em = edge_map(scan.image)
        out = []
        for k, b in boxes:
            # the box's own points: those of its object within a cell of it
            obj = world[labels == k]
            own = obj[np.all(np.abs((obj - b.center) @ b.rotation) <= b.size / 2 + cell, axis=1)]
            if len(own) < EDGE_MIN_POINTS:
                out.append((k, b))
                continue
            c, R, info = refine_box(b.center, b.rotation, b.size, own, em, scan.intrinsics,
                                    T_world_cam, upright=not b.slanted)
            edge_infos.append(info)
            refined += int(info.get("accepted", False))
            out.append((k, type(b)(c, R, b.size, b.points, b.slanted)))
        boxes = out
        timings["edges"] = time.perf_counter() - t

    # ---- arrangement
    t = step("assemble")
    cuboids = []
    for i, (k, b) in enumerate(boxes):
        extra = {"points": int(b.points)}
        if part_of[k] is not None:
            extra["instance"] = part_of[k]  # the segmentation's part id
            # the parts the part -> object map names for its object, seen or not
            named = sum(nm == names[k] for nm in scan.instance_objects.values())
            if named > 1:
                extra["object_parts"] = int(named)
        if b.slanted:
            extra["slanted"] = True
        cuboids.append(Cuboid(f"b{i}", b.center, b.rotation, b.size, object=names[k],
                              observed=ObservedBox(b.center, b.size), extra=extra))
    meta = {"camera_pose": np.asarray(T_world_cam).tolist(),
            "source": scan.source,
            "input_frame": "camera" if camera else "cloud",
            "stage": "initial",
            "cell": cell,
            "plane_threshold": frame.threshold}
    if scan.intrinsics is not None:
        meta["intrinsics"] = scan.intrinsics.to_json()
    arr = Arrangement(tuple(cuboids), (frame.ground,) + tuple(frame.walls), (), meta=meta)
    timings["assemble"] = time.perf_counter() - t
    timings["total"] = float(sum(timings.values()))
    counts = {"points": int(len(world)),
              "ground_points": int((frame.labels == 0).sum()),
              "wall_points": int((frame.labels >= 1).sum()),
              "walls": len(frame.walls),
              "object_points": int((labels >= 0).sum()),
              "objects": len(names),
              "cuboids": len(cuboids),
              "slanted": int(sum(b.slanted for _, b in boxes)),
              "edge_refined": refined,
              "edge_tried": len(edge_infos)}
    report = {"timings": timings, "counts": counts, "notes": notes,
              "segmentation": ("instance" if inst is not None and np.any(inst > 0) else
                               "scribbles" if scribble_labels is not None else "cluster"),
              "cell": cell, "plane_threshold": frame.threshold, "objects": names,
              "labels": labels, "world": world, "pose": np.asarray(T_world_cam, float)}
    return arr, report
