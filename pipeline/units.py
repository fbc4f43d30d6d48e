"""The units step at the input: make a scan metric before anything else reads it.

Every constant of the method is in metres (RANSAC thresholds, clustering radii, noise
models, contact tolerances), so a cloud written in millimetres, or a model scaled to a
matchbox, would silently give nonsense ("0 cuboids, stable").  This step looks at the
extent of the scan (the diagonal of the box holding the 2nd-98th percentile of its
points) and decides once:

- ``--scale S`` given: every coordinate is multiplied by S (the input's unit in metres:
  0.001 for millimetres);
- extent within :data:`PLAUSIBLE_EXTENT` (an indoor scan, 0.2 m to 50 m): kept as is;
- otherwise, a bare point cloud (no camera, no depth image) is rescaled by the power of
  ten that brings its extent into [1, 10) m (a factor within :data:`SCALE_RANGE`, as
  ``--scale`` must be; beyond it the cloud is refused), and the report says so; a scan with a depth
  image is refused, naming ``--depth-scale`` and ``--scale``, because its depth encoding
  is the likelier mistake.

The factor applied is recorded as ``meta["input_scale"]`` (metres per input unit, 1.0
when nothing was changed) and the arrangement is written in metres as the format says:
``p_output = input_scale * p_input`` in the input's frame (before ``meta.camera_pose``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .errors import InputError
from .scan_io import ScanInput

#: Extent (metres) of a plausible indoor scan: a shelf seen from 20 cm to a hall of 50 m.
PLAUSIBLE_EXTENT = (0.2, 50.0)
#: Accepted explicit ``--scale`` factors.
SCALE_RANGE = (1e-6, 1e6)
#: Extents below this (metres, after scaling) hold no geometry at all.
MIN_EXTENT = 1e-9


def extent(points: np.ndarray) -> float:
    """Diagonal of the 2nd-98th percentile box of ``points (n, 3)`` (robust to outliers)."""
    lo, hi = np.percentile(points, [2, 98], axis=0)
    return float(np.linalg.norm(hi - lo))


def _scaled(scan: ScanInput, s: float) -> ScanInput:
    views = tuple(_scaled(v, s) for v in scan.views)
    T = None
    if scan.T_world_cam is not None:
        T = np.array(scan.T_world_cam, float)
        T[:3, 3] *= s
    return replace(scan, points=scan.points * s,
                   depth=None if scan.depth is None else scan.depth * s,
                   T_world_cam=T, views=views)


def to_metres(scan: ScanInput, scale: float | None = None) -> tuple[ScanInput, float, str | None]:
    """The scan in metres, the factor applied, and a note for the report (None if none).

    Parameters
    ----------
    scan : ScanInput
    scale : float, optional
        Metres per input unit (``--scale``); None decides from the extent.

    Raises
    ------
    InputError
        Points that coincide, an implausible extent of a scan with a depth image, or a
        ``scale`` outside :data:`SCALE_RANGE`.
    """
    src = scan.source or "input"
    if scale is not None:
        if not (np.isfinite(scale) and SCALE_RANGE[0] <= scale <= SCALE_RANGE[1]):
            raise InputError(f"--scale {scale}: must be a number in [{SCALE_RANGE[0]:g}, "
                             f"{SCALE_RANGE[1]:g}] (metres per input unit, 0.001 for mm)")
    ext = extent(scan.points) if len(scan.points) else 0.0
    if not ext * (scale or 1.0) > MIN_EXTENT:
        raise InputError(f"{src}: all {len(scan.points)} points coincide (extent "
                         f"{ext:.3g}); a scene needs points spread in space")
    if scale is not None:
        if scale == 1.0:
            return scan, 1.0, None
        return _scaled(scan, scale), float(scale), \
            f"input scaled by {scale:g} (--scale) to metres; extent {ext * scale:.3g} m"
    if PLAUSIBLE_EXTENT[0] <= ext <= PLAUSIBLE_EXTENT[1]:
        return scan, 1.0, None
    has_camera = scan.depth is not None or scan.T_world_cam is not None or bool(scan.views)
    if has_camera:
        raise InputError(f"{src}: the scan is {ext:.3g} m across, not an indoor scene "
                         f"({PLAUSIBLE_EXTENT[0]:g}-{PLAUSIBLE_EXTENT[1]:g} m); check "
                         "--depth-scale, or give --scale (metres per unit) to accept it")
    s = float(10.0 ** -np.floor(np.log10(ext)))
    if not SCALE_RANGE[0] <= s <= SCALE_RANGE[1]:
        raise InputError(f"{src}: the cloud is {ext:.3g} units across; no unit from "
                         f"{SCALE_RANGE[0]:g} to {SCALE_RANGE[1]:g} m makes it an indoor "
                         f"scene ({PLAUSIBLE_EXTENT[0]:g}-{PLAUSIBLE_EXTENT[1]:g} m); check "
                         "how the file was written")
    return _scaled(scan, s), s, (f"the cloud is {ext:.3g} units across, not {PLAUSIBLE_EXTENT[0]:g}-"
                                 f"{PLAUSIBLE_EXTENT[1]:g} m: scaled by {s:g} to metres "
                                 "(--scale 1 keeps it as it is)")
