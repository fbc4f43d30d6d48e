"""Rows of books on a board: noisy fits set one in front of the other go back side by side."""

import numpy as np

from pipeline.camera import Intrinsics, look_at
from pipeline.contacts import find_contacts
from pipeline.evidence import DepthView
from pipeline.model import Arrangement, ObservedBox, box, ground
from pipeline.priors.rows import row_order as _row_order
from tests.pipeline.priors_util import changed
from tests.pipeline.test_imagine import _depth_of_boxes


def resolve_rows(arr, views=None):
    """The ``rows`` prior alone: (arrangement, ids of the boxes of the rows it set side
    by side, in row order)."""
    return changed("rows", arr, views)

TOP = 0.51  # the board's top face
H = 0.25  # the books' height


def _book(name: str, x0: float, x1: float, y0: float, y1: float, h: float = H):
    c = box(name, ((x0 + x1) / 2, (y0 + y1) / 2, TOP + h / 2), (x1 - x0, y1 - y0, h),
            object=name)
    return c.with_(observed=ObservedBox(c.center, c.size))


def _zigzag(flat: bool = False) -> Arrangement:
    """Three books 3-4 cm thick fitted 5 cm wide: each overlaps the next along the board
    while the overlap repair set the middle one behind the other two."""
    board = box("board", (0.0, 0.0, 0.5), (0.8, 0.3, 0.02), object="shelf")
    h = 0.02 if flat else H
    books = (_book("a", -0.305, -0.255, -0.14, -0.10, h),
             _book("b", -0.285, -0.235, -0.09, -0.05, h),
             _book("c", -0.260, -0.205, -0.14, -0.11, h))
    return Arrangement((board.with_(observed=ObservedBox(board.center, board.size)),)
                       + books, (ground(),))


def _x(c):
    return (float(c.center[0] - c.size[0] / 2), float(c.center[0] + c.size[0] / 2))


def _y(c):
    return (float(c.center[1] - c.size[1] / 2), float(c.center[1] + c.size[1] / 2))


def test_a_zigzag_row_goes_back_side_by_side():
    arr = _zigzag()
    out, ids = resolve_rows(arr)
    assert ids == ["a", "b", "c"]
    a, b, c = (out.cuboid(k) for k in "abc")
    # each overlap split at its middle, the outer ends kept
    np.testing.assert_allclose(_x(a), (-0.305, -0.27), atol=1e-12)
    np.testing.assert_allclose(_x(b), (-0.27, -0.2475), atol=1e-12)
    np.testing.assert_allclose(_x(c), (-0.2475, -0.205), atol=1e-12)
    # front faces as seen, back faces at the board's back edge (y = 0.15), no book
    # deeper than it is tall (H = 0.25)
    for k, front in zip((a, b, c), (-0.14, -0.09, -0.14)):
        np.testing.assert_allclose(_y(k), (front, min(0.15, front + H)), atol=1e-12)
        # the box still holds what the sensor saw of it (the refinement's constraint)
        o = k.observed
        assert np.all(np.abs(o.center - k.center) + o.size / 2 <= k.size / 2 + 1e-12)
    cs = find_contacts(out)
    assert not cs.penetrations
    touching = cs.lookup()
    assert ("a", "b") in touching and ("b", "c") in touching
    assert ("a", "c") not in touching  # neighbours only, not the book two places on


def test_flat_boxes_are_no_row():
    arr = _zigzag(flat=True)  # a keyboard and a monitor's foot lie flat, side by side
    out, ids = resolve_rows(arr)
    assert ids == [] and out is arr


def _moved(c, d):
    """``c`` as the sensor would have fitted it ``d`` away (its observed box too)."""
    return c.with_(center=c.center + d, observed=ObservedBox(c.center + d, c.size))


def test_row_order_ignores_depth_noise_along_the_ray():
    intr = Intrinsics.kinect_v1()
    eye = np.array([1.5, -3.0, 2.0])
    T = look_at(eye, (0.0, 0.0, 0.6))
    view = DepthView(np.zeros((intr.height, intr.width)), intr, T)
    arr = _zigzag()
    board, book = arr.cuboid("board"), arr.cuboid("b")
    X = np.array([1.0, 0.0, 0.0])
    key = _row_order(book, board, X, [view])
    ray = (book.center - eye) / np.linalg.norm(book.center - eye)
    for t in (-0.08, -0.03, 0.05):  # noise moves the fitted centre along the ray only
        moved = _moved(book, t * ray)
        assert abs(_row_order(moved, board, X, [view]) - key) < 1e-6
        # without the image the same noise would move it along the row by ~|t| cos
        assert abs(_row_order(moved, board, X, []) - _row_order(book, board, X, [])) > 0.01
    # along the row the image order is the true order
    assert _row_order(_moved(book, 0.02 * X), board, X, [view]) > key
    # where the overlap repair moved the box afterwards (back across the row, not along
    # the ray) does not count: the sensor's fit does
    pushed = book.with_(center=book.center + np.array([0.0, 0.06, 0.0]))
    assert abs(_row_order(pushed, board, X, [view]) - key) < 1e-9


