"""The per-scene work shared by the paper's suites: synthesize, scan, run, score.

Every function here runs inside one :class:`eval.runner.Task`, so it writes its scene
directory to a temporary folder (Dask workers need no shared disk) and returns plain
JSON-ready dicts.  Nothing here reads a clock into a record: records of the same task and
seed are byte-identical; timings are the runner's (``timing.json``).
"""

from __future__ import annotations

import contextlib
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

#: Search budget per scene, seconds (the pipeline's default).
BUDGET = 10.0
#: First scene seed of the suites (tests use smaller seeds, so the suites never reuse them).
SCENE_SEED0 = 1000


def scene_seed(suite_seed: int, index: int) -> int:
    """Scene seed ``index`` of a suite run with ``--seed suite_seed`` (always >= 1000)."""
    return SCENE_SEED0 + 100 * int(suite_seed) + int(index)


def run_config(budget: float = BUDGET, config: dict | None = None):
    """The :class:`pipeline.run.RunConfig` of a suite's scene: ``unseen run``'s defaults,
    the search ``budget`` and ``config``, JSON-able overrides of the
    :class:`pipeline.priors.ImagineConfig` (``{"disable": [...], "params": {...}}``)."""
    from pipeline.priors import ImagineConfig
    from pipeline.run import RunConfig

    imagine = ImagineConfig.from_dict({"budget": float(budget), **(config or {})})
    return RunConfig(imagine=imagine)


def check_config(config: dict | None) -> dict:
    """A pipeline configuration (JSON-able :meth:`pipeline.priors.ImagineConfig.from_dict`
    overrides: ``{"disable": [prior, ...], "params": {prior: {field: value}}}``), checked:
    an unknown key or prior name raises, so a suite never runs silently unconfigured."""
    from pipeline.priors import ImagineConfig

    config = dict(config or {})
    ImagineConfig.from_dict(config)
    return config


@contextlib.contextmanager
def scratch() -> Iterator[Path]:
    """A temporary folder removed afterwards."""
    with tempfile.TemporaryDirectory(prefix="unseen-suite-") as tmp:
        yield Path(tmp)


def make_scene(family: str, seed: int, folder: Path, *, views: int = 1, noise: str = "kinect",
               **options: Any):
    """:func:`synth_scenes.scene_dir.make_scene_dir`, raising when no valid scene exists."""
    from synth_scenes.scene_dir import make_scene_dir

    made = make_scene_dir(family, folder, seed=seed, views=views, noise=noise, **options)
    if made.truth.status != "ok":
        raise RuntimeError(f"{family} seed {seed}: no physically valid scene ({made.truth.status})")
    return made


def initial_from_dir(scene_dir: Path, budget: float = BUDGET, config: dict | None = None):
    """(scan, initial arrangement, run config) of a scene directory (section 4.1)."""
    from dataclasses import replace

    from pipeline.run import run_scan

    cfg = run_config(budget, config)
    res = run_scan(scene_dir, replace(cfg, stage="initial"))
    return res.scan, res.initial, cfg


def run_dir(scene_dir: Path, budget: float = BUDGET, config: dict | None = None):
    """The whole pipeline on a scene directory: a :class:`pipeline.run.Result`."""
    from pipeline.run import run_scan

    return run_scan(scene_dir, run_config(budget, config))


def summary_of(result_arr, report) -> dict:
    """Counts of a pipeline result: cuboids, contacts, fixed contacts (all, and ``n_glue``:
    those between different objects or with a support), analytic verdict."""
    n_fixed = sum(c.type == "fixed" for c in result_arr.contacts)
    objects = {c.id: c.object for c in result_arr.cuboids}
    n_glue = sum(c.type == "fixed" and (objects.get(c.a) is None
                                        or objects.get(c.a) != objects.get(c.b))
                 for c in result_arr.contacts)
    return {"n_final": len(result_arr.cuboids), "n_contacts": len(result_arr.contacts),
            "n_fixed": int(n_fixed), "n_glue": int(n_glue),
            "stable": bool(report.stable),
            "hallucinated": len(report.hallucinated)}


def settle_stands(arr, engine: str = "mujoco") -> bool:
    """Whether ``arr`` stands when settled in ``engine``."""
    from simulate.engines import settle

    return bool(settle(arr, engine).stable)


def unseen_parts(scan_dir: Path, gt) -> list[str]:  # noqa: ANN001 - an Arrangement
    """Ids of the ground-truth cuboids the scan gave fewer points than the pipeline needs
    to make a cuboid of an instance (:data:`pipeline.segment.MIN_INSTANCE_POINTS`): parts
    no view saw, or saw too little of, whose contacts only physics can recover."""
    from pipeline.segment import MIN_INSTANCE_POINTS
    from simulate.scan import read_ply

    _, _, inst = read_ply(Path(scan_dir) / "points.ply")
    counts = np.bincount(inst.astype(np.int64), minlength=len(gt.cuboids) + 1) \
        if inst is not None else np.zeros(len(gt.cuboids) + 1, np.int64)
    return [c.id for k, c in enumerate(gt.cuboids) if counts[k + 1] < MIN_INSTANCE_POINTS]


