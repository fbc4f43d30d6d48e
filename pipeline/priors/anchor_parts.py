"""An object hung on a wall hangs there as a whole: its parts against the wall are fixed to it.

Evidence: the contacts the search chose (an object fixed to a wall) and the candidate
extensions to the wall.  Regularity: a wall shelf's board fixed to the wall is held with
its brackets; a bracket seen only at its front, its face toward the wall short of it by
at most its own extent there, is extended to the wall as its candidate put it, and every
part of the object against that wall is fixed to it, when the arrangement still stands.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..boxops import changed_boxes, pushed_to_extension
from ..contacts import find_contacts
from ..model import Contact
from .base import Edit, Prior, principle_of


@dataclass(frozen=True)
class Params:
    pass


def apply(arr, evidence, p: Params, ctx):
    final, initial = arr, ctx.initial
    objects = {c.id: c.object for c in final.cuboids}
    held: dict[str, set[str]] = {}
    for c in final.contacts:
        for a, b in ((c.a, c.b), (c.b, c.a)):
            if (c.type == "fixed" and b.startswith("wall:") and objects.get(a) is not None):
                held.setdefault(objects[a], set()).add(b)
    if not held:
        return
    reach = {}
    for e in ctx.edges:
        if isinstance(e.b, str) and e.b.startswith("wall:"):
            ext = [o for o in e.options if o.type == "fixed" and len(o.extensions) == 1]
            x = ext[0].extensions[0] if ext else None
            if x is not None and x.length <= float(initial.sizes[x.box, x.axis]):
                reach[(initial.cuboids[e.a].id, e.b)] = x
    for obj in sorted(held):
        for wall in sorted(held[obj]):
            for m in [c.id for c in final.cuboids if c.object == obj]:
                fixed = [c for c in final.contacts if c.type == "fixed"]
                if any({c.a, c.b} == {m, wall} for c in fixed):
                    continue
                touching = find_contacts(final).lookup()
                trial = final
                if tuple(sorted((m, wall))) not in touching:
                    if (m, wall) not in reach:
                        continue
                    trial = pushed_to_extension(final, initial, reach[(m, wall)])
                    cs = find_contacts(trial)
                    if (any(m in (a, b) for a, b, _ in cs.penetrations)
                            or tuple(sorted((m, wall))) not in cs.lookup()):
                        continue
                v = yield Edit(changed_boxes(trial, final),
                               f"{m}, a part of {obj} hung on {wall}, fixed to it",
                               fixed=(*fixed, Contact(m, wall, "fixed")))
                if v.ok:
                    final = v.arrangement


PRIOR = Prior("anchor_parts", "settle", Params(), apply, principle_of(__doc__))
