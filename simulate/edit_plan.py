"""Planning an image edit: what moves with what, and whether the edit is allowed.

Section 6 (iii) of the paper: an object of a stable arrangement is moved or removed.  An
object moves with everything it *carries*: the objects resting on it (a contact whose
normal, pointing from the lower object into the upper one, is within 45 degrees of up),
transitively, and those ``fixed`` to it.  An object merely *leaning* on it (a side
contact) is not carried: it stays, and the stability check decides whether it still
stands.  A ``fixed`` contact of a moved object with the ground (or a wall it slides along)
stays fixed: whatever hidden cause the search glued it for travels with the object.  The
move is a translation along the floor.  It is refused, with a one-line reason, when the
moved group would enter another box or a wall beyond the contact tolerance, when nothing
is under it at its new place, when a carried object also rests on something that stays,
or when any body that stood before no longer stands (analytic statics,
:func:`pipeline.stability.check_stability`).  A removed object takes what it carries with
it, under the same checks.

The image itself is edited by :func:`simulate.edit.edit_image` from the :class:`EditPlan`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pipeline.model import Arrangement, Contact, Cuboid, is_support_id

#: Cosine of the largest angle from up of a contact normal that makes one object rest on
#: another (45 degrees): a box on a table top carries, a box against its side does not.
CARRY_MIN_NZ = float(np.cos(np.radians(45.0)))


@dataclass(frozen=True)
class Operation:
    """One edit: ``move`` an object by (dx, dy) metres along the floor, or ``remove`` it."""

    kind: str
    object: str
    dx: float = 0.0
    dy: float = 0.0

    def describe(self) -> str:
        if self.kind == "remove":
            return f"remove {self.object}"
        return f"move {self.object} by ({self.dx:+.3f}, {self.dy:+.3f}) m"


@dataclass(frozen=True)
class GroupEdit:
    """What one operation did: the object, what it carried, the cuboids and the offset."""

    operation: Operation
    objects: tuple[str, ...]  #: the object first, then what it carries
    cuboids: tuple[str, ...]
    offset: np.ndarray  #: (3,) metres (zero for a removal)


@dataclass(frozen=True)
class EditPlan:
    """The outcome of :func:`plan_edit`: the edited arrangement, or why it was refused.

    ``moved`` maps each moved cuboid id to its (3,) offset; ``removed`` lists removed ids.
    ``refusal`` is None when every operation is legal; ``checks`` lists what was checked.
    """

    before: Arrangement
    after: Arrangement
    groups: tuple[GroupEdit, ...]
    refusal: str | None = None
    checks: tuple[str, ...] = ()
    moved: dict = field(default_factory=dict)
    removed: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        return self.refusal is None

    @property
    def gone(self) -> tuple[str, ...]:
        """Cuboid ids whose old pixels are deleted (moved or removed)."""
        return tuple(self.moved) + tuple(self.removed)


def object_of(c: Cuboid) -> str:
    """The object a cuboid belongs to (its own id when it names none)."""
    return c.object if c.object else c.id


def object_names(arr: Arrangement) -> list[str]:
    """Object names in the order of their first cuboid."""
    return list(dict.fromkeys(object_of(c) for c in arr.cuboids))


def support_graph(arr: Arrangement, contacts=None, min_nz: float = CARRY_MIN_NZ
                  ) -> tuple[dict[str, set[str]], dict[str, set[str]]]:
    """Who rests on whom, and who is fixed to whom, between objects.

    Parameters
    ----------
    arr : Arrangement
    contacts : ContactSet, optional
        Its contacts (found from the geometry when omitted).
    min_nz : float
        An object rests on another when a contact normal from the other into it has
        ``n_z >= min_nz``.

    Returns
    -------
    under : {object: set of objects or support ids it rests on}
    fixed : {object: set of objects or support ids it is ``fixed`` to}
    """
    from pipeline.contacts import find_contacts

    cs = find_contacts(arr) if contacts is None else contacts
    K = len(arr.cuboids)
    obj = [object_of(c) for c in arr.cuboids]
    node = obj + list(cs.names[K:])
    under: dict[str, set[str]] = {o: set() for o in obj}
    fixed: dict[str, set[str]] = {o: set() for o in obj}
    nz = cs.normal[:, 2] if cs.count else np.zeros(0)
    for m, (a, b) in enumerate(zip(cs.a.tolist(), cs.b.tolist())):
        if node[a] == node[b]:
            continue
        if nz[m] >= min_nz:           # the normal points from b into a: a rests on b
            under[node[a]].add(node[b])
        elif nz[m] <= -min_nz and b < K:
            under[node[b]].add(node[a])
    idx = arr.index
    for c in arr.contacts:
        if c.type != "fixed":
            continue
        na = obj[idx[c.a]] if c.a in idx else c.a
        nb = obj[idx[c.b]] if c.b in idx else c.b
        if na != nb:
            for x, y in ((na, nb), (nb, na)):
                if x in fixed:
                    fixed[x].add(y)
    return under, fixed


def carried_set(arr: Arrangement, name: str, contacts=None) -> tuple[list[str], str | None]:
    """The object ``name`` and everything it carries, transitively.

    Carried: an object resting on a carried one (:func:`support_graph`), or ``fixed`` to
    one (a fused contact makes one rigid body).  Glue to the ground or a wall does not
    carry (it stays only while the object still touches that support).

    Returns
    -------
    objects : list of str
        ``name`` first, then the carried objects in order of discovery.
    conflict : str or None
        Why the group cannot move alone: a carried object that also rests on something
        that stays.
    """
    under, fixed = support_graph(arr, contacts)
    group, todo = [name], [name]
    while todo:
        cur = todo.pop(0)
        for o in under:
            if o in group:
                continue
            if cur in under[o] or cur in fixed[o]:
                group.append(o)
                todo.append(o)
    members = set(group)
    for o in group[1:]:
        others = sorted(x for x in under[o] if x not in members)
        if others:
            return group, (f"{o} rests on {', '.join(sorted(under[o] & members))} and on "
                           f"{', '.join(others)}: it cannot go with {name} alone")
    return group, None


def _kept_contacts(arr: Arrangement, ids: set[str], moved: set[str],
                   touching: set | None = None) -> tuple[Contact, ...]:
    """The listed ``fixed`` contacts that survive: both ends kept, and both moved or both
    staying; a moved cuboid's glue to the ground or a wall survives when the pair still
    touches after the move (``touching``: sorted id pairs that do).  Touch contacts are
    found again from the geometry."""
    out = []
    for c in arr.contacts:
        if c.type != "fixed":
            continue
        ends = [x for x in (c.a, c.b) if not is_support_id(x)]
        if any(x not in ids for x in ends):
            continue
        if (c.a in moved) == (c.b in moved) or (
                touching is not None and len(ends) == 1 and c.key in touching):
            out.append(c)
    return tuple(out)


def _with_touches(arr: Arrangement) -> Arrangement:
    """``arr`` with its listed contacts: the fixed ones kept, every touching pair as touch."""
    from pipeline.contacts import find_contacts

    cs = find_contacts(arr)
    fixed = {c.key for c in arr.contacts}
    touches = [Contact(a, b, "touch") for a, b in cs.pairs
               if ((a, b) if a <= b else (b, a)) not in fixed]
    return arr.with_(contacts=tuple(arr.contacts) + tuple(touches))


def _cm(x: float) -> str:
    return f"{100 * x:.1f} cm"


def plan_edit(arr: Arrangement, operations: list[Operation] | tuple[Operation, ...],
              mu: float | None = None, contacts=None, stability=None) -> EditPlan:
    """Apply ``operations`` in order to ``arr`` if each is legal (see the module docstring).

    Parameters
    ----------
    arr : Arrangement
        The scan's result (world frame z up, supports ``ground`` / ``wall:k``).
    operations : sequence of Operation
    mu : float, optional
        Friction for the stability check (default ``arr.meta["mu"]`` or 0.7).
    contacts, stability : optional
        ``find_contacts(arr)`` and ``check_stability(arr, mu)`` when the caller has them
        (many plans on one arrangement).

    Returns
    -------
    EditPlan
        ``refusal`` says, in one line, why the first illegal operation is refused.
    """
    from pipeline.contacts import find_contacts
    from pipeline.stability import check_stability

    mu = float(arr.meta.get("mu", 0.7)) if mu is None else float(mu)
    cur = arr
    groups: list[GroupEdit] = []
    checks: list[str] = []
    offsets: dict[str, np.ndarray] = {}
    removed: list[str] = []
    first = {c.id: c for c in arr.cuboids}
    cs = find_contacts(cur) if contacts is None else contacts
    stab = check_stability(cur, mu=mu, contacts=cs) if stability is None else stability

    def refuse(msg: str) -> EditPlan:
        return EditPlan(arr, cur, tuple(groups), msg, tuple(checks), offsets, tuple(removed))

    for op in operations:
        names = object_names(cur)
        if op.object not in names:
            gone = f" ({op.object} was removed or moved with another object)" \
                if op.object in object_names(arr) else ""
            return refuse(f"unknown object {op.object!r}{gone}; objects: {', '.join(names)}")
        group, conflict = carried_set(cur, op.object, cs)
        if conflict:
            return refuse(f"cannot {op.describe()}: {conflict}")
        members = set(group)
        ids = [c.id for c in cur.cuboids if object_of(c) in members]
        idset = set(ids)
        carried = f" with {', '.join(group[1:])}" if len(group) > 1 else ""
        if op.kind == "remove":
            offset = np.zeros(3)
            keep = [c for c in cur.cuboids if c.id not in idset]
            after = cur.with_(cuboids=tuple(keep),
                              contacts=_kept_contacts(cur, {c.id for c in keep}, set()))
        elif op.kind == "move":
            offset = np.array([op.dx, op.dy, 0.0], float)
            if not np.all(np.isfinite(offset)) or np.abs(offset).max() > 1e3:
                return refuse(f"cannot {op.describe()}: the offset must be finite metres")
            new = [c.with_(center=c.center + offset) if c.id in idset else c
                   for c in cur.cuboids]
            after = cur.with_(cuboids=tuple(new),
                              contacts=_kept_contacts(cur, set(cur.ids), idset))
        else:
            raise ValueError(f"operation kind must be 'move' or 'remove', got {op.kind!r}")
        cs_after = find_contacts(after)
        if op.kind == "move":  # glue to the floor (or a wall it slides along) goes with it
            after = after.with_(contacts=_kept_contacts(cur, set(cur.ids), idset,
                                                        set(cs_after.lookup())))
        obj_of = {c.id: object_of(c) for c in cur.cuboids}
        if op.kind == "move":
            before_pen = {(a, b) if a <= b else (b, a) for a, b, _ in cs.penetrations}
            new_pen = [(a, b, d) for a, b, d in cs_after.penetrations
                       if ((a in idset) != (b in idset))
                       and ((a, b) if a <= b else (b, a)) not in before_pen]
            if new_pen:
                a, b, d = max(new_pen, key=lambda p: p[2])
                mover, other = (a, b) if a in idset else (b, a)
                what = obj_of.get(other, other)
                return refuse(f"cannot {op.describe()}: {obj_of[mover]} would enter {what} "
                              f"by {_cm(d)}")
            checks.append(f"{op.describe()}: enters nothing")
            # something outside the group must hold it up at its new place
            under_after, _ = support_graph(after, cs_after)
            holders = set().union(*(under_after[o] for o in group)) - members
            if not holders:
                low = min(float(after.cuboid(i).corners()[:, 2].min()) for i in ids)
                floor = next((float(s.point[2]) for s in after.supports if s.id == "ground"),
                             None)
                hang = f" (its bottom would hang {_cm(low - floor)} above the floor)" \
                    if floor is not None else ""
                return refuse(f"cannot {op.describe()}: nothing under {op.object} at its new "
                              f"place{hang}")
            checks.append(f"{op.describe()}: rests on {', '.join(sorted(holders))}")
        stab_after = check_stability(after, mu=mu, contacts=cs_after)
        was = {b.id: b.stable for b in stab.bodies}
        falls = [b.id for b in stab_after.bodies if not b.stable and was.get(b.id, False)]
        if falls:
            fo = list(dict.fromkeys(obj_of.get(i, i) for i in falls))
            moving = [o for o in fo if o in members]
            if moving:
                return refuse(f"cannot {op.describe()}: {', '.join(moving)} would not stand "
                              "at its new place")
            return refuse(f"cannot {op.describe()}: {', '.join(fo)} would no longer stand "
                          f"once {op.object}{carried} {'is gone' if op.kind == 'remove' else 'moves'}")
        checks.append(f"{op.describe()}: every body that stood still stands")
        groups.append(GroupEdit(op, tuple(group), tuple(ids), offset))
        if op.kind == "remove":
            removed.extend(ids)  # deleted where they first were, moved before or not
            for i in ids:
                offsets.pop(i, None)
        else:
            for i in ids:
                offsets[i] = after.cuboid(i).center - first[i].center
        cur, cs, stab = after, cs_after, stab_after
    cur = _with_touches(cur)
    return EditPlan(arr, cur, tuple(groups), None, tuple(checks), offsets, tuple(removed))


__all__ = ["CARRY_MIN_NZ", "Operation", "GroupEdit", "EditPlan", "object_of", "object_names",
           "support_graph", "carried_set", "plan_edit"]
