"""Image edits in the original view: the colour image after a planned move or removal.

Section 6 (iii) of the paper: the colour image of a single-view scan is edited with the
structure the method recovered (ground, walls, the stable cuboid arrangement).

1. **Plan** (:func:`simulate.edit_plan.plan_edit`): what moves with what, and whether
   the edit is allowed.
2. **Background** (:func:`edit_image`).  The pixels whose back-projected depth point lies
   inside one of the moving or removed cuboids grown by ``margin``, plus the pixels of
   their silhouette without a depth reading, dilated by a few pixels, are deleted.  The
   hole is filled surface by surface: each hole pixel is assigned the surface its ray
   now meets in the remaining arrangement (the ground, a wall, another cuboid), and is
   filled by pull-push interpolation (Gortler et al. 1996) from the known pixels that
   see the same surface; what is left (no surface behind, or no pixels of it) is filled
   by OpenCV's Telea inpainting (``fill="telea"`` or ``"ns"``, Navier-Stokes, use OpenCV
   alone for the whole hole).
3. **Foreground.**  The moved cuboids are ray cast from the original camera (numpy, with
   ``supersample``^2 rays per pixel for anti-aliased edges), depth-tested against the
   background's depth (measured where kept, the remaining arrangement's in the hole).
   A visible point takes the colour of the same point of the object in the original
   image when the camera saw it there (its old position projects onto a pixel whose
   depth agrees); otherwise the mean colour of that face, or of the object, shaded.
4. **Shadow.**  Light from above: parallel rays along ``light`` (default straight down,
   ``(0, 0, -1)``).  Every background point whose ray towards the light meets a moved
   cuboid is darkened by ``shadow_strength``, with an edge softened over
   ``shadow_soft`` metres.
5. **Composite**: background, shadow, then the foreground by its coverage.

Frames: those of :mod:`simulate.view` (the arrangement's world, z up; OpenCV pixels).
Ray casting is :mod:`simulate.raycast`; the pixel filling algorithms are
:mod:`simulate.inpaint`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.camera import Intrinsics, project
from pipeline.errors import InputError
from pipeline.model import Arrangement, Cuboid

from .edit_plan import EditPlan, object_names, object_of
from .inpaint import pull_push, shift_fill
from .raycast import box_arrays, cast_boxes, cast_scene, inside_boxes, pixel_rays, silhouette
from .view import View

#: Known pixels of a surface needed before the hole is filled from them alone.
MIN_SURFACE_PIXELS = 20


@dataclass(frozen=True)
class EditParams:
    """How the image is edited (lengths in metres, angles as vectors).

    Attributes
    ----------
    margin : float
        Depth points within this distance of a moving or removed cuboid are deleted
        (the cuboids are estimates and the depth is noisy).
    dilate_px : int
        The deleted region is dilated by this many pixels (colour bleeds over edges).
    fill : {"surface", "telea", "ns"}
        ``surface``: per-surface pull-push, Telea for the rest; ``telea`` / ``ns``:
        OpenCV's inpainting (``cv2.INPAINT_TELEA`` / ``cv2.INPAINT_NS``) for the whole hole.
    inpaint_radius : float
        Pixels, OpenCV's inpainting neighbourhood.
    texture : bool
        With ``fill="surface"``: copy texture from a shifted part of the same surface
        (:func:`simulate.inpaint.shift_fill`) over the smooth fill.
    shadow : bool
    light : (3,) float
        Direction the light travels (down), world frame.
    shadow_strength : float
        Share of the light a shadowed point loses, in [0, 1].
    shadow_soft : float
        Width of the shadow's soft edge, metres (Gaussian sigma at the shadow's depth).
    occlusion_tol : float
        The moved object is hidden where the background is nearer by more than this.
    seen_tol : float
        A pixel shows a cuboid's face when its depth is within this (plus 2 % of the
        depth) of the face.
    supersample : int
        Rays per pixel side for the foreground.
    """

    margin: float = 0.03
    dilate_px: int = 3
    fill: str = "surface"
    inpaint_radius: float = 5.0
    texture: bool = True
    shadow: bool = True
    light: tuple[float, float, float] = (0.0, 0.0, -1.0)
    shadow_strength: float = 0.45
    shadow_soft: float = 0.03
    occlusion_tol: float = 0.02
    seen_tol: float = 0.03
    supersample: int = 2

    def __post_init__(self) -> None:
        if self.fill not in FILLS:
            raise InputError(f"--fill: must be one of {', '.join(FILLS)}, got {self.fill!r}")
        if not (np.isfinite(self.margin) and 0 <= self.margin <= 1):
            raise InputError(f"--margin: must be in [0, 1] m, got {self.margin}")
        light = np.asarray(self.light, float)
        if light.shape != (3,) or not np.all(np.isfinite(light)) or light[2] >= -1e-3:
            raise InputError(f"light: must point down (negative z), got {self.light}")


FILLS = ("surface", "telea", "ns")


# ----------------------------------------------------------------------------- filling
def fill_hole(view: View, hole: np.ndarray, remaining: Arrangement, params: EditParams,
              cast: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """The colour image with ``hole`` filled (see the module docstring, step 2).

    ``cast``: the remaining arrangement's (depth, surface label) per pixel when known
    (:func:`simulate.raycast.cast_scene`); labels are 1 + cuboid index, -(1 + support
    index), 0 none.
    """
    import cv2

    img = view.image
    if not hole.any():
        return img.copy()
    flag = cv2.INPAINT_NS if params.fill == "ns" else cv2.INPAINT_TELEA
    todo = hole.copy()
    out = img.astype(np.float32)
    if params.fill == "surface":
        t_rem, lab = cast if cast is not None else cast_scene(view, remaining)
        d = view.depth
        agree = (d > 0) & (np.abs(d - t_rem) <= params.seen_tol + 0.02 * d)
        known_lab = np.where(~hole & agree, lab, 0)
        for L in np.unique(lab[hole]):
            if L == 0:
                continue
            src = known_lab == L
            if src.sum() < MIN_SURFACE_PIXELS:
                continue
            tgt = hole & (lab == L)
            ys, xs = np.nonzero(src | tgt)
            pad = 8
            y0, y1 = max(ys.min() - pad, 0), min(ys.max() + pad + 1, img.shape[0])
            x0, x1 = max(xs.min() - pad, 0), min(xs.max() + pad + 1, img.shape[1])
            crop = pull_push(out[y0:y1, x0:x1], src[y0:y1, x0:x1])
            sub = tgt[y0:y1, x0:x1]
            out[y0:y1, x0:x1][sub] = crop[sub]
            if params.texture:
                shift_fill(out, img.astype(np.float32), src, tgt)
            todo &= ~tgt
    if todo.any():
        u8 = np.clip(np.rint(out), 0, 255).astype(np.uint8)
        out = cv2.inpaint(u8, todo.astype(np.uint8) * 255, params.inpaint_radius, flag
                          ).astype(np.float32)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


# ----------------------------------------------------------------------------- the edit
@dataclass(frozen=True)
class EditImages:
    """What :func:`edit_image` made.

    Attributes
    ----------
    before, after : (H, W, 3) uint8
    hole : (H, W) bool, the deleted pixels
    background : (H, W, 3) uint8, the filled background before shadow and foreground
    shadow : (H, W) float in [0, 1], the darkening applied
    alpha : (H, W) float in [0, 1], the foreground's coverage
    old_region, new_region : (H, W) bool, silhouettes of the moving or removed cuboids
        at their old places, and of the moved ones at their new places
    """

    before: np.ndarray
    after: np.ndarray
    hole: np.ndarray
    background: np.ndarray
    shadow: np.ndarray
    alpha: np.ndarray
    old_region: np.ndarray
    new_region: np.ndarray


def hole_mask(view: View, cubs: list[Cuboid], params: EditParams,
              behind: np.ndarray | None = None) -> np.ndarray:
    """(H, W) bool: the pixels to delete for ``cubs`` (step 2 of the module docstring).

    ``behind``: per pixel, the depth of what stays behind the cuboids (the remaining
    arrangement, inf where nothing); then also deleted, near the cuboids' silhouette
    (within ``dilate_px + 2`` pixels), the readings between the cuboids' front and what
    stays behind them: mixed pixels at the object's edges (a depth sensor averages the
    object and the background there), which are neither."""
    import cv2

    H, W = view.depth.shape
    if not cubs:
        return np.zeros((H, W), bool)
    d = view.depth
    v, u = np.nonzero(d > 0)
    o, dirs = pixel_rays(view, u, v)
    pts = o + dirs * d[v, u][:, None]
    mask = np.zeros((H, W), bool)
    mask[v, u] = inside_boxes(pts, cubs, params.margin)
    H_, W_ = np.mgrid[0:H, 0:W]
    o, dirs = pixel_rays(view, W_.ravel(), H_.ravel())
    front, _, _ = cast_boxes(o, dirs, *box_arrays(cubs))
    front = front.reshape(H, W)
    mask |= np.isfinite(front) & ~(d > 0)
    if behind is not None:
        k = 2 * (params.dilate_px + 2) + 1
        near_front = cv2.erode(np.where(np.isfinite(front), front, 1e9).astype(np.float32),
                               np.ones((k, k), np.uint8)).astype(float)
        tol = params.seen_tol + 0.02 * d
        mask |= (d > 0) & (near_front < 1e8) & (d >= near_front - params.margin) \
            & (d < behind - tol)
    if params.dilate_px > 0:
        k = 2 * params.dilate_px + 1
        mask = cv2.dilate(mask.astype(np.uint8), np.ones((k, k), np.uint8)).astype(bool)
    return mask


def _face_colours(view: View, cubs: list[Cuboid], params: EditParams
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Mean colour of each face of ``cubs`` where the image shows it: ``(K, 6, 3)`` float
    (NaN where unseen) and the mean colour of each cuboid's object ``(K, 3)`` (NaN)."""
    H, W = view.depth.shape
    K = len(cubs)
    v, u = np.mgrid[0:H, 0:W]
    o, d = pixel_rays(view, u.ravel(), v.ravel())
    t, k, f = cast_boxes(o, d, *box_arrays(cubs))
    z = view.depth.ravel()
    seen = (k >= 0) & (z > 0) & (np.abs(z - t) <= params.seen_tol + 0.02 * z)
    col = view.image.reshape(-1, 3).astype(float)
    ids = (k * 6 + f)[seen]
    cnt = np.bincount(ids, minlength=6 * K).astype(float)
    sums = np.stack([np.bincount(ids, col[seen, c], minlength=6 * K) for c in range(3)], 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        face = (sums / cnt[:, None]).reshape(K, 6, 3)
    objs = [object_of(c) for c in cubs]
    obj_mean = np.full((K, 3), np.nan)
    cnt_k, sums_k = cnt.reshape(K, 6).sum(1), sums.reshape(K, 6, 3).sum(1)
    for name in set(objs):
        rows = [i for i, o_ in enumerate(objs) if o_ == name]
        n = cnt_k[rows].sum()
        if n > 0:
            obj_mean[rows] = sums_k[rows].sum(0) / n
    return face, obj_mean


def bilinear(image: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Colours of ``image (H, W, 3)`` at sub-pixel ``u, v (n,)`` (clamped at the border),
    bilinear: ``(n, 3)`` float."""
    H, W = image.shape[:2]
    u = np.clip(u, 0, W - 1)
    v = np.clip(v, 0, H - 1)
    x0 = np.minimum(np.floor(u).astype(int), W - 2) if W > 1 else np.zeros(len(u), int)
    y0 = np.minimum(np.floor(v).astype(int), H - 2) if H > 1 else np.zeros(len(v), int)
    x1, y1 = np.minimum(x0 + 1, W - 1), np.minimum(y0 + 1, H - 1)
    a, b = (u - x0)[:, None], (v - y0)[:, None]
    im = image.astype(float)
    return ((im[y0, x0] * (1 - a) + im[y0, x1] * a) * (1 - b)
            + (im[y1, x0] * (1 - a) + im[y1, x1] * a) * b)


@dataclass(frozen=True)
class PlacedModel:
    """A retrieved model on an object (``unseen retrieve``): world vertices at the
    object's place in the scan, faces, and an RGB colour (None: the object's mean colour
    in the image)."""

    vertices: np.ndarray  #: (n, 3) float, world
    faces: np.ndarray  #: (m, 3) int
    rgb: tuple | None = None


def read_retrieved(folder, arr: Arrangement) -> dict:
    """Object name -> :class:`PlacedModel` from an ``unseen retrieve`` output folder
    (``retrieval.json``: per object its ``model`` file, under the ``models`` folder it
    names, and the 4x4 ``transform`` from the file's coordinates to world).  Objects the
    arrangement does not have are skipped; a missing file is an :class:`InputError`."""
    from pathlib import Path

    import trimesh

    from pipeline.safe_read import load_json

    folder = Path(folder)
    path = folder / "retrieval.json" if folder.is_dir() else folder
    if not path.is_file():
        raise InputError(f"--retrieved {folder}: no retrieval.json (give the output folder "
                         "of 'unseen retrieve')")
    data = load_json(path, "retrieval file", limit=64 * 2**20)
    if not isinstance(data, dict) or not isinstance(data.get("objects"), list):
        raise InputError(f"{path}: not a retrieval.json (no 'objects' list)")
    names = set(object_names(arr))
    root = Path(str(data.get("models", "")))
    out = {}
    for k, o in enumerate(data["objects"]):
        if not isinstance(o, dict) or o.get("object") not in names:
            continue
        where = f"{path}: objects[{k}]"
        try:
            T = np.asarray(o["transform"], float)
            rel = Path(str(o["model"]))
        except (KeyError, TypeError, ValueError):
            raise InputError(f"{where}: needs 'model' and a 4x4 'transform'") from None
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise InputError(f"{where}.transform: must be a 4x4 matrix of numbers")
        cands = [rel] if rel.is_absolute() else [root / rel, folder / root / rel, folder / rel]
        file = next((c for c in cands if c.is_file()), None)
        if file is None:
            raise InputError(f"{where}.model: {rel} not found (looked in {root} and {folder})")
        try:
            mesh = trimesh.load(file, force="mesh", process=False)
        except Exception as exc:  # noqa: BLE001 - any reader failure is bad input
            raise InputError(f"{file}: cannot read the model ({exc.__class__.__name__})") from None
        V = np.asarray(mesh.vertices, float) @ T[:3, :3].T + T[:3, 3]
        out[o["object"]] = PlacedModel(V, np.asarray(mesh.faces, np.int64))
    return out


def _object_rgb(view: View, cubs: list[Cuboid], params: EditParams) -> tuple:
    """The mean colour (uint8 RGB) of the pixels showing ``cubs`` (grey when none)."""
    _, obj = _face_colours(view, cubs, params)
    m = obj[np.isfinite(obj[:, 0])]
    return tuple(int(x) for x in np.clip(np.rint(m[0]), 0, 255)) if len(m) else (128, 128, 128)


def _shade(normals: np.ndarray, light: np.ndarray) -> np.ndarray:
    """Lambert shading with ambient, for faces no pixel showed: (n,) in [0.55, 1]."""
    return 0.55 + 0.45 * np.clip(normals @ (-light), 0.0, 1.0)


def edit_image(view: View, plan: EditPlan, params: EditParams | None = None,
               progress=None, meshes: dict | None = None) -> EditImages:
    """Edit the view's colour image as ``plan`` says (module docstring, steps 2-5).

    ``meshes``: object name -> :class:`PlacedModel` (its retrieved model at its old
    place); a moved object that has one is drawn as that model (the cuboids still delete
    its pixels and cast its shadow).  ``progress(step)`` hears the name of each step.
    """
    import cv2

    params = params or EditParams()
    step = progress or (lambda name: None)
    H, W = view.depth.shape
    before = plan.before
    gone = [before.cuboid(i) for i in plan.gone]
    placed = [plan.after.cuboid(i) for i in plan.moved]
    offsets = np.array([plan.moved[i] for i in plan.moved]).reshape(-1, 3)
    remaining = plan.after.with_(cuboids=tuple(c for c in plan.after.cuboids
                                               if c.id not in plan.moved))
    light = np.asarray(params.light, float)
    light = light / np.linalg.norm(light)

    step("mask")
    t_rem, lab = cast_scene(view, remaining)
    hole = hole_mask(view, gone, params, behind=t_rem)
    old_region = silhouette(view, gone)
    new_region = silhouette(view, placed)

    step("fill")
    background = fill_hole(view, hole, remaining, params, cast=(t_rem, lab))
    d = view.depth
    bg_depth = np.where(~hole & (d > 0), d, t_rem)  # what the background's pixels see

    # world point of every background pixel
    v, u = np.mgrid[0:H, 0:W]
    o, dirs = pixel_rays(view, u.ravel(), v.ravel())
    with np.errstate(invalid="ignore"):
        pts = o + dirs * bg_depth.reshape(-1, 1)

    shadow = np.zeros((H, W))
    if params.shadow and placed:
        step("shadow")
        C, R, S = box_arrays(placed)
        corners = np.concatenate([c.corners() for c in placed])
        top = corners[:, 2].max()
        lo, hi = corners[:, :2].min(0), corners[:, :2].max(0)
        fin = np.all(np.isfinite(pts), axis=1)
        with np.errstate(invalid="ignore"):
            reach = np.where(fin, np.maximum(top - pts[:, 2], 0.0), 0.0) \
                * np.linalg.norm(light[:2]) / max(-light[2], 1e-6)
            near = fin & (pts[:, 2] < top) & np.all(
                (pts[:, :2] >= lo - reach[:, None] - params.shadow_soft * 3)
                & (pts[:, :2] <= hi + reach[:, None] + params.shadow_soft * 3), axis=1)
        idx = np.nonzero(near)[0]
        if len(idx):
            start = pts[idx] + 1e-3 * np.array([0.0, 0.0, 1.0])
            t, _, _ = cast_boxes(start, np.broadcast_to(-light, (len(idx), 3)), C, R, S)
            hard = np.zeros(H * W)
            hard[idx[np.isfinite(t)]] = 1.0
            hard = hard.reshape(H, W)
            if hard.any():
                zs = bg_depth.ravel()[idx[np.isfinite(t)]]
                z = float(np.median(zs[np.isfinite(zs)])) if np.isfinite(zs).any() else 2.0
                sigma = max(0.5, view.intrinsics.fx * params.shadow_soft / max(z, 0.1))
                shadow = cv2.GaussianBlur(hard.astype(np.float32), (0, 0), sigma).astype(float)
                shadow = np.clip(shadow, 0.0, 1.0) * params.shadow_strength
    shaded = background.astype(float) * (1.0 - shadow[..., None])

    alpha = np.zeros((H, W))
    fg = np.zeros((H, W, 3))
    if placed:
        step("render")
        meshes = meshes or {}
        drawn = [object_of(c) in meshes for c in placed]
        items = []
        for name in dict.fromkeys(object_of(c) for c in placed if object_of(c) in meshes):
            j = next(k for k, c in enumerate(placed) if object_of(c) == name)
            pm = meshes[name]
            rgb = pm.rgb if pm.rgb is not None else _object_rgb(
                view, [before.cuboid(c.id) for c in placed if object_of(c) == name], params)
            items.append((pm.vertices + offsets[j], pm.faces, offsets[j], rgb))
        boxes = [c for c, m in zip(placed, drawn) if not m]
        offs = offsets[[not m for m in drawn]].reshape(-1, 3)
        alpha, fg = _render_moved(view, boxes, offs, bg_depth, params, light, items)
    after = shaded * (1 - alpha[..., None]) + fg * alpha[..., None]
    after = np.clip(np.rint(after), 0, 255).astype(np.uint8)
    return EditImages(view.image.copy(), after, hole, background, shadow, alpha,
                      old_region, new_region)


def _texture(view: View, X: np.ndarray, offsets: np.ndarray, params: EditParams
             ) -> tuple[np.ndarray, np.ndarray]:
    """Colour of world points ``X (n, 3)`` of moved objects taken where the camera saw the
    same points before the move (``X - offsets``): ``(n, 3)`` float and ``(n,)`` bool, True
    where the old point projects into the image onto a pixel whose depth agrees with it."""
    H, W = view.depth.shape
    p0 = (X - offsets - view.T_world_cam[:3, 3]) @ view.T_world_cam[:3, :3]
    uv0, z0 = project(p0, view.intrinsics)
    uv0 = np.nan_to_num(uv0, nan=-1.0, posinf=-1.0, neginf=-1.0)
    inside = (z0 > 0) & (uv0[:, 0] >= 0) & (uv0[:, 0] <= W - 1) & (uv0[:, 1] >= 0) \
        & (uv0[:, 1] <= H - 1)
    iu = np.clip(np.rint(uv0[:, 0]).astype(int), 0, W - 1)
    iv = np.clip(np.rint(uv0[:, 1]).astype(int), 0, H - 1)
    dz = view.depth[iv, iu]
    seen = inside & (dz > 0) & (np.abs(dz - z0) <= params.seen_tol + 0.02 * np.abs(z0))
    return bilinear(view.image, uv0[:, 0], uv0[:, 1]), seen


def _render_moved(view: View, placed: list[Cuboid], offsets: np.ndarray,
                  bg_depth: np.ndarray, params: EditParams, light: np.ndarray,
                  meshes: list | tuple = ()) -> tuple[np.ndarray, np.ndarray]:
    """Coverage (H, W) and colour (H, W, 3) of the moved objects at their new places.

    ``placed``: the moved cuboids drawn as boxes, ``offsets (K, 3)`` theirs; ``meshes``:
    ``(vertices (n, 3) at the new place, faces (m, 3), offset (3,), rgb (3,))`` per object
    drawn as its retrieved model (:func:`pipeline.raster.rasterize`, at the same
    supersampling)."""
    H, W = bg_depth.shape
    alpha = np.zeros((H, W))
    colour = np.zeros((H, W, 3))
    pts = [c.corners() for c in placed] + [np.asarray(m[0], float) for m in meshes]
    if not pts:
        return alpha, colour
    pts = np.concatenate(pts)
    pc = (pts - view.T_world_cam[:3, 3]) @ view.T_world_cam[:3, :3]
    if np.all(pc[:, 2] > 1e-3):
        uv, _ = project(pc, view.intrinsics)
        x0, y0 = np.floor(uv.min(0)).astype(int) - 1
        x1, y1 = np.ceil(uv.max(0)).astype(int) + 2
        x0, x1, y0, y1 = max(x0, 0), min(x1, W), max(y0, 0), min(y1, H)
    else:
        x0, x1, y0, y1 = 0, W, 0, H
    if x1 <= x0 or y1 <= y0:
        return alpha, colour
    s = max(int(params.supersample), 1)
    h, w = (y1 - y0) * s, (x1 - x0) * s
    vv, uu = np.mgrid[0:h, 0:w]
    u = x0 + (uu.ravel() + 0.5) / s - 0.5
    v = y0 + (vv.ravel() + 0.5) / s - 0.5
    o, d = pixel_rays(view, u, v)
    C, R, S = box_arrays(placed)
    t_box, k, f = cast_boxes(o, d, C, R, S)
    # retrieved models: rasterised into the same sub-pixel grid
    n = len(u)
    t_mesh, mesh_id, mesh_col = np.full(n, np.inf), np.full(n, -1), np.zeros((n, 3))
    i = view.intrinsics
    sub = Intrinsics(w, h, i.fx * s, i.fy * s, s * (i.cx - x0 + 0.5) - 0.5,
                     s * (i.cy - y0 + 0.5) - 0.5)
    for m, (V, F, _, rgb) in enumerate(meshes):
        from pipeline.raster import rasterize  # only with retrieved models

        img, dep = rasterize(V, F, np.tile(np.asarray(rgb, np.uint8), (len(F), 1)), sub,
                             view.T_world_cam, light=-light)
        dep = dep.ravel()
        closer = dep < t_mesh
        t_mesh[closer], mesh_id[closer] = dep[closer], m
        mesh_col[closer] = img.reshape(-1, 3)[closer]
    use_mesh = t_mesh < t_box
    t = np.minimum(t_box, t_mesh)
    pu = np.clip(np.rint(u).astype(int), 0, W - 1)
    pv = np.clip(np.rint(v).astype(int), 0, H - 1)
    behind = bg_depth[pv, pu]
    vis = np.isfinite(t) & ~(behind < t - params.occlusion_tol)
    idx = np.nonzero(vis)[0]
    col = np.zeros((n, 3))
    if len(idx):
        mesh_off = np.array([m[2] for m in meshes], float).reshape(-1, 3)
        off = np.zeros((len(idx), 3))
        on_mesh = use_mesh[idx]
        off[on_mesh] = mesh_off[mesh_id[idx][on_mesh]]
        off[~on_mesh] = offsets[k[idx][~on_mesh]]
        X = o + d[idx] * t[idx, None]
        tex, seen = _texture(view, X, off, params)
        fallback = mesh_col[idx].astype(float)
        bi = np.nonzero(~on_mesh)[0]
        if len(bi):  # a box: the face's mean colour where seen, else the object's, shaded
            kk, ff = k[idx][bi], f[idx][bi]
            old = [c.with_(center=c.center - of) for c, of in zip(placed, offsets)]
            face_col, obj_col = _face_colours(view, old, params)
            fc = face_col[kk, ff]
            axis, plus = ff // 2, ff % 2
            normals = R[kk, :, axis] * np.where(plus, 1.0, -1.0)[:, None]
            seen_faces = np.isfinite(face_col[..., 0])
            base = np.where(np.isfinite(obj_col[kk]), obj_col[kk], 128.0)
            mean_shade = np.array([
                _shade(np.array([R[j][:, a] * (1.0 if p else -1.0)
                                 for a in range(3) for p in (0, 1)])[seen_faces[j]],
                       light).mean()
                if seen_faces[j].any() else 1.0 for j in range(len(placed))])
            shaded = base * (_shade(normals, light) / mean_shade[kk])[:, None]
            fallback[bi] = np.where(np.isfinite(fc), fc, shaded)
        col[idx] = np.where(seen[:, None], tex, fallback)
    cov = vis.reshape(h, w).astype(float)
    acc = (col * vis[:, None]).reshape(h, w, 3)
    cov = cov.reshape(y1 - y0, s, x1 - x0, s).mean(axis=(1, 3))
    acc = acc.reshape(y1 - y0, s, x1 - x0, s, 3).mean(axis=(1, 3))
    alpha[y0:y1, x0:x1] = cov
    with np.errstate(invalid="ignore", divide="ignore"):
        colour[y0:y1, x0:x1] = np.where(cov[..., None] > 0, acc / cov[..., None], 0.0)
    return alpha, colour



__all__ = ["EditParams", "FILLS", "EditImages", "PlacedModel", "read_retrieved", "edit_image",
           "hole_mask", "fill_hole", "bilinear"]
