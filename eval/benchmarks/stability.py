"""Analytic stability check against the number of bodies: running-bond brick walls.

Times ``check_stability`` (contacts + equilibrium; median of several runs) for about
100, 300 and 900 bricks, with the default ``auto`` backend (load-path certificate,
then NNLS / Clarabel) and with the global Clarabel QP forced.  When ``compas_cra``
(PyPI 0.8.0; ``make bench`` installs it) is importable, its RBE solver (``rbe_solve``,
IPOPT) runs on the same walls and the ratio is reported.
"""

from __future__ import annotations

import time

from . import BenchTable, median_time

TITLE = "Stability check vs bodies (running-bond brick walls)"


def _compas_rbe(arr) -> tuple[float, float] | None:
    """(interfaces seconds, rbe_solve seconds) of compas_cra on the same wall, or None."""
    try:
        from compas.geometry import Box, Frame
        from compas_assembly.datastructures import Block
        from compas_cra.algorithms import assembly_interfaces_numpy
        from compas_cra.datastructures import CRA_Assembly
        from compas_cra.equilibrium import rbe_solve
    except ImportError:
        return None
    import contextlib
    import io

    a = CRA_Assembly()
    lo, hi = arr.centers.min(axis=0), arr.centers.max(axis=0)
    span = float(hi[0] - lo[0]) + 1.0
    a.add_block(Block.from_shape(Box(span, 1.0, 0.1, Frame([float(lo[0] + hi[0]) / 2, 0, -0.05],
                                                             [1, 0, 0], [0, 1, 0]))), node=0)
    for k, c in enumerate(arr.cuboids):
        a.add_block(Block.from_shape(Box(*map(float, c.size), Frame(list(map(float, c.center)),
                                                                    [1, 0, 0], [0, 1, 0]))),
                    node=k + 1)
    a.set_boundary_conditions([0])
    with contextlib.redirect_stdout(io.StringIO()):  # compas_cra prints as it goes
        t = time.perf_counter()
        assembly_interfaces_numpy(a, nmax=10, amin=1e-4, tmax=1e-4)
        t_if = time.perf_counter() - t
        t = time.perf_counter()
        rbe_solve(a, mu=0.7, density=1000.0)
        t_rbe = time.perf_counter() - t
    return t_if, t_rbe


def run(quick: bool) -> list[BenchTable]:
    from pipeline.stability import check_stability
    from synth_scenes.brick_wall import brick_wall

    sizes = (100, 300) if quick else (100, 300, 900)
    repeats = 3 if quick else 7
    rows, auto_series, qp_series, cra_series = [], [], [], []
    for n in sizes:
        arr = brick_wall(n)
        res = check_stability(arr)
        t_auto = median_time(lambda a=arr: check_stability(a), repeats)
        t_qp = median_time(lambda a=arr: check_stability(a, backend="qp"),
                           max(1, repeats // 2) if n > 300 else repeats)
        # compas_cra needs minutes beyond 300 bricks on 2 cores: it runs up to there
        cra = None if n > (100 if quick else 300) else _compas_rbe(arr)
        row = [n, res.n_contacts, "stable" if res.stable else "UNSTABLE", res.backend,
               t_auto * 1000, t_qp * 1000]
        if cra is None:
            row += ["-", "-"]
        else:
            row += [cra[1] * 1000, f"{cra[1] / t_auto:.0f}x"]
            cra_series.append((n, cra[1]))
        rows.append(row)
        auto_series.append((n, t_auto))
        qp_series.append((n, t_qp))
    series = {"unseen auto": auto_series, "unseen Clarabel QP": qp_series}
    if cra_series:
        series["compas_cra rbe_solve"] = cra_series
    note = ("Medians of repeated runs, contacts included.  Targets on 2 cores: 100 bricks "
            "< 50 ms, 900 bricks < 1 s.  compas_cra columns are empty unless it is installed "
            "(`make bench` installs compas-cra 0.8.0); its time excludes its interface detection; it is not run on the 900-brick wall.")
    return [BenchTable(TITLE, ["bricks", "contacts", "verdict", "backend used", "auto [ms]",
                               "Clarabel QP [ms]", "compas_cra RBE [ms]", "compas_cra / auto"],
                       rows, note, series)]
