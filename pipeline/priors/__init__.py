"""The priors: what a single noisy view cannot show, added by stated principles.

Each module here is one prior (:class:`pipeline.priors.base.Prior`): its docstring states
the principle (the evidence it reads, the physics or regularity it assumes), its
``Params`` dataclass the parameters with units, and its ``apply`` proposes edits that
:func:`pipeline.priors.gate.accept` judges.  :data:`PRIORS` is the order
:func:`pipeline.imagine.imagine` runs them in; :class:`ImagineConfig` switches each on or
off and sets its parameters.
"""

from __future__ import annotations

from .base import STAGES, Context, Edit, Prior, Verdict
from .gate import accept
from .registry import BY_NAME, GROUPS, PRIORS, ImagineConfig, expand
from .runner import EditLog, EditRecord, run_prior, run_stage

__all__ = ["run_prior", "run_stage", "PRIORS", "BY_NAME", "GROUPS", "STAGES", "Prior", "Edit",
           "Verdict", "Context", "ImagineConfig", "EditLog", "EditRecord", "accept", "expand"]
