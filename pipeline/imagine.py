"""Imagining the unseen: initial cuboids -> a stable, typed arrangement (sections 4.2-4.3).

:func:`imagine` is the orchestrator.  It runs, in order:

1. the ``prepare`` priors (orientation and overlaps of the fit) and the ``complete``
   priors (volume where the sensor could not see), :data:`pipeline.priors.PRIORS`;
2. the paper's *candidates* (:mod:`pipeline.extend`), pruned by interpenetration and by
   what the views saw empty, and its *branch and bound* (:mod:`pipeline.search`): fewest
   fixed contacts, then least added volume, standing with gravity tilted by 2 degrees.
   Boxes nothing can hold up get a second search in which their candidates are judged
   by whether the view saw through the added volume as a whole (the median of its
   samples), not by the share of samples seen through: that share also counts the
   mixed depths along a silhouette, and the slab between a box's bottom and the floor
   a few centimetres below is mostly silhouette.  Gravity is certain; a support the
   view cannot rule out beats a box left hanging.  Boxes still not held reach over what
   is under them (the ``reach`` prior) or get a post each (``posts``) where the view
   allows, and a third search.  Each search
   again is kept only when fewer boxes fall.  Boxes still not held (their support was
   never seen) are set aside and the rest searched again (:data:`ISOLATE_ROUNDS`);
3. the set-aside boxes come back, then the ``settle`` priors (loads leaning on walls
   carried from below, glue relaxed, parts anchored to walls, gaps closed) on an
   arrangement with a contact graph and a verdict;
4. the paper's *refinement* (:mod:`pipeline.refine`) when the result still carries
   residual energy above a hundredth of the threshold, and the *closing* of contact gaps
   the statics counted as touching (:func:`pipeline.snap.close_gaps`: what the engines
   load is what the statics judged).

Every edit a prior proposes passes :func:`pipeline.priors.gate.accept`; the report
records each (prior, boxes, reason, verdict).  ``config.budget`` seconds bound the search,
the second search and the glue relaxation (whatever is found by then is kept); the final
refinement gets what is left, at least a tenth of it.  The seconds are the work clock's
(:mod:`pipeline.workclock`: stability checks and contact evaluations counted at a fixed
cost each), so the result depends only on the input, within the budget or past it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from . import workclock
from .constants import ENERGY_THRESHOLD
from .contacts import find_contacts
from .evidence import Evidence
from .extend import candidate_edges, prune_by_visibility
from .model import Arrangement, Cuboid, ObservedBox
from .priors import Context, Edit, ImagineConfig
from .priors.runner import EditLog, EditRecord, run_stage
from .refine import refine
from .search import falling, finalize, search
from .snap import close_gaps

#: Rounds of setting aside boxes that nothing can hold up and searching the rest again.
ISOLATE_ROUNDS = 3


@dataclass
class ImagineReport(EditLog):
    """What :func:`imagine` did: every proposal and its verdict (:class:`EditLog`), the
    search's statistics, the verdict of the result and timings per step (seconds)."""

    disabled: tuple[str, ...] = ()
    candidate_edges: int = 0
    candidate_options: int = 0
    rejected_by_visibility: int = 0
    visibility: str = ""
    search: dict = field(default_factory=dict)
    fixed_chosen: int = 0
    added_volume_m3: float = 0.0
    set_aside: list[str] = field(default_factory=list)
    judged_whole: list[str] = field(default_factory=list)
    gap_closed_m: float = 0.0
    refine: dict | None = None
    cuboids: int = 0
    stable: bool = False
    energy: float = float("nan")
    unstable: list[str] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)

    def to_json(self) -> dict:
        return {"edits": [e.to_json() for e in self.edits], "disabled": list(self.disabled),
                "candidate_edges": self.candidate_edges,
                "candidate_options": self.candidate_options,
                "rejected_by_visibility": self.rejected_by_visibility,
                "visibility": self.visibility, "search": self.search,
                "fixed_chosen": self.fixed_chosen, "added_volume_m3": self.added_volume_m3,
                "set_aside": self.set_aside, "judged_whole": self.judged_whole,
                "gap_closed_m": self.gap_closed_m,
                "refine": self.refine, "cuboids": self.cuboids, "stable": self.stable,
                "energy": self.energy, "unstable": self.unstable, "added": self.added,
                "timings": self.timings}


