"""Choosing contact types and extensions: branch and bound (paper section 4.2, Algorithm 1).

Every candidate edge (a pair of cuboids, or a cuboid and a support, see
:mod:`pipeline.extend`) takes exactly one of its options.  A choice is feasible when no
boxes interpenetrate and the arrangement is stable (:mod:`pipeline.stability`); among
feasible choices we minimise, lexicographically, the number of ``fixed`` contacts, then
the number of pieces the objects fall into, then the number of parts of one object a
short extension could join but that are left apart, then the added volume.  Edges
between two parts of the same object are fused where they touch (their ``fixed`` costs
nothing: the segmentation says they are one rigid object): they choose between staying
apart and an extension that joins them, and join when a short extension can
(:data:`SHORT_JOIN`: a shelf's boards all meet its side panel, not only the one the
statics needs; a desk's two side panels stay apart rather than grow into one).

Branch and bound
----------------
The root sets every edge to its most supportive option (``fixed``, with the smallest
extension that does not interpenetrate).  Turning a ``fixed`` into ``touch`` or none can
only remove support, so when a node is unstable with its undecided edges still fixed, no
completion of it can be stable: the whole subtree is pruned.  Edges are decided one at a
time in a fixed order (the most expensive first), each trying its options cheapest
first, so the first leaf reached is a greedy solution and later leaves only replace it
when strictly cheaper; a node whose decided edges already cost as much as the best leaf
is cut.  A greedy solution comes first (:meth:`_Group.greedy`: relax fixed to touch
keeping extensions, then shed volume; then single-edge moves to cheaper options, joins
swapped and glue moved along a chain of contacts), so the bound prunes hard from the
start; groups of up to ``EXACT_MAX_EDGES`` edges are then searched exhaustively within
the budget.  When the siblings step (:meth:`_Group.siblings`) gives hanging parts their
siblings' support, single-edge moves to cheaper options are tried once more, keeping
what that step would give back (a chair's back the greedy left stretched to the floor
while two legs hung is released once all four legs stand).  Independent groups (cuboids
that no edge connects) are searched separately, stability results are cached per
assignment, and contact geometry per set of extensions (type changes reuse it).

Evaluating a node reuses the work of earlier nodes exactly: its contacts are updated from
the closest recent geometry (only pairs with a box whose extensions differ are recomputed,
:func:`pipeline.contacts.update_contacts`); the equilibrium is solved per independent
component of free bodies, and a component whose sub-problem (matrix blocks and right-hand
side, digested) was solved at an earlier node, or under another tilt, takes that solution
from the group's cache (``check_stability(solve_cache=...)``), so a node that changes one
edge re-solves only the components its boxes belong to.  A node in which some box touches
nothing is unstable without a solve (that box's body has no contact force to carry its
weight).  The search has a budget on the work clock (:mod:`pipeline.workclock`: the same
input stops at the same point on any machine) and returns the best arrangement found;
when even the root is unstable (a support was missed), the root is returned, marked
unstable, with the boxes that move.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np

from . import workclock
from .boxops import same_column
from .contacts import (
    ContactSet,
    changed_cuboids,
    find_contacts,
    pair_tolerance,
    sat_separation,
    update_contacts,
)
from .errors import InputError
from .extend import Edge, Option, apart, apply_offsets, offsets_of
from .model import Arrangement, Contact, StabilitySummary
from .stability import check_stability

log = logging.getLogger(__name__)

#: Groups with at most this many edges are searched exhaustively (within the budget);
#: larger ones get a greedy dive followed by single-edge improvements and join swaps.
EXACT_MAX_EDGES = 10
#: The search accepts an arrangement only if it also stands with gravity tilted by this
#: many degrees (see ``check_stability(tilt_deg=...)``): no knife-edge explanations.
ROBUST_TILT_DEG = 2.0
#: Contacts of a new geometry are updated from the closest of this many recent ones.
RECENT_BASES = 8


@dataclass
class SearchStats:
    """Counters of one search (all groups)."""

    groups: int = 0
    edges: int = 0
    nodes: int = 0
    leaves: int = 0
    pruned_unstable: int = 0
    pruned_bound: int = 0
    pruned_penetration: int = 0
    stability_checks: int = 0
    cache_hits: int = 0
    contact_evaluations: int = 0
    seconds: float = 0.0
    budget_spent: bool = False
    unstable_groups: int = 0

    def to_json(self) -> dict:
        return dict(self.__dict__)


@dataclass(frozen=True)
class SearchResult:
    arrangement: Arrangement  #: final geometry, typed contacts, stability summary
    stable: bool
    n_fixed: int  #: fixed contacts chosen by the search (same-object fusions not counted)
    added_volume: float  #: m^3
    unstable_ids: tuple[str, ...]
    stats: SearchStats
    choices: dict = field(default_factory=dict)  #: edge (a, b) -> option type chosen


def _edge_name(arr: Arrangement, e: Edge) -> tuple[str, str]:
    b = e.b if isinstance(e.b, str) else arr.cuboids[e.b].id
    return arr.cuboids[e.a].id, b


#: Parts of one object that a join reaches with extensions of at most this fraction of
#: the extended box's extent along them (a board a few centimetres short of its side
#: panel) should be joined; leaving them apart costs more than any added volume.
SHORT_JOIN = 0.25


def short_join(arr: Arrangement, o: Option) -> bool:
    """Whether ``o`` is a join (``fixed``) whose extensions are all short
    (:data:`SHORT_JOIN` of the extended box's extent along them)."""
    return o.type == "fixed" and all(
        x.length <= SHORT_JOIN * float(arr.sizes[x.box, x.axis]) for x in o.extensions)


def _short_join(arr: Arrangement, e: Edge, links: dict[int, set[int]] | None = None
                ) -> bool:
    """Whether same-object edge ``e`` has a short join (with ``links``, one that does
    not run along a part touching both, :func:`along_link`)."""
    return e.same_object and any(
        short_join(arr, o) and not (links and along_link(arr, o.extensions, links, e.a, e.b))
        for o in e.options)


def touching_links(edges: list[Edge]) -> dict[int, set[int]]:
    """Box index -> the boxes of its object it touches (the touching same-object edges)."""
    links: dict[int, set[int]] = {}
    for e in edges:
        if e.same_object and e.touching and not isinstance(e.b, str):
            links.setdefault(e.a, set()).add(e.b)
            links.setdefault(e.b, set()).add(e.a)
    return links


def along_link(arr: Arrangement, extensions, links: dict[int, set[int]], a: int,
                b: int) -> bool:
    """Whether the space an extension adds touches a part that touches both ``a`` and
    ``b`` (``links``: who touches whom): a join grown alongside the part that already
    joins the two (a screen, deepened to its neck, grown down beside it onto the foot
    the neck stands on) would be a second joint parallel to it."""
    third = (links.get(a, set()) & links.get(b, set())) - {a, b}
    if not third:
        return False
    for x in extensions:
        c = arr.cuboids[x.box]
        u = c.rotation[:, x.axis] * (1.0 if x.side else -1.0)
        size = c.size.copy()
        size[x.axis] = x.length
        slab = c.with_(center=c.center + u * (c.size[x.axis] + x.length) / 2, size=size)
        for t in third:
            o = arr.cuboids[t]
            tol = float(pair_tolerance(slab.size, o.size))
            sep, _, _ = sat_separation(slab.center[None], slab.rotation[None],
                                       slab.size[None] / 2, o.center[None], o.rotation[None],
                                       o.size[None] / 2, np.array([tol]))
            if float(sep[0]) <= tol:
                return True
    return False


def _option_cost(e: Edge, o: Option, eager: bool = False) -> tuple[int, int, float]:
    """(fixed contacts, parts of one object left apart, added volume) of one option;
    ``eager``: ``e`` is a same-object edge with a short join (:data:`SHORT_JOIN`)."""
    return (int(o.type == "fixed" and not e.same_object),
            int(eager and o.type == "none"), o.volume)


class _Group:
    """One independent group: its cuboids, edges and caches."""

    #: greedy pass 1 tests blocks of edges at once (same answer as one by one, fewer checks)
    BLOCK_RELAX = True

    def __init__(self, arr: Arrangement, boxes: list[int], edges: list[Edge], mu: float,
                 threshold: float | None, stats: SearchStats) -> None:
        self.full = arr
        self.boxes = boxes
        self.local = {k: n for n, k in enumerate(boxes)}
        self.sub = arr.with_(cuboids=tuple(arr.cuboids[k] for k in boxes), contacts=())
        # same-object edges only fuse (or stay apart when they cannot reach each other)
        fixed_edges = []
        for e in edges:
            if e.same_object:  # parts of one object: fused where they touch, or apart
                opts = [o for o in e.options if o.type != "touch"] or list(e.options)
                e = Edge(e.a, e.b, tuple(sorted(opts, key=lambda o: o.volume)), True, e.touching)
            fixed_edges.append(e)
        # decide the most expensive edges first; options cheapest first
        self.edges = sorted(fixed_edges, key=lambda e: -max(o.volume for o in e.options))
        links = touching_links(self.edges)
        eager = {id(e) for e in self.edges if _short_join(arr, e, links)}
        self._cost = lambda e, o: _option_cost(e, o, id(e) in eager)
        self.options = [sorted(e.options, key=lambda o: self._cost(e, o)) for e in self.edges]
        # per option: (fixed, apart, ((face, length), ...)); per face the two extents
        # across it, as Python floats (the sums in :meth:`cost` do the same arithmetic)
        self._terms = [[(*self._cost(e, o)[:2],
                         tuple(((x.box, x.axis, x.side), x.length) for x in o.extensions))
                        for o in opts] for e, opts in zip(self.edges, self.options)]
        self._across = {}
        for opts in self._terms:
            for *_, exts in opts:
                for face, _length in exts:
                    s = arr.sizes[face[0]].tolist()
                    self._across[face] = [s[k] for k in range(3) if k != face[1]]
        # parts of multi-part objects, and the levels of the edges that can join two
        self._object_of = {k: arr.cuboids[k].object for k in boxes
                           if arr.cuboids[k].object is not None}
        self._joins = [lv for lv, e in enumerate(self.edges)
                       if e.same_object and not isinstance(e.b, str)
                       and any(o.type == "fixed" for o in self.options[lv])]
        self.mu, self.threshold, self.stats = mu, threshold, stats
        self.stab_cache: dict[tuple, tuple[bool, object]] = {}
        self.geom_cache: dict[tuple, tuple[Arrangement, ContactSet]] = {}
        self.solve_cache: dict[bytes, tuple] = {}  # component digest -> solution
        self.recent: list[tuple] = []  # (extension keys, geometry, contacts) bases
        self.cuboid_memo: dict = {}  # (box, offsets) -> extended Cuboid

    # -- evaluation
    def geometry(self, assignment: tuple[int, ...]) -> tuple[Arrangement, ContactSet]:
        exts = []
        for _e, opts, i in zip(self.edges, self.options, assignment):
            exts.extend(opts[i].extensions)
        key = tuple(sorted((x.box, x.axis, x.side, x.length) for x in exts))
        hit = self.geom_cache.get(key)
        if hit is not None:
            return hit
        local_exts = [type(x)(self.local[x.box], x.axis, x.side, x.length) for x in exts]
        geom = apply_offsets(self.sub, offsets_of(local_exts, len(self.boxes)), self.cuboid_memo)
        # incremental: recompute only the pairs of boxes that differ from the closest of
        # the recently evaluated geometries (update_contacts equals find_contacts)
        # (boxes whose extensions differ bound the boxes that changed)
        keyset = frozenset(key)
        base, fewest = None, None
        for ks, g, c in self.recent:
            n = len({x[0] for x in keyset ^ ks})
            if fewest is None or n < fewest:
                base, fewest = (g, c), n
        if base is not None:
            geom.inherit_views(base[0])  # most boxes are the same objects as the base's
        cs = find_contacts(geom) if base is None else update_contacts(geom, *base)
        self.stats.contact_evaluations += 1
        self.geom_cache[key] = (geom, cs)
        self.recent = (self.recent + [(keyset, geom, cs)])[-RECENT_BASES:]
        return geom, cs

    def evaluate(self, assignment: tuple[int, ...], quick: bool = True):
        """(stable, result-or-status) of an assignment, cached.

        With ``quick``, a box that touches nothing (its body has no contact force, so its
        weight is unbalanced: E >= 1) answers "floating" without the equilibrium solve, and
        an unstable answer may come from a one-body bound instead of a solve
        (``check_stability(verdict_only=True)``): the verdict is exact, the energy of an
        unstable result is not (only the root's unstable result is reported).
        """
        hit = self.stab_cache.get(assignment)
        if hit is not None:
            self.stats.cache_hits += 1
            return hit
        geom, cs = self.geometry(assignment)
        touched = np.zeros(len(self.boxes), bool)
        touched[cs.a] = True
        touched[cs.b[cs.b < len(self.boxes)]] = True
        if cs.penetrations:
            out = (False, "penetration")
        elif quick and not touched.all():
            out = (False, "floating")
        else:
            fixed = (Contact(*_edge_name(self.full, e), "fixed")
                     for e, opts, i in zip(self.edges, self.options, assignment)
                     if opts[i].type == "fixed")
            arr = geom.with_(contacts=tuple(_glued(fixed, cs)))
            try:
                res = check_stability(arr, mu=self.mu, threshold=self.threshold, contacts=cs,
                                      tilt_deg=ROBUST_TILT_DEG, solve_cache=self.solve_cache,
                                      verdict_only=quick)
            except InputError:  # a fixed pair that does not touch in this geometry
                out = (False, "detached")
            else:
                self.stats.stability_checks += 1
                out = (res.stable, res)
        self.stab_cache[assignment] = out
        return out

    def pieces(self, assignment: tuple[int, ...], upto: int | None = None) -> int:
        """Into how many more pieces than objects the joins split the objects' parts,
        with the edges from ``upto`` on counted as joined (a lower bound)."""
        n = len(assignment) if upto is None else upto
        if not self._joins:
            return 0
        parent = {k: k for k in self._object_of}

        def find(x: int) -> int:
            while parent[x] != x:
                parent[x] = parent[parent[x]]
                x = parent[x]
            return x

        for lv in self._joins:
            if lv < n and self.options[lv][assignment[lv]].type != "fixed":
                continue
            e = self.edges[lv]
            ra, rb = find(e.a), find(e.b)
            if ra != rb:
                parent[ra] = rb
        roots = {(self._object_of[k], find(k)) for k in parent}
        return len(roots) - len(set(self._object_of.values()))

    def cost(self, assignment: tuple[int, ...], upto: int | None = None
             ) -> tuple[int, int, int, float]:
        """(fixed contacts, extra pieces of objects, same-object short joins left apart,
        added volume) of the first ``upto`` decided edges: a lower bound of every
        completion, compared in order."""
        n = len(assignment) if upto is None else upto
        fixed = apart = 0
        exts: dict = {}  # face -> longest push, in order of first appearance
        for terms, i in zip(self._terms[:n], assignment[:n]):
            f, a, pushes = terms[i]
            fixed += f
            apart += a
            for face, length in pushes:
                exts[face] = max(exts.get(face, 0.0), length)
        vol = 0.0
        across = self._across
        for face, length in exts.items():
            s0, s1 = across[face]
            vol += length * s0 * s1
        return fixed, self.pieces(assignment, n), apart, vol

    # -- search
    def root(self) -> tuple[int, ...]:
        """The most supportive assignment without interpenetration, built edge by edge.

        Pairs that already touch start fused; then support edges, then pair edges (each
        group cheapest first) take their smallest ``fixed`` extension that does not drive
        a box into another given the extensions already taken; an edge none of whose
        fixed options fit stays apart.  Touching pairs that may also grow the lower box
        under an overhang (:func:`pipeline.extend.pair_edges` ``overhang``) come last:
        they only add support to a box already resting, and must not take space that a
        pair still apart needs to touch at all.
        """
        out = []
        for opts in self.options:
            plain = [n for n, o in enumerate(opts) if o.type == "fixed" and not o.extensions]
            none = [n for n, o in enumerate(opts) if o.type == "none"]
            out.append(plain[0] if plain else (none[0] if none else 0))
        order = sorted(range(len(self.edges)),
                       key=lambda k: (not isinstance(self.edges[k].b, str),
                                      not self.edges[k].same_object,
                                      self.edges[k].touching,
                                      min(o.volume for o in self.options[k])))
        for k in order:
            opts = self.options[k]
            if not any(o.extensions for o in opts):
                continue
            fixed = sorted((n for n, o in enumerate(opts) if o.type == "fixed" and o.extensions),
                           key=lambda n: opts[n].volume)
            for i in fixed:
                trial = list(out)
                trial[k] = i
                _, cs = self.geometry(tuple(trial))
                if not cs.penetrations:
                    out = trial
                    break
            else:
                out = self._share_extension(out, k, fixed)
        return tuple(out)

    def _share_extension(self, out: list[int], k: int, fixed: list[int]) -> list[int]:
        """Edge ``k``'s fixed options (``fixed``) all drive a box into another given the
        extensions taken so far: try each with an edge already fused that could instead
        take an option pushing out the same face (one extension explaining both
        contacts: a deck grown down onto two pillars, where the first pillar grown up to
        the deck left no room for the deck to come down onto the second)."""
        for i in fixed:
            faces = {(x.box, x.axis, x.side) for x in self.options[k][i].extensions}
            for m, opts in enumerate(self.options):
                if m == k or not opts[out[m]].extensions:
                    continue
                for j, o in enumerate(opts):
                    if (j == out[m] or o.type != "fixed"
                            or not faces & {(x.box, x.axis, x.side) for x in o.extensions}):
                        continue
                    trial = list(out)
                    trial[k], trial[m] = i, j
                    _, cs = self.geometry(tuple(trial))
                    if not cs.penetrations:
                        return trial
        return out

    def run(self, deadline: float) -> tuple[tuple[int, ...], bool, object]:
        root = self.root()
        ok, res = self.evaluate(root, quick=False)
        self.stats.nodes += 1
        if not ok:
            return root, False, res
        best = [root, self.cost(root), res]
        n = len(self.edges)

        def dive(level: int, assignment: list[int]) -> None:
            if workclock.now() > deadline:
                self.stats.budget_spent = True
                return
            if level == n:
                self.stats.leaves += 1
                c = self.cost(tuple(assignment))
                if c < best[1]:
                    best[0], best[1] = tuple(assignment), c
                    best[2] = self.evaluate(tuple(assignment))[1]
                return
            for i in range(len(self.options[level])):
                trial = list(assignment)
                trial[level] = i
                lower = self.cost(tuple(trial), level + 1)
                if lower >= best[1]:
                    self.stats.pruned_bound += 1
                    continue
                self.stats.nodes += 1
                ok, res = self.evaluate(tuple(trial))
                if not ok:
                    if res == "penetration":
                        self.stats.pruned_penetration += 1
                    else:
                        self.stats.pruned_unstable += 1
                    continue
                dive(level + 1, trial)
                if workclock.now() > deadline:
                    self.stats.budget_spent = True
                    return

        greedy = self.improve(self.greedy(root, deadline), deadline)
        best[0], best[1], best[2] = greedy, self.cost(greedy), self.evaluate(greedy)[1]
        if n <= EXACT_MAX_EDGES:  # prove (or improve on) the greedy answer exhaustively
            dive(0, list(root))
        alike = self.siblings(best[0], deadline)
        if alike != best[0]:
            # the parts given their siblings' support may make an extension the greedy
            # kept unnecessary (a chair's back stretched to the floor while two legs
            # hung): cheaper single-edge moves that the siblings step would not undo
            alike = self.improve(alike, deadline,
                                 keep=lambda a: self.siblings(a, deadline) == a)
        best[0] = alike
        best[2] = self.evaluate(best[0])[1]
        return best[0], True, best[2]

    def greedy(self, root: tuple[int, ...], deadline: float) -> tuple[int, ...] | None:
        """Two greedy passes that follow the objective's priorities.

        Pass 1 (fewest fixed): every edge in turn tries its cheapest ``touch`` option (or
        ``none`` for a pair already fused by nothing); one that keeps the arrangement
        stable is kept.  Extensions stay in place, so support is not thrown away early.
        First all edges at once, then (group testing) halves of a failing block: turning
        fixed into touch with the same extensions can only lose stability, so a block
        that stands relaxed together is exactly what one by one would give, and only the
        blocks that fail are split down to single edges.
        Pass 2 (least volume): every edge in turn tries the options of the same type
        count with less volume (``none`` included).
        """
        current = list(root)

        def attempt(level: int, i: int) -> bool:
            nonlocal current
            if workclock.now() > deadline:
                self.stats.budget_spent = True
                return False
            trial = list(current)
            trial[level] = i
            self.stats.nodes += 1
            ok, res = self.evaluate(tuple(trial))
            if ok:
                current = trial
            elif res == "penetration":
                self.stats.pruned_penetration += 1
            else:
                self.stats.pruned_unstable += 1
            return ok

        # pass 1, all at once first (the common case: everything just rests)
        relax = {}
        for level, (e, opts) in enumerate(zip(self.edges, self.options)):
            if self._cost(e, opts[current[level]])[0] == 0:
                continue
            same = opts[current[level]].extensions
            touch = sorted((n for n, o in enumerate(opts) if o.type == "touch"),
                           key=lambda n: (opts[n].extensions != same, opts[n].volume))
            if touch:
                relax[level] = touch
        bulk = list(current)
        for level, touch in relax.items():
            bulk[level] = touch[0]
        self.stats.nodes += 1
        if relax and self.evaluate(tuple(bulk))[0]:
            current = bulk
        else:
            def keeps(level: int) -> bool:
                opts = self.options[level]
                return opts[relax[level][0]].extensions == opts[current[level]].extensions

            def block(levels: list[int], known_bad: bool) -> bool:
                """Relax ``levels`` in order as one by one would; True when all of them
                took their first touch option."""
                nonlocal current
                if len(levels) > 1 and not known_bad and all(keeps(lv) for lv in levels):
                    if workclock.now() > deadline:
                        self.stats.budget_spent = True
                        return False
                    trial = list(current)
                    for lv in levels:
                        trial[lv] = relax[lv][0]
                    self.stats.nodes += 1
                    if self.evaluate(tuple(trial))[0]:
                        current = trial
                        return True
                    self.stats.pruned_unstable += 1
                    known_bad = True
                if len(levels) == 1:
                    for i in relax[levels[0]]:
                        if attempt(levels[0], i):
                            return i == relax[levels[0]][0]
                    return False
                half = len(levels) // 2
                first = block(levels[:half], False)
                # the whole failed and its first half went through: the rest fails as a block
                second = block(levels[half:], known_bad and first)
                return first and second

            if self.BLOCK_RELAX:
                block(list(relax), True)
            else:
                for level, touch in relax.items():
                    for i in touch:
                        if attempt(level, i):
                            break
        # pass 2, in bulk first: extensions whose contact carries no load in the current
        # equilibrium are dropped together (verified by one evaluation)
        ok, res = self.evaluate(tuple(current))
        if ok and getattr(res, "contact_load", None) is not None:
            _, cs = self.geometry(tuple(current))
            lookup = cs.lookup()
            bulk = list(current)
            for level, (e, opts) in enumerate(zip(self.edges, self.options)):
                o = opts[current[level]]
                if not o.extensions or e.same_object:  # joins are dropped one by one
                    continue
                a, b = _edge_name(self.full, e)
                m = lookup.get((a, b) if a <= b else (b, a))
                if m is not None and res.contact_load[m] > 1e-9:
                    continue
                cheaper = [n for n, p in enumerate(opts)
                           if self._cost(e, p)[:2] <= self._cost(e, o)[:2]
                           and not p.extensions and p.type != "fixed"]
                if cheaper:
                    bulk[level] = cheaper[0]
            if bulk != current:
                self.stats.nodes += 1
                if self.evaluate(tuple(bulk))[0]:
                    current = bulk
        for level, (e, opts) in enumerate(zip(self.edges, self.options)):
            here = self._cost(e, opts[current[level]])
            for i in range(len(opts)):  # cheapest first
                c = self._cost(e, opts[i])
                if not (c[:2] <= here[:2] and c[2] < here[2]):
                    continue
                trial = list(current)
                trial[level] = i
                if (self.cost(tuple(trial))[:3] <= self.cost(tuple(current))[:3]
                        and attempt(level, i)):
                    break
        self.stats.leaves += 1
        return tuple(current)

    def siblings(self, assignment: tuple[int, ...], deadline: float) -> tuple[int, ...]:
        """Treat repeated parts alike: a part left hanging whose sibling (same object,
        same support; same size within 10 %, or a reach of at most half its height as it
        stands) was extended to that support gets the same kind of contact, when that
        stays stable.  Four legs of a table all reach the
        floor even though two diagonal ones would balance it (the symmetry prior of the
        paper's section 5.1 (ii)); this may add volume on purpose."""
        current = list(assignment)
        full = self.full
        for k, (e, opts) in enumerate(zip(self.edges, self.options)):
            if not isinstance(e.b, str) or opts[current[k]].type != "none":
                continue
            me = full.cuboids[e.a]
            for m, (f, fopts) in enumerate(zip(self.edges, self.options)):
                if m == k or f.b != e.b or fopts[current[m]].type == "none":
                    continue
                other = full.cuboids[f.a]
                if me.object is None or me.object != other.object:
                    continue
                alike = (np.allclose(np.sort(me.size), np.sort(other.size), rtol=0.1)
                         or same_column(me, other))
                want = fopts[current[m]].type
                done = False
                for i, o in enumerate(opts):
                    if o.type != want or workclock.now() > deadline:
                        continue
                    if not alike and not self._short_reach(current, o):
                        continue
                    trial = list(current)
                    trial[k] = i
                    self.stats.nodes += 1
                    if self.evaluate(tuple(trial))[0]:
                        current = trial
                        done = True
                        break
                if done or alike:
                    break
        return tuple(current)

    def _short_reach(self, assignment: list[int], option: Option) -> bool:
        """Whether ``option``'s extensions are each at most half the box's vertical extent
        as ``assignment`` has it: a leg seen only in its lower part and joined to the top
        reaches the floor by a few centimetres, a table top would need its whole height."""
        geom, _ = self.geometry(tuple(assignment))
        for x in option.extensions:
            c = geom.cuboids[self.local[x.box]]
            if x.length > 0.5 * float(np.abs(c.rotation[2, :]) @ c.size):
                return False
        return bool(option.extensions)

    def improve(self, assignment: tuple[int, ...], deadline: float,
                keep=None) -> tuple[int, ...]:
        """Single-edge moves to cheaper options while any lowers the cost, then
        :meth:`_join_swaps` (local optimum); ``keep``: a further test a stable move must
        pass."""
        current = tuple(assignment)
        cost = self.cost(current)
        changed = True
        while changed and workclock.now() < deadline:
            changed = False
            for level in range(len(self.edges)):
                for i in range(len(self.options[level])):
                    if i == current[level]:
                        continue
                    trial = list(current)
                    trial[level] = i
                    trial = tuple(trial)
                    c = self.cost(trial)
                    if c >= cost:
                        continue
                    self.stats.nodes += 1
                    ok, _ = self.evaluate(trial)
                    if ok and (keep is None or keep(trial)):
                        current, cost, changed = trial, c, True
                        break
                if workclock.now() > deadline:
                    self.stats.budget_spent = True
                    break
            if not changed and workclock.now() < deadline:
                for trial in (*self._join_swaps(current), *self._glue_moves(current, deadline)):
                    c = self.cost(trial)
                    if c >= cost:
                        continue
                    self.stats.nodes += 1
                    ok, _ = self.evaluate(trial)
                    if ok and (keep is None or keep(trial)):
                        current, cost, changed = trial, c, True
                        break
        return current

    def _glue_moves(self, assignment: tuple[int, ...], deadline: float):
        """Assignments that move glue along a chain: one edge next to a glued one (sharing
        a box or a support with it) becomes ``fixed``, then every glued edge between
        different objects next to it in turn takes its cheapest option that still stands,
        a touch before none.  The greedy relaxes edges in one order, and a shelf board's
        joint to the wall relaxed first while the book on it was still glued to board
        and wall leaves two joints where one holds both; no single-edge move gets there
        (adding the one raises the cost first)."""
        glued = [lv for lv, (e, i) in enumerate(zip(self.edges, assignment))
                 if self.options[lv][i].type == "fixed" and not e.same_object]
        if not glued:
            return
        near = set()
        for lv in glued:
            e = self.edges[lv]
            near |= {e.a, e.b}
        for lv, e in enumerate(self.edges):
            if (lv in glued or e.same_object or not {e.a, e.b} & near
                    or workclock.now() > deadline):
                continue
            for i, o in enumerate(self.options[lv]):
                if o.type != "fixed":
                    continue
                trial = list(assignment)
                trial[lv] = i
                ends = {e.a, e.b}
                for g in glued:  # a touch first, as the greedy's first pass does
                    if not {self.edges[g].a, self.edges[g].b} & ends:
                        continue
                    opts = self.options[g]
                    for j in sorted((j for j, q in enumerate(opts) if q.type != "fixed"),
                                    key=lambda j: opts[j].type != "touch"):
                        t2 = list(trial)
                        t2[g] = j
                        self.stats.nodes += 1
                        if self.evaluate(tuple(t2))[0]:
                            trial = t2
                            break
                yield tuple(trial)
                break

    def _join_swaps(self, assignment: tuple[int, ...]):
        """Assignments that move one extended join of two parts of an object to another
        join of one of those parts: two edges at once, which no single-edge move reaches
        (dropping the join alone leaves the object in two pieces, adding the other alone
        adds volume).  A table leg seen at its foot is joined to the top by its own short
        reach up rather than by its neighbour leg growing 30 cm sideways to it."""
        joined = [lv for lv in self._joins
                  if self.options[lv][assignment[lv]].type == "fixed"
                  and self.options[lv][assignment[lv]].extensions]
        for lv in joined:
            e = self.edges[lv]
            apart = [i for i, o in enumerate(self.options[lv]) if o.type != "fixed"]
            if not apart:
                continue
            volume = self.options[lv][assignment[lv]].volume
            for other in self._joins:
                f = self.edges[other]
                if (other == lv or self.options[other][assignment[other]].type == "fixed"
                        or not {e.a, e.b} & {f.a, f.b}):
                    continue
                for i, o in enumerate(self.options[other]):
                    if o.type == "fixed" and o.volume < volume:
                        trial = list(assignment)
                        trial[lv], trial[other] = apart[0], i
                        yield tuple(trial)


def _groups(K: int, edges: list[Edge]) -> list[tuple[list[int], list[Edge]]]:
    parent = list(range(K))

    def find(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for e in edges:
        if not isinstance(e.b, str):
            ra, rb = find(e.a), find(e.b)
            if ra != rb:
                parent[max(ra, rb)] = min(ra, rb)
    members: dict[int, list[int]] = {}
    for k in range(K):
        members.setdefault(find(k), []).append(k)
    by_root: dict[int, list[Edge]] = {r: [] for r in members}
    for e in edges:
        by_root[find(e.a)].append(e)
    return [(members[r], by_root[r]) for r in sorted(members)]


@workclock.fresh()  # a clock of its own when called alone; imagine's when inside it
def search(arr: Arrangement, edges: list[Edge], *, budget: float = 10.0, mu: float = 0.7,
           threshold: float | None = None, progress=None) -> SearchResult:
    """Branch and bound over the candidate edges of ``arr`` (see the module docstring).

    Parameters
    ----------
    arr : Arrangement
        Initial cuboids and supports (contacts ignored).
    edges : list of Edge
        Candidates from :func:`pipeline.extend.candidate_edges` (after pruning).
    budget : float
        Work-clock seconds (:mod:`pipeline.workclock`); the best arrangement found is kept.
    progress : callable, optional: ``progress(done_groups, total_groups)``.
    """
    t0, w0 = time.perf_counter(), workclock.now()
    stats = SearchStats(edges=len(edges))
    K = len(arr.cuboids)
    groups = _groups(K, edges)
    stats.groups = len(groups)
    # biggest groups first, each with a share of the remaining budget
    groups.sort(key=lambda g: -len(g[1]))
    total_edges = max(sum(len(g[1]) for g in groups), 1)
    remaining_edges = total_edges
    all_exts = []
    contacts: list[Contact] = []
    unstable: list[str] = []
    choices = {}
    n_fixed = 0
    for gi, (boxes, gedges) in enumerate(groups):
        now = workclock.now()
        left = budget - (now - w0)
        share = left * max(len(gedges), 1) / max(remaining_edges, 1)
        remaining_edges -= len(gedges)
        group = _Group(arr, boxes, gedges, mu, threshold, stats)
        assignment, ok, res = group.run(now + max(share, 0.0))
        if not ok:
            stats.unstable_groups += 1
            if hasattr(res, "unstable_ids"):
                unstable += list(res.unstable_ids)
            else:
                unstable += [arr.cuboids[k].id for k in boxes]
        for e, opts, i in zip(group.edges, group.options, assignment):
            o = opts[i]
            all_exts.extend(o.extensions)
            choices[_edge_name(arr, e)] = o.type
            if o.type == "fixed":
                contacts.append(Contact(*_edge_name(arr, e), "fixed"))
                n_fixed += int(not e.same_object)
        if progress is not None:
            progress(gi + 1, len(groups))
    grown = apply_offsets(arr, offsets_of(all_exts, K))

    def falls(cubs) -> int:
        try:
            res = finalize(grown.with_(cuboids=cubs), contacts, mu=mu, threshold=threshold)
        except InputError:  # a chosen fixed pair no longer touches
            return K
        return len(falling(res, mu=mu, threshold=threshold))

    geom = apart(arr, grown, falls)
    added = float(np.sum(np.prod(geom.sizes, axis=1) - np.prod(arr.sizes, axis=1)))
    final = finalize(geom, contacts, mu=mu, threshold=threshold)
    stats.seconds = time.perf_counter() - t0
    stable = bool(final.stability.stable) if final.stability else False
    return SearchResult(final, stable, n_fixed, added, tuple(unstable), stats, choices)


def _glued(fixed, cs: ContactSet) -> list[Contact]:
    """The ``fixed`` contacts whose boxes meet in a patch of ``cs``: the others glue nothing."""
    touching = cs.lookup()
    return [c for c in fixed if c.key in touching]


def finalize(geom: Arrangement, fixed: list[Contact], mu: float = 0.7,
             threshold: float | None = None) -> Arrangement:
    """List every touching pair as a contact (``fixed`` where chosen, else ``touch``) and
    attach the stability summary of the whole arrangement.

    Repeated calls on variants of one scene (the caller trying joins one at a time) reuse
    work exactly: contacts are updated from the closest recent geometry with the same
    cuboids (:func:`pipeline.contacts.update_contacts`), and component solutions are
    shared through a bounded cache keyed by the digest of each sub-problem."""
    cs = _finalize_contacts(geom)
    fixed_keys = {c.key for c in fixed}
    listed = _glued(fixed, cs)
    for a, b in cs.pairs:
        c = Contact(a, b, "touch")
        if c.key not in fixed_keys:
            listed.append(c)
    listed.sort(key=lambda c: (c.key, c.type))
    arr = geom.with_(contacts=tuple(listed))
    if len(_FINALIZE_SOLVES) > FINALIZE_CACHE_MAX:
        _FINALIZE_SOLVES.clear()
    res = check_stability(arr, mu=mu, threshold=threshold, contacts=cs,
                          solve_cache=_FINALIZE_SOLVES)
    return arr.with_(stability=StabilitySummary(res.energy, res.stable, res.threshold))


def falling(arr: Arrangement, mu: float = 0.7, threshold: float | None = None) -> tuple:
    """The boxes of ``arr`` (from :func:`finalize`, whose exact memo it reuses) that fall
    in the analytic check: none when it stands, all when the check names none."""
    if arr.stability is not None and arr.stability.stable:
        return ()
    if len(_FINALIZE_SOLVES) > FINALIZE_CACHE_MAX:
        _FINALIZE_SOLVES.clear()
    res = check_stability(arr, mu=mu, threshold=threshold, solve_cache=_FINALIZE_SOLVES)
    return tuple(res.unstable_ids) or arr.ids


#: bounded memo of :func:`finalize` (exact: digests of sub-problems, same-cuboid bases)
FINALIZE_CACHE_MAX = 512
_FINALIZE_SOLVES: dict[bytes, tuple] = {}
_FINALIZE_RECENT: list[tuple[Arrangement, ContactSet]] = []


def _finalize_contacts(geom: Arrangement) -> ContactSet:
    base, fewest = None, len(geom.cuboids) // 2 + 1
    for g, c in list(_FINALIZE_RECENT):
        if g.ids != geom.ids or g.support_ids != geom.support_ids:
            continue
        n = int(changed_cuboids(geom, g).sum())
        if n < fewest:
            base, fewest = (g, c), n
    cs = find_contacts(geom) if base is None else update_contacts(geom, *base)
    _FINALIZE_RECENT.append((geom, cs))
    del _FINALIZE_RECENT[:-4]
    return cs


__all__ = ["search", "SearchResult", "SearchStats", "finalize", "falling"]
