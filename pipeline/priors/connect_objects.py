"""An object is one connected rigid body: parts the search left apart are joined.

Evidence: the segmentation's objects and the candidate extensions between their parts.
Regularity: a table's leg reaches its top even when it could stand alone.  For each
object whose parts fall into several rigid groups (through ``fixed`` contacts), the
cheapest candidate extension between two groups is applied (the face pushed to where the
candidate put it) with the pair fused, when the arrangement still stands.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..boxops import changed_boxes, fixed_components, pushed_to_extension
from ..model import Contact
from .base import Edit, Prior, principle_of


@dataclass(frozen=True)
class Params:
    pass


def apply(arr, evidence, p: Params, ctx):
    final, initial = arr, ctx.initial
    for obj in sorted({c.object for c in final.cuboids if c.object is not None}):
        members = [c.id for c in final.cuboids if c.object == obj]
        if len(members) < 2:
            continue
        for _ in range(len(members)):
            comp = fixed_components(members, final.contacts)
            if len(set(comp.values())) < 2:
                break
            options = []
            for e in ctx.edges:
                if not e.same_object or isinstance(e.b, str):
                    continue
                a, b = initial.cuboids[e.a].id, initial.cuboids[e.b].id
                if a not in comp or b not in comp or comp[a] == comp[b]:
                    continue
                for o in e.options:
                    if o.type == "fixed" and o.extensions:
                        options.append((o.volume, a, b, o))
            joined = False
            for _vol, a, b, o in sorted(options, key=lambda t: t[0]):
                trial = final
                for x in o.extensions:
                    trial = pushed_to_extension(trial, initial, x)
                fixed = [c for c in trial.contacts if c.type == "fixed"]
                fixed.append(Contact(a, b, "fixed"))
                v = yield Edit(changed_boxes(trial, final),
                               f"{a} and {b}, parts of {obj}, joined by their candidate "
                               f"extension", fixed=tuple(fixed))
                if v.ok:
                    final, joined = v.arrangement, True
                    break
            if not joined:
                break


PRIOR = Prior("connect_objects", "connect", Params(), apply, principle_of(__doc__))
