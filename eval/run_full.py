"""The full ``unseen run``: initial cuboids (section 4.1), then imagining the unseen (4.2-4.3).

Writes ``arrangement.json`` (final cuboids with their observed boxes, typed contacts,
stability), ``initial.json`` (the initial cuboids), ``scene.xml`` (MJCF), ``scene.urdf``,
``arrangement.glb``, ``overlay.png`` (initial and final boxes over the image,
hallucinated parts dashed magenta, contacts: fixed solid red, touch dashed blue),
``view.png`` (3D with the contact graph) and ``report.md``.
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time
from pathlib import Path

import numpy as np

FIXED_COLOUR = (230, 30, 30)
TOUCH_COLOUR = (40, 90, 255)
HALLUCINATED_COLOUR = (230, 0, 230)
INITIAL_COLOUR = (200, 200, 200)


def _soa(cubs) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centres, rotations, sizes) of a list of cuboids, for the picture functions."""
    if not cubs:
        return np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros((0, 3))
    return (np.stack([c.center for c in cubs]), np.stack([c.rotation for c in cubs]),
            np.stack([c.size for c in cubs]))


def contact_segments(arr) -> list[tuple[np.ndarray, np.ndarray, str]]:
    """(centre a, centre b or foot on the support, type) for every listed contact."""
    out = []
    idx = arr.index
    for c in arr.contacts:
        a = arr.cuboids[idx[c.a]].center if c.a in idx else None
        if c.b in idx:
            b = arr.cuboids[idx[c.b]].center
        else:
            sup = arr.support(c.b)
            b = a - sup.signed_distance(a[None])[0] * sup.normal
        if a is not None:
            out.append((a, b, c.type))
    return out


def write_full_outputs(out: Path, scan, initial, result, report0: dict, engines: dict | None,
                       command: str, seed: int, mu: float | None = None) -> None:
    """Every output of a full run into ``out`` (an :func:`pipeline.outdir.output_folder`'s
    temporary folder).  ``mu`` (default: the arrangement's ``meta.mu``, else 0.7) goes into
    scene.xml and scene.urdf."""
    from pipeline import atomic
    from pipeline.arrangement_io import write_arrangement
    from pipeline.camera import Intrinsics, look_at
    from pipeline.pictures import depth_picture, draw_overlay, draw_view, splat_points, write_png
    from simulate.export import export_all

    final = result.arrangement
    out.mkdir(parents=True, exist_ok=True)
    write_arrangement(final, out / "arrangement.json")
    write_arrangement(initial, out / "initial.json")
    if mu is None:
        mu = final.meta.get("mu")
    export_all(final, out, mu=mu)

    world, labels = report0["world"], report0["labels"]
    T = np.asarray(final.meta["camera_pose"], float)
    if scan.image is not None:
        base, intr = scan.image, scan.intrinsics
    elif scan.depth is not None:
        base, intr = depth_picture(scan.depth), scan.intrinsics
    else:
        intr = Intrinsics.kinect_v1()
        lo, hi = np.percentile(world, [2, 98], axis=0)
        mid, r = (lo + hi) / 2, float(np.linalg.norm(hi - lo))
        T = look_at(mid + np.array([0.0, -0.9 * r, 0.6 * r]), mid)
        base = splat_points(world, scan.colors, intr, T)
    seen_c = [c for c in final.cuboids if not c.extra.get("hallucinated")]
    imagined_c = [c for c in final.cuboids if c.extra.get("hallucinated")]
    seen, imagined = _soa(seen_c), _soa(imagined_c)
    segs = contact_segments(final)
    lines = [(a, b, FIXED_COLOUR if t == "fixed" else TOUCH_COLOUR,
              "solid" if t == "fixed" else "dashed") for a, b, t in segs]
    overlay = draw_overlay(base, intr, T,
                           [(initial, INITIAL_COLOUR, "thin"), (seen, "palette", "solid"),
                            (imagined, HALLUCINATED_COLOUR, "dashed")],
                           labels=[[], [c.id for c in seen_c], [c.id for c in imagined_c]],
                           lines=lines)
    write_png(out / "overlay.png", overlay)
    colors = scan.colors
    n_fixed = sum(c.type == "fixed" for c in final.contacts)
    stable = final.stability.stable if final.stability else False
    view = draw_view(world[labels >= 0], colors[labels >= 0] if colors is not None else None,
                     [(seen, "palette", "solid"), (imagined, HALLUCINATED_COLOUR, "dashed")],
                     contacts=segs,
                     title=f"{len(final.cuboids)} cuboids, {len(final.contacts)} contacts "
                           f"({n_fixed} fixed: red, touch: blue dashed), "
                           f"{'stable' if stable else 'UNSTABLE'}")
    write_png(out / "view.png", view)
    atomic.write_text(out / "report.md",
                      full_report(final, report0, result.report, engines, command, seed))


