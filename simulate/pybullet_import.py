"""Import ``pybullet`` without its ``pybullet build time: ...`` banner.

PyBullet's C extension prints that line on standard output when it is first imported,
below Python's ``sys.stdout``, so a command's output (``unseen check --json``) would
start with it.  :func:`pybullet` imports the module with file descriptors 1 and 2
pointed at ``/dev/null`` for the duration of the import only.
"""

from __future__ import annotations

import os
import sys


def pybullet():
    """The ``pybullet`` module, imported once, silently."""
    if "pybullet" in sys.modules:
        return sys.modules["pybullet"]
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    saved = [os.dup(1), os.dup(2)]
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 1)
        os.dup2(null, 2)
        import pybullet as p
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, null):
            os.close(fd)
    return p