def missed_at(rec_false_negatives, parts: list[str]) -> int:  # noqa: ANN001
    """How many missed true contacts (``(a, b, type)``) touch one of ``parts``."""
    ids = set(parts)
    return sum(1 for e in rec_false_negatives if e[0] in ids or e[1] in ids)


def scene_task(rng: np.random.Generator, family: str, seed: int, views: int = 1,
               noise: str = "kinect", budget: float = BUDGET, options: dict | None = None,
               engine: str | None = None, engines: tuple | list | None = None,
               config: dict | None = None) -> dict:
    """One scene through the whole pipeline, scored (a :class:`eval.runner.Task` function).

    ``config``: overrides of the inference configuration (:func:`check_config`), e.g.
    ``{"disable": ["symmetry"]}``; recorded in the result when given.

    Returns :func:`eval.suites._common.score_record` (with ``unseen``: the parts of
    :func:`unseen_parts`, ``fn_unseen``, ``n_seen``, ``n_matched_seen``) plus ``family``,
    ``seed``, ``views``, ``n_gt``/``n_gt_contacts``, ``n_initial`` and :func:`summary_of`;
    with ``engine`` also ``stands`` (the result settled in that engine), with ``engines``
    also ``stands_in`` (engine -> whether it stands there).  When the pipeline refuses
    the scan (an ``InputError``, e.g. no ground plane found) the record says so in
    ``pipeline_error`` and scores an empty result: every true contact missed.
    """
    from eval.suites._common import score_record
    from pipeline.errors import InputError

    del rng  # the scene is a function of its seed; the pipeline is seeded by its config
    config = check_config(config)  # fail before the scene is made
    with scratch() as tmp:
        made = make_scene(family, seed, tmp / "scene", views=views, noise=noise,
                          **(options or {}))
        gt = made.truth.arrangement
        unseen = unseen_parts(made.path / "scan", gt)
        try:
            result = run_dir(made.path, budget, config)
            initial = result.initial
        except InputError as exc:  # the method gave up on this scan: a result, not a crash
            return _gave_up(gt, unseen, str(exc), family, seed, views, config, engine, engines)
    rec = score_record(result.arrangement, gt, initial=initial, unseen=unseen)
    rec.update(family=family, seed=int(seed), views=int(views), n_gt=len(gt.cuboids),
               n_gt_contacts=len(gt.contacts), n_initial=len(initial.cuboids),
               priors={k: list(v) for k, v in sorted(result.report.counts().items())},
               **summary_of(result.arrangement, result.report))
    if config:
        rec["config"] = config
    if engine:
        rec["stands"] = settle_stands(result.arrangement, engine)
    if engines:
        rec["stands_in"] = {e: settle_stands(result.arrangement, e) for e in engines}
    return rec


def _gave_up(gt, unseen: list[str], error: str, family: str, seed: int, views: int,  # noqa: ANN001
             config: dict, engine: str | None, engines) -> dict:  # noqa: ANN001
    """The record of a scene the pipeline refused (``unseen run`` would exit 2 with
    ``error``, e.g. no ground plane found): no cuboids and no contacts, initially or
    after optimization, so every true contact counts as missed; nothing stands."""
    from eval.suites._common import score_record
    from pipeline.model import Arrangement

    empty = Arrangement((), ())
    rec = score_record(empty, gt, initial=empty, unseen=unseen)
    rec.update(family=family, seed=int(seed), views=int(views), n_gt=len(gt.cuboids),
               n_gt_contacts=len(gt.contacts), n_initial=0, n_final=0, n_contacts=0,
               n_fixed=0, n_glue=0, stable=False, hallucinated=0, pipeline_error=error)
    if config:
        rec["config"] = config
    if engine:
        rec["stands"] = False
    if engines:
        rec["stands_in"] = {e: False for e in engines}
    return rec


def f1_of(rec: dict, key: str = "optimized.typed") -> float:
    """Per-scene F1 in [0, 1] of a :func:`score_record` result (NaN when absent)."""
    from eval.metrics import PRF

    cur: Any = rec
    for part in key.split("."):
        if not isinstance(cur, dict) or part not in cur:
            return float("nan")
        cur = cur[part]
    return float(PRF(int(cur["tp"]), int(cur["n_pred"]), int(cur["n_gt"])).f1)


def failure_note(summary) -> str:  # noqa: ANN001 - eval.runner.RunSummary
    """A line about failed tasks for a table note (empty when none failed)."""
    from eval.suites._common import failures_markdown

    return failures_markdown(summary)
