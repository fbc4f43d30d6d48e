"""What ``unseen retrieve`` writes: the placed models as glTF, a picture, JSON and a report."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from . import atomic
from .camera import Intrinsics, look_at
from .model import Arrangement
from .retrieve import ObjectRetrieval, RepoModel, placed_mesh

#: Colour per kind (RGB), also of the repository's files (``unseen models make``); kinds
#: not listed get grey.
KIND_RGB = {"table": (166, 118, 72), "chair": (214, 96, 77), "shelf": (120, 160, 90),
            "desk": (90, 120, 170), "sofa": (150, 100, 170), "monitor": (70, 70, 80),
            "box": (200, 170, 110)}
#: glTF is y up: x stays, y' = z, z' = -y.
Y_UP_FROM_Z_UP = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]])


def _rgb(kind: str) -> np.ndarray:
    return np.array(KIND_RGB.get(kind, (150, 150, 150)), np.uint8)


#: Colour of the cuboids of objects no model was retrieved for.
KEPT_RGB = (185, 185, 185)


def kept_cuboids(arr: Arrangement, results: tuple[ObjectRetrieval, ...]) -> list:
    """The cuboids of the objects that got no model (fewer cuboids than asked for)."""
    done = {i for r in results for i in r.cuboids}
    return [c for c in arr.cuboids if c.id not in done]


def _box_mesh(c) -> tuple[np.ndarray, np.ndarray]:  # noqa: ANN001
    import trimesh

    T = np.eye(4)
    T[:3, :3], T[:3, 3] = c.rotation, c.center
    m = trimesh.creation.box(extents=c.size, transform=T)
    return np.asarray(m.vertices), np.asarray(m.faces)


def scene_meshes(models: tuple[RepoModel, ...], results: tuple[ObjectRetrieval, ...],
                 kept: list = ()) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All placed models (and the ``kept`` cuboids, grey) as one triangle soup: vertices,
    faces, face colours (RGB)."""
    vs, fs, cs = [], [], []
    n = 0
    for c in kept:
        v, f = _box_mesh(c)
        vs.append(v)
        fs.append(f + n)
        cs.append(np.tile(np.array(KEPT_RGB, np.uint8), (len(f), 1)))
        n += len(v)
    for r in results:
        v, f = placed_mesh(models[r.best.model], r.best)
        vs.append(v)
        fs.append(f + n)
        cs.append(np.tile(_rgb(r.best.kind), (len(f), 1)))
        n += len(v)
    if not vs:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 3), np.uint8)
    return np.concatenate(vs), np.concatenate(fs), np.concatenate(cs)


def retrieval_glb(arr: Arrangement, models: tuple[RepoModel, ...],
                  results: tuple[ObjectRetrieval, ...]) -> bytes:
    """Binary glTF: one node per object (its retrieved model, placed), the cuboids of the
    objects without a model (``cuboid:<id>``, grey) and the ground."""
    import trimesh

    scene = trimesh.Scene()
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for r in results:
        v, f = placed_mesh(models[r.best.model], r.best)
        mesh = trimesh.Trimesh(v, f, process=False)
        rgba = np.append(_rgb(r.best.kind), 255).astype(np.uint8)
        mesh.visual.face_colors = np.tile(rgba, (len(f), 1))
        scene.add_geometry(mesh, node_name=r.object, geom_name=r.object)
        lo, hi = np.minimum(lo, v.min(axis=0)), np.maximum(hi, v.max(axis=0))
    for c in kept_cuboids(arr, results):
        v, f = _box_mesh(c)
        mesh = trimesh.Trimesh(v, f, process=False)
        mesh.visual.face_colors = np.tile(np.array([*KEPT_RGB, 255], np.uint8), (len(f), 1))
        scene.add_geometry(mesh, node_name=f"cuboid:{c.id}", geom_name=f"cuboid:{c.id}")
        lo, hi = np.minimum(lo, v.min(axis=0)), np.maximum(hi, v.max(axis=0))
    if any(s.id == "ground" for s in arr.supports) and np.all(np.isfinite(lo)):
        g = arr.support("ground")
        mid = (lo + hi) / 2
        span = float(np.max(hi[:2] - lo[:2])) * 1.5 + 0.5
        T = np.eye(4)
        T[:3, 3] = [mid[0], mid[1], float(g.point[2]) - 0.005]
        slab = trimesh.creation.box(extents=(span, span, 0.01), transform=T)
        slab.visual.face_colors = np.tile([200, 200, 200, 255], (len(slab.faces), 1))
        scene.add_geometry(slab, node_name="support:ground", geom_name="support:ground")
    scene.apply_transform(Y_UP_FROM_Z_UP)
    return scene.export(file_type="glb")


