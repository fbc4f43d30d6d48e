"""The contract every prior keeps: a name, a stage, frozen parameters, proposals.

A prior reads the arrangement and the evidence and *proposes* edits; it applies none
itself.  :func:`pipeline.priors.gate.accept` judges each proposal against the
arrangement as it stands when it is made, and the prior hears the verdict, so a prior
whose later proposals depend on its earlier ones (a row of joins, each on the boxes the
last one left) is written as a generator::

    def apply(arr, evidence, params, ctx):
        for ...:
            verdict = yield Edit(boxes=(grown,), reason="...")
            if verdict.ok:
                arr = verdict.arrangement

Stages, in the order :func:`pipeline.imagine.imagine` runs them:

* ``prepare``: corrections of the fit itself (orientation, overlaps), before anything is
  added;
* ``complete``: volume added where the sensor could not see, before the candidates;
* ``settle``: after the search, on the arrangement with its contact graph and verdict:
  glue relaxed, parts anchored and grounded, supports added, gaps closed.
"""

from __future__ import annotations

from collections.abc import Callable, Generator
from dataclasses import dataclass, field
from typing import Any

from ..model import Arrangement, Contact, Cuboid

STAGES = ("prepare", "complete", "settle")


@dataclass(frozen=True)
class Edit:
    """One proposed change of an arrangement.

    Attributes
    ----------
    boxes : tuple of Cuboid
        The new versions of existing cuboids (same id) and new cuboids (new id).
    reason : str
        One line: why the prior proposes it (the evidence, in numbers).
    removed : tuple of str
        Ids of cuboids the edit takes away (merged into one of ``boxes``).
    fixed : tuple of Contact or None
        After the search: the ``fixed`` contacts the edited arrangement lists (None:
        the current ones).
    prior : str
        Filled in by the orchestrator.
    """

    boxes: tuple[Cuboid, ...] = ()
    reason: str = ""
    removed: tuple[str, ...] = ()
    fixed: tuple[Contact, ...] | None = None
    prior: str = ""

    @property
    def ids(self) -> tuple[str, ...]:
        return tuple(c.id for c in self.boxes)


@dataclass(frozen=True)
class Verdict:
    """What :func:`pipeline.priors.gate.accept` says of an :class:`Edit`.

    ``arrangement`` is the arrangement after the edit when ``ok``, the one before
    otherwise; ``reason`` says why not (``""`` when ok)."""

    ok: bool
    arrangement: Arrangement
    reason: str = ""


@dataclass(frozen=True)
class Context:
    """What a ``settle`` prior needs besides the arrangement and the evidence: the
    searched boxes before extension (``initial``), their candidate edges, the friction
    coefficient, the stability threshold and a deadline (a :func:`pipeline.workclock.now` value)."""

    initial: Arrangement | None = None
    edges: tuple = ()
    mu: float = 0.7
    threshold: float | None = None
    deadline: float = float("inf")
    #: boxes the search could not hold with every candidate fixed (for ``posts``)
    unheld: tuple[str, ...] = ()
    memo: dict = field(default_factory=dict, repr=False, compare=False)  #: the gate's


Proposals = Generator[Edit, Verdict, None]


@dataclass(frozen=True)
class Prior:
    """A prior: ``apply(arrangement, evidence, params, ctx)`` yields :class:`Edit` s.

    ``principle`` is the module docstring's first paragraph: the evidence it reads and
    the physics or regularity it assumes."""

    name: str
    stage: str
    params: Any  #: the frozen dataclass of its parameters, at their defaults
    apply: Callable[..., Proposals]
    principle: str = field(default="", repr=False)

    def __post_init__(self) -> None:
        if self.stage not in STAGES:
            raise ValueError(f"prior {self.name}: unknown stage {self.stage!r}")


def principle_of(doc: str | None) -> str:
    """The first paragraph of a docstring, on one line."""
    return " ".join((doc or "").strip().split("\n\n")[0].split())