def full_report(final, report0: dict, rep: dict, engines: dict | None, command: str,
                seed: int) -> str:
    try:
        from importlib.metadata import version
        ver = version("unseen")
    except Exception:  # noqa: BLE001
        ver = "unknown"
    st = rep.search
    lines = ["# unseen run", "", f"- command: `{command}`", f"- seed: {seed}", f"- unseen {ver}",
             f"- input: {report0.get('segmentation', '')} segmentation, "
             f"{report0['counts']['objects']} objects, {report0['counts']['cuboids']} initial cuboids",
             f"- result: {len(final.cuboids)} cuboids, {len(final.contacts)} contacts "
             f"({sum(c.type == 'fixed' for c in final.contacts)} fixed), "
             f"**{'stable' if rep.stable else 'UNSTABLE'}** (E = {rep.energy:.3g})", ""]
    if report0.get("notes"):
        lines += ["Notes: " + "; ".join(report0["notes"]), ""]
    if rep.unstable:
        lines += [f"Even with every candidate contact fixed, these boxes cannot be held: "
                  f"{', '.join(rep.unstable)} (a support was probably not seen); "
                  "the result is the best effort.", ""]
    lines += glue_section(final, rep.edits)
    lines += ["## Timings (seconds)", "", "| step | seconds |", "|---|---|"]
    lines += [f"| initial: {k} | {v:.3f} |" for k, v in report0["timings"].items() if k != "total"]
    lines += [f"| imagine: {k} | {v:.3f} |" for k, v in rep.timings.items()]
    lines += ["", "## Search", "", "| statistic | value |", "|---|---|"]
    lines += [f"| {k} | {v} |" for k, v in st.items()]
    lines += [f"| candidate edges (after pruning) | {rep.candidate_edges} |",
              f"| candidate options (before pruning) | {rep.candidate_options} |",
              f"| rejected: seen as empty | {rep.rejected_by_visibility} |",
              f"| visibility check | {rep.visibility} |",
              "| held once judged by the whole added volume seen through, not the share "
              f"of its samples | {', '.join(rep.judged_whole) or 'none'} |",
              f"| parts the priors added | {', '.join(rep.hallucinated) or 'none'} |",
              f"| fixed contacts chosen (beyond same-object fusions) | {rep.fixed_chosen} |",
              f"| added volume (m^3) | {rep.added_volume_m3:.4g} |",
              f"| largest contact gap closed (mm) | {1000 * rep.gap_closed_m:.3g} |"]
    if rep.refine:
        r = rep.refine
        lines += [f"| refinement | E {r['energy_before']:.3g} -> {r['energy_after']:.3g} in "
                  f"{r['steps']} steps |"]
    if engines:
        lines += ["", "## Engines", "", "| engine | verdict | bodies moving |", "|---|---|---|"]
        for name, res in engines.items():
            moving = [b["id"] for b in res.get("bodies", []) if not b.get("stable", True)]
            lines.append(f"| {name} | {'stable' if res['stable'] else 'UNSTABLE'} | "
                         f"{', '.join(moving) or '-'} |")
    lines += ["", "## Priors", "", "What each prior proposed (see README, 'The method'); "
              f"switched off: {', '.join(rep.disabled) or 'none'}.", "",
              "| prior | boxes | why | kept |", "|---|---|---|---|"]
    lines += [f"| {e.prior} | {', '.join(e.boxes)} | {e.reason} | "
              f"{'yes' if e.accepted else 'no: ' + e.why_not} |" for e in rep.edits]
    lines += ["", "## Cuboids", "", "| id | object | size (m) | observed size (m) | note |",
              "|---|---|---|---|---|"]
    for c in final.cuboids:
        obs = " x ".join(f"{v:.3f}" for v in c.observed.size) if c.observed is not None else "-"
        note = "hallucinated" if c.extra.get("hallucinated") else ""
        lines.append(f"| {c.id} | {c.object} | {' x '.join(f'{v:.3f}' for v in c.size)} | "
                     f"{obs} | {note} |")
    lines += ["", "## Contacts", "", "| a | b | type |", "|---|---|---|"]
    lines += [f"| {c.a} | {c.b} | {c.type} |" for c in final.contacts]
    return "\n".join(lines) + "\n"