def test_a_book_does_not_go_back_into_space_the_sensor_saw_empty():
    intr = Intrinsics.kinect_v1()
    # from the open end of the row, looking along it (the boxes are then ordered as
    # fitted): the space behind the last book
    T = look_at((1.0, -0.08, 0.75), (-0.25, -0.08, 0.63))
    arr = _zigzag()
    # the scene really is what was fitted: nothing behind the last book ...
    empty = [DepthView(_depth_of_boxes(list(arr.cuboids), T, intr), intr, T)]
    out, ids = resolve_rows(arr, empty)
    assert ids == ["a", "b", "c"]  # (still split side by side)
    np.testing.assert_allclose(_x(out.cuboid("c")), (-0.2475, -0.205), atol=1e-12)
    np.testing.assert_allclose(_y(out.cuboid("c")), (-0.14, -0.11), atol=1e-12)
    # ... while a book as deep as the row hides that space, and the fit goes back, as
    # far as the board reaches and the book is tall
    deep = [c if c.id != "c" else c.with_(center=np.array([c.center[0], -0.095, c.center[2]]),
                                          size=np.array([c.size[0], 0.09, c.size[2]]))
            for c in arr.cuboids]
    hidden = [DepthView(_depth_of_boxes(deep, T, intr), intr, T)]
    out, _ = resolve_rows(arr, hidden)
    np.testing.assert_allclose(_y(out.cuboid("c")), (-0.14, -0.14 + H), atol=1e-12)


def test_a_lone_book_seen_by_its_spine_goes_back_to_the_board_edge():
    """A book standing alone on a board, rendered from the front: only its spine is
    fitted (1 cm deep); the space behind it is hidden by the book itself, and the
    board under it says how deep the shelf is."""
    intr = Intrinsics.kinect_v1()
    T = look_at((0.2, -1.6, 0.75), (0.0, 0.0, 0.6))
    board = box("board", (0.0, 0.0, 0.5), (0.8, 0.3, 0.02), object="shelf")
    true_book = box("book", (0.0, -0.03, TOP + 0.1), (0.04, 0.24, 0.2), object="book")
    views = [DepthView(_depth_of_boxes([board, true_book], T, intr), intr, T)]
    spine = _book("book", -0.02, 0.02, -0.15, -0.14, 0.2)
    arr = Arrangement((board.with_(observed=ObservedBox(board.center, board.size)), spine),
                      (ground(),))
    out, ids = resolve_rows(arr, views)
    assert ids == ["book"]
    np.testing.assert_allclose(_y(out.cuboid("book")), (-0.15, 0.05), atol=1e-12)  # its height
    # a board shallower than the book is tall stops it at the board's back edge
    shallow = box("board", (0.0, -0.075, 0.5), (0.8, 0.15, 0.02), object="shelf")
    arr2 = arr.with_(cuboids=(shallow.with_(observed=ObservedBox(shallow.center,
                                                                  shallow.size)), spine))
    out, _ = resolve_rows(arr2, views)
    np.testing.assert_allclose(_y(out.cuboid("book")), (-0.15, 0.0), atol=1e-12)


def test_neighbours_overlapping_a_little_along_the_row_go_back_side_by_side():
    """Two spines fitted one behind the other, overlapping by 2 mm along the board (a
    tenth of the narrower): both cannot reach the back edge, so they are one row, the
    overlap split at its middle and both as deep as the board."""
    board = box("board", (0.0, 0.0, 0.5), (0.8, 0.3, 0.02), object="shelf")
    a = _book("a", -0.10, -0.08, -0.15, -0.14)
    b = _book("b", -0.082, -0.06, -0.13, -0.12)
    arr = Arrangement((board.with_(observed=ObservedBox(board.center, board.size)), a, b),
                      (ground(),))
    out, ids = resolve_rows(arr)
    assert ids == ["a", "b"]
    np.testing.assert_allclose(_x(out.cuboid("a")), (-0.10, -0.081), atol=1e-12)
    np.testing.assert_allclose(_x(out.cuboid("b")), (-0.081, -0.06), atol=1e-12)
    np.testing.assert_allclose(_y(out.cuboid("a")), (-0.15, 0.1), atol=1e-12)  # H deep
    np.testing.assert_allclose(_y(out.cuboid("b")), (-0.13, 0.12), atol=1e-12)
    assert not find_contacts(out).penetrations


