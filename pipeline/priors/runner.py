"""Running priors: each proposal through the gate, every verdict recorded.

:func:`run_stage` runs the enabled priors of one stage in their order; :class:`EditLog`
keeps an :class:`EditRecord` per proposal (which prior, which boxes, why, and the gate's
verdict).  :func:`pipeline.imagine.imagine` runs the stages; ``run_prior`` in
:mod:`pipeline.priors` runs one prior alone.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..evidence import Evidence
from ..model import Arrangement
from .base import Context
from .gate import accept
from .registry import BY_NAME, PRIORS, ImagineConfig


@dataclass(frozen=True)
class EditRecord:
    """One proposal of a prior and what the gate said of it."""

    prior: str
    stage: str
    boxes: tuple[str, ...]
    reason: str
    accepted: bool
    why_not: str = ""
    #: the (sorted) pairs the edit fixed that were not fixed before (not in ``to_json``)
    fixed: tuple[tuple[str, str], ...] = ()

    def to_json(self) -> dict:
        return {"prior": self.prior, "stage": self.stage, "boxes": list(self.boxes),
                "reason": self.reason, "accepted": self.accepted, "why_not": self.why_not}


@dataclass
class EditLog:
    """Every proposal of the priors that ran, and the ids of the boxes they added."""

    edits: list[EditRecord] = field(default_factory=list)
    added: list[str] = field(default_factory=list)  #: boxes the priors added

    def changed_by(self, prior: str) -> list[str]:
        """Ids of the boxes the accepted edits of ``prior`` changed or added (in order,
        each once)."""
        out: list[str] = []
        for e in self.edits:
            if e.accepted and e.prior == prior:
                out += [b for b in e.boxes if b not in out]
        return out

    @property
    def hallucinated(self) -> list[str]:
        """Boxes the priors added (no observed box): the copies of hidden parts."""
        return list(self.added)

    def counts(self) -> dict[str, tuple[int, int]]:
        """Prior -> (edits accepted, edits rejected)."""
        out: dict[str, list[int]] = {}
        for e in self.edits:
            n = out.setdefault(e.prior, [0, 0])
            n[0 if e.accepted else 1] += 1
        return {k: (v[0], v[1]) for k, v in out.items()}


def run_stage(stage: str, arr: Arrangement, evidence: Evidence, ctx: Context, config,
              report: EditLog, only: str | tuple[str, ...] | None = None) -> Arrangement:
    """Run the enabled priors of ``stage`` (or those named in ``only``) on ``arr``: each
    proposal through :func:`pipeline.priors.gate.accept`, recorded in ``report``;
    ``config`` is the :class:`pipeline.priors.ImagineConfig`."""
    if isinstance(only, str):
        only = (only,)
    for prior in PRIORS:
        if prior.stage != stage or not config.enabled(prior.name) or (
                only is not None and prior.name not in only):
            continue
        gen = prior.apply(arr, evidence, config.params_of(prior), ctx)
        verdict = None
        while True:
            try:
                edit = next(gen) if verdict is None else gen.send(verdict)
            except StopIteration:
                break
            verdict = accept(arr, edit, evidence, ctx, stage)
            new = [c.id for c in edit.boxes if c.id not in arr.index]
            fixed = () if edit.fixed is None else tuple(sorted(
                {c.key for c in edit.fixed if c.type == "fixed"} - arr.fixed_pairs()))
            report.edits.append(EditRecord(prior.name, stage, edit.ids, edit.reason,
                                           verdict.ok, verdict.reason, fixed))
            if verdict.ok:
                arr = verdict.arrangement
                report.added += [i for i in new if i not in report.added]
    return arr


def run_prior(name: str, arr, evidence=None, *, margin: float = 0.0, ctx: Context | None = None,
              params: Any = None, **ctx_fields) -> tuple[Any, list[str]]:
    """Run one prior alone on ``arr``, every proposal through the gate, as
    :func:`pipeline.imagine.imagine` runs it in its stage: returns the arrangement and the
    ids of the boxes its accepted edits changed or added (in order, each once).

    ``evidence`` is an :class:`~pipeline.evidence.Evidence`, a list of depth views (with
    ``margin``) or None; ``ctx`` or ``ctx_fields`` (``initial``, ``edges``, ``mu``,
    ``threshold``, ``deadline``) give a ``connect`` or ``settle`` prior what it needs;
    ``params`` overrides its parameters (its ``Params`` or a dict of fields)."""
    prior = BY_NAME[name]
    if evidence is None:
        evidence = Evidence()
    elif not isinstance(evidence, Evidence):
        evidence = Evidence(tuple(evidence), margin)
    ctx = ctx or Context(**ctx_fields)
    config = ImagineConfig(params={} if params is None else {name: params})
    report = EditLog()
    out = run_stage(prior.stage, arr, evidence, ctx, config, report, only=name)
    return out, report.changed_by(name)
