"""A part of a grounded object that hangs from one other part by glue stands on the floor.

Evidence: the contacts the search chose, each part's observed height, the candidate
extensions to the floor.  Regularity: glue between parts of one object costs the search
nothing, so a part whose bottom the sensor never saw (a sofa's arm seen from behind as
its top; a table's leg seen only at its top) hangs from the part it is fused to rather
than reaching the floor.  A part of an object with a grounded part, not on the floor
itself and fused to exactly one other part, whose drop to the floor is more than
``drop_rel`` times its seen height and ``min_drop``, is extended down as its candidate
put it, when it then touches the floor and the arrangement still stands.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..boxops import changed_boxes, pushed_to_extension, up_axis
from ..contacts import find_contacts
from .base import Edit, Prior, principle_of


@dataclass(frozen=True)
class Params:
    drop_rel: float = 1.5  #: the drop, in seen heights of the part
    min_drop: float = 0.15  #: metres


def apply(arr, evidence, p: Params, ctx):
    final, initial = arr, ctx.initial
    grounded = {c.a for c in final.contacts if c.b == "ground"} | \
        {c.b for c in final.contacts if c.a == "ground"}
    objects = {final.cuboid(g).object for g in grounded
               if g in final.index and final.cuboid(g).object is not None}
    if not objects:
        return
    reach = {}
    for e in ctx.edges:
        if e.b == "ground":
            ext = [o for o in e.options if o.type == "touch" and len(o.extensions) == 1]
            if ext:
                reach[initial.cuboids[e.a].id] = ext[0].extensions[0]
    for c in list(final.cuboids):
        if (c.object not in objects or c.id in grounded or c.id not in reach
                or c.extra.get("hallucinated")):
            continue
        # hanging from one part (an arm from the back, a leg from the top), not
        # spanning between several (a shelf's bottom board between its sides)
        glued = {k.b if k.a == c.id else k.a for k in final.contacts
                 if k.type == "fixed" and c.id in (k.a, k.b)}
        if len(glued) != 1:
            continue
        # ... a drop the sensor could not have seen the part's bottom across
        drop = float(reach[c.id].length)
        seen = c.observed.size if c.observed is not None else c.size
        height = float(seen[up_axis(c)])
        if drop < max(p.min_drop, p.drop_rel * height):
            continue
        trial = pushed_to_extension(final, initial, reach[c.id])
        cs = find_contacts(trial)
        if tuple(sorted((c.id, "ground"))) not in cs.lookup():
            continue
        fixed = [k for k in final.contacts if k.type == "fixed"]
        v = yield Edit(changed_boxes(trial, final),
                       f"{c.id} hangs by glue {100 * drop:.0f} cm above the floor, "
                       f"seen {100 * height:.0f} cm tall: extended to it", fixed=tuple(fixed))
        if v.ok:
            final = v.arrangement


PRIOR = Prior("ground_parts", "settle", Params(), apply, principle_of(__doc__))
