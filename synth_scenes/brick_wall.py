"""Running-bond brick walls, built in code: the stability benchmark's workload.

Courses alternate between whole bricks and a half-brick offset closed by half bricks,
so each brick rests on two below (one at the ends): a connected, statically indeterminate structure with
about 2 face contacts per brick, the same kind of problem compas_cra benchmarks.
"""

from __future__ import annotations

import numpy as np

from pipeline.model import Arrangement, Cuboid, ground

#: a standard brick, metres (length, depth, height)
BRICK = (0.215, 0.1025, 0.065)


def brick_wall(n_bricks: int, per_course: int | None = None, brick=BRICK) -> Arrangement:
    """A running-bond wall of about ``n_bricks`` bricks standing on the ground.

    Odd courses are shifted by half a brick; the wall is roughly square in bricks
    (``per_course`` about sqrt(3 n)) unless given.
    """
    L, D, H = brick
    per_course = per_course or max(2, int(round(np.sqrt(3 * n_bricks))))
    cuboids = []
    course = 0
    while len(cuboids) < n_bricks:
        if course % 2 == 0:
            starts, lengths = np.arange(per_course) * L, np.full(per_course, L)
        else:  # half bricks close both ends of the shifted courses, as masons lay them
            starts = np.concatenate([[0.0], L / 2 + np.arange(per_course - 1) * L,
                                     [per_course * L - L / 2]])
            lengths = np.concatenate([[L / 2], np.full(per_course - 1, L), [L / 2]])
        for x, length in zip(starts, lengths):
            if len(cuboids) >= n_bricks:
                break
            k = len(cuboids)
            cuboids.append(Cuboid(f"b{k}", np.array([x + length / 2, 0.0, course * H + H / 2]),
                                  np.eye(3), np.array([length, D, H]), object=f"brick{k}"))
        course += 1
    return Arrangement(tuple(cuboids), (ground(),))
