"""The ``unseen`` command line: a thin, lazily-importing layer over the four packages.

Each subcommand lives in ``eval/commands/<name>.py`` with two functions:
``add_arguments(parser)`` and ``run(args) -> int``.  Only the chosen subcommand's
module is imported, so ``unseen --help`` stays instant.  Bad input (an
:class:`~pipeline.errors.InputError`) becomes one line on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import importlib
import os
import re
import sys

#: name -> (module, one-line help, example)
COMMANDS: dict[str, tuple[str, str, str]] = {
    "demo": ("eval.commands.demo", "synthesize a default occluded scene, scan it, run, check, score",
             "unseen demo --out demo_out"),
    "run": ("eval.commands.run", "scan (RGB-D folder, scene dir, .ply/.pcd) -> stable arrangement",
            "unseen run scene_dir --out result"),
    "check": ("eval.commands.check", "is an arrangement stable? analytic statics and/or engines",
              "unseen check arrangement.json --engine all --json"),
    "export": ("eval.commands.export", "write MJCF, URDF and glTF for an arrangement",
               "unseen export arrangement.json --out exported"),
    "synth": ("eval.commands.synth", "synthesize a scene with ground truth and scan it",
              "unseen synth table --out scenes/table0 --seed 0"),
    "score": ("eval.commands.score", "score a predicted arrangement against ground truth",
              "unseen score result/arrangement.json scenes/table0 --json"),
    "eval": ("eval.commands.evaluate", "run an experiment suite (the paper's tables)",
             "unseen eval table1 --out results/table1 --workers 2"),
    "bench": ("eval.commands.bench", "performance benchmarks, printed as a table",
              "unseen bench --out bench_out"),
    "dataset": ("eval.commands.dataset", "make a benchmark dataset: many scenes, splits, manifest",
                "unseen dataset make --out data --families all --n 200 --workers 2"),
    "import": ("eval.commands.import_", "an MJCF or URDF of boxes -> arrangement.json",
               "unseen import scene.xml --out arrangement.json"),
    "regress": ("eval.commands.regress", "record the results of your own scans, verify them later",
                "unseen regress verify my_scans --junit regress.xml"),
    "complete": ("eval.commands.complete", "complete a partial scan from a good scan of the same kind",
                 "unseen complete partial_scan --template good_scan --out completed"),
    "models": ("eval.commands.models", "make a repository of furniture meshes for retrieval",
               "unseen models make --out models"),
    "retrieve": ("eval.commands.retrieve", "place a repository model on each object of a result",
                 "unseen retrieve result --models models --out retrieved"),
    "edit": ("eval.commands.edit", "move or remove an object in the original colour image",
             "unseen edit scan result --move table0 0.3 0 --out edited"),
}


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr (exit 2), not usage + error,
    and that reads a negative number in any float spelling (``-1e-3``, ``-.5``) as a value:
    argparse's own pattern knows only ``-1`` and ``-1.5`` and takes ``-1e-3`` for an
    option (``--move box0 0 -1e-3``)."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?$")

    def error(self, message: str):  # noqa: D401 - argparse's signature
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())} "
                     f"(see {self.prog} --help)\n")


def _top_parser() -> argparse.ArgumentParser:
    width = max(map(len, COMMANDS)) + 2
    lines = [f"  {name:<{width}}{help_}" for name, (_, help_, _) in COMMANDS.items()]
    examples = [f"  {ex}" for (_, _, ex) in COMMANDS.values()]
    return argparse.ArgumentParser(
        prog="unseen",
        description="Imagine what a depth sensor could not see: physically stable cuboid "
                    "arrangements from partial RGB-D scans, cross-checked in MuJoCo and PyBullet.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="commands:\n" + "\n".join(lines) + "\n\nexamples:\n" + "\n".join(examples)
               + "\n\n'unseen COMMAND --help' for a command's options.",
    )


def _dash_values(parser: argparse.ArgumentParser, argv: list[str]) -> list[str]:
    """``argv`` with each option of one value followed by a value that starts with a dash
    joined to it (``--up -y`` -> ``--up=-y``): argparse takes ``-y`` or ``-0.1,-1,0`` for
    an option and says the option expected one argument.  A token that starts with two
    dashes or is one of the parser's own options (``--out --json``, ``--out -h``: the
    value forgotten) is left to argparse."""
    one = {s for a in parser._actions if isinstance(a, argparse._StoreAction) and a.nargs is None
           for s in a.option_strings}
    known = set(parser._option_string_actions)
    out: list[str] = []
    k = 0
    while k < len(argv):
        t = argv[k]
        if (t in one and k + 1 < len(argv) and argv[k + 1].startswith("-")
                and not argv[k + 1].startswith("--") and argv[k + 1] not in known):
            out.append(f"{t}={argv[k + 1]}")
            k += 2
            continue
        out.append(t)
        k += 1
    return out


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    top = _top_parser()
    top.add_argument("command", choices=sorted(COMMANDS), metavar="COMMAND",
                     help="one of: " + ", ".join(COMMANDS))
    top.add_argument("--version", action="version", version=_version())
    if not argv:  # nothing asked: the overview, and the exit code of a usage error
        top.print_help()
        return 2
    if argv[0] in ("-h", "--help", "--version"):
        top.parse_args(argv[:1])
        return 0
    if argv[0] not in COMMANDS:
        print(f"unseen: error: unknown command {argv[0]!r}; one of {', '.join(COMMANDS)} "
              "(see unseen --help)", file=sys.stderr)
        return 2
    name = argv[0]
    # headless rendering: MuJoCo picks its GL backend when first imported
    os.environ.setdefault("MUJOCO_GL", "egl")
    module_name, help_, example = COMMANDS[name]
    module = importlib.import_module(module_name)
    parser = OneLineParser(
        prog=f"unseen {name}", description=help_[0].upper() + help_[1:] + ".",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=f"example:\n  {example}" + (("\n\n" + module.EPILOG) if hasattr(module, "EPILOG") else ""),
    )
    module.add_arguments(parser)
    args = parser.parse_args(_dash_values(parser, argv[1:]))
    from pipeline.errors import InputError

    try:
        return int(module.run(args) or 0)
    except InputError as exc:
        print(f"unseen {name}: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    except OSError as exc:  # the file system refused (read-only, full, gone): say where
        where = f" {exc.filename}" if exc.filename else ""
        print(f"unseen {name}: error: cannot write or read{where}: "
              f"{exc.strerror or exc.__class__.__name__}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"unseen {name}: interrupted", file=sys.stderr)
        return 130


def _version() -> str:
    try:
        from importlib.metadata import version

        return f"unseen {version('unseen')}"
    except Exception:  # noqa: BLE001 - not installed: still answer
        return "unseen (not installed)"


if __name__ == "__main__":
    sys.exit(main())