def _ground_quad(lo: np.ndarray, hi: np.ndarray, z: float) -> tuple[np.ndarray, np.ndarray]:
    m = 0.3 * float(np.max(hi[:2] - lo[:2])) + 0.3
    x0, y0, x1, y1 = lo[0] - m, lo[1] - m, hi[0] + m, hi[1] + m
    v = np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]])
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def view_camera(vertices: np.ndarray, T_world_cam: np.ndarray | None,
                intr: Intrinsics) -> np.ndarray:
    """A camera-to-world pose looking down at ``vertices`` from the side the scan's camera
    was on (or from -y), far enough to frame them."""
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    mid = (lo + hi) / 2
    r = max(float(np.linalg.norm(hi - lo)) / 2, 0.3)
    d = np.array([0.0, 1.0, 0.0]) if T_world_cam is None else np.asarray(T_world_cam)[:3, 2].copy()
    d[2] = 0.0
    d = d / np.linalg.norm(d) if np.linalg.norm(d) > 1e-6 else np.array([0.0, 1.0, 0.0])
    f = min(intr.fx / intr.width, intr.fy / intr.height)
    dist = 1.25 * r / np.tan(np.arctan(0.5 / f))
    eye = mid - d * dist * 0.8 + np.array([0.0, 0.0, dist * 0.6])
    return look_at(eye, mid)


def retrieval_picture(arr: Arrangement, models: tuple[RepoModel, ...],
                      results: tuple[ObjectRetrieval, ...], image: np.ndarray | None = None,
                      intr: Intrinsics | None = None, T_world_cam: np.ndarray | None = None,
                      width: int = 560) -> np.ndarray:
    """(H, W', 3) uint8: the retrieved models over the scan's colour image (when given,
    from the scan's camera, half transparent) beside a view of them on the ground from
    above the camera's side; each panel ``width`` pixels wide, labelled by kind."""
    import cv2

    from .raster import rasterize

    v, f, c = scene_meshes(models, results, kept_cuboids(arr, results))
    panels = []
    if image is not None and intr is not None and T_world_cam is not None and len(f):
        img, depth = rasterize(v, f, c, intr, T_world_cam)
        hit = np.isfinite(depth)
        base = np.asarray(image, np.uint8).copy()
        if base.shape[:2] != (intr.height, intr.width):
            base = cv2.resize(base, (intr.width, intr.height))
        base[hit] = (0.35 * base[hit] + 0.65 * img[hit]).astype(np.uint8)
        panels.append(base)
    vi = Intrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)
    if len(f):
        z0 = float(arr.support("ground").point[2]) if any(s.id == "ground"
                                                          for s in arr.supports) else v[:, 2].min()
        gv, gf = _ground_quad(v.min(axis=0), v.max(axis=0), z0 - 0.002)
        V = np.concatenate([v, gv])
        F = np.concatenate([f, gf + len(v)])
        C = np.concatenate([c, np.full((2, 3), 215, np.uint8)])
        T = view_camera(v, T_world_cam, vi)
        img, depth = rasterize(V, F, C, vi, T)
        img[~np.isfinite(depth)] = 255
        _label(img, results, vi, T)
        panels.append(img)
    else:
        panels.append(np.full((480, 640, 3), 255, np.uint8))
    out = []
    for p in panels:
        h = int(round(p.shape[0] * width / p.shape[1]))
        out.append(cv2.resize(p, (width, h), interpolation=cv2.INTER_AREA))
    H = max(p.shape[0] for p in out)
    out = [np.pad(p, ((0, H - p.shape[0]), (0, 0), (0, 0)), constant_values=255) for p in out]
    return np.concatenate(out, axis=1)


