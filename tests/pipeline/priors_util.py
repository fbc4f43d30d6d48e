"""Running one prior (or a few, in order) alone as :func:`pipeline.imagine.imagine` runs
it in its stage, with the report of every proposal and the gate's verdict."""

from __future__ import annotations

import re

from pipeline.evidence import Evidence
from pipeline.priors import BY_NAME, Context, EditLog, ImagineConfig, run_stage


def evidence_of(views=None, margin: float = 0.0) -> Evidence:
    """An :class:`Evidence` from a list of depth views (or one already made)."""
    if isinstance(views, Evidence):
        return views
    return Evidence(tuple(views or ()), margin)


def run(names, arr, views=None, margin: float = 0.0, params=None, **ctx_fields):
    """Run the prior ``names`` (a name or a sequence, in that order) on ``arr``, each
    proposal through the gate; returns ``(arrangement, report)``.

    ``ctx_fields``: :class:`pipeline.priors.Context` fields (``initial``, ``edges``,
    ``mu``, ``threshold``, ``deadline``); ``params``: ``{prior: {field: value}}``."""
    if isinstance(names, str):
        names = (names,)
    evidence = evidence_of(views, margin)
    if "edges" in ctx_fields:
        ctx_fields["edges"] = tuple(ctx_fields["edges"])
    ctx = Context(**ctx_fields)
    config = ImagineConfig(params=dict(params or {}))
    report = EditLog()
    for name in names:
        arr = run_stage(BY_NAME[name].stage, arr, evidence, ctx, config, report, only=name)
    return arr, report


def changed(names, arr, views=None, margin: float = 0.0, **kw):
    """``(arrangement, ids its accepted edits changed or added)``: each id once, in order."""
    if isinstance(names, str):
        names = (names,)
    out, report = run(names, arr, views, margin, **kw)
    ids: list[str] = []
    for n in names:
        ids += [i for i in report.changed_by(n) if i not in ids]
    return out, ids


def assert_box(got, size, center) -> None:
    """``got`` has the ``size`` and ``center`` given (to 1e-9 m)."""
    import numpy as np

    np.testing.assert_allclose(got.size, size, atol=1e-9)
    np.testing.assert_allclose(got.center, center, atol=1e-9)


def accepted(report: EditLog, prior: str | None = None):
    """The accepted :class:`pipeline.imagine.EditRecord` s (of ``prior``)."""
    return [e for e in report.edits if e.accepted and (prior is None or e.prior == prior)]


def relax_fixed(final, **ctx_fields):
    """The ``relax_glue`` prior alone: ``(arrangement, joints tried, joints relaxed)`` (what
    the old ``relax_fixed`` returned).  A joint is tried when the prior takes up its group
    (one ``touching_group`` call each); relaxed, when the gate accepts its edit."""
    from unittest import mock

    import pipeline.priors.relax_glue as relax_glue

    with mock.patch.object(relax_glue, "touching_group",
                           wraps=relax_glue.touching_group) as spy:
        out, report = run("relax_glue", final, **ctx_fields)
    return out, spy.call_count, len(accepted(report, "relax_glue"))


def reason_pairs(report: EditLog, prior: str, pattern: re.Pattern, sep: str) -> list[str]:
    """``a<sep>b`` for each accepted edit of ``prior``, from the two ids ``pattern``
    reads in its reason (every reason must match)."""
    out = []
    for e in accepted(report, prior):
        m = pattern.match(e.reason)
        assert m is not None, e.reason
        out.append(f"{m.group(1)}{sep}{m.group(2)}")
    return out


_CLOSED = re.compile(r"^(\S+) and (\S+) \d+ mm apart where no view saw the gap: closed$")


def closed_pairs(report: EditLog) -> list[str]:
    """The ``a|b`` pairs the accepted ``close_gaps`` edits closed (``b`` may be a wall)."""
    return reason_pairs(report, "close_gaps", _CLOSED, "|")


_JOINED = re.compile(r"^(\S+) and (\S+), parts of one object, meet by a short extension$")


def joined_pairs(report: EditLog) -> list[str]:
    """``a+b`` for each pair of parts the accepted ``join_parts`` edits joined."""
    return reason_pairs(report, "join_parts", _JOINED, "+")
