"""What ``unseen run`` checks before any work: every option's range and the files it reads.

Shared by :mod:`eval.commands.run` (``--stage initial``) and :mod:`eval.run_full`; it
imports neither, so the two stay free of an import cycle.
"""

from __future__ import annotations

import argparse

from pipeline.errors import InputError

#: Accepted ranges of the numeric options (checked before any work).
CELL_RANGE = (1e-4, 0.1)
BUDGET_RANGE = (0.01, 86400.0)


def _finite(value, flag: str, lo: float, hi: float, what: str, lo_open: bool = False) -> None:
    import math

    if value is None:
        return
    ok = math.isfinite(value) and (value > lo if lo_open else value >= lo) and value <= hi
    if not ok:
        raise InputError(f"{flag}: {what}, got {value}")


#: The largest seed accepted (numpy takes any integer; a seed is recorded in JSON files,
#: whose integers other tools read as 64-bit).
SEED_MAX = 2**63 - 1


def check_seed(seed: int, flag: str = "--seed") -> None:
    """InputError unless ``seed`` is an integer in [0, :data:`SEED_MAX`]."""
    if not 0 <= seed <= SEED_MAX:
        raise InputError(f"{flag}: must be an integer from 0 to {SEED_MAX}, got {seed}")


def comma_list(text: str) -> tuple[str, ...]:
    """The items of a comma list (``--kinds chair, table``), stripped, each once, in order."""
    return tuple(dict.fromkeys(k.strip() for k in text.split(",") if k.strip()))


def _check_intrinsics(text: str | None) -> None:
    """``--intrinsics`` given as numbers: four finite ones, focal lengths positive (a
    .json file is read, and checked, with the scan)."""
    import math

    from pipeline.scan_io import intrinsic_numbers

    if text is None or text.strip().endswith(".json"):
        return
    vals = intrinsic_numbers(text)
    if vals is None or not all(math.isfinite(v) for v in vals) or min(vals[:2]) <= 0:
        raise InputError(f"--intrinsics {text!r}: expected fx,fy,cx,cy (4 finite numbers, "
                         "fx and fy > 0) or a .json file")


def check_frame_flags(args: argparse.Namespace) -> None:
    """The flags that read a frame (``--intrinsics``, ``--depth-scale``), for every command
    that takes them (``run``, ``edit``)."""
    _check_intrinsics(getattr(args, "intrinsics", None))
    _finite(getattr(args, "depth_scale", None), "--depth-scale", 0.0, 1e9,
            "must be a positive number of raw units per metre", lo_open=True)


def validate_args(args: argparse.Namespace) -> None:
    """Every option of ``unseen run`` checked before any work (one line, exit 2)."""
    from pipeline.constants import MU_RANGE
    from pipeline.outdir import check_out

    if not str(args.input).strip():
        raise InputError("INPUT: empty path; give a scene folder, an RGB-D folder or a cloud")
    check_seed(args.seed)
    check_frame_flags(args)
    _finite(getattr(args, "budget", None), "--budget", *BUDGET_RANGE,
            "must be a positive number of seconds up to a day", lo_open=True)
    _finite(getattr(args, "mu", None), "--mu", *MU_RANGE,
            f"must be a friction coefficient in [{MU_RANGE[0]:g}, {MU_RANGE[1]:g}]")
    _finite(args.cell, "--cell", *CELL_RANGE,
            f"voxel size as a fraction of the scene diameter, in [{CELL_RANGE[0]:g}, "
            f"{CELL_RANGE[1]:g}] (default 0.005)")
    _finite(args.max_depth, "--max-depth", 0.0, 1e4,
            "must be a positive distance in metres", lo_open=True)
    _finite(getattr(args, "scale", None), "--scale", 1e-6, 1e6,
            "must be metres per input unit in [1e-06, 1e+06] (0.001 for mm)")
    check_out(args.out, command="run")


def inputs(args: argparse.Namespace) -> list[str]:
    """Every file or folder the run reads (none may lie inside --out)."""
    return [v for v in (args.input, args.color, args.depth, args.instance, args.scribbles)
            if v]
