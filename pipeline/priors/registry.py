"""The registry of priors (:data:`PRIORS`, their order) and :class:`ImagineConfig`."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ..errors import InputError
from .anchor_parts import PRIOR as _anchor_parts
from .base import Prior
from .between import PRIOR as _between
from .boards import PRIOR as _boards
from .close_gaps import PRIOR as _close_gaps
from .copies import PRIOR as _copies
from .deepen import PRIOR as _deepen
from .from_below import PRIOR as _from_below
from .join_parts import PRIOR as _join_parts
from .mirror import PRIOR as _mirror
from .object_yaw import PRIOR as _object_yaw
from .overlaps import PRIOR as _overlaps
from .posts import PRIOR as _posts
from .reach import PRIOR as _reach
from .relax_glue import PRIOR as _relax_glue
from .rows import PRIOR as _rows
from .span import PRIOR as _span
from .support_yaw import PRIOR as _support_yaw
from .upright import PRIOR as _upright
from .yaw_fit import PRIOR as _yaw_fit

#: Every prior, in the order they run (stage by stage).
PRIORS: tuple[Prior, ...] = (
    _upright, _yaw_fit, _object_yaw, _support_yaw, _overlaps,
    _deepen, _join_parts, _span, _rows, _mirror, _copies, _boards, _between, _reach, _posts,
    _from_below, _relax_glue, _anchor_parts, _close_gaps)
BY_NAME: dict[str, Prior] = {p.name: p for p in PRIORS}
#: Shorthands accepted where priors are named: ``symmetry`` is both symmetry priors.
GROUPS: dict[str, tuple[str, ...]] = {"symmetry": ("mirror", "copies")}


def expand(names) -> frozenset[str]:
    """Prior names with the shorthands of :data:`GROUPS` expanded; an unknown name is an
    :class:`~pipeline.errors.InputError` listing the known ones."""
    out = set()
    for n in names:
        n = str(n).strip()
        if not n:
            continue
        if n in GROUPS:
            out |= set(GROUPS[n])
        elif n in BY_NAME:
            out.add(n)
        else:
            raise InputError(f"unknown prior {n!r}: one of {', '.join(BY_NAME)} "
                             f"(or {', '.join(GROUPS)})")
    return frozenset(out)


@dataclass(frozen=True)
class ImagineConfig:
    """How :func:`pipeline.imagine.imagine` runs.

    Attributes
    ----------
    budget : float
        Seconds for the search, the second search and the glue relaxation; the final
        refinement gets what is left, at least a tenth of it.
    mu : float
        Friction coefficient.
    threshold : float or None
        Stability threshold on the scale-free energy (None: the default, 1e-5).
    refine_steps : int
        Steps of the final refinement.
    disabled : frozenset of str
        Priors switched off (names of :data:`PRIORS`).
    params : mapping
        Prior name -> its ``Params`` (or a dict of fields to override).
    """

    budget: float = 10.0
    mu: float = 0.7
    threshold: float | None = None
    refine_steps: int = 20
    disabled: frozenset[str] = frozenset()
    params: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "disabled", expand(self.disabled))
        for name in self.params:
            if name not in BY_NAME:
                expand([name])  # raises, naming the known priors
                raise InputError(f"params: give a prior's name, not the group {name!r}")
            self.params_of(BY_NAME[name])  # a field it lacks raises here

    def enabled(self, name: str) -> bool:
        return name not in self.disabled

    def params_of(self, prior: Prior):
        """The parameters ``prior`` runs with."""
        p = self.params.get(prior.name)
        if p is None:
            return prior.params
        if isinstance(p, Mapping):
            try:
                return dataclasses.replace(prior.params, **p)
            except TypeError as exc:
                raise InputError(f"params of prior {prior.name}: {exc}") from None
        return p

    def without(self, *names: str) -> ImagineConfig:
        """This configuration with the priors ``names`` switched off as well."""
        return dataclasses.replace(self, disabled=self.disabled | expand(names))

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> ImagineConfig:
        """From JSON-able settings: ``{"disable": [...], "params": {prior: {field: v}},
        "budget": s, "mu": m, "threshold": t, "refine_steps": n}``."""
        d = dict(d or {})
        known = {"disable", "params", "budget", "mu", "threshold", "refine_steps"}
        extra = set(d) - known
        if extra:
            raise InputError(f"imagine config: unknown keys {sorted(extra)}; known: "
                             f"{sorted(known)}")
        kw: dict[str, Any] = {"disabled": frozenset(d.get("disable", ())),
                              "params": dict(d.get("params", {}))}
        for k in ("budget", "mu", "threshold", "refine_steps"):
            if k in d:
                kw[k] = d[k]
        return cls(**kw)

    def to_dict(self) -> dict:
        return {"disable": sorted(self.disabled), "budget": self.budget, "mu": self.mu,
                "threshold": self.threshold, "refine_steps": self.refine_steps,
                "params": {k: (dict(v) if isinstance(v, Mapping) else dataclasses.asdict(v))
                           for k, v in sorted(self.params.items())}}