def _label(img: np.ndarray, results: tuple[ObjectRetrieval, ...], intr: Intrinsics,
           T_world_cam: np.ndarray) -> None:
    """Write each object's retrieved kind/variant at its model's top centre."""
    import cv2

    from .camera import invert, project, transform

    for r in results:
        M = r.best.M
        top = M[:3, :3] @ np.array([0.5, 0.5, 1.0]) + M[:3, 3]
        uv, z = project(transform(invert(T_world_cam), top[None]), intr)
        if z[0] <= 0:
            continue
        u, v = int(uv[0, 0]), int(uv[0, 1]) - 6
        text = f"{r.best.kind}:{r.best.variant}"
        cv2.putText(img, text, (u - 4 * len(text), v), cv2.FONT_HERSHEY_SIMPLEX, 0.42,
                    (0, 0, 0), 1, cv2.LINE_AA)


def retrieval_json(results: tuple[ObjectRetrieval, ...], models: tuple[RepoModel, ...],
                   header: dict) -> str:
    objs = []
    for r in results:
        objs.append({"object": r.object, "cuboids": list(r.cuboids), "points": r.n_points,
                     **r.best.to_json(models[r.best.model]),
                     "runner_up": None if r.runner_up is None else {
                         "model": r.runner_up.file, "kind": r.runner_up.kind,
                         "variant": r.runner_up.variant, "score": round(r.runner_up.score, 6),
                         "kind_score": round(r.runner_up.kind_score, 6)},
                     "per_kind": {k: {"model": c.file, "variant": c.variant,
                                      "score": round(c.score, 6),
                                      "kind_score": round(c.kind_score, 6)}
                                  for k, c in sorted(r.per_kind.items())}})
    return json.dumps({"format": "unseen.retrieval", "version": 1, **header, "objects": objs},
                      indent=1) + "\n"


def report_markdown(results: tuple[ObjectRetrieval, ...], header: dict, notes: list[str]) -> str:
    lines = ["# unseen retrieve", ""]
    lines += [f"- {k}: `{v}`" if k == "command" else f"- {k}: {v}" for k, v in header.items()]
    lines += ["", "Score = share of the model's surface samples inside the (grown) cuboids + "
              "share of the cuboids' volume samples inside the model's solid (0-2); it picks "
              "the model within a kind.  Kind score = score - stretch_cost x stretch, stretch "
              "= ln(max / min) of the factors scaling the model's axes into the object's box; "
              "it picks the kind (and orders the runner-up).", "",
              "| object | cuboids | points | model | kind | variant | score | stretch | "
              "kind score | model covered | structure covered | ICP fitness | runner-up "
              "(kind score) |", "|" + "---|" * 13]
    for r in results:
        b = r.best
        icp = "-" if b.icp is None else f"{b.icp['fitness']:.2f}" + \
            ("" if b.icp["applied"] else " (not kept)")
        ru = "-" if r.runner_up is None else \
            f"{r.runner_up.kind}:{r.runner_up.variant} {r.runner_up.kind_score:.3f}"
        lines.append(f"| {r.object} | {len(r.cuboids)} | {r.n_points} | {b.file} | {b.kind} | "
                     f"{b.variant} | {b.score:.3f} | {b.stretch:.3f} | {b.kind_score:.3f} | "
                     f"{b.a:.3f} | {b.b:.3f} | {icp} | {ru} |")
    if notes:
        lines += ["", "Notes: " + "; ".join(notes)]
    return "\n".join(lines) + "\n"


def write_outputs(out: Path, arr: Arrangement, models: tuple[RepoModel, ...],
                  results: tuple[ObjectRetrieval, ...], header: dict, notes: list[str],
                  image=None, intr=None, T_world_cam=None) -> None:  # noqa: ANN001
    """retrieved.glb, retrieval.json, retrieval.png, report.md into ``out``."""
    from .pictures import write_png

    out.mkdir(parents=True, exist_ok=True)
    atomic.write_bytes(out / "retrieved.glb", retrieval_glb(arr, models, results))
    atomic.write_text(out / "retrieval.json", retrieval_json(results, models, header))
    write_png(out / "retrieval.png",
              retrieval_picture(arr, models, results, image, intr, T_world_cam))
    atomic.write_text(out / "report.md", report_markdown(results, header, notes))