def test_a_book_goes_back_only_as_far_as_it_enters_nothing_outside_its_row():
    """A lone spine with a box standing behind it on the same board (too flat for a row):
    the book goes back in steps, to the last one that leaves the box whole."""
    board = box("board", (0.0, 0.0, 0.5), (0.8, 0.3, 0.02), object="shelf")
    spine = _book("book", -0.02, 0.02, -0.15, -0.14, 0.2)
    crate = box("crate", (0.0, 0.05, TOP + 0.04), (0.2, 0.1, 0.08), object="crate")
    arr = Arrangement((board.with_(observed=ObservedBox(board.center, board.size)), spine,
                       crate.with_(observed=ObservedBox(crate.center, crate.size))),
                      (ground(),))
    out, ids = resolve_rows(arr)
    assert ids == ["book"]
    # as deep as tall ends at y = 0.05, inside the crate (from y = 0.0); of the steps
    # 0.19 * j / 4 behind the spine's back at -0.14, j = 3 ends at 0.0025 (inside
    # too) and j = 2 at -0.045
    np.testing.assert_allclose(_y(out.cuboid("book")), (-0.15, -0.045), atol=1e-12)
    assert not find_contacts(out).penetrations


def test_books_go_back_after_the_board_under_them_is_deepened():
    """The order of the priors: a board seen only by its front edge is deepened (and
    joined to its side panels) before the books on it go back to its back edge."""
    from pipeline.priors.registry import PRIORS

    order = [p.name for p in PRIORS]
    assert order.index("deepen") < order.index("rows")
    assert order.index("join_parts") < order.index("rows")


def test_a_book_sunk_a_little_into_its_board_still_goes_back():
    """A spine fitted 3 mm into the board under it (noise): the slab behind it lies on
    that board, which is the book's support and not a box it would enter."""
    board = box("board", (0.0, 0.0, 0.5), (0.8, 0.3, 0.02), object="shelf")
    spine = _book("book", -0.02, 0.02, -0.15, -0.14, 0.2)
    sunk = spine.with_(center=spine.center - np.array([0.0, 0.0, 0.003]),
                       observed=ObservedBox(spine.center - np.array([0.0, 0.0, 0.003]),
                                            spine.size))
    arr = Arrangement((board.with_(observed=ObservedBox(board.center, board.size)), sunk),
                      (ground(),))
    out, ids = resolve_rows(arr)
    assert ids == ["book"]
    np.testing.assert_allclose(_y(out.cuboid("book")), (-0.15, 0.05), atol=1e-12)


def _beside_scene(overlap: float) -> Arrangement:
    """A 4 cm spine on the board and, overlapping it by ``overlap`` along the row at its
    right end, a neighbour already as deep as the row whose foot the view did not see
    (fitted 6 cm above the board, so it is no member of the row)."""
    board = box("board", (0.0, 0.0, 0.5), (0.8, 0.3, 0.02), object="shelf")
    spine = _book("a", -0.10, -0.06, -0.15, -0.14)
    x0 = -0.06 - overlap
    nb = box("n", ((x0 - 0.03) / 2 + 0.0, -0.02, TOP + 0.06 + H / 2),
             (-0.03 - x0, 0.24, H), object="n")
    nb = nb.with_(observed=ObservedBox(nb.center, nb.size))
    return Arrangement((board.with_(observed=ObservedBox(board.center, board.size)),
                        spine, nb), (ground(),))


def test_a_book_gives_up_the_strip_a_neighbour_beside_it_covers_and_goes_back():
    """The neighbour covers 1 cm of the spine's 4 (a quarter): it lies beside the
    spine, not behind it, so the spine yields that strip along the row and goes back as
    deep as it is tall; the neighbour is not moved."""
    arr = _beside_scene(0.01)
    # the neighbour is no member of the row: nothing rests on the board but the spine
    out, ids = resolve_rows(arr)
    assert ids == ["a"]
    np.testing.assert_allclose(_x(out.cuboid("a")), (-0.10, -0.07), atol=1e-12)
    np.testing.assert_allclose(_y(out.cuboid("a")), (-0.15, -0.15 + H), atol=1e-12)
    assert out.cuboid("n") is arr.cuboid("n")
    assert not find_contacts(out).penetrations
    # the observed box is cut with it (the refinement keeps a box around what was seen)
    o = out.cuboid("a").observed
    np.testing.assert_allclose(o.center[0] + np.array([-1, 1]) * o.size[0] / 2,
                               (-0.10, -0.07), atol=1e-12)


def test_a_neighbour_covering_half_the_book_is_behind_it_and_stops_the_push():
    """Just inside and just outside ``beside_rel`` (half the spine's 4 cm width): a
    neighbour covering 1.9 cm of it is beside it, one covering 2.1 cm stops the push
    (every step back enters it: the spine stays as fitted)."""
    out, _ = resolve_rows(_beside_scene(0.019))
    np.testing.assert_allclose(_x(out.cuboid("a")), (-0.10, -0.079), atol=1e-12)
    np.testing.assert_allclose(_y(out.cuboid("a")), (-0.15, -0.15 + H), atol=1e-12)
    out, _ = resolve_rows(_beside_scene(0.021))
    np.testing.assert_allclose(_x(out.cuboid("a")), (-0.10, -0.06), atol=1e-12)
    np.testing.assert_allclose(_y(out.cuboid("a")), (-0.15, -0.14), atol=1e-12)
