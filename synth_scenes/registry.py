"""Registry of scene families: name -> ``make_<family>(rng, **opts) -> Arrangement``.

``FAMILIES`` maps each name to its function and the options it accepts, so the
command line can pass ``--n-boxes``/``--n-objects`` only where they mean something.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from pipeline.errors import InputError
from pipeline.model import Arrangement

from . import families as f
from .demo import make_demo

#: name -> (function, accepted option names)
FAMILIES: dict[str, tuple[Callable[..., Arrangement], tuple[str, ...]]] = {
    "stack": (f.make_stack, ("n_boxes", "variant")),
    "counterweight": (f.make_counterweight, ("proportions",)),
    "bridge": (f.make_bridge, ("proportions",)),
    "table": (f.make_table, ("n_items", "style", "proportions")),
    "chair": (f.make_chair, ("arms", "proportions")),
    "shelf": (f.make_shelf, ("proportions",)),
    "wall_shelf": (f.make_wall_shelf, ("proportions",)),
    "desk": (f.make_desk, ("proportions",)),
    "sofa": (f.make_sofa, ("arms", "proportions")),
    "room": (f.make_room, ("n_objects", "min_cuboids", "max_cuboids")),
    "demo": (make_demo, ()),
}


#: The options of :func:`make` that ``unseen synth`` offers as flags (``--n-boxes``, ...).
SIZE_OPTIONS = ("n_boxes", "n_objects")


def family_names() -> tuple[str, ...]:
    return tuple(FAMILIES)


def make(name: str, rng: np.random.Generator, **opts) -> Arrangement:
    """Build one (unvalidated) scene of family ``name``; ``None`` options are dropped.

    Raises
    ------
    InputError
        Unknown family, or an option the family does not take.
    """
    if name not in FAMILIES:
        raise InputError(f"unknown scene family {name!r}; choose one of: {', '.join(FAMILIES)}")
    fn, accepted = FAMILIES[name]
    given = {k: v for k, v in opts.items() if v is not None}
    bad = sorted(set(given) - set(accepted))
    if bad:
        names = ", ".join("--" + k.replace("_", "-") for k in bad)
        flags = [f"--{k.replace('_', '-')}" for k in accepted if k in SIZE_OPTIONS]
        raise InputError(f"{names}: not an option of family {name!r}"
                         + (f" (it takes {', '.join(flags)})" if flags
                            else " (it takes no size option)"))
    try:
        return fn(rng, **given)
    except ValueError as exc:
        raise InputError(f"family {name!r}: {exc}") from None