def glue_section(final, edits=()) -> list[str]:
    """report.md's list of the ``fixed`` joints between different objects or with a
    support, each with what it holds (:func:`pipeline.stability.glue_reasons`) or the
    prior that set it (``edits``: the report's prior edits)."""
    from pipeline.stability import glue_reasons

    reasons = glue_reasons(final, mu=float(final.meta.get("mu", 0.7)))
    if not reasons:
        return []
    lines = ["## Glue between objects", "",
             "A `fixed` joint between different objects, or with the floor or a wall, is the "
             "search's last resort (it minimises their number first).  Each one below, and "
             "what cannot be held when it alone is loosened to a touch:", "",
             "| a | b | without it |", "|---|---|---|"]
    for c, moving, margin in reasons:
        setter = next((e for e in edits if e.accepted and c.key in e.fixed), None)
        why = (f"{', '.join(moving)} cannot be held" if moving else
               "stands, but not with gravity tilted by 2 deg (the search's margin)"
               if not margin else f"stands too; set by the prior {setter.prior}: "
               f"{setter.reason}" if setter else "stands too (the search's tie-break kept it)")
        lines.append(f"| {c.a} | {c.b} | {why} |")
    return lines + [""]


def check_engines(arr, mu: float) -> dict:
    from simulate.engines import settle

    out = {}
    for engine in ("mujoco", "pybullet"):
        out[engine] = settle(arr, engine, mu=mu).to_json()
    return out


def run_full(args: argparse.Namespace, config) -> tuple[int, str]:
    """Run and write everything (``config``: the :class:`pipeline.run.RunConfig` of
    ``args``); returns (exit code, one summary line for the terminal)."""
    from eval.run_checks import inputs, validate_args
    from pipeline.outdir import output_folder
    from pipeline.progress import Progress
    from pipeline.run import run_scan

    validate_args(args)
    out = Path(args.out)
    t0 = time.perf_counter()
    command = "unseen run " + " ".join(shlex.quote(a) for a in sys.argv[2:]) \
        if len(sys.argv) > 1 and sys.argv[1] == "run" else f"unseen run {args.input}"
    with output_folder(out, inputs=inputs(args), command="run") as tmp:
        with Progress(None, "unseen run") as bar:
            result = run_scan(args.input, config, progress=lambda name: bar.update(note=name),
                              search_progress=lambda done, total: bar.update(
                                  note=f"group {done}/{total}"))
            scan, initial, report0 = result.scan, result.initial, result.initial_report
            engines = None
            if args.check_engines:
                bar.update(note="engines")
                engines = check_engines(result.arrangement, args.mu)
        write_full_outputs(tmp, scan, initial, result, report0, engines, command, args.seed,
                           mu=args.mu)
    final = result.arrangement
    n_fixed = sum(c.type == "fixed" for c in final.contacts)
    verdict = "stable" if result.report.stable else "UNSTABLE (best effort)"
    line = (f"{len(final.cuboids)} cuboids, {len(final.contacts)} contacts ({n_fixed} fixed), "
            f"{verdict}, {time.perf_counter() - t0:.2f} s -> {out}")
    if engines:
        line += "; engines: " + ", ".join(
            f"{k} {'stable' if v['stable'] else 'UNSTABLE'}" for k, v in engines.items())
    ok = result.report.stable and (not engines or all(v["stable"] for v in engines.values()))
    return (0 if ok else 1), line