@dataclass(frozen=True)
class ImagineResult:
    arrangement: Arrangement
    initial: Arrangement  #: after the prepare and complete priors, before extension
    report: ImagineReport


def _stable(arr: Arrangement) -> bool:
    return arr.stability is not None and arr.stability.stable


def _search_again(arr: Arrangement, edges, n_falling: int, t0: float,
                  config: ImagineConfig):
    """A search of ``arr`` with wider candidates ``edges`` and the boxes that fall in its
    result, when fewer than ``n_falling`` do (None otherwise, or when less than a tenth
    of the budget is left)."""
    left = config.budget - (workclock.now() - t0)
    if left < 0.1 * config.budget:
        return None
    again = search(arr, edges, budget=left, mu=config.mu, threshold=config.threshold)
    fall = falling(again.arrangement, config.mu, config.threshold)
    return (again, fall) if len(fall) < n_falling else None


@workclock.fresh()  # a work clock of its own, started at zero
def imagine(arr: Arrangement, evidence: Evidence | None = None,
            config: ImagineConfig | None = None, *, progress=None) -> ImagineResult:
    """Extend the initial cuboids of ``arr`` into a stable arrangement (module docstring),
    on a work clock of its own that starts at zero (:func:`pipeline.workclock.fresh`)."""
    config = config or ImagineConfig()
    evidence = evidence if evidence is not None else Evidence()
    budget, mu, threshold = config.budget, config.mu, config.threshold
    report = ImagineReport(disabled=tuple(sorted(config.disabled)))
    timings = report.timings
    t = time.perf_counter()
    t0 = workclock.now()  # the budget is counted in work (pipeline.workclock)
    arr = arr.with_(contacts=(), stability=None)
    # keep the observed box of every cuboid (before any change)
    arr = arr.with_(cuboids=tuple(
        c if c.observed is not None else c.with_(observed=ObservedBox(c.center, c.size))
        for c in arr.cuboids))
    ctx = Context(mu=mu, threshold=threshold, deadline=t0 + budget)
    arr = run_stage("prepare", arr, evidence, ctx, config, report)
    timings["prepare"] = time.perf_counter() - t

    t = time.perf_counter()
    evidence = evidence.scaled_to(arr)
    arr = run_stage("complete", arr, evidence, ctx, config, report)
    timings["complete"] = time.perf_counter() - t

    t = time.perf_counter()
    eyes = [v.eye for v in evidence.views]
    unpruned = candidate_edges(arr, eyes=eyes)
    report.candidate_options = sum(len(e.options) for e in unpruned)
    seen: dict = {}  # visibility verdicts of the extensions, shared with the second search
    edges, report.rejected_by_visibility = prune_by_visibility(
        arr, unpruned, list(evidence.views), evidence.margin, cache=seen)
    timings["candidates"] = time.perf_counter() - t

    t = time.perf_counter()
    result = search(arr, edges, budget=budget, mu=mu, threshold=threshold, progress=progress)
    fall = falling(result.arrangement, mu, threshold)
    unheld = tuple(result.unstable_ids) or fall
    if unheld and evidence.views:
        # boxes nothing can hold: their candidates judged by the whole-slab test alone
        whole = frozenset(arr.index[b] for b in unheld if b in arr.index)
        wider, _ = prune_by_visibility(arr, unpruned, list(evidence.views),
                                       evidence.margin, whole_only=whole, cache=seen)
        if sum(len(e.options) for e in wider) > sum(len(e.options) for e in edges):
            again = _search_again(arr, wider, len(fall), t0, config)
            if again is not None:
                (result, fall), edges = again, wider
                after = tuple(result.unstable_ids) or fall
                report.judged_whole = sorted(set(unheld) - set(after))
                unheld = after
    if unheld and (config.enabled("reach") or config.enabled("posts")):
        # ... and those still not held reach over what is under them, or get a post each,
        # where the view allows
        n_edits, n_added = len(report.edits), len(report.added)
        posted = run_stage("complete", arr, evidence,
                           Context(mu=mu, threshold=threshold, deadline=t0 + budget,
                                   unheld=unheld), config, report, only=("reach", "posts"))
        if posted is not arr:  # run_stage returns ``arr`` itself when it accepted nothing
            whole = frozenset(posted.index[b] for b in report.added[n_added:] + list(unheld)
                              if b in posted.index)
            wider, _ = prune_by_visibility(posted, candidate_edges(posted, eyes=eyes),
                                           list(evidence.views), evidence.margin,
                                           whole_only=whole)
            again = _search_again(posted, wider, len(fall), t0, config)
            if again is not None:
                arr, edges, result = posted, wider, again[0]
            else:  # they hold nothing: the result does not carry them
                del report.edits[n_edits:], report.added[n_added:]
    # boxes nothing can hold up (their support was never seen) are set aside and the rest
    # searched again: glue cannot save them, and gluing their whole group would only hide
    # the contacts the rest of the scene does have
    prepared, full = arr, (arr, edges, result)
    aside: list[Cuboid] = []
    for _ in range(ISOLATE_ROUNDS):
        bad = set(result.unstable_ids)
        if result.stable or not bad or len(bad) >= len(arr.cuboids):
            break
        aside += [c for c in arr.cuboids if c.id in bad]
        arr = arr.with_(cuboids=tuple(c for c in arr.cuboids if c.id not in bad))
        edges, _ = prune_by_visibility(arr, candidate_edges(arr, eyes=eyes),
                                       list(evidence.views), evidence.margin)
        left = budget - (workclock.now() - t0)
        if left < 0.1 * budget:  # no time for another search: keep the best effort
            break
        result = search(arr, edges, budget=left, mu=mu, threshold=threshold)

    final = result.arrangement
    if aside:  # the set-aside boxes come back, unless an extension grew into one
        with_aside = final.with_(cuboids=final.cuboids + tuple(aside), stability=None)
        ids = {c.id for c in aside}
        if any(a in ids or b in ids for a, b, _ in find_contacts(with_aside).penetrations):
            arr, edges, result = full
            aside, final = [], full[2].arrangement
        else:
            final = finalize(with_aside, [c for c in final.contacts if c.type == "fixed"],
                             mu=mu, threshold=threshold)
    ctx = Context(arr, tuple(edges), mu, threshold, t0 + budget)
    timings["search"] = time.perf_counter() - t

    t = time.perf_counter()
    final = run_stage("settle", final, evidence, ctx, config, report)
    timings["settle"] = time.perf_counter() - t

    t = time.perf_counter()
    if final.stability is not None and final.stability.energy > (
            ENERGY_THRESHOLD if threshold is None else threshold) / 100:
        refined = refine(final, mu=mu, max_steps=config.refine_steps, threshold=threshold,
                         deadline=max(t0 + budget, workclock.now() + 0.1 * budget))
        fixed = [c for c in refined.arrangement.contacts if c.type == "fixed"]
        final = finalize(refined.arrangement, fixed, mu=mu, threshold=threshold)
        report.refine = {"energy_before": refined.energy_before,
                         "energy_after": refined.energy_after, "steps": refined.steps,
                         "evaluations": refined.evaluations}
    timings["refine"] = time.perf_counter() - t

    # the faces the statics counted as touching are made to touch (the engines see the
    # file's geometry: a gap within the contact tolerance is a drop, an overlap a push)
    t = time.perf_counter()
    closed, gap_closed = close_gaps(final)
    if closed is not final:
        closed = finalize(closed, [c for c in final.contacts if c.type == "fixed"], mu=mu,
                          threshold=threshold)
        if _stable(closed) or not _stable(final):
            final = closed
        else:
            gap_closed = 0.0
    timings["close"] = time.perf_counter() - t

    if final.stability is not None and not final.stability.stable:
        from .stability import check_stability

        report.unstable = list(check_stability(final, mu=mu, threshold=threshold).unstable_ids)
    final = final.with_(meta={**final.meta, "stage": "full"})
    report.cuboids = len(final.cuboids)
    report.candidate_edges = len(edges)
    report.visibility = ("depth image" if evidence else
                         "skipped (no camera: a bare point cloud)")
    report.search = result.stats.to_json()
    report.fixed_chosen = result.n_fixed
    report.added_volume_m3 = result.added_volume
    report.set_aside = [c.id for c in aside]
    report.gap_closed_m = gap_closed
    report.stable = _stable(final)
    report.energy = float(final.stability.energy) if final.stability else float("nan")
    return ImagineResult(final, prepared, report)


__all__ = ["imagine", "ImagineResult", "ImagineReport", "EditRecord", "ImagineConfig",
           "run_stage", "Edit"]
