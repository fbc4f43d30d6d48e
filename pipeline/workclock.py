"""The imagining's time budget, counted in work done rather than on the wall clock.

A budget in wall-clock seconds ends a search wherever the machine's load happens to
put it, so one scan run twice could give two results (Table 1's room-1001 gave 55.1 to
55.9 typed F1 over three runs of the same code).  The budget is therefore counted on a
work clock: each stability check and each contact evaluation advances it by a fixed
cost per box of the arrangement it looks at, whatever time it really takes.  The same
input then ends its search at the same point on any machine and under any load.

The costs are set from this project's reference machine (2 cores, shared): a stability
check 0.5 ms per box, a contact evaluation 0.06 ms per box, between what they took there
in Table 1's longest search (room-1001: about 0.75 and 0.1) and in the search benchmark's
rooms (0.12-0.46 and 0.02-0.03; cached equilibria make many checks cheap).  A budget of
``budget`` seconds so stops a search after about half to twice as much wall time on that
machine (room-1001 spends its 10 s in about 15 s); on a faster machine it takes less
time, on a slower one more, and the answer is the same.

The clock is kept per context (:mod:`contextvars`): each thread and each process
counts its own work, and :func:`fresh` starts it at zero for one call (an ``imagine``),
so the sums it compares with its deadlines do not depend on the work done before it
(floating-point sums of the same charges from another start could round differently);
``search`` called alone does the same (``fresh`` also decorates).
"""

from __future__ import annotations

import contextlib
import contextvars

#: Work-clock seconds one stability check charges per box of its arrangement.
STABILITY_COST_PER_BOX = 5e-4
#: Work-clock seconds one contact evaluation charges per box of its arrangement.
CONTACTS_COST_PER_BOX = 6e-5

_spent: contextvars.ContextVar[float] = contextvars.ContextVar("unseen_work_spent", default=0.0)
_inside: contextvars.ContextVar[bool] = contextvars.ContextVar("unseen_work_fresh", default=False)


@contextlib.contextmanager
def fresh():
    """Run the block on a work clock started at zero, then put the outer one back with
    the block's work added; inside another ``fresh`` block it only runs the block."""
    if _inside.get():
        yield
        return
    inside, spent = _inside.set(True), _spent.set(0.0)
    try:
        yield
    finally:
        work = _spent.get()
        _spent.reset(spent)
        _inside.reset(inside)
        charge(work)


def now() -> float:
    """Work-clock seconds spent so far in this context (only differences mean anything)."""
    return _spent.get()


def charge(seconds: float) -> None:
    """Advance this context's work clock by ``seconds``."""
    _spent.set(_spent.get() + float(seconds))


def charge_stability(n_boxes: int) -> None:
    """Charge one stability check of an arrangement of ``n_boxes`` boxes."""
    charge(STABILITY_COST_PER_BOX * max(int(n_boxes), 1))


def charge_contacts(n_boxes: int) -> None:
    """Charge one contact evaluation of an arrangement of ``n_boxes`` boxes."""
    charge(CONTACTS_COST_PER_BOX * max(int(n_boxes), 1))


__all__ = ["now", "fresh", "charge", "charge_stability", "charge_contacts",
           "STABILITY_COST_PER_BOX", "CONTACTS_COST_PER_BOX"]
