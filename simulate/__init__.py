"""Physics and rendering: importing this package prepares the process for headless MuJoCo.

``mujoco`` fixes its GL backend from ``MUJOCO_GL`` when it is first imported and cannot
switch later.  Importing :mod:`simulate` therefore chooses the backend
(:func:`headless_gl`) before any of its modules can import ``mujoco``, so every process
that runs our code renders without a display: a ``dask worker`` started with no
environment set, a spawned pool process, a user's own script.  A backend the user chose
is kept.
"""

from __future__ import annotations

import os


def headless_gl() -> str:
    """Set ``MUJOCO_GL`` (and PyOpenGL's platform) for offscreen rendering where unset.

    EGL by default; OSMesa when no EGL library can be found but OSMesa can.  Returns the
    backend in force.  It must run before ``import mujoco``; importing :mod:`simulate`
    runs it.
    """
    if "MUJOCO_GL" not in os.environ:
        import ctypes.util

        if ctypes.util.find_library("EGL") is None and ctypes.util.find_library("OSMesa"):
            os.environ["MUJOCO_GL"] = "osmesa"
        else:
            os.environ["MUJOCO_GL"] = "egl"
    if os.environ["MUJOCO_GL"] in ("egl", "osmesa"):
        os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])
    return os.environ["MUJOCO_GL"]


headless_gl()
