"""Bench section: settle time against the number of boxes in MuJoCo and PyBullet, and the
analytic check's time on the same arrangements (the ratio analytic : engine)."""

from __future__ import annotations

import numpy as np

from eval.benchmarks import BenchTable, median_time

TITLE = "Physics engines: settle time vs number of boxes"


def towers(n_boxes: int, size: float = 0.1, height: int = 5) -> object:
    """``n_boxes`` cubes of edge ``size`` in towers of up to ``height`` on a grid (stable)."""
    from pipeline.model import Arrangement, Contact, box, ground

    cubes, contacts = [], []
    n_towers = -(-n_boxes // height)
    side = int(np.ceil(np.sqrt(n_towers)))
    for i in range(n_boxes):
        t, level = divmod(i, height)
        x, y = (t % side) * 2.5 * size, (t // side) * 2.5 * size
        cubes.append(box(f"t{t}_{level}", (x, y, size * (level + 0.5)), (size, size, size)))
        contacts.append(Contact(cubes[-1].id, "ground" if level == 0 else f"t{t}_{level - 1}"))
    return Arrangement(tuple(cubes), (ground(),), tuple(contacts))


def run(quick: bool) -> list[BenchTable]:
    from pipeline.stability import check_stability
    from simulate.engines import default_duration, settle

    sizes = [1, 5, 10] if quick else [1, 5, 10, 20, 40]
    repeats = 1 if quick else 3
    rows, series = [], {"mujoco": [], "pybullet": [], "analytic": []}
    for n in sizes:
        arr = towers(n)
        t_an = median_time(lambda a=arr: check_stability(a), repeats=repeats)
        t_mj = median_time(lambda a=arr: settle(a, "mujoco"), repeats=repeats)
        t_pb = median_time(lambda a=arr: settle(a, "pybullet"), repeats=repeats)
        series["mujoco"].append((n, t_mj))
        series["pybullet"].append((n, t_pb))
        series["analytic"].append((n, t_an))
        rows.append([n, default_duration(arr), t_mj, t_pb, t_an, t_mj / t_an, t_pb / t_an])
    table = BenchTable(
        "Settle time (s) vs number of boxes (towers of 10 cm cubes, up to 5 high)",
        ["boxes", "simulated s", "MuJoCo s", "PyBullet s", "analytic s", "MuJoCo : analytic",
         "PyBullet : analytic"], rows,
        note=f"Median of {repeats} run(s) after a warm-up; load + simulate + judge.",
        series=series)

    # the same on random arrangements of the agreement study
    from synth_scenes.random_arrangements import random_arrangement

    rng = np.random.default_rng(0)
    arrs = [random_arrangement(rng) for _ in range(8 if quick else 40)]
    t = {"analytic": [], "mujoco": [], "pybullet": []}
    for a in arrs:
        t["analytic"].append(median_time(lambda a=a: check_stability(a), repeats=1, warmup=0))
        t["mujoco"].append(median_time(lambda a=a: settle(a, "mujoco"), repeats=1, warmup=0))
        t["pybullet"].append(median_time(lambda a=a: settle(a, "pybullet"), repeats=1,
                                         warmup=0))
    tot = {k: float(np.sum(v)) for k, v in t.items()}
    rand = BenchTable(
        f"Random arrangements of the agreement study ({len(arrs)}, 1-7 boxes)",
        ["check", "total s", "mean s", "max s", "time : analytic"],
        [[k, tot[k], tot[k] / len(arrs), float(np.max(t[k])), tot[k] / tot["analytic"]]
         for k in ("analytic", "mujoco", "pybullet")])
    return [table, rand]
