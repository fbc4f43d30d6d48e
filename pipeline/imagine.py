"""Imagining the unseen: initial cuboids -> a stable, typed arrangement (sections 4.2-4.3).

:func:`imagine` runs, in order:

0. *alignment* (:func:`align_boxes`): boxes tilted by a few degrees stand upright, and
   the parts of one object share its yaw;
1. *overlap repair*: initial boxes fitted to noisy points may overlap slightly; each
   overlapping pair is separated by shrinking the box with fewer points along the
   separating axis (a true overlap cannot be a contact);
2. *depth and joins*: boxes seen face-on get depth (:func:`deepen_thin_boxes`), parts
   of one object a short extension joins are joined (:func:`join_parts`); *symmetry*
   (:mod:`pipeline.symmetry`): wholly occluded repeated parts (the fourth leg) are
   hallucinated where the object's other parts show the pattern and the sensor saw
   nothing there;
3. *candidates* (:mod:`pipeline.extend`) with interpenetration and visibility pruning;
4. *search* (:mod:`pipeline.search`): fewest fixed contacts, then least added volume;
   then parts of one object that were left apart are joined where an extension can
   (:func:`connect_objects`: an object is one connected rigid body), and glue joints
   between different objects are dropped where refining the boxes makes them stand
   without (:func:`relax_fixed`), and a box stretched to the floor far below what was
   seen of it rests on a hidden support instead (:func:`hidden_supports`: a sofa's seat);
5. *refinement* (:mod:`pipeline.refine`) when the result still carries residual energy;
6. *closing* (:func:`pipeline.snap.close_gaps`): contacts between different rigid bodies,
   touching within the contact tolerance, are made exact (what the engines load is what
   the statics judged).

It returns the final arrangement (each cuboid keeps its ``observed`` box) and a report
dict with counts, statistics and timings per step.  ``budget`` seconds bound the search,
the second search after boxes are set aside and the glue relaxation (whatever is found
by then is kept); the final refinement gets what is left, at least a tenth of it.  Below
the budget the result depends only on the input and the seed.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from .contacts import find_contacts, pair_tolerance, sat_separation
from .errors import InputError
from .extend import DepthView, candidate_edges, depth_noise, prune_by_visibility
from .model import Arrangement, Contact, Cuboid, ObservedBox, is_support_id
from .refine import refine
from .search import search
from .snap import close_gaps, close_pair
from .symmetry import complete_by_mirror, hallucinate, hidden_connectors

#: Rounds of setting aside boxes that nothing can hold up and searching the rest again.
ISOLATE_ROUNDS = 3


@dataclass(frozen=True)
class ImagineResult:
    arrangement: Arrangement
    initial: Arrangement  #: after overlap repair and symmetry, before extension
    report: dict


#: A box tilted by at most this many degrees (and not marked ``slanted``) is set upright
#: (the threshold below which :mod:`pipeline.fit` calls an object upright) ...
ALIGN_MAX_DEG = 15.0
#: ... and a part whose yaw is within this many degrees of its object's takes the object's.
OBJECT_YAW_MAX_DEG = 30.0


#: An upright box's yaw is fitted to the depth views within this many degrees either
#: side of its own (:func:`fit_yaws`), in steps of :data:`YAW_FIT_STEP_DEG` ...
YAW_FIT_MAX_DEG = 20.0
YAW_FIT_STEP_DEG = 1.0
#: ... and the box turns only when the turned box holds this many times the observed
#: points it held as it was, and at least :data:`YAW_FIT_MIN_POINTS` more.
YAW_FIT_GAIN = 1.15
YAW_FIT_MIN_POINTS = 50
#: Pixel stride of the observed points used (every n-th row and column).
YAW_FIT_STRIDE = 2
#: An upright box whose bottom lies within this many metres of another upright box's
#: top, over it, rests on it (:func:`yaws_from_supports`) ...
SUPPORT_YAW_GAP = 0.03
#: ... and takes its yaw when the points it holds at that yaw fall short of the most it
#: holds at any yaw by at most this many times their Poisson noise.
SUPPORT_YAW_SIGMAS = 2.0


def observed_points(views: list[DepthView], stride: int = YAW_FIT_STRIDE
                    ) -> tuple[np.ndarray, np.ndarray]:
    """World points of every ``stride``-th pixel of the views and a distance tolerance
    per point (twice the sensor's axial noise at its depth, at least a centimetre)."""
    from .camera import backproject, transform

    pts, tol = [np.zeros((0, 3))], [np.zeros(0)]
    for v in views:
        d = np.zeros_like(np.asarray(v.depth, float))
        d[::stride, ::stride] = np.asarray(v.depth, float)[::stride, ::stride]
        p, _ = backproject(d, v.intrinsics)
        tol.append(np.maximum(0.01, 2 * depth_noise(p[:, 2])))
        pts.append(transform(np.asarray(v.T_world_cam, float), p))
    return np.concatenate(pts), np.concatenate(tol)


_CLOUD: list = []  #: the views of the last :func:`_observed_cloud` call and its result


def _observed_cloud(views: list[DepthView]):
    """(points, tolerances, KD-tree) of :func:`observed_points`, kept for the views of
    the last call (:func:`align_boxes` asks three times for the same views)."""
    from scipy.spatial import cKDTree

    if _CLOUD and len(_CLOUD[0]) == len(views) and all(
            a is b for a, b in zip(_CLOUD[0], views, strict=True)):
        return _CLOUD[1]
    pts, tol = observed_points(views)
    out = (pts, tol, cKDTree(pts) if len(pts) else None)
    _CLOUD[:] = [tuple(views), out]
    return out


def fit_yaws(arr: Arrangement, views: list[DepthView], max_deg: float = YAW_FIT_MAX_DEG,
             step_deg: float = YAW_FIT_STEP_DEG, gain: float = YAW_FIT_GAIN,
             min_points: int = YAW_FIT_MIN_POINTS) -> tuple[Arrangement, list[str]]:
    """Turn upright boxes about the vertical through their centres to fit what was seen.

    An initial box can come with a yaw that is off (a box fitted to a few points, or
    initial cuboids from elsewhere): a shelf's board turned by 15 degrees about its own
    centre pokes 10 cm out of the shelf at one end and lets the books at the other fall
    through.  The observed points (every :data:`YAW_FIT_STRIDE`-th pixel of every view)
    that lie in a box, grown by the sensor noise, are counted at yaws within
    ``max_deg`` of its own; a box that holds ``gain`` times as many (and ``min_points``
    more) at another yaw takes the best one.  Boxes marked ``slanted`` or not upright
    are left alone.  Returns the arrangement and the ids turned.
    """

    from .model import rotation_about_axis

    if not views:
        return arr, []
    pts, tol, tree = _observed_cloud(views)
    if not len(pts):
        return arr, []
    pad = float(tol.max())
    offsets = np.radians(np.arange(-max_deg, max_deg + 1e-9, step_deg))
    zero = int(np.argmin(np.abs(offsets)))
    cos, sin = np.cos(offsets), np.sin(offsets)
    cubs = list(arr.cuboids)
    turned = []
    for i, c in enumerate(cubs):
        if c.extra.get("slanted") or abs(c.rotation[2]).max() < 1 - 1e-9:
            continue
        near = tree.query_ball_point(c.center, float(np.linalg.norm(c.size)) / 2 + pad)
        if len(near) < min_points:
            continue
        d = pts[near] - c.center
        t = tol[near]
        lim = c.size / 2 + t[:, None]
        inside = np.zeros(len(offsets), int)
        for k in range(len(offsets)):
            # the box turned by +a about z holds the points turned by -a
            q = np.stack([cos[k] * d[:, 0] + sin[k] * d[:, 1],
                          -sin[k] * d[:, 0] + cos[k] * d[:, 1], d[:, 2]], axis=1) @ c.rotation
            inside[k] = int(np.count_nonzero(np.all(np.abs(q) <= lim, axis=1)))
        # the points held within the noise make a plateau of yaws: take its middle
        top = np.flatnonzero(inside >= inside.max() - max(1, 0.005 * inside.max()))
        best = int(top[len(top) // 2])
        if inside[best] >= gain * inside[zero] and inside[best] - inside[zero] >= min_points:
            cubs[i] = c.with_(rotation=rotation_about_axis([0.0, 0.0, 1.0], offsets[best])
                              @ c.rotation)
            turned.append(c.id)
    return arr.with_(cuboids=tuple(cubs)), turned


def _yaw_counts(c: Cuboid, pts: np.ndarray, tol: np.ndarray, near: list[int],
                offsets: np.ndarray) -> np.ndarray:
    """Observed points (grown by their tolerance) box ``c`` holds turned by each of
    ``offsets`` (radians) about the vertical through its centre."""
    d = pts[near] - c.center
    lim = c.size / 2 + tol[near][:, None]
    cos, sin = np.cos(offsets), np.sin(offsets)
    inside = np.zeros(len(offsets), int)
    for k in range(len(offsets)):
        # the box turned by +a about z holds the points turned by -a
        q = np.stack([cos[k] * d[:, 0] + sin[k] * d[:, 1],
                      -sin[k] * d[:, 0] + cos[k] * d[:, 1], d[:, 2]], axis=1) @ c.rotation
        inside[k] = int(np.count_nonzero(np.all(np.abs(q) <= lim, axis=1)))
    return inside


def _yaw_of(R: np.ndarray) -> float:
    """The yaw of an upright frame (the angle of a horizontal axis), radians."""
    h = R[:, int(np.argmin(np.abs(R[2])))]
    return float(np.arctan2(h[1], h[0]))


def _resting_on(arr: Arrangement, c: Cuboid, gap: float) -> Cuboid | None:
    """The upright box whose top face ``c``'s bottom lies on: within ``gap`` of its
    height, ``c``'s footprint over it or within ``gap`` of its edge (the support's far
    end may be hidden); the highest such when several, None when none."""
    bottom = c.center[2] - 0.5 * float(np.abs(c.rotation[2]) @ c.size)
    best, best_top = None, -np.inf
    for s in arr.cuboids:
        if s.id == c.id or abs(s.rotation[2]).max() < 1 - 1e-9:
            continue
        top = s.center[2] + 0.5 * float(np.abs(s.rotation[2]) @ s.size)
        if abs(bottom - top) > gap or top <= best_top:
            continue
        local = (c.center - s.center) @ s.rotation
        horizontal = np.abs(s.rotation[2]) < 0.5
        reach = 0.5 * np.abs(s.rotation.T @ c.rotation) @ c.size + gap  # c's footprint
        if np.all(np.abs(local[horizontal]) <= s.size[horizontal] / 2 + reach[horizontal]):
            best, best_top = s, top
    return best


def _not_in_others(arr: Arrangement, c: Cuboid, pts: np.ndarray, near: list[int]
                   ) -> list[int]:
    """The points ``near`` that lie in no other box of ``arr`` than ``c`` (the points
    another box holds are its evidence: turned across a row of books, a book's box
    would hold its neighbours' spines)."""
    keep = np.ones(len(near), bool)
    P = pts[near]
    reach = float(np.linalg.norm(c.size)) / 2
    for o in arr.cuboids:
        if o.id == c.id or np.linalg.norm(o.center - c.center) > reach + float(
                np.linalg.norm(o.size)) / 2:
            continue
        q = (P - o.center) @ o.rotation
        keep &= ~np.all(np.abs(q) <= o.size / 2, axis=1)
    return [n for n, k in zip(near, keep, strict=True) if k]


def yaws_from_supports(arr: Arrangement, views: list[DepthView],
                       gap: float = SUPPORT_YAW_GAP, sigmas: float = SUPPORT_YAW_SIGMAS
                       ) -> tuple[Arrangement, list[str]]:
    """Give an upright box whose yaw the points leave open the yaw of the box it rests on.

    The yaw of a box fitted to a few hundred points on one face (a book's spine seen
    between its neighbours) is hardly determined by them: :func:`fit_yaws`'s counts of
    the points it holds vary by less than their counting noise over tens of degrees,
    and the fitted box can come 40 degrees off the board it stands on -- a sliver at
    that yaw cannot be given its depth and stands only held from above.  Here the
    counts (of the points no other box holds, :func:`_not_in_others`) are taken at every
    yaw (modulo 180 degrees) and at the two yaws of the box it
    rests on (:func:`_resting_on`: its bottom within ``gap`` of that box's top, its
    footprint over it, as Jia et al. orient boxes by their supporting relations); of
    those the smaller turn is taken unless the other holds more points by over their
    Poisson noise (a spine's strip holds nearly as many either way); when that one
    holds at least the most held at any yaw less ``sigmas`` times its
    Poisson noise (the square root of the count), the box takes it.  A box the points
    pin (a board, a crate seen on two faces) keeps its yaw unless it is the support's.
    Only a box standing on a narrow end (a horizontal extent below
    :data:`THIN_FRACTION` of its height: a book on a shelf, not a book lying in a pile,
    whose top face shows its yaw) is turned; parts of an object with other parts keep
    their object's shared yaw (a monitor's foot on a desk); boxes marked ``slanted`` or not upright, and boxes resting on
    nothing, are left alone.  Returns the arrangement and the ids turned.
    """

    from .model import rotation_about_axis

    if not views:
        return arr, []
    pts, tol, tree = _observed_cloud(views)
    if not len(pts):
        return arr, []
    pad = float(tol.max())
    sweep = np.radians(np.arange(-90.0, 90.0, YAW_FIT_STEP_DEG))
    cubs = list(arr.cuboids)
    turned = []
    for i, c in enumerate(arr.cuboids):
        if (c.extra.get("slanted") or abs(c.rotation[2]).max() < 1 - 1e-9
                or not _single_part(arr, c)):
            continue
        up = int(np.argmax(np.abs(c.rotation[2])))
        if np.delete(c.size, up).min() >= THIN_FRACTION * c.size[up]:
            continue  # not standing on its narrow end: its top face shows its yaw
        s = _resting_on(arr, c, gap)
        if s is None or s.extra.get("slanted"):
            continue
        d = (_yaw_of(s.rotation) - _yaw_of(c.rotation) + np.pi / 4) % (np.pi / 2) - np.pi / 4
        if abs(d) <= np.radians(YAW_FIT_STEP_DEG):
            continue
        near = tree.query_ball_point(c.center, float(np.linalg.norm(c.size)) / 2 + pad)
        near = _not_in_others(arr, c, pts, near)
        if not near:
            continue
        to_support = np.array([d, d + np.pi / 2 if d < 0 else d - np.pi / 2])
        at = _yaw_counts(c, pts, tol, near, to_support)
        # the smaller turn unless the points favour the other beyond their noise
        best = int(at[1] > at[0] + np.sqrt(max(int(at[1]), 1)))
        most = int(_yaw_counts(c, pts, tol, near, sweep).max())
        if at[best] < most - sigmas * np.sqrt(most):
            continue
        cubs[i] = c.with_(rotation=rotation_about_axis([0.0, 0.0, 1.0], to_support[best])
                          @ c.rotation)
        turned.append(c.id)
    return arr.with_(cuboids=tuple(cubs)), turned


def _object_yaw(cubs: list[Cuboid], idx: list[int], yaws: np.ndarray, mean: float,
                yaw_deg: float, views: list[DepthView]) -> float:
    """The yaw the upright parts ``idx`` of one object share, fitted to the views.

    Each part fitted on its own (:func:`fit_yaws`) turns only when the points clearly
    favour another yaw; a board 15 degrees off, whose top holds 1.14 times the points
    turned back, stays, and the object's volume-weighted ``mean`` yaw then lands
    5 degrees off with the heavy boards (the shelf's far side panel pokes into its bottom
    board's end).  When the parts within ``yaw_deg`` of ``mean`` disagree (by more than
    :data:`YAW_FIT_STEP_DEG`), every yaw between the least and the greatest of theirs is
    tried for all of them at once (each turned about its own centre) and the yaw holding
    the most observed points in all of them together (the middle of their plateau, as
    in :func:`fit_yaws`) is returned.  Parts that agree keep ``mean``: their summed
    counts may well peak elsewhere (a room's shelf, fitted at 2 degrees, would turn to
    19 by the points of what stands around it), and ``mean`` is returned when no part
    holds any points either.
    """

    parts = []
    for i, y in zip(idx, yaws, strict=True):
        d = (y - mean + np.pi / 4) % (np.pi / 2) - np.pi / 4
        if abs(d) <= np.radians(yaw_deg) and abs(cubs[i].rotation[2]).max() > 1 - 1e-9:
            parts.append((i, float(d)))
    ds = [d for _, d in parts]
    if not ds or max(ds) - min(ds) <= np.radians(YAW_FIT_STEP_DEG):
        return mean  # the parts agree: nothing to choose between
    pts, tol, tree = _observed_cloud(views)
    if not len(pts):
        return mean
    pad = float(tol.max())
    step = np.radians(YAW_FIT_STEP_DEG)
    sweep = mean + np.arange(min(ds), max(ds) + 1e-9, step)
    total = np.zeros(len(sweep), int)
    for i, d in parts:
        c = cubs[i]
        near = tree.query_ball_point(c.center, float(np.linalg.norm(c.size)) / 2 + pad)
        if near:
            total += _yaw_counts(c, pts, tol, near, sweep - (mean + d))
    if total.max() <= 0:
        return mean
    top = np.flatnonzero(total >= total.max() - max(1, 0.005 * total.max()))
    return float(sweep[int(top[len(top) // 2])])


def align_boxes(arr: Arrangement, max_deg: float = ALIGN_MAX_DEG,
                yaw_deg: float = OBJECT_YAW_MAX_DEG,
                views: list[DepthView] | None = None) -> tuple[Arrangement, int]:
    """Undo small fitting errors in orientation: gravity and an object's own axes.

    A box whose axis nearest the vertical is off by at most ``max_deg`` is turned about
    its centre to stand upright (furniture and boxes stand; leaning parts are fitted as
    ``slanted`` and left alone); with ``views``, upright boxes then take the yaw that
    fits the observed points best (:func:`fit_yaws`); and the parts of one object whose
    yaws (modulo 90 degrees) lie within ``yaw_deg`` of the object's volume-weighted mean
    yaw take that yaw (with ``views``, the yaw near it that fits their points together
    best, :func:`_object_yaw`): a chair's legs and seat share one frame; with ``views``
    boxes whose yaw the points leave open then take that of the box they rest on
    (:func:`yaws_from_supports`).  Returns the arrangement and the number of boxes
    turned.
    """
    from .model import rotation_about_axis

    cubs = list(arr.cuboids)
    limit = np.radians(max_deg)
    turned = set()
    for i, c in enumerate(cubs):
        if c.extra.get("slanted"):
            continue
        k = int(np.argmax(np.abs(c.rotation[2])))
        a = c.rotation[:, k] * np.sign(c.rotation[2, k])
        tilt = float(np.arccos(np.clip(a[2], -1.0, 1.0)))
        if 1e-9 < tilt <= limit:
            R = rotation_about_axis(np.cross(a, [0.0, 0.0, 1.0]), tilt) @ c.rotation
            cubs[i] = c.with_(rotation=R)
            turned.add(i)
    if views:
        fitted, ids = fit_yaws(arr.with_(cuboids=tuple(cubs)), views)
        cubs = list(fitted.cuboids)
        turned |= {arr.index[k] for k in ids}
    groups: dict[str, list[int]] = {}
    for i, c in enumerate(cubs):
        if c.object is not None and not c.extra.get("slanted"):
            groups.setdefault(c.object, []).append(i)
    for idx in groups.values():
        if len(idx) < 2:
            continue
        yaws, weights = [], []
        for i in idx:
            R = cubs[i].rotation
            h = R[:, int(np.argmin(np.abs(R[2])))]  # a horizontal axis
            yaws.append(np.arctan2(h[1], h[0]))
            weights.append(float(np.prod(cubs[i].size)))
        yaws = np.array(yaws)
        mean = np.angle(np.sum(np.array(weights) * np.exp(4j * yaws))) / 4.0
        if views:
            mean = _object_yaw(cubs, idx, yaws, mean, yaw_deg, views)
        for i, y in zip(idx, yaws, strict=True):
            d = (y - mean + np.pi / 4) % (np.pi / 2) - np.pi / 4
            if 1e-9 < abs(d) <= np.radians(yaw_deg) and abs(cubs[i].rotation[2]).max() > 1 - 1e-9:
                cubs[i] = cubs[i].with_(rotation=rotation_about_axis([0.0, 0.0, 1.0], -d)
                                        @ cubs[i].rotation)
                turned.add(i)
    if views:
        fitted, ids = yaws_from_supports(arr.with_(cuboids=tuple(cubs)), views)
        cubs = list(fitted.cuboids)
        turned |= {arr.index[k] for k in ids}
    return arr.with_(cuboids=tuple(cubs)), len(turned)


def repair_overlaps(arr: Arrangement, max_rounds: int = 10,
                    views: list[DepthView] | None = None) -> tuple[Arrangement, int]:
    """Remove overlaps between initial boxes (they cannot be contacts).

    Two overlapping boxes of the same object with the same axes are one part seen as
    two slabs: they merge into the box that bounds both (unless the segmentation named
    them as different parts, ``extra["instance"]``: a shelf's board and its side stay
    two).  Otherwise the box that loses the smallest share of its extent to clear the
    other gives way (a tall box whose noisy bottom reaches into the plank it stands on,
    not the plank); when each would lose more than half through its least overlapping
    face (two books a centimetre deep, one in front of the other), the faces are chosen
    by the share they cost instead (the books give way sideways), and when still each
    would lose more than half, both give way by half the overlap.  In that thin case a
    box fitted to :data:`EVIDENCE_RATIO` times the other's points keeps the space and the
    other gives way through its cheapest face: a book fitted askew from a few hundred
    spine points that reaches into a shelf's side panel (tens of thousands of points) is
    narrowed, where cutting the smallest share would have cut the panel's bottom off and
    stood it on the book (the panel fused to the board under the book then clamps the
    book, which only friction from that clamp holds: both engines drop it).  Such a weak
    box turned more than :data:`SQUARE_MIN_DEG` against the strong one first takes its
    axes (:func:`_square_to`).  With ``views``, two thin boxes that are both slabs seen
    face-on (:func:`_face_on_axis`) are never cleared along the viewing direction: the
    camera saw both fronts, so neither stands behind the other (the one behind would
    have been hidden where they overlap), and they give way sideways even where a few
    millimetres of depth would have cost a smaller share; two thin boxes standing side
    by side (:func:`_side_by_side`) are never cleared from below or above.  A box
    reaching below a support plane loses the part
    below it.
    """
    eye = np.asarray(views[0].T_world_cam, float)[:3, 3] if views else None
    repaired = 0
    floor = next((float(s.point[2]) for s in arr.supports
                  if s.id == "ground" and s.normal[2] > 0.99), None)
    for _ in range(max_rounds):
        cs = find_contacts(arr)
        if not cs.penetrations:
            break
        cubs: list[Cuboid | None] = list(arr.cuboids)
        idx = arr.index
        for a_id, b_id, _depth in cs.penetrations:
            if b_id.startswith(("ground", "wall:")):
                k = idx[a_id]
                if cubs[k] is not None:
                    cubs[k] = _lift_from_plane(cubs[k], arr.support(b_id))
                    repaired += 1
                continue
            i, j = idx[a_id], idx[b_id]
            ci, cj = cubs[i], cubs[j]
            if ci is None or cj is None:
                continue
            if (ci.object is not None and ci.object == cj.object and _same_axes(ci, cj)
                    and _same_part(ci, cj)):
                cubs[i], cubs[j] = _merge(ci, cj), None
            elif not _penetrating(ci, cj):
                continue  # an earlier cut of this round already cleared them
            elif (rest := _resting_cut(ci, cj, slabs=floor)) is not None:
                cubs[i], cubs[j] = rest
            else:
                ri, rj = _relative_overlap(ci, cj), _relative_overlap(cj, ci)
                by_share = min(ri, rj) > 0.5
                skip = None
                side = False
                if by_share:  # thin boxes: clear through the face that costs least of them
                    # (through their sides when they stand side by side on one surface)
                    side = _side_by_side(ci, cj)
                    if eye is not None:
                        ai, aj = _face_on_axis(ci, eye), _face_on_axis(cj, eye)
                        if (ai is not None and aj is not None
                                and abs(ci.rotation[:, ai] @ cj.rotation[:, aj]) > 0.9):
                            skip = (ai, aj)
                    ri = _relative_overlap(ci, cj, True, None if skip is None else skip[0],
                                           side)
                    rj = _relative_overlap(cj, ci, True, None if skip is None else skip[1],
                                           side)
                    # ... unless one was fitted to far more points: the other gives way
                    pi, pj = _points(ci), _points(cj)
                    if pj >= EVIDENCE_RATIO * pi:
                        ri, rj = 0.0, 1.0
                        ci = cubs[i] = _square_to(ci, cj)
                    elif pi >= EVIDENCE_RATIO * pj:
                        ri, rj = 1.0, 0.0
                        cj = cubs[j] = _square_to(cj, ci)
                    if not _penetrating(ci, cj):
                        repaired += 1
                        continue
                si, sj = (None, None) if skip is None else skip
                if min(ri, rj) <= 0.5:  # the box that loses least of itself gives way
                    if ri <= rj:
                        cubs[i] = _shrink_against(ci, cj, by_share=by_share, skip=si,
                                                  sideways=side)
                    else:
                        cubs[j] = _shrink_against(cj, ci, by_share=by_share, skip=sj,
                                                  sideways=side)
                else:
                    cubs[i] = _shrink_against(ci, cj, share=0.5, by_share=by_share, skip=si,
                                              sideways=side)
                    cubs[j] = _shrink_against(cj, ci, share=0.5, by_share=by_share, skip=sj,
                                              sideways=side)
            repaired += 1
        arr = arr.with_(cuboids=tuple(c for c in cubs if c is not None))
    return arr, repaired


#: A box is "seen face-on" when its extent along a horizontal axis within 45 degrees of
#: the viewing direction is below this fraction of its other horizontal extent; it is
#: then given depth up to that other extent (a square footprint: a leg, a pillar, a box).
THIN_FRACTION = 0.5
#: ... and when that axis is within this many degrees of the horizontal viewing direction
#: (a box of its own: neighbours hide the sides of a box in a pile seen obliquely; or a
#: part whose seen face is at least FACE_ON_PART_MIN_FACE on both sides: a sofa's base) ...
FACE_ON_MAX_DEG = 70.0
#: ... or this many for a smaller part of an object with other parts (a bracket plate
#: under a board, seen from the side, is thin).
FACE_ON_PART_MAX_DEG = 45.0
FACE_ON_PART_MIN_FACE = 0.2


#: :func:`deepen_thin_boxes` finds how deep a box blocked within a step goes to this
#: resolution (metres).
DEEPEN_RESOLUTION = 0.002


def _deepened(arr: Arrangement, k: int, axis: int, u: np.ndarray, length: float
              ) -> Arrangement:
    """``arr`` with box ``k``'s face on ``axis`` towards ``u`` pushed out by ``length``."""
    c = arr.cuboids[k]
    size = c.size.copy()
    size[axis] += length
    cubs = list(arr.cuboids)
    cubs[k] = c.with_(center=c.center + u * length / 2, size=size)
    return arr.with_(cuboids=tuple(cubs))


def deepen_thin_boxes(arr: Arrangement, views: list[DepthView], margin: float = 0.0,
                      steps: int = 4) -> tuple[Arrangement, list[str]]:
    """Give depth to boxes the sensor saw only face-on.

    A part seen from the front (a leg, a pillar, a box behind a table top) is fitted as
    a slab a few millimetres deep along the viewing direction: its depth is simply not
    in the data, and as a sliver it can stand only glued.  Such a box (horizontal extent
    along an axis within 45 degrees of the first view's horizontal direction below
    :data:`THIN_FRACTION` of its other horizontal extent; within 70 degrees when it is
    also thin against its height and is a box of its own or shows a face of at least
    :data:`FACE_ON_PART_MIN_FACE`: a box in a pile seen obliquely, whose sides its
    neighbours hide, or a sofa's base) has its back face pushed away
    from the camera towards that other extent, in ``steps`` increments, as far as no
    view saw the added space empty and no other box or support is entered.  A part of an
    object with other parts goes no deeper than they span together along that axis (a
    shelf's bottom board, seen from the front edge, as deep as its side panels and
    other boards, not as deep as it is wide), and no further than they reach behind it
    (a chair's back, seen face-on on the rear of its seat, to the seat's rear edge: as
    deep as the chair, it would hang 40 cm out behind it).  Returns the arrangement and
    the ids deepened.
    """
    from .extend import FREE_FRACTION_MAX, Extension, slab_samples, visible_free_fraction

    if not views:
        return arr, []
    eye = np.asarray(views[0].T_world_cam, float)[:3, 3]
    deepened = []
    for k in range(len(arr.cuboids)):
        c = arr.cuboids[k]
        look = c.center - eye
        look[2] = 0.0  # the horizontal viewing direction (cameras often look down steeply)
        if np.linalg.norm(look) < 1e-9:
            continue
        look /= np.linalg.norm(look)
        horizontal = [a for a in range(3) if abs(c.rotation[2, a]) <= 0.5]
        height = float(c.size[int(np.argmax(np.abs(c.rotation[2])))])
        for axis in horizontal:
            along = float(c.rotation[:, axis] @ look)
            width = max((float(c.size[a]) for a in horizontal if a != axis), default=0.0)
            if c.size[axis] >= THIN_FRACTION * width:
                continue
            if abs(along) < np.cos(np.radians(FACE_ON_PART_MAX_DEG)):
                # seen obliquely: only a box of its own or a big face, and only a slab
                # standing on its edge (not a keyboard seen from above)
                big = np.delete(c.size, axis).min() >= FACE_ON_PART_MIN_FACE
                if (abs(along) < np.cos(np.radians(FACE_ON_MAX_DEG))
                        or not (big or _single_part(arr, c))
                        or c.size[axis] >= THIN_FRACTION * height):
                    continue
            side = 1 if along > 0 else 0  # the face away from the camera
            u = c.rotation[:, axis] * (1.0 if side else -1.0)
            target = min(width, _object_depth(arr, c, axis),
                         _object_reach(arr, c, u) + float(c.size[axis]) / 2)
            full = target - float(c.size[axis])
            if full <= 1e-4:
                break
            def deeper(length: float, base=arr, k=k, cid=c.id, axis=axis, u=u
                       ) -> Arrangement | None:
                return _settle_resting(_deepened(base, k, axis, u, length), cid)

            best, done = None, 0.0
            for j in range(1, steps + 1):
                length = full * j / steps
                x = Extension(k, axis, side, length)
                if visible_free_fraction(slab_samples(arr, x), views, margin) > FREE_FRACTION_MAX:
                    break
                trial = deeper(length)
                if trial is None:
                    # blocked within this step by a broad face (a back cushion a few
                    # degrees askew to the sofa's back): as deep as it goes, to 2 mm (a
                    # wall, the floor or a small box in the way say nothing of the depth)
                    pens = find_contacts(_deepened(arr, k, axis, u, length)).penetrations
                    into = [q if p == c.id else p for p, q, _ in pens if c.id in (p, q)]
                    if any(is_support_id(q) or not _broad_face(arr.cuboid(q), -u)
                           for q in into):
                        break
                    lo, hi = done, length
                    while hi - lo > DEEPEN_RESOLUTION:
                        mid = 0.5 * (lo + hi)
                        trial = deeper(mid)
                        if trial is None:
                            hi = mid
                        else:
                            lo, best = mid, trial
                    break
                best, done = trial, length
            if best is not None:
                arr = best
                deepened.append(c.id)
            break
    return arr, deepened


#: A box grows towards the camera, behind a broad part that hides it, by at most this
#: fraction of its widest horizontal extent (:func:`reach_occluders`).
REACH_MAX_REL = 1.0
#: ... and only across a gap wider than this (metres): a box that touches stays as it is.
REACH_MIN = 1e-3
#: ... when the added slab lies behind that part, as seen from the first view, for at
#: least this fraction of its samples.
SHADOW_FRACTION_MIN = 0.9
#: ... and the box is turned onto the part's axes when their yaws differ by at most this.
REACH_SQUARE_MAX_DEG = 15.0


def in_shadow(points: np.ndarray, eye: np.ndarray, box: Cuboid) -> np.ndarray:
    """Per point of ``points``: whether the segment from ``eye`` to it passes through
    ``box`` (the box hides the point from a camera at ``eye``)."""
    half = box.size / 2
    p0 = (np.asarray(eye, float) - box.center) @ box.rotation  # in the box's frame
    d = (np.asarray(points, float) - box.center) @ box.rotation - p0
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (-half - p0) / d
        t2 = (half - p0) / d
    lo = np.where(np.abs(d) < 1e-12, np.where(np.abs(p0) <= half, -np.inf, np.inf),
                  np.minimum(t1, t2))
    hi = np.where(np.abs(d) < 1e-12, np.where(np.abs(p0) <= half, np.inf, -np.inf),
                  np.maximum(t1, t2))
    enter = np.maximum(lo.max(axis=1), 0.0)
    leave = np.minimum(hi.min(axis=1), 1.0)
    return enter < leave


def reach_occluders(arr: Arrangement, views: list[DepthView], margin: float = 0.0
                    ) -> tuple[Arrangement, list[str]]:
    """Grow a box towards the camera, through the shadow of a broad part in front of it,
    until it touches that part.

    Seen from behind a sofa, each seat cushion shows a strip of its top along its
    front: the sofa's back hides the rest, and the cushion really reaches back to it.
    A fitted (not hallucinated) upright box whose horizontal face looks towards the
    first view's camera, with a box showing a broad face (:data:`BROAD_FACE_AREA`)
    ahead of it across its whole face, is turned onto that box's axes (when within
    :data:`REACH_SQUARE_MAX_DEG` in yaw) and grown to touch it when the gap is at most
    :data:`REACH_MAX_REL` of the box's widest horizontal extent, the added slab lies
    behind the broad box as seen from the camera (:func:`in_shadow`,
    :data:`SHADOW_FRACTION_MIN` of its samples), no view saw any of it empty, and no other
    box is entered.  Without views nothing changes.  Returns the arrangement and the ids
    grown.
    """
    from .extend import Extension, slab_samples, visible_free_fraction
    from .model import rotation_about_axis

    if not views:
        return arr, []
    eye = np.asarray(views[0].T_world_cam, float)[:3, 3]
    grown = []
    # the parts that could hide a box: upright, with some face broad enough
    broad = [o.id for o in arr.cuboids if abs(o.rotation[2]).max() >= 1 - 1e-6
             and float(np.prod(o.size) / o.size.min()) >= BROAD_FACE_AREA]
    for k in range(len(arr.cuboids)):
        c = arr.cuboids[k]
        if not broad:
            break
        if (c.observed is None or c.extra.get("hallucinated") or c.extra.get("slanted")
                or abs(c.rotation[2]).max() < 1 - 1e-6):
            continue
        to_eye = eye - c.center
        to_eye[2] = 0.0
        if np.linalg.norm(to_eye) < 1e-9:
            continue
        to_eye /= np.linalg.norm(to_eye)
        widest = max(float(c.size[a]) for a in range(3) if abs(c.rotation[2, a]) <= 0.5)
        best = None
        for axis in range(3):
            if abs(c.rotation[2, axis]) > 0.5:
                continue
            for side in (0, 1):
                u = c.rotation[:, axis] * (1.0 if side else -1.0)
                if float(u @ to_eye) <= 0.0:
                    continue
                face = float(c.center @ u + c.size[axis] / 2)
                for o in (arr.cuboid(i) for i in broad):
                    if o.id == c.id:
                        continue
                    if not _broad_face(o, -u) or not _overlap_across(c, o, u):
                        continue
                    g = float((o.corners() @ u).min()) - face
                    if REACH_MIN < g <= REACH_MAX_REL * widest and (best is None or g < best[0]):
                        best = (g, axis, side, o)
        if best is None:
            continue
        _, axis, side, o = best
        # onto the broad box's axes (a strip's yaw is a guess), then the gap again
        ax_c = next(a for a in range(3) if abs(c.rotation[2, a]) < 0.5)
        ax_o = next(a for a in range(3) if abs(o.rotation[2, a]) < 0.5)
        turn = ((np.arctan2(o.rotation[1, ax_o], o.rotation[0, ax_o])
                 - np.arctan2(c.rotation[1, ax_c], c.rotation[0, ax_c]) + np.pi / 4)
                % (np.pi / 2) - np.pi / 4)
        if abs(np.degrees(turn)) > REACH_SQUARE_MAX_DEG:
            continue
        sq = c.with_(rotation=rotation_about_axis([0.0, 0.0, 1.0], turn) @ c.rotation)
        u = sq.rotation[:, axis] * (1.0 if side else -1.0)
        g = float((o.corners() @ u).min()) - float(sq.center @ u + sq.size[axis] / 2)
        if g <= REACH_MIN or g > REACH_MAX_REL * widest:
            continue
        base = arr.with_(cuboids=tuple(sq if i == k else b for i, b in enumerate(arr.cuboids)))
        x = Extension(k, axis, side, g)
        samples = slab_samples(base, x)
        if (in_shadow(samples, eye, o).mean() < SHADOW_FRACTION_MIN
                or visible_free_fraction(samples, views, margin) > 0.0):
            continue
        trial = _deepened(base, k, axis, u, g)
        if any(c.id in (p, q) for p, q, _ in find_contacts(trial).penetrations):
            continue
        arr = trial
        grown.append(c.id)
    return arr, grown


def _settle_resting(arr: Arrangement, cid: str) -> Arrangement | None:
    """``arr`` with the overlaps of box ``cid`` cleared where they are a box resting on
    another (:func:`_resting_cut`) or where ``cid`` reaches into the other by at most a
    tenth of its extent (the plank on a block that a deepening made reach under it);
    None when another overlap remains."""
    for _ in range(4):
        pens = [(a, b) for a, b, _ in find_contacts(arr).penetrations if cid in (a, b)]
        if not pens:
            return arr
        cubs = list(arr.cuboids)
        for a, b in pens:
            if b.startswith(("ground", "wall:")):
                return None
            ia, ib = arr.index[a], arr.index[b]
            rest = _resting_cut(cubs[ia], cubs[ib])
            if rest is not None:
                cubs[ia], cubs[ib] = rest
                continue
            # else the deepened box gives way where it reaches least far, if by little
            k, other = (ia, cubs[ib]) if a == cid else (ib, cubs[ia])
            face = _overlap_face(cubs[k], other)
            if face is None or face[0] > 0.1 * float(cubs[k].size[face[1]]):
                return None
            cubs[k] = _shrink_against(cubs[k], other)
        arr = arr.with_(cuboids=tuple(cubs))
    return None


#: :func:`join_parts` trims a box in the way of a join by at most this much (metres) or
#: this fraction of the box's extent there, whichever is larger.
JOIN_TRIM_ABS = 0.02
JOIN_TRIM_REL = 0.1
#: ... and never more than this share of it (the absolute allowance is for a board's
#: noisy edge, not for clearing a box thinner than it).
JOIN_TRIM_MAX_SHARE = 0.5


def join_parts(arr: Arrangement, max_rounds: int = 64, views: list[DepthView] | None = None,
               margin: float = 0.0) -> tuple[Arrangement, list[str]]:
    """Extend parts of one object to meet where a short extension does, trimming the
    noisy edge of another object's box that is in the way.

    A shelf's board whose end was not seen stops a few centimetres short of its side
    panel, and the book standing at that end, fitted to its visible points, reaches a
    centimetre below the board's top there.  The search would reject the join (it
    drives the board into the book) and the book would be extended to the floor past
    the board.  Here a join whose extensions are short (:func:`pipeline.search.short_join`)
    is applied when every box it enters belongs to another object
    and gives way by at most :data:`JOIN_TRIM_ABS` or :data:`JOIN_TRIM_REL` of its extent
    (the face that reaches least far in), and never by more than
    :data:`JOIN_TRIM_MAX_SHARE` of it.  With ``views``, two parts already held together
    through their object's other parts (a screen on its neck on its foot) are not joined
    through space a view saw empty (:func:`pipeline.extend.prune_by_visibility`'s test)
    nor by an extension that runs along a third part touching both
    (:func:`pipeline.search.along_link`);
    parts nothing else holds together are joined as before.  Two parts that no single
    extension joins may be joined across a corner by two short ones
    (:func:`_corner_joins`: a desk's panel just past the end of its top).  Smallest
    added volume first; returns the arrangement and ``"a+b"`` for each pair joined.
    """
    from .extend import MAX_EXTENSION_REL, apply_offsets, offsets_of, pair_edges
    from .search import along_link, short_join, touching_links

    if not any(c.object is not None for c in arr.cuboids):
        return arr, []
    joined: list[str] = []
    max_ext = MAX_EXTENSION_REL * arr.scale_length()
    for _ in range(max_rounds):
        K = len(arr.cuboids)
        trials = []
        held = _same_object_groups(arr) if views else {}
        reached = set()  # pairs that touch or that one extension joins
        edges = [e for e in pair_edges(arr, max_ext, same_object=True)
                 if e.same_object and not isinstance(e.b, str)]
        links = touching_links(edges)  # parts of one object touching each other
        for e in edges:
            if e.touching or any(short_join(arr, o) for o in e.options):
                reached.add((min(e.a, e.b), max(e.a, e.b)))
            if e.touching:
                continue
            # parts already held together through their object's other parts (a screen
            # on its neck on its foot) do not grow through space the sensor saw empty,
            # nor along a part that touches them both (beside the neck onto the foot)
            both = held and held.get(e.a) == held.get(e.b)
            trials += [(o.volume, e.a, e.b, o) for o in e.options
                       if o.extensions and short_join(arr, o)
                       and not (both and (_seen_through(arr, o.extensions, views, margin)
                                          or along_link(arr, o.extensions, links,
                                                        e.a, e.b)))]
        for a, b, o in _corner_joins(arr, max_ext, reached):
            if not (held and held.get(a) == held.get(b)
                    and _seen_through(arr, o.extensions, views, margin)):
                trials.append((o.volume, a, b, o))
        touched: set[int] = set()  # boxes changed this round: their trials wait
        for _vol, a, b, o in sorted(trials, key=lambda t: (t[0], t[1], t[2])):
            grown = {x.box for x in o.extensions}
            if touched & ({a, b} | grown):
                continue
            geom = apply_offsets(arr, offsets_of(list(o.extensions), K))
            cubs = list(geom.cuboids)
            near = _near(geom, grown)  # only boxes near the grown ones can be entered
            local = geom.with_(cuboids=tuple(cubs[n] for n in near))
            ok = True
            for p, q, _depth in find_contacts(local).penetrations:
                kp, kq = geom.index.get(p), geom.index.get(q)
                if kp is None or kq is None or (kp in grown and kq in grown):
                    ok = False  # into a support, or two grown boxes into each other
                    break
                if kp not in grown and kq not in grown:
                    continue  # an overlap the join did not make
                k, other = (kq, kp) if kp in grown else (kp, kq)
                r = cubs[k]
                if r.object is not None and r.object == cubs[other].object:
                    ok = False
                    break
                face = _overlap_face(r, cubs[other])
                if face is None:
                    continue
                depth, axis, side = face
                if depth > min(max(JOIN_TRIM_ABS, JOIN_TRIM_REL * float(r.size[axis])),
                               JOIN_TRIM_MAX_SHARE * float(r.size[axis])):
                    ok = False  # (2 cm of a 12 mm book would leave a negative size)
                    break
                u = r.rotation[:, axis] * (1.0 if side else -1.0)
                size = r.size.copy()
                size[axis] -= depth
                cubs[k] = r.with_(center=r.center - u * depth / 2, size=size)
            if not ok:
                continue
            trial = arr.with_(cuboids=tuple(cubs))
            changed = {n for n, (c, before) in enumerate(zip(cubs, arr.cuboids))
                       if c is not before}
            names = {cubs[n].id for n in changed}
            local = trial.with_(cuboids=tuple(cubs[n] for n in near))
            if any(p in names or q in names for p, q, _ in find_contacts(local).penetrations):
                continue
            arr = trial
            touched |= changed | {a, b}
            joined.append(f"{arr.cuboids[a].id}+{arr.cuboids[b].id}")
        if not touched:
            break
    return arr, joined


def _corner_joins(arr: Arrangement, max_ext: float, skip: set[tuple[int, int]]):
    """Joins of two parts of one object apart across a corner: ``(a, b, option)``.

    A part that sits just beyond the end of another and a little off its face (a desk's
    side panel 2 mm past the end of a top shrunk by noise and 6 cm below it; a chair's
    back just behind the seat's rear edge and just above it) meets it by no single
    extension: one box's face reaches past the other's far side (the top over the whole
    panel), then the other's face reaches it (the panel up to the top).  Both must be
    short (:data:`pipeline.search.SHORT_JOIN` of the box's extent) and the two must then
    touch.  Smallest added volume first, except that a part hanging above the other's
    end grows down past it first where that takes its bottom near the floor (within
    :data:`pipeline.search.SHORT_JOIN` of its height: a shelf's side panel, fitted down
    to the top of the bottom board in front of it, reaches past the board and the board
    meets its face, rather than the board sliding in under the panel and the panel
    standing on it, out of the floor's reach), and last where it would end hanging
    beside the other far above the floor (a chair's back rests on its seat).  Pairs in
    ``skip`` (touching, or joined by one extension) are not tried.
    """
    from .contacts import candidate_pairs
    from .extend import Extension, Option
    from .model import box_corners
    from .search import SHORT_JOIN

    K = len(arr.cuboids)
    if K < 2:
        return []
    C, R, S = arr.centers, arr.rotations, arr.sizes
    ii, jj = candidate_pairs(C, R, S, max_ext)
    corners = box_corners(C, R, S)
    floor = next((float(s.point[2]) for s in arr.supports
                  if s.id == "ground" and s.normal[2] > 0.99), None)
    out = []
    for i, j in zip(ii.tolist(), jj.tolist()):
        ci, cj = arr.cuboids[i], arr.cuboids[j]
        if ci.object is None or ci.object != cj.object or (i, j) in skip:
            continue
        tol = float(pair_tolerance(S[i], S[j]))
        best, best_key = None, None
        for a, b in ((i, j), (j, i)):
            for axis in range(3):
                u = R[a][:, axis]
                for side in (0, 1):
                    sgn = 1.0 if side else -1.0
                    face = sgn * (C[a] @ u) + S[a, axis] / 2
                    proj = sgn * (corners[b] @ u) - face
                    near, far = float(proj.min()), float(proj.max())
                    if near < -tol or far <= tol or far > SHORT_JOIN * S[a, axis]:
                        continue
                    x1 = Extension(a, axis, side, far)
                    grown = _grown(arr.cuboids[a], x1)
                    # the other box reaches the grown one through the face nearest it
                    for axis2 in range(3):
                        v = R[b][:, axis2]
                        for side2 in (0, 1):
                            sgn2 = 1.0 if side2 else -1.0
                            face2 = sgn2 * (C[b] @ v) + S[b, axis2] / 2
                            gap = float((sgn2 * (grown.corners() @ v) - face2).min())
                            if gap <= tol or gap > SHORT_JOIN * S[b, axis2]:
                                continue
                            x2 = Extension(b, axis2, side2, gap)
                            other = _grown(arr.cuboids[b], x2)
                            sep, _, _ = sat_separation(
                                grown.center[None], grown.rotation[None], grown.size[None] / 2,
                                other.center[None], other.rotation[None], other.size[None] / 2,
                                np.array([tol]))
                            if abs(float(sep[0])) > tol:
                                continue
                            vol = x1.volume(S) + x2.volume(S)
                            # a part hanging over the other's end grows down past it
                            # (its bottom there is where the other hid it) rather than
                            # the other sliding in under it, when that takes it down
                            # near the floor (a shelf's side panel past its bottom
                            # board); one that would end hanging beside the other, far
                            # above the floor (a chair's back beside its seat), rests
                            # on it instead
                            down = 1
                            if sgn * u[2] < -0.9 and _z_range(
                                    arr.cuboids[a])[0] >= _z_range(arr.cuboids[b])[1] - tol:
                                low = _z_range(grown)[0]
                                down = 0 if floor is not None and low - floor <= \
                                    SHORT_JOIN * (_z_range(grown)[1] - low) else 2
                            if best is None or (down, vol) < best_key:
                                best, best_key = Option("fixed", (x1, x2), vol), (down, vol)
        if best is not None:
            out.append((i, j, best))
    return out


def _grown(c: Cuboid, x) -> Cuboid:
    """``c`` with extension ``x`` applied (its face pushed out by ``x.length``)."""
    u = c.rotation[:, x.axis] * (1.0 if x.side else -1.0)
    size = c.size.copy()
    size[x.axis] += x.length
    return c.with_(center=c.center + u * x.length / 2, size=size)


def _same_object_groups(arr: Arrangement) -> dict[int, int]:
    """Box index -> a label shared by the parts of one object that touch, directly or
    through its other parts."""
    parent = list(range(len(arr.cuboids)))

    def find(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    idx = arr.index
    for a, b in find_contacts(arr).pairs:
        ia, ib = idx.get(a), idx.get(b)
        if (ia is not None and ib is not None and arr.cuboids[ia].object is not None
                and arr.cuboids[ia].object == arr.cuboids[ib].object):
            parent[find(ia)] = find(ib)
    return {k: find(k) for k in range(len(arr.cuboids)) if arr.cuboids[k].object is not None}


def _seen_through(arr: Arrangement, extensions, views: list[DepthView] | None,
                  margin: float) -> bool:
    """Whether a view saw empty some slab the ``extensions`` would add (as
    :func:`pipeline.extend.prune_by_visibility` judges a candidate)."""
    from .extend import FREE_FRACTION_MAX, slab_samples, visible_free_fraction

    return bool(views) and any(
        visible_free_fraction(slab_samples(arr, x), views, margin) > FREE_FRACTION_MAX
        for x in extensions)


def _near(arr: Arrangement, ids: set[int], pad: float = 0.01) -> list[int]:
    """Indices of the boxes whose world bounds come within ``pad`` of those of the boxes
    ``ids`` (themselves included), in order."""
    half = np.einsum("kij,kj->ki", np.abs(arr.rotations), arr.sizes / 2.0)
    lo, hi = arr.centers - half, arr.centers + half
    sel = sorted(ids)
    mask = np.zeros(len(arr.cuboids), bool)
    for k in sel:
        mask |= np.all((lo <= hi[k] + pad) & (hi >= lo[k] - pad), axis=1)
    return np.nonzero(mask)[0].tolist()


def _single_part(arr: Arrangement, c: Cuboid) -> bool:
    """Whether ``c`` is the only part of its object (or has no object)."""
    return c.object is None or not any(o.object == c.object and o.id != c.id
                                       for o in arr.cuboids)


def _object_depth(arr: Arrangement, c: Cuboid, axis: int) -> float:
    """How far the other parts of ``c``'s object span along ``c``'s ``axis`` together
    (inf when it has none): how deep the object shows itself to be there (a table's
    legs front and back span its top's depth; a shelf's panels and boards, its boards')."""
    if c.object is None:
        return float("inf")
    u = c.rotation[:, axis]
    proj = [o.corners() @ u for o in arr.cuboids if o.object == c.object and o.id != c.id]
    if not proj:
        return float("inf")
    proj = np.concatenate(proj)
    return float(proj.max() - proj.min())


def _object_reach(arr: Arrangement, c: Cuboid, u: np.ndarray) -> float:
    """How far the other parts of ``c``'s object reach beyond ``c``'s centre along the
    unit vector ``u`` (inf when it has none): a chair's back, seen face-on at the rear
    of its seat, has the seat's rear edge a few centimetres behind it, not the seat's
    depth."""
    if c.object is None:
        return float("inf")
    proj = [o.corners() @ u for o in arr.cuboids if o.object == c.object and o.id != c.id]
    if not proj:
        return float("inf")
    return float(np.concatenate(proj).max() - c.center @ u)


def _vertical_axis(c: Cuboid) -> int | None:
    """The local axis of an upright box that points up or down (None when tilted)."""
    ax = int(np.argmax(np.abs(c.rotation[2])))
    return ax if abs(c.rotation[2, ax]) > 0.99 else None


#: A box under another is a slab it rests on (:func:`_resting_cut`) when its footprint
#: is this many times the upper box's and it is at most half as tall.
SLAB_AREA_RATIO = 4.0


def _resting_cut(a: Cuboid, b: Cuboid, slabs: float | None = None
                 ) -> tuple[Cuboid, Cuboid] | None:
    """Clear the overlap of a box resting on a broader one at the face they share.

    When one upright box's bottom lies in the upper three quarters of a broader upright box
    at most half as tall again and its top above it (a book whose noisy bottom reaches
    into the thick-looking board under it; not two books side by side), the
    overlap is depth noise at the interface they rest on: the upper box's bottom rises
    (by at most half of its height; beyond that the lower box's top drops by half the
    overlap and the upper's bottom rises by the other half).  Cutting the board's end
    instead shortened it one book at a time until it no longer reached its side panel.

    With ``slabs``, the floor's height (initial boxes, whose overlaps are fitting noise),
    the lower box may also be a slab: a footprint :data:`SLAB_AREA_RATIO` times the
    upper's, at most half as tall as the upper box and as half its own narrower side,
    that the upper box's bottom reaches down to (at most half the slab's height below
    it, and not down to the floor: a sofa's back stands beside its seat).  A shelf's bottom
    board 4 m away is fitted several centimetres high and thick, and the books on it,
    their bottoms as noisy, end at its underside; cutting the board's ends instead let
    the books reach past it to the floor.  Returns the two boxes ``(a, b)`` after the
    cut, or None when the pair is not of that kind or cannot be cleared that way.
    """
    ax_a, ax_b = _vertical_axis(a), _vertical_axis(b)
    if ax_a is None or ax_b is None:
        return None
    za, zb = _z_range(a), _z_range(b)
    if za[0] + za[1] < zb[0] + zb[1]:  # a is the lower one
        r = _resting_cut(b, a, slabs)
        return None if r is None else (r[1], r[0])
    (lo_u, hi_u), (lo_l, hi_l) = za, zb
    area_u = float(np.prod(np.delete(a.size, ax_a)))
    area_l = float(np.prod(np.delete(b.size, ax_b)))
    h_u, h_l = hi_u - lo_u, hi_l - lo_l
    slab = slabs is not None and (
        area_l >= SLAB_AREA_RATIO * area_u and h_l <= 0.5 * h_u
        and h_l <= 0.5 * np.delete(b.size, ax_b).min() and lo_u > slabs + 0.5 * h_l
        and lo_l - 0.5 * h_l < lo_u < hi_l < hi_l + 0.25 * h_u < hi_u)
    if not (slab or (area_l >= area_u and h_l <= 1.5 * h_u
                     and lo_l + 0.25 * h_l < lo_u < hi_l < hi_u)):
        return None
    tol = float(pair_tolerance(a.size[None], b.size[None])[0])
    cut = hi_l - lo_u + 0.25 * tol
    if cut <= 0.5 * a.size[ax_a]:  # the upper box's bottom rises
        cut_u, cut_l = cut, 0.0
    elif 0.5 * cut <= 0.5 * min(a.size[ax_a], b.size[ax_b]):  # both give way
        cut_u = cut_l = 0.5 * cut
    else:
        return None
    sa, sb = a.size.copy(), b.size.copy()
    sa[ax_a] -= cut_u
    sb[ax_b] -= cut_l
    return (a.with_(center=a.center + [0.0, 0.0, cut_u / 2], size=sa),
            b if cut_l == 0.0 else b.with_(center=b.center - [0.0, 0.0, cut_l / 2], size=sb))


def _penetrating(a: Cuboid, b: Cuboid) -> bool:
    """Whether two boxes overlap by more than their contact tolerance."""
    tol = pair_tolerance(a.size[None], b.size[None])
    sep, _, _ = sat_separation(a.center[None], a.rotation[None], a.size[None] / 2,
                               b.center[None], b.rotation[None], b.size[None] / 2, tol)
    return bool(sep[0] < -tol[0])


def _same_part(a: Cuboid, b: Cuboid) -> bool:
    """False when the segmentation gave the two boxes different part ids."""
    ia, ib = a.extra.get("instance"), b.extra.get("instance")
    return ia is None or ib is None or ia == ib


def _same_axes(a: Cuboid, b: Cuboid, cos_tol: float = np.cos(np.radians(5))) -> bool:
    """True when the boxes' axes coincide up to order and sign (within 5 degrees)."""
    M = np.abs(a.rotation.T @ b.rotation)
    return bool(np.all(M.max(axis=1) > cos_tol))


def _merge(a: Cuboid, b: Cuboid) -> Cuboid:
    """The box in ``a``'s frame that bounds both ``a`` and ``b`` (keeps ``a``'s id)."""
    local = (b.corners() - a.center) @ a.rotation
    lo = np.minimum(-a.size / 2, local.min(axis=0))
    hi = np.maximum(a.size / 2, local.max(axis=0))
    center = a.center + a.rotation @ ((lo + hi) / 2)
    extra = dict(a.extra)
    extra["points"] = int(a.extra.get("points", 0)) + int(b.extra.get("points", 0))
    obs = ObservedBox(center, hi - lo)
    return Cuboid(a.id, center, a.rotation, hi - lo, a.density, a.object, obs, extra)


#: When two overlapping boxes would each lose more than half through their least
#: overlapping face, one fitted to at least this many times the other's points keeps the
#: disputed space (:func:`repair_overlaps`).
EVIDENCE_RATIO = 4.0


#: A weak box askew to the box it reaches into by more than this many degrees about the
#: vertical first takes that box's axes (:func:`_square_to`).
SQUARE_MIN_DEG = 10.0


def _square_to(c: Cuboid, other: Cuboid, min_deg: float = SQUARE_MIN_DEG) -> Cuboid:
    """``c`` turned about the vertical through its centre onto the axes of ``other``
    (both upright, the turn of at most 45 degrees that does it) when they are more than
    ``min_deg`` apart and ``c`` would clear ``other`` sideways; otherwise ``c`` (a book
    lying askew on another is cut from below, where its yaw does not matter).

    A box fitted to a few dozen points can come out turned by 40 degrees (a book seen
    by its spine next to a shelf's side panel).  Cut against the panel's faces it never
    clears it: every cut is capped at half the box, and ten rounds leave a sliver of a
    few millimetres that then blocks the panel from reaching the floor.  Turned onto the
    panel's axes first, one cut (or none) clears it.
    """
    from .model import rotation_about_axis

    up = np.array([0.0, 0.0, 1.0])
    if (c.extra.get("slanted") or abs(c.rotation[2]).max() < 1 - 1e-9
            or abs(other.rotation[2]).max() < 1 - 1e-9):
        return c
    ax_c = next(k for k in range(3) if abs(c.rotation[2, k]) < 0.5)
    ax_o = next(k for k in range(3) if abs(other.rotation[2, k]) < 0.5)
    a = np.arctan2(c.rotation[1, ax_c], c.rotation[0, ax_c])
    b = np.arctan2(other.rotation[1, ax_o], other.rotation[0, ax_o])
    turn = (b - a + np.pi / 4) % (np.pi / 2) - np.pi / 4
    face = _overlap_face(c, other, by_share=True)
    if (abs(np.degrees(turn)) <= min_deg or face is None
            or abs(c.rotation[2, face[1]]) > 0.5):  # cleared from above or below: no turn
        return c
    return c.with_(rotation=rotation_about_axis(up, turn) @ c.rotation)


def _side_by_side(a: Cuboid, b: Cuboid) -> bool:
    """Whether two upright boxes stand side by side: each at least as tall as its narrower
    horizontal side (no slab), their bottoms level within a quarter of the lower box's
    height (two books on one board, neither on the other)."""
    for c in (a, b):
        ax = _vertical_axis(c)
        if ax is None or c.size[ax] < np.delete(c.size, ax).min():
            return False
    (lo_a, hi_a), (lo_b, hi_b) = _z_range(a), _z_range(b)
    return abs(lo_a - lo_b) <= 0.25 * min(hi_a - lo_a, hi_b - lo_b)


def _points(c: Cuboid) -> float:
    """The points a box was fitted to (1 when unknown: every box counts alike)."""
    return max(float(c.extra.get("points", 1)), 1.0)


def _face_on_axis(c: Cuboid, eye: np.ndarray) -> int | None:
    """The horizontal axis of ``c`` within 45 degrees of the horizontal viewing
    direction from ``eye`` when ``c`` is a slab seen face-on along it (its extent there
    below :data:`THIN_FRACTION` of its other horizontal extent), else None."""
    look = c.center - eye
    look[2] = 0.0
    if np.linalg.norm(look) < 1e-9:
        return None
    look /= np.linalg.norm(look)
    horizontal = [a for a in range(3) if abs(c.rotation[2, a]) <= 0.5]
    for axis in horizontal:
        width = max((float(c.size[a]) for a in horizontal if a != axis), default=0.0)
        if (abs(float(c.rotation[:, axis] @ look)) >= np.cos(np.radians(45.0))
                and c.size[axis] < THIN_FRACTION * width):
            return axis
    return None


def _overlap_face(c: Cuboid, other: Cuboid, by_share: bool = False,
                  skip: int | None = None, sideways: bool = False
                  ) -> tuple[float, int, int] | None:
    """(overlap, axis, side) of the face of ``c`` reaching least far into ``other``
    (``by_share``: whose retreat costs ``c`` the smallest share of its extent there),
    not along axis ``skip`` (``sideways``: of its upright faces only)."""
    best, least = None, None
    for ax in range(3):
        if ax == skip or (sideways and abs(c.rotation[2, ax]) > 0.5):
            continue
        for side in (0, 1):
            u = c.rotation[:, ax] * (1 if side else -1)
            face = c.center @ u + c.size[ax] / 2
            proj = other.corners() @ u
            overlap = face - proj.min()  # how far c reaches into the other along u
            key = overlap / max(float(c.size[ax]), 1e-12) if by_share else overlap
            if overlap > 0 and (least is None or key < least):
                best, least = (float(overlap), ax, side), key
    return best


def _relative_overlap(c: Cuboid, other: Cuboid, by_share: bool = False,
                      skip: int | None = None, sideways: bool = False) -> float:
    """The share of its extent ``c`` would lose to clear ``other`` (inf when it cannot)."""
    best = _overlap_face(c, other, by_share, skip, sideways)
    return float("inf") if best is None else best[0] / float(c.size[best[1]])


def _shrink_against(c: Cuboid, other: Cuboid, share: float = 1.0,
                    by_share: bool = False, skip: int | None = None,
                    sideways: bool = False) -> Cuboid:
    """Move the face of ``c`` that overlaps ``other`` back by ``share`` of the overlap
    (at most half of ``c``'s extent there)."""
    tol = float(pair_tolerance(c.size[None], other.size[None])[0])
    best = _overlap_face(c, other, by_share, skip, sideways)
    if best is None:
        return c
    overlap, ax, side = best
    cut = min(share * overlap + 0.25 * tol, 0.5 * c.size[ax])
    if cut <= 0:
        return c
    size = c.size.copy()
    size[ax] -= cut
    u = c.rotation[:, ax] * (1 if side else -1)
    return c.with_(center=c.center - u * cut / 2, size=size)


def _lift_from_plane(c: Cuboid, sup) -> Cuboid:
    """Trim the part of ``c`` below a support plane (an upright box loses its bottom)."""
    d = sup.signed_distance(c.corners())
    depth = -d.min()
    if depth <= 0:
        return c
    cos = np.abs(c.rotation.T @ sup.normal)
    ax = int(np.argmax(cos))
    cut = min(depth / max(cos[ax], 1e-6), 0.9 * c.size[ax])
    size = c.size.copy()
    size[ax] -= cut
    u = c.rotation[:, ax] * np.sign(c.rotation[:, ax] @ sup.normal)
    return c.with_(center=c.center + u * cut / 2, size=size)


def connect_objects(final: Arrangement, initial: Arrangement, edges, mu: float = 0.7,
                    threshold: float | None = None) -> tuple[Arrangement, int]:
    """Join the parts of an object that the search left apart (an object is one rigid,
    connected body: a table's leg reaches its top even when it could stand alone).

    For each object whose parts fall into several groups through ``fixed`` contacts, the
    cheapest same-object extension between two groups (its face pushed to where the
    candidate put it) is applied and kept when the whole still stands and nothing
    interpenetrates.  Returns (arrangement, joins made).
    """
    from .search import finalize

    joins = 0
    for obj in sorted({c.object for c in final.cuboids if c.object is not None}):
        members = [c.id for c in final.cuboids if c.object == obj]
        if len(members) < 2:
            continue
        for _ in range(len(members)):
            comp = _components_of(members, final.contacts)
            if len(set(comp.values())) < 2:
                break
            options = []
            for e in edges:
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
                    trial = _push_face(trial, initial, x)
                fixed = [c for c in trial.contacts if c.type == "fixed"]
                fixed.append(Contact(a, b, "fixed"))
                if find_contacts(trial).penetrations:
                    continue
                try:
                    cand = finalize(trial, fixed, mu=mu, threshold=threshold)
                except InputError:  # they do not touch after all
                    continue
                if cand.stability is not None and cand.stability.stable:
                    final, joined = cand, True
                    joins += 1
                    break
            if not joined:
                break
    return final, joins


def anchor_parts(final: Arrangement, initial: Arrangement, edges, mu: float = 0.7,
                 threshold: float | None = None) -> tuple[Arrangement, list[str]]:
    """Fix to a wall every part of an object that the wall holds.

    An object fixed to a wall (a wall shelf's board) hangs there as one rigid body; its
    other parts against that wall (the brackets under the board) are fixed to it too.  A
    part whose face toward the wall stops short of it by at most its own extent there
    (a bracket seen only at its front) is extended to the wall first, as the candidate
    extension put it (space no view saw empty, nothing entered).  Each change is kept
    when the arrangement still stands.  Returns the arrangement and the ``part|wall``
    pairs fixed.
    """
    from .search import finalize

    objects = {c.id: c.object for c in final.cuboids}
    held: dict[str, set[str]] = {}
    for c in final.contacts:
        for a, b in ((c.a, c.b), (c.b, c.a)):
            if (c.type == "fixed" and b.startswith("wall:") and objects.get(a) is not None):
                held.setdefault(objects[a], set()).add(b)
    if not held:
        return final, []
    reach = {}
    for e in edges:
        if isinstance(e.b, str) and e.b.startswith("wall:"):
            ext = [o for o in e.options if o.type == "fixed" and len(o.extensions) == 1]
            x = ext[0].extensions[0] if ext else None
            if x is not None and x.length <= float(initial.sizes[x.box, x.axis]):
                reach[(initial.cuboids[e.a].id, e.b)] = x
    done: list[str] = []
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
                    trial = _push_face(final, initial, reach[(m, wall)])
                    cs = find_contacts(trial)
                    if (any(m in (a, b) for a, b, _ in cs.penetrations)
                            or tuple(sorted((m, wall))) not in cs.lookup()):
                        continue
                try:
                    cand = finalize(trial, [*fixed, Contact(m, wall, "fixed")], mu=mu,
                                    threshold=threshold)
                except InputError:
                    continue
                if cand.stability is not None and cand.stability.stable:
                    final = cand
                    done.append(f"{m}|{wall}")
    return final, done


def ground_parts(final: Arrangement, initial: Arrangement, edges, mu: float = 0.7,
                 threshold: float | None = None) -> tuple[Arrangement, list[str]]:
    """Stand on the floor every part of a grounded object that hangs from its other
    parts only by glue.

    Glue between the parts of one object costs the search nothing, so a part whose
    bottom the sensor never saw (a sofa's arm seen from behind, only its top) hangs
    from the back it is fused to rather than being extended to the floor, and a table's
    leg seen only at its top hangs from the table top while three others stand.  A part
    of an object with a grounded part, not itself on the floor and fused to exactly one
    other part (not a shelf's bottom board between its two sides, nor a seat on its
    legs), whose drop to the floor is as for :func:`hidden_supports`
    (more than :data:`HIDDEN_DROP_REL` times its seen height and
    :data:`HIDDEN_MIN_DROP`), is extended down as the candidate extension put it (space
    no view saw empty, nothing entered) and touches the floor; each change is kept when
    the arrangement still stands.  Returns the arrangement and the ids of the parts
    grounded.
    """
    from .search import finalize

    grounded = {c.a for c in final.contacts if c.b == "ground"} | \
        {c.b for c in final.contacts if c.a == "ground"}
    objects = {final.cuboid(g).object for g in grounded
               if g in final.index and final.cuboid(g).object is not None}
    if not objects:
        return final, []
    reach = {}
    for e in edges:
        if e.b == "ground":
            ext = [o for o in e.options if o.type == "touch" and len(o.extensions) == 1]
            if ext:
                reach[initial.cuboids[e.a].id] = ext[0].extensions[0]
    done: list[str] = []
    for c in list(final.cuboids):
        if (c.object not in objects or c.id in grounded or c.id not in reach
                or c.extra.get("hallucinated")):
            continue
        # hanging from one part (an arm from the back, a leg from the top), not
        # spanning between several (a shelf's bottom board between its sides, a seat
        # on its legs)
        glued = {k.b if k.a == c.id else k.a for k in final.contacts
                 if k.type == "fixed" and c.id in (k.a, k.b)}
        if len(glued) != 1:
            continue
        # ... a drop the sensor could not have seen the part's bottom across: more than
        # it saw of the part's height (an arm seen as its top), not a bottom board's
        # few centimetres over the floor
        drop = float(reach[c.id].length)
        seen = c.observed.size if c.observed is not None else c.size
        height = float(seen[int(np.argmax(np.abs(c.rotation[2])))])
        if drop < max(HIDDEN_MIN_DROP, HIDDEN_DROP_REL * height):
            continue
        trial = _push_face(final, initial, reach[c.id])
        cs = find_contacts(trial)
        if (any(c.id in (a, b) for a, b, _ in cs.penetrations)
                or tuple(sorted((c.id, "ground"))) not in cs.lookup()):
            continue
        fixed = [k for k in final.contacts if k.type == "fixed"]
        try:
            cand = finalize(trial, fixed, mu=mu, threshold=threshold)
        except InputError:
            continue
        if cand.stability is not None and cand.stability.stable:
            final = cand
            done.append(c.id)
    return final, done


#: Gaps between two boxes up to this long (metres), in space no view saw empty, are
#: closed by :func:`close_hidden_gaps` (about three standard deviations of Kinect depth
#: noise at 2 m).
GAP_CLOSE = 0.02
#: ... and gaps between a box and a wall up to this many times as long (a wall is seen
#: as a plane fitted to many points; the box's back face is a guess from its front).
WALL_GAP_CLOSE_REL = 1.5
#: A face at least this many square metres (the back of a sofa) is, like a wall, a plane
#: fitted to many points: a box's own face is pushed to it across up to
#: :data:`WALL_GAP_CLOSE_REL` times the gap between two boxes (:func:`_facing_push`).
BROAD_FACE_AREA = 0.5
#: A push whose box reaches at most this far (metres) into boxes it already touches
#: (a corner of a box a degree askew) is made by :func:`pipeline.snap.close_pair`.
GRAZE_DEPTH = 0.001
#: A box's top is raised to the underside of a box above it across a hidden gap up to
#: this long (metres) when the box above rests on a neighbour that stands on the same
#: level (a row of boxes, a bridge's two pillars: the fitted heights of two supports
#: differ by the noise of two fits, and the upper box rests on the taller one) ...
LEVEL_GAP_CLOSE = 0.04
#: ... where the two bottoms are within this distance (metres).
LEVEL_TOL = 0.015
#: :func:`close_hidden_gaps` pushes a box's own face to the other box (beyond the pair's
#: candidate extensions) only between faces the sensor saw: within this distance
#: (metres) of where their box's observed face was (not one a deepening placed) ...
SEEN_FACE_TOL = 0.005
#: ... and that face each other (normals within 5 degrees): a corner of a box turned
#: against the other's face is where the fit saw it.
GAP_FACE_COS = float(np.cos(np.radians(5.0)))


def _face_seen(c: Cuboid, u: np.ndarray) -> bool:
    """Whether the face of ``c`` whose outward normal is nearest the unit vector ``u`` is
    where the sensor saw it (its observed box's face, within :data:`SEEN_FACE_TOL`)."""
    o = c.observed
    if o is None:
        return False
    cos = c.rotation.T @ u
    axis = int(np.argmax(np.abs(cos)))
    w = c.rotation[:, axis] * np.sign(cos[axis])
    face = float(c.center @ w) + float(c.size[axis]) / 2
    seen = float(np.asarray(o.center) @ w) + float(np.asarray(o.size)[axis]) / 2
    return face - seen <= SEEN_FACE_TOL


def _levelled(arr: Arrangement, touching, x, other: int) -> bool:
    """Whether extension ``x`` raises the top of its box to the underside of box
    ``other``, which rests on a neighbour standing on the same level as the box
    (:data:`LEVEL_TOL`): the gap between them is then a difference of fitted heights."""
    from .model import box_corners

    c = arr.cuboids[x.box]
    if c.rotation[2, x.axis] * (1.0 if x.side else -1.0) < 0.9:
        return False
    z = box_corners(arr.centers, arr.rotations, arr.sizes)[..., 2]
    bottom, top = z.min(axis=1), z.max(axis=1)
    if bottom[other] < top[x.box]:
        return False
    lower, upper = arr.cuboids[x.box].id, arr.cuboids[other].id
    index = {cid: k for k, cid in enumerate(arr.ids)}
    for p, q in touching:
        s = q if p == upper else p if q == upper else None
        if s is None or s == lower or is_support_id(s):
            continue
        k = index[s]
        if (abs(bottom[k] - bottom[x.box]) <= LEVEL_TOL
                and abs(top[k] - bottom[other]) <= LEVEL_TOL):
            return True
    return False


def _under_a_held_part(arr: Arrangement, a: str, b: str, x, rigid: dict[str, int]) -> bool:
    """Whether closing the vertical gap of extension ``x`` between ``a`` and ``b`` would
    put the top of one box against the underside of a part of another object that is
    fused to other parts of its own object (a book's top against the board above it:
    the board is held by its shelf, and the book under it touches it only by chance;
    a bridge's deck glued to another deck still rests on its pillars)."""
    c = arr.cuboids[x.box]
    if abs(c.rotation[2, x.axis]) < 0.9:
        return False  # a sideways push
    lower, upper = sorted((a, b), key=lambda i: float(arr.cuboid(i).center[2]))
    if arr.cuboid(lower).object == arr.cuboid(upper).object:
        return False
    obj = arr.cuboid(upper).object
    return obj is not None and sum(1 for i, v in rigid.items() if v == rigid[upper]
                                   and arr.cuboid(i).object == obj) > 1


def _broad_face(c: Cuboid, u: np.ndarray) -> bool:
    """Whether the face of ``c`` whose outward normal is nearest ``u`` is at least
    :data:`BROAD_FACE_AREA` square metres (the back of a sofa, a shelf's side panel)."""
    axis = int(np.argmax(np.abs(c.rotation.T @ u)))
    return float(np.prod(np.delete(c.size, axis))) >= BROAD_FACE_AREA


def _facing_push(arr: Arrangement, k: int, other: Cuboid, max_len: float, steps: int = 32,
                 broad_len: float | None = None):
    """The shortest push of one face of box ``k`` that makes it just touch ``other`` (an
    :class:`pipeline.extend.Extension`), or None when no push of at most ``max_len``
    does.  Only faces that face one of ``other``'s faces the sensor saw are pushed
    (:func:`_face_seen`, :data:`GAP_FACE_COS`; the pushed face may be a guess, a
    deepened cushion's rear face).  Towards a broad face of ``other``
    (:func:`_broad_face`) the push may be ``broad_len`` long.  A cushion a few degrees off its sofa's
    back in yaw: the back's corners reach past the cushion's rear face plane, so the
    candidate edges offer only to push the back (its whole face, into the arms beside
    it).  The length is found on a grid of ``steps`` and refined on a second one
    (``max_len / steps**2``), all faces in one separating-axis call each."""
    from .extend import Extension

    c = arr.cuboids[k]
    faces = []
    for axis in range(3):
        for side in (0, 1):
            u = c.rotation[:, axis] * (1.0 if side else -1.0)
            if (float(u @ (other.center - c.center)) > 0.0
                    and np.max(np.abs(other.rotation.T @ u)) >= GAP_FACE_COS
                    and _face_seen(other, -u)):
                faces.append((axis, side, u))
    if not faces:
        return None
    reach = np.array([broad_len if broad_len is not None and _broad_face(other, -u)
                      else max_len for _, _, u in faces])
    tol = float(pair_tolerance(c.size[None], other.size[None])[0])

    def first_touch(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Per face, the smallest grid length in [lo, hi] at which the boxes meet (inf)."""
        t = np.linspace(0.0, 1.0, steps + 1)[1:]
        L = lo[:, None] + (hi - lo)[:, None] * t[None, :]  # (F, steps)
        U = np.array([u for _, _, u in faces])
        ax = np.array([a for a, _, _ in faces])
        n = L.size
        size = np.repeat(c.size[None], n, axis=0)
        size[np.arange(n), np.repeat(ax, steps)] += L.ravel()
        center = c.center + np.repeat(U, steps, axis=0) * L.ravel()[:, None] / 2
        sep, _, _ = sat_separation(center, np.repeat(c.rotation[None], n, axis=0), size / 2,
                                   np.repeat(other.center[None], n, axis=0),
                                   np.repeat(other.rotation[None], n, axis=0),
                                   np.repeat(other.size[None] / 2, n, axis=0),
                                   np.full(n, tol))
        meet = sep.reshape(L.shape) <= 0.0
        return np.where(meet.any(axis=1), L[np.arange(len(L)), np.argmax(meet, axis=1)], np.inf)

    zero = np.zeros(len(faces))
    coarse = first_touch(zero, reach)
    ok = np.isfinite(coarse)
    if not ok.any():
        return None
    step = reach / steps
    fine = first_touch(np.where(ok, np.maximum(coarse - step, 0.0), 0.0),
                       np.where(ok, coarse, step))
    fine = np.where(ok, np.minimum(fine, coarse), np.inf)
    f = int(np.argmin(fine))
    axis, side, _ = faces[f]
    return Extension(k, axis, side, float(fine[f]))


def close_hidden_gaps(final: Arrangement, views: list[DepthView], margin: float = 0.0,
                      mu: float = 0.7, threshold: float | None = None,
                      gap: float = GAP_CLOSE) -> tuple[Arrangement, list[str]]:
    """Close gaps of at most ``gap`` between boxes that no view saw into.

    Two books in a row, a cushion and the back of its sofa: fitted to noisy points, boxes
    that touch end up a few millimetres apart, and the search leaves them apart because
    they stand either way.  Where the slab between them lies in space that no depth view
    saw empty (the sensor could not have seen the gap), one box's face is pushed to the
    other (the candidate extension of the pair, or, between two seen faces that face
    each other, the box's own face: :func:`_facing_push`, for a cushion turned a degree
    off its back, whose candidates offer only to push the back's whole face; shortest
    first); the change is kept when nothing interpenetrates and the arrangement still
    stands; parts of one object that meet so are fused (parts already fused into one
    rigid body are left as they are: a chair's back fixed to its seat does not grow down
    to a leg).  A box's face just off a wall is pushed to the wall the same way (the
    wall behind a book on a wall shelf is hidden by the book).  A hallucinated box
    (:mod:`pipeline.symmetry`: a chair's hidden back leg, a copy of its front leg) is not
    pushed: its faces were not fitted to noisy points, and widening it to a part it
    happens to stand near (the chair's back) adds a contact no data suggests.  Without
    views (a bare point cloud) nothing is closed.  Returns the arrangement and the
    ``a|b`` pairs closed (``b`` may be a wall's id).
    """
    from .extend import (
        FREE_FRACTION_MAX,
        pair_edges,
        slab_samples,
        support_edges,
        visible_free_fraction,
    )
    from .search import finalize

    if not views or final.stability is None or not final.stability.stable:
        return final, []
    touching = find_contacts(final).lookup()
    opts = []
    level_gap = max(gap, LEVEL_GAP_CLOSE)
    for e in pair_edges(final, level_gap):
        a, b = final.cuboids[e.a].id, final.cuboids[e.b].id
        if tuple(sorted((a, b))) in touching:
            continue
        ca, cb = final.cuboids[e.a], final.cuboids[e.b]
        pushes = {}
        for o in e.options:
            if o.type != "touch" or len(o.extensions) != 1:
                continue
            x = o.extensions[0]
            if x.length <= gap or (x.length <= level_gap and _levelled(
                    final, touching, x, e.b if x.box == e.a else e.a)):
                pushes[(x.box, x.axis, x.side)] = x
        # each box's own face towards the other, where the candidates offer none
        # (between faces the sensor saw: not against a face a deepening guessed)
        for k, other in ((e.a, cb), (e.b, ca)):
            if any(key[0] == k for key in pushes):
                continue
            x = _facing_push(final, k, other, gap, broad_len=WALL_GAP_CLOSE_REL * gap)
            if x is not None:
                pushes[(x.box, x.axis, x.side)] = x
        opts += [(x.length, a, b, x) for x in pushes.values()]
    # ... and a box's face to a wall it stands just off (the wall behind a book on a
    # wall shelf is hidden by the book itself)
    wall_gap = WALL_GAP_CLOSE_REL * gap
    for e in support_edges(final, wall_gap):
        a = final.cuboids[e.a].id
        if not str(e.b).startswith("wall:") or tuple(sorted((a, e.b))) in touching:
            continue
        for o in e.options:
            if (o.type == "touch" and len(o.extensions) == 1
                    and o.extensions[0].length <= wall_gap):
                opts.append((o.extensions[0].length, a, e.b, o.extensions[0]))
    closed: list[str] = []
    grown: set[tuple[str, int, int]] = set()
    rigid = _components_of(list(final.ids), final.contacts)
    for _length, a, b, x in sorted(opts, key=lambda t: (*t[:3], t[3].box, t[3].axis,
                                                            t[3].side)):
        cid = final.cuboids[x.box].id
        if (cid, x.axis, x.side) in grown or tuple(sorted((a, b))) in touching:
            continue
        if final.cuboids[x.box].extra.get("hallucinated"):
            continue  # a copy of a seen part, not a fit to noisy points: no noise to undo
        oa = final.cuboid(a).object
        ob = None if is_support_id(b) else final.cuboid(b).object
        if oa is not None and oa == ob and rigid[a] == rigid[b]:
            continue  # parts already one rigid body: a joint between them adds nothing
        if ob is not None and _under_a_held_part(final, a, b, x, rigid):
            continue
        if visible_free_fraction(slab_samples(final, x), views, margin) > FREE_FRACTION_MAX / 2:
            continue
        c = final.cuboids[x.box]
        u = c.rotation[:, x.axis] * (1.0 if x.side else -1.0)
        size = c.size.copy()
        size[x.axis] += x.length
        cubs = list(final.cuboids)
        cubs[x.box] = c.with_(center=c.center + u * x.length / 2, size=size)
        trial = final.with_(cuboids=tuple(cubs), stability=None)
        cs = find_contacts(trial)
        mine = [(p, q, d) for p, q, d in cs.penetrations if cid in (p, q)]
        grazing = all(d <= GRAZE_DEPTH and tuple(sorted((p, q))) in touching
                      for p, q, d in mine)
        if mine and (abs(u[2]) > 0.9 or grazing) and not is_support_id(b):
            # the face carries (or rests on) a second box: level the boxes that touch;
            # a box a degree or two askew grazes a neighbour it touches as it moves
            trial = close_pair(final, final.index[b if cid == a else a], x.box, u,
                               x.length, x.length)
            if trial is None:
                continue
            cs = find_contacts(trial)
        if any(cid in (p, q) for p, q, _ in cs.penetrations) or \
                tuple(sorted((a, b))) not in cs.lookup():
            continue
        fixed = [c for c in final.contacts if c.type == "fixed"]
        if oa is not None and oa == ob:  # parts of one object are fused where they meet
            fixed.append(Contact(a, b, "fixed"))
        cand = finalize(trial, fixed, mu=mu, threshold=threshold)
        if cand.stability is not None and cand.stability.stable:
            final, touching = cand, cs.lookup()
            rigid = _components_of(list(final.ids), final.contacts)
            grown.add((cid, x.axis, x.side))
            closed.append(f"{a}|{b}")
    return final, closed


#: :func:`relax_fixed` stops refining a group after a step that leaves more than this
#: fraction of its energy (:func:`pipeline.refine.refine` ``stall``).
REFINE_STALL = 0.97


def relax_fixed(final: Arrangement, mu: float = 0.7, threshold: float | None = None,
                tilt_deg: float | None = None, deadline: float = float("inf"),
                max_steps: int = 4, max_group: int = 16, views: list[DepthView] | None = None,
                margin: float = 0.0) -> tuple[Arrangement, int, int]:
    """Turn ``fixed`` contacts between different objects into ``touch`` where a box that
    was seen only in part can be completed so that the arrangement stands without them.

    The search judges the boxes as fitted; noisy, partly seen boxes put a centre of mass
    off (a box under another, half hidden by it, looks too short to carry it), and the
    search pays with a glue joint the scene does not have.  For each such joint (in
    contact order) the joint becomes a ``touch`` and, smallest added volume first,

    1. one horizontal face of either box grows (:func:`_growths`), into space no depth
       view saw empty (``views``) and without interpenetration;
    2. else the boxes of the joint's connected group are refined
       (:func:`pipeline.refine.refine`, at most ``max_steps`` steps, groups of up to
       ``max_group`` cuboids so the outcome does not depend on the machine's speed);

    and the first variant under which the group stands with gravity tilted by
    ``tilt_deg`` (a margin) is kept.  Joints within one object (a table's legs) are
    left: they are what holds an object together.  No trial starts, and no refinement
    step, after ``deadline``.

    Returns (arrangement, joints tried, joints relaxed); the stability summary is left
    for the caller to recompute.
    """
    from dataclasses import replace

    from .search import ROBUST_TILT_DEG
    from .stability import check_stability

    tilt = ROBUST_TILT_DEG if tilt_deg is None else tilt_deg
    objects = {c.id: c.object for c in final.cuboids}
    tried = relaxed = 0
    # component solutions shared by every check below (digest-keyed: exact reuse)
    cache: dict = {}

    def stands(arr: Arrangement, cs=None) -> bool:
        try:
            return check_stability(arr, mu=mu, threshold=threshold, tilt_deg=tilt, contacts=cs,
                                   solve_cache=cache, verdict_only=True).stable
        except InputError:  # a fixed pair pulled apart
            return False

    final_cs = None  # contacts of the current geometry (type changes keep them)
    for i in range(len(final.contacts)):
        c = final.contacts[i]
        if c.type != "fixed" or c.a not in objects:
            continue
        if c.b in objects and objects[c.a] is not None and objects[c.a] == objects[c.b]:
            continue
        if time.perf_counter() > deadline:
            break
        tried += 1
        contacts = tuple(replace(x, type="touch") if j == i else x
                         for j, x in enumerate(final.contacts))
        trial = final.with_(contacts=contacts, stability=None)
        if final_cs is None:
            final_cs = find_contacts(trial)
        group = _touching_group(trial, c.a, final_cs)
        sub = trial.with_(cuboids=tuple(x for x in trial.cuboids if x.id in group),
                          contacts=tuple(x for x in contacts
                                         if x.a in group and (x.b in group or x.b not in objects)))
        sub_cs = find_contacts(sub)
        found = sub if stands(sub, sub_cs) else None  # the search may have kept a spare joint
        if found is None:
            found = next((g for g, cs in _growths(sub, [c.a, c.b], views or [], margin,
                                                   with_contacts=True, contacts=sub_cs)
                          if stands(g, cs)), None)
        if found is None and len(group) <= max_group:
            try:
                refined = refine(sub, mu=mu, max_steps=max_steps, tilt_deg=tilt,
                                 deadline=deadline, contacts=sub_cs,
                                 solve_cache=cache, stall=REFINE_STALL).arrangement
            except InputError:
                refined = None
            if refined is not None and stands(refined):
                found = refined
        if found is None:
            continue
        moved = {x.id: x for x in found.cuboids if x is not sub.cuboids[sub.index[x.id]]}
        merged = trial.with_(cuboids=tuple(moved.get(x.id, x) for x in trial.cuboids))
        if moved and any(a in moved or b in moved
                         for a, b, _ in find_contacts(merged).penetrations):
            continue
        final = merged
        final_cs = None if moved else final_cs
        relaxed += 1
    return final, tried, relaxed


#: A box of a one-part object extended down to the floor by more than this many times
#: its seen height, and by at least :data:`HIDDEN_MIN_DROP` metres, rests on a hidden
#: support instead (:func:`hidden_supports`).
HIDDEN_DROP_REL = 1.5
HIDDEN_MIN_DROP = 0.15
#: Hidden supports side by side (gap below this, metres) with tops this close merge.
HIDDEN_MERGE_GAP = 0.05
#: A hidden support reaches out to the parts of a multi-part object around it across at
#: most this fraction of its widest horizontal extent (a seat to its sofa's arms and back).
HIDDEN_REACH_REL = 0.25


def _z_range(c: Cuboid) -> tuple[float, float]:
    """(bottom, top) heights of an upright box."""
    h = float(c.size[int(np.argmax(np.abs(c.rotation[2])))]) / 2
    return float(c.center[2]) - h, float(c.center[2]) + h


def _gap(a: Cuboid, b: Cuboid) -> float:
    """Separation of two boxes (negative: they overlap), by the separating-axis test."""
    sep, _, _ = sat_separation(a.center[None], a.rotation[None], a.size[None] / 2,
                               b.center[None], b.rotation[None], b.size[None] / 2, np.zeros(1))
    return float(sep[0])


def _reach_out(support: Cuboid, others: list[Cuboid], reach: float,
               views: list[DepthView], margin: float) -> Cuboid:
    """``support`` with each horizontal face pushed out to the nearest of ``others`` it
    faces (overlapping it sideways and in height) when that is at most ``reach`` away
    and no view saw the added slab empty: a seat hidden under cushions meets the arms
    and the back around it."""
    from .extend import FREE_FRACTION_MAX, Extension, slab_samples, visible_free_fraction

    out = support
    for axis in range(3):
        if abs(support.rotation[2, axis]) > 0.5:
            continue
        for side in (0, 1):
            u = out.rotation[:, axis] * (1.0 if side else -1.0)
            face = float(out.center @ u + out.size[axis] / 2)
            best = None
            for o in others:
                if _overlap_across(out, o, u) and (gap := float((o.corners() @ u).min()) - face) > 0:
                    best = gap if best is None else min(best, gap)
            if best is None or best > reach:
                continue
            tmp = Arrangement((out,), ())
            x = Extension(0, axis, side, best)
            if views and visible_free_fraction(slab_samples(tmp, x), views,
                                               margin) > FREE_FRACTION_MAX:
                continue
            size = out.size.copy()
            size[axis] += best
            out = out.with_(center=out.center + u * best / 2, size=size)
    return out


def _overlap_across(a: Cuboid, b: Cuboid, u: np.ndarray) -> bool:
    """Whether ``b`` overlaps ``a`` in every direction of ``a``'s axes but ``u``'s."""
    ca, cb = a.corners(), b.corners()
    for ax in range(3):
        w = a.rotation[:, ax]
        if abs(float(w @ u)) > 0.5:
            continue
        pa, pb = ca @ w, cb @ w
        if pb.max() <= pa.min() or pb.min() >= pa.max():
            return False
    return True


def hidden_supports(final: Arrangement, mu: float = 0.7, threshold: float | None = None,
                    views: list[DepthView] | None = None, margin: float = 0.0
                    ) -> tuple[Arrangement, list[str]]:
    """Give a box that the search stretched down to the floor a support of its own.

    A sofa's seat is hidden under its cushions and behind its back; the search can hold
    a cushion up only by growing it to the floor, half a metre of cushion.  A box of an
    object with no other parts, seen over a height ``h`` and grown down to the floor by
    more than :data:`HIDDEN_DROP_REL` ``h`` (and :data:`HIDDEN_MIN_DROP`), keeps its
    seen part and stands on a new box below it (``extra["hidden_support"]``, hallucinated,
    no observed box).  New boxes side by side with tops at one height merge (one seat
    under two cushions); a new box that touches parts of a multi-part object becomes a
    part of it (the seat of the sofa whose arms and back hold it), fused to them.  A
    box alone, next to no such object, is left as the search made it: one tall box
    whose top was all the sensor saw is as likely.  Each change is kept only if nothing
    interpenetrates and the arrangement stands.  Returns the arrangement and the ids of
    the new boxes.
    """
    from .search import finalize

    if final.stability is None or not final.stability.stable:
        return final, []
    parts: dict[str, int] = {}
    for c in final.cuboids:
        if c.object is not None:
            parts[c.object] = parts.get(c.object, 0) + 1
    grounded = {c.a for c in final.contacts if c.b == "ground"} | \
        {c.b for c in final.contacts if c.a == "ground"}
    cands = []  # (cut box, support box)
    for c in final.cuboids:
        o = c.observed
        if (o is None or c.extra.get("hallucinated") or c.id not in grounded
                or (c.object is not None and parts[c.object] > 1)):
            continue
        k = int(np.argmax(np.abs(c.rotation[2])))
        if abs(c.rotation[2, k]) < 1 - 1e-6:
            continue
        bottom, _ = _z_range(c)
        seen_bottom = float(o.center[2] - o.size[k] / 2)
        drop = seen_bottom - bottom
        if drop < max(HIDDEN_MIN_DROP, HIDDEN_DROP_REL * float(o.size[k])):
            continue
        size = c.size.copy()
        size[k] = drop
        low = c.with_(center=np.array([*c.center[:2], bottom + drop / 2]), size=size)
        size = c.size.copy()
        size[k] -= drop
        cut = c.with_(center=np.array([*c.center[:2], seen_bottom + size[k] / 2]), size=size)
        cands.append((cut, low))
    if not cands:
        return final, []
    def beside(i: int, j: int) -> bool:
        a, b = cands[i][1], cands[j][1]
        return (_same_axes(a, b) and _gap(a, b) < HIDDEN_MERGE_GAP
                and abs(_z_range(a)[1] - _z_range(b)[1]) < HIDDEN_MERGE_GAP)

    def grouped(members: list[int], chain: bool) -> list[list[int]]:
        """Supports side by side with tops at one height, as groups: beside any box of
        the group (``chain``: a row of three cushions) or beside its first one."""
        out: list[list[int]] = []
        for i in members:
            for g in out:
                if any(beside(i, j) for j in (g if chain else g[:1])):
                    g.append(i)
                    break
            else:
                out.append([i])
        return out

    # each group becomes one box (in its first box's frame); a row that cannot (the
    # merged box grazes an arm) is tried again as the boxes beside its first one
    groups = grouped(list(range(len(cands))), chain=True)
    objects = {c.object for c in final.cuboids if c.object is not None and parts[c.object] > 1}
    added: list[str] = []
    current = final
    n = -1
    while groups:
        g = groups.pop(0)
        n += 1
        low = cands[g[0]][1]
        for i in g[1:]:
            low = _merge(low, cands[i][1])
        k = int(np.argmax(np.abs(low.rotation[2])))
        top = min(_z_range(cands[i][0])[0] for i in g)
        size = low.size.copy()
        size[k] = top - _z_range(low)[0]
        new_id = f"hidden{n}"
        while new_id in current.index:
            new_id += "_"
        support = Cuboid(new_id, np.array([*low.center[:2], top - size[k] / 2]), low.rotation,
                         size, low.density, None, None,
                         {"hallucinated": True, "hidden_support": True, "points": 0})
        cut = {}
        for i in g:  # each box down to the common top (at most the merge gap)
            c = cands[i][0]
            grow = _z_range(c)[0] - top
            sz = c.size.copy()
            sz[int(np.argmax(np.abs(c.rotation[2])))] += grow
            cut[c.id] = c.with_(center=c.center - np.array([0, 0, grow / 2]), size=sz)
        # a part of the multi-part object it touches most (the sofa around its seat),
        # reaching out to that object's parts across hidden space
        around = [c for c in current.cuboids if c.object in objects and c.id not in cut]
        reach = HIDDEN_REACH_REL * float(max(support.size[a] for a in range(3)
                                             if abs(support.rotation[2, a]) <= 0.5))
        support = _reach_out(support, around, reach, views or [], margin)
        near = {}
        for c in current.cuboids:
            if c.object in objects and c.id not in cut and _gap(support, c) < 0.02:
                near[c.object] = near.get(c.object, 0) + 1
        if near:
            support = support.with_(object=max(sorted(near), key=lambda x: near[x]))
        elif len(g) > 1:  # under several boxes at one height: their own support
            support = support.with_(object=new_id)
        else:  # one box alone: as likely one tall box whose top was all that was seen
            continue
        trial = current.with_(cuboids=tuple(cut.get(c.id, c) for c in current.cuboids)
                              + (support,), stability=None)
        changed = set(cut) | {new_id}
        cs = find_contacts(trial)
        cand = None
        if not any(a in changed or b in changed for a, b, _ in cs.penetrations):
            fixed = [c for c in current.contacts if c.type == "fixed"]
            touching = cs.lookup()
            fixed += [Contact(new_id, c.id, "fixed") for c in trial.cuboids
                      if c.object == support.object and c.id != new_id
                      and tuple(sorted((new_id, c.id))) in touching]
            cand = finalize(trial, fixed, mu=mu, threshold=threshold)
        if cand is not None and cand.stability is not None and cand.stability.stable:
            current = cand
            added.append(new_id)
        elif len(g) > 1 and len(parts_of := grouped(g, chain=False)) > 1:
            groups[:0] = parts_of
    return current, added


#: Growths tried per face by :func:`relax_fixed`, as fractions of the box's extent there
#: (besides the pushes that reach the partner box's centre and its far side).
GROWTH_FRACTIONS = (0.25, 0.5, 1.0)


def _growths(arr: Arrangement, ids: list[str], views: list[DepthView],
             margin: float, with_contacts: bool = False, contacts=None) -> Iterator:
    """Variants of ``arr`` with one horizontal face of one of the two boxes ``ids``
    pushed out, into space no view saw empty and without interpenetration, smallest
    added volume first.  A face is pushed by :data:`GROWTH_FRACTIONS` of the box's extent
    and, when it faces the other box, until it reaches that box's centre or its far
    side (the paper's extension length, horizontally: under a box that overhangs), and
    by the same fractions of the box's widest horizontal extent (a part seen edge-on,
    such as a pillar seen only from the front, has almost no depth).  ``with_contacts``:
    yield ``(arrangement, its contacts)``; ``contacts`` (those of ``arr``) lets them be
    updated for the one grown box instead of found anew."""
    from .extend import FREE_FRACTION_MAX, Extension, slab_samples, visible_free_fraction

    out = []
    boxes = [arr.cuboids[arr.index[i]] for i in ids if i in arr.index]
    for c in boxes:
        k = arr.index[c.id]
        other = [o for o in boxes if o.id != c.id]
        for axis in range(3):
            if abs(c.rotation[2, axis]) > 0.5:  # the vertical axis: extensions do that
                continue
            for side in (0, 1):
                u = c.rotation[:, axis] * (1.0 if side else -1.0)
                face = float(c.center @ u + c.size[axis] / 2)
                # fractions of this extent, and of the widest horizontal one (a slab seen
                # edge-on, a pillar seen from the front, has almost no depth)
                widest = max(float(c.size[a]) for a in range(3) if abs(c.rotation[2, a]) <= 0.5)
                lengths = {round(f * e, 6) for f in GROWTH_FRACTIONS
                           for e in (float(c.size[axis]), widest)}
                for o in other:
                    lengths |= {round(float(o.center @ u) - face, 6),
                                round(float((o.corners() @ u).max()) - face, 6)}
                for length in sorted(x for x in lengths if x > 1e-4):
                    x = Extension(k, axis, side, length)
                    if views and visible_free_fraction(slab_samples(arr, x), views,
                                                       margin) > FREE_FRACTION_MAX:
                        break  # a longer push would cross the same seen-empty space
                    size = c.size.copy()
                    size[axis] += length
                    cubs = list(arr.cuboids)
                    cubs[k] = c.with_(center=c.center + u * length / 2, size=size)
                    out.append((x.volume(arr.sizes), len(out), c.id,
                                arr.with_(cuboids=tuple(cubs)).inherit_views(arr)))
    out.sort(key=lambda t: t[:2])
    from .contacts import update_contacts_of_one

    found: dict[int, object] = {}  # id of a variant -> its contacts
    for _v, _n, cid, g in out:  # lazily: the caller stops at the first that stands
        if contacts is None:
            cs = find_contacts(g)
        else:
            if id(g) not in found:  # all variants of this box at once (one batch)
                mine = [t[3] for t in out if t[2] == cid]
                found.update(zip(map(id, mine), update_contacts_of_one(
                    mine, arr, contacts, arr.index[cid])))
            cs = found[id(g)]
        if not any(cid in (a, b) for a, b, _ in cs.penetrations):
            yield (g, cs) if with_contacts else g


def _touching_group(arr: Arrangement, start: str, cs=None) -> set[str]:
    """Ids of the cuboids connected to ``start`` through touching cuboids (supports do
    not connect: what stands on the floor apart from each other is independent);
    ``cs``: the contacts of ``arr`` when known."""
    cs = find_contacts(arr) if cs is None else cs
    nbrs: dict[str, set[str]] = {}
    for a, b in cs.pairs:
        nbrs.setdefault(a, set()).add(b)
        nbrs.setdefault(b, set()).add(a)
    cuboid_ids = set(arr.ids)
    seen, todo = {start}, [start]
    while todo:
        for n in nbrs.get(todo.pop(), ()):
            if n in cuboid_ids and n not in seen:
                seen.add(n)
                todo.append(n)
    return seen


def _components_of(members: list[str], contacts) -> dict[str, int]:
    parent = {m: m for m in members}

    def find(x: str) -> str:
        while parent[x] != x:
            x = parent[x]
        return x

    for c in contacts:
        if c.type == "fixed" and c.a in parent and c.b in parent:
            parent[find(c.a)] = find(c.b)
    roots = sorted({find(m) for m in members})
    return {m: roots.index(find(m)) for m in members}


def _push_face(arr: Arrangement, initial: Arrangement, x) -> Arrangement:
    """Move face (axis, side) of cuboid ``x.box`` out to where extension ``x`` puts it."""
    c0 = initial.cuboids[x.box]
    k = arr.index[c0.id]
    c = arr.cuboids[k]
    u = c.rotation[:, x.axis] * (1.0 if x.side else -1.0)
    target = c0.center @ u + c0.size[x.axis] / 2 + x.length
    now = c.center @ u + c.size[x.axis] / 2
    grow = target - now
    if grow <= 0:
        return arr
    size = c.size.copy()
    size[x.axis] += grow
    cubs = list(arr.cuboids)
    cubs[k] = c.with_(center=c.center + u * grow / 2, size=size)
    return arr.with_(cuboids=tuple(cubs))


def views_from_scan(scan, arr: Arrangement) -> list[DepthView]:
    """The depth image(s) of a loaded scan in the arrangement's world frame (every frame
    of a fused multi-view scan)."""
    pose = arr.meta.get("camera_pose")
    if scan is None or pose is None:
        return []
    T = np.asarray(pose, float)  # input frame -> world
    frames = [(f, T @ np.asarray(f.T_world_cam, float)) for f in getattr(scan, "views", ())]
    if not frames:
        frames = [(scan, T)]
    return [DepthView(np.asarray(f.depth, float), f.intrinsics, P) for f, P in frames
            if getattr(f, "depth", None) is not None and f.intrinsics is not None]


def imagine(arr: Arrangement, views: list[DepthView] | None = None, *, budget: float = 10.0,
            mu: float = 0.7, threshold: float | None = None, symmetry: bool = True,
            refine_steps: int = 20, progress=None) -> ImagineResult:
    """Extend the initial cuboids of ``arr`` into a stable arrangement (module docstring)."""
    views = views or []
    timings: dict[str, float] = {}
    t0 = t = time.perf_counter()
    arr = arr.with_(contacts=(), stability=None)
    # keep the observed box of every cuboid (before any change)
    arr = arr.with_(cuboids=tuple(
        c if c.observed is not None else c.with_(observed=ObservedBox(c.center, c.size))
        for c in arr.cuboids))
    arr, aligned = align_boxes(arr, views=views)
    arr, repaired = repair_overlaps(arr, views=views)
    timings["repair"] = time.perf_counter() - t

    t = time.perf_counter()
    margin = 0.0
    if views:
        scale = arr.scale_length()
        margin = 0.05 * scale
    from .rows import resolve_rows

    arr, rows = resolve_rows(arr, views, margin)
    arr, deepened = deepen_thin_boxes(arr, views, margin)
    arr, reached = reach_occluders(arr, views, margin)
    arr, connectors = hidden_connectors(arr, views, margin)
    arr, joined_parts = join_parts(arr, views=views, margin=margin)
    hallucinated = []
    mirrored: list[str] = []
    if symmetry:
        arr, mirrored = complete_by_mirror(arr, views, margin)
        arr, hallucinated = hallucinate(arr, views, margin)
    timings["symmetry"] = time.perf_counter() - t

    t = time.perf_counter()
    edges = candidate_edges(arr)
    n_candidates = sum(len(e.options) for e in edges)
    edges, rejected_visibility = prune_by_visibility(arr, edges, views, margin)
    timings["candidates"] = time.perf_counter() - t

    t = time.perf_counter()
    result = search(arr, edges, budget=budget, mu=mu, threshold=threshold, progress=progress)
    # boxes nothing can hold up (their support was never seen) are set aside and the rest
    # searched again: glue cannot save them, and gluing their whole group would only hide
    # the contacts the rest of the scene does have
    prepared = arr
    full = (arr, edges, result)
    aside: list[Cuboid] = []
    for _ in range(ISOLATE_ROUNDS):
        bad = set(result.unstable_ids)
        if result.stable or not bad or len(bad) >= len(arr.cuboids):
            break
        aside += [c for c in arr.cuboids if c.id in bad]
        arr = arr.with_(cuboids=tuple(c for c in arr.cuboids if c.id not in bad))
        edges, _ = prune_by_visibility(arr, candidate_edges(arr), views, margin)
        left = budget - (time.perf_counter() - t0)
        if left < 0.1 * budget:  # no time for another search: keep the best effort
            break
        result = search(arr, edges, budget=left, mu=mu, threshold=threshold)
    timings["search"] = time.perf_counter() - t

    t = time.perf_counter()
    final, joins = connect_objects(result.arrangement, arr, edges, mu=mu, threshold=threshold)
    if aside:
        from .search import finalize

        with_aside = final.with_(cuboids=final.cuboids + tuple(aside), stability=None)
        ids = {c.id for c in aside}
        if any(a in ids or b in ids  # an extension grew into one: undo
               for a, b, _ in find_contacts(with_aside).penetrations):
            arr, edges, result = full
            aside = []
            final, joins = connect_objects(result.arrangement, arr, edges, mu=mu,
                                           threshold=threshold)
        else:
            final = finalize(with_aside, [c for c in final.contacts if c.type == "fixed"],
                             mu=mu, threshold=threshold)
    timings["connect"] = time.perf_counter() - t

    t = time.perf_counter()
    final, relax_tried, relaxed = relax_fixed(final, mu=mu, threshold=threshold,
                                              deadline=t0 + budget, views=views,
                                              margin=margin)
    if relaxed:
        from .search import finalize

        final = finalize(final, [c for c in final.contacts if c.type == "fixed"], mu=mu,
                         threshold=threshold)
    final, anchored = anchor_parts(final, arr, edges, mu=mu, threshold=threshold)
    final, grounded_parts = ground_parts(final, arr, edges, mu=mu, threshold=threshold)
    # (the boxes the search grew to the floor first get their hidden supports: their
    # gaps are those of the boxes the sensor saw)
    final, hidden = hidden_supports(final, mu=mu, threshold=threshold, views=views,
                                    margin=margin)
    final, gaps = close_hidden_gaps(final, views, margin, mu=mu, threshold=threshold)
    timings["relax"] = time.perf_counter() - t

    t = time.perf_counter()
    refined = None
    if final.stability is not None and final.stability.energy > (threshold or 1e-5) / 100:
        refined = refine(final, mu=mu, max_steps=refine_steps,
                         deadline=max(t0 + budget, time.perf_counter() + 0.1 * budget))
        from .search import finalize

        fixed = [c for c in refined.arrangement.contacts if c.type == "fixed"]
        final = finalize(refined.arrangement, fixed, mu=mu, threshold=threshold)
    timings["refine"] = time.perf_counter() - t

    # the faces the statics counted as touching are made to touch (the engines see the
    # file's geometry: a gap within the contact tolerance is a drop, an overlap a push)
    t = time.perf_counter()
    closed, gap_closed = close_gaps(final)
    if closed is not final:
        from .search import finalize

        closed = finalize(closed, [c for c in final.contacts if c.type == "fixed"], mu=mu,
                          threshold=threshold)
        was_stable = final.stability is not None and final.stability.stable
        if closed.stability is not None and (closed.stability.stable or not was_stable):
            final = closed
        else:
            gap_closed = 0.0
    timings["close"] = time.perf_counter() - t

    unstable = []
    if final.stability is not None and not final.stability.stable:
        from .stability import check_stability

        unstable = check_stability(final, mu=mu, threshold=threshold).unstable_ids
    meta = dict(final.meta)
    meta.update(stage="full")
    final = final.with_(meta=meta)
    report = {
        "cuboids": len(final.cuboids),
        "aligned_boxes": aligned,
        "repaired_overlaps": repaired,
        "hallucinated": connectors + hallucinated + hidden,
        "connectors": connectors,
        "hidden_supports": hidden,
        "mirrored": mirrored,
        "candidate_edges": len(edges),
        "candidate_options": n_candidates,
        "rejected_by_visibility": rejected_visibility,
        "visibility": "depth image" if views else "skipped (no camera: a bare point cloud)",
        "search": result.stats.to_json(),
        "fixed_chosen": result.n_fixed,
        "object_joins": joins,
        "deepened": deepened,
        "reached_occluders": reached,
        "rows": rows,
        "joined_parts": joined_parts,
        "set_aside": [c.id for c in aside],
        "relaxed_joints": {"tried": relax_tried, "relaxed": relaxed},
        "anchored_parts": anchored,
        "grounded_parts": grounded_parts,
        "closed_gaps": gaps,
        "added_volume_m3": result.added_volume,
        "gap_closed_m": gap_closed,
        "refine": None if refined is None else {
            "energy_before": refined.energy_before, "energy_after": refined.energy_after,
            "steps": refined.steps, "evaluations": refined.evaluations},
        "stable": bool(final.stability.stable) if final.stability else False,
        "energy": float(final.stability.energy) if final.stability else float("nan"),
        "unstable": list(unstable),
        "timings": timings,
    }
    return ImagineResult(final, prepared, report)


__all__ = ["imagine", "ImagineResult", "repair_overlaps", "views_from_scan", "depth_noise",
           "sat_separation"]
