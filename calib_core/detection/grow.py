"""Grow a detected chessboard lattice over the whole visible board.

OpenCV's grids stop short of the board where distortion bends its lines
(``CALIB_CB_LARGER`` grows with a homography of the whole grid). Here every
missing lattice position next to found corners is predicted from its own
neighbours, with a model that follows the bending:

- quadratic extrapolation along a row or column from the last three corners
  (``3 p1 − 3 p2 + p3``: exact where the spacing changes linearly, which is
  what a smooth lens does over a few squares), averaged over the directions
  that have three; else linear from two; else the parallelogram of the
  nearest cell;
- confirmed by ``cornerSubPix`` with a window of a quarter of the local square
  (``corner_refine.half_window``), and kept only if it moved less than 0.4 of a
  square and the image there is an X-junction of the right colours
  (``saddle.is_x_junction``, whose parity test is what keeps ids right).

Holes, and the lines a detector skipped (``grid.expand``), are filled first by
interpolation between neighbours on a line (cubic where four are known). A
confirmed corner must also have four arms (``saddle.arm_steps``: a T-junction
on the board's outer line passes the quadrant test), hold no other corner in
its window, and sit where windows one px apart agree (``MAX_WOBBLE``).

Growth runs ring by ring (all candidates of a front at once) and stops where
no candidate is confirmed: at the board's edge (its white border is no
X-junction, and the lattice never outgrows the board's size), at the image's
border (the window must fit inside) and at a lens's image circle (the window
must not reach the unlit frame, ``image_circle``). The corners given are
checked the same way, and those that fail, or that their neighbours place
elsewhere, are dropped. Last, every corner is moved to the saddle point of a
quadratic surface fitted to the smoothed image (``corner_refine.saddle_fit``; dropped
where there is no saddle).

Ids are the board's ``row * cols + col`` as placed by ``grid.place_grid``; the
grown lattice is shifted back onto the board keeping the square colours' parity.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

from . import corner_refine, saddle
from .image_circle import UnlitDistance

MAX_MOVE = 0.4         # of a square: how far cornerSubPix may take a prediction
MAX_WOBBLE = 0.5       # px between refinements with windows one px apart (0.25: 326 fewer BabelCalib corners)
MAX_ROUNDS = 200       # fronts; a 22 x 22 board needs at most ~44
MAX_SURPRISE = 0.5     # of a square: a given corner this far from its neighbours' prediction is dropped
MIN_SEED_AGREEMENT = 0.6  # share of the given corners that must read as X-junctions to grow at all


@dataclass
class Grown:
    ids: np.ndarray      # (N,) int64
    points: np.ndarray   # (N, 2) float64
    added: int           # corners the growth found beyond those given
    dropped: int         # corners given that failed a test (X-junction, neighbours, saddle)
    after_growth_added: int = 0  # corners the after_growth hook (and growth from them) added

    def astuple(self) -> tuple[np.ndarray, np.ndarray]:
        return self.ids, self.points


def grow_board(gray: np.ndarray, ids: np.ndarray, pts: np.ndarray, cols: int, rows: int,
               unlit: np.ndarray | UnlitDistance | None = None, after_growth=None) -> Grown:
    """The given corners (ids (N,), pixels (N, 2) on a cols × rows board) checked, and grown
    over the visible board. Returned unchanged if they do not read as a checker lattice.

    after_growth(lattice, unlit), if given, may add corners once growth has stopped
    (``model_guided``); growth then resumes from them. ``Grown.after_growth_added``
    counts what that hook and the growth it enabled added."""
    lat = Lattice.of(ids, pts, cols, rows)
    unlit = UnlitDistance(gray) if unlit is None else unlit
    seed_ok, flip = _seed_check(gray, lat)
    if seed_ok is None:
        return Grown(ids, pts, 0, 0)
    lat.parity = flip
    n_given = int(lat.known.sum())
    lat.p[~seed_ok] = np.nan
    dropped = n_given - int(lat.known.sum())
    dropped += _drop_inconsistent(lat)
    given = lat.known.copy()
    _grow(gray, lat, unlit)
    grown = lat.known.copy()
    if after_growth is not None and after_growth(lat, unlit):
        _grow(gray, lat, unlit)
    dropped += int((given & ~_saddle_polish(gray, lat)).sum())
    out_ids, out_pts = lat.placed()
    known = lat.known
    return Grown(out_ids, out_pts, int((known & ~given).sum()), dropped, int((known & ~grown).sum()))


def _saddle_polish(gray: np.ndarray, lat: Lattice) -> np.ndarray:
    """Every corner moved to the saddle point of the smoothed image (``corner_refine.saddle_fit``);
    corners where the surface is no saddle, or whose saddle lies far from cornerSubPix's
    answer, are dropped. Returns the (R, C) mask of corners kept.

    Measured on BabelCalib ov_plane, same corners: median distance to the authors' saddle
    detector 0.224 -> 0.032 px; on rendered fisheye views, to the truth 0.046 -> 0.023 px."""
    i, j = np.nonzero(lat.known)
    e_col, e_row = lat.steps()
    half = corner_refine.half_window(corner_refine.nearest_corner(e_col[i, j], e_row[i, j]))
    fitted, det, sure = corner_refine.saddle_points(gray, lat.p[i, j], half)
    spacing = corner_refine.nearest_corner(e_col[i, j], e_row[i, j])
    ok = (det < 0) & sure & (np.linalg.norm(fitted - lat.p[i, j], axis=1) <= corner_refine.MAX_SADDLE_SHIFT)
    ok &= corner_refine.window_holds_one_corner(np.nan_to_num(spacing, nan=np.inf))
    lat.p[i, j] = np.where(ok[:, None], fitted, np.nan)
    return lat.known


def _grow(gray: np.ndarray, lat: Lattice, unlit: np.ndarray | UnlitDistance) -> None:
    """Grow front by front until no candidate is confirmed."""
    tried = np.zeros(lat.known.shape, int)
    for _ in range(MAX_ROUNDS):
        if not _grow_front(gray, lat, tried, unlit):
            break


@dataclass
class Lattice:
    """Corner pixels p (R, C, 2), NaN where unknown, on a padded copy of the board's lattice:
    array row i is board row i - r0 (columns likewise). parity 1 flips the square colours."""

    p: np.ndarray
    r0: int
    c0: int
    cols: int
    rows: int
    parity: int = 0
    _steps: tuple | None = field(default=None, repr=False, compare=False)

    @classmethod
    def of(cls, ids: np.ndarray, pts: np.ndarray, cols: int, rows: int) -> Lattice:
        p = np.full((3 * rows, 3 * cols, 2), np.nan)
        p[ids // cols + rows, ids % cols + cols] = pts
        return cls(p, rows, cols, cols, rows)

    @property
    def known(self) -> np.ndarray:
        return np.isfinite(self.p[..., 0])

    def steps(self) -> tuple[np.ndarray, np.ndarray]:
        """``lattice_steps(self.p)``, kept until p changes (read only): a board seen whole asks
        for them three times over an unchanged lattice."""
        if self._steps is None or not np.array_equal(self._steps[0], self.p, equal_nan=True):
            self._steps = (self.p.copy(), lattice_steps(self.p))
        return self._steps[1]

    def even(self) -> np.ndarray:
        """(R, C) bool: the corner's top-left and bottom-right squares are bright."""
        i, j = np.indices(self.p.shape[:2])
        return (i - self.r0 + j - self.c0 + self.parity) % 2 == 0

    def sizes(self) -> list[tuple[int, int]]:
        """The board's (rows, cols) the lattice may still grow within: a board that is not
        square either way round while the corners known fit it both ways (a partial view's
        seed was placed one way round, and which it is shows only once the lattice outgrows
        the shorter side; ``placed`` turns it the other way if it grew so)."""
        r, c = np.nonzero(self.known)
        span = (r.max() - r.min() + 1, c.max() - c.min() + 1)
        ways = [(self.rows, self.cols)] if self.rows == self.cols else [(self.rows, self.cols), (self.cols, self.rows)]
        return [(n, m) for n, m in ways if span[0] <= n and span[1] <= m] or ways[:1]

    def box_allows(self) -> np.ndarray:
        """(R, C) bool: positions that keep the lattice within the board's size (either way round
        while that is open, ``sizes``)."""
        r, c = np.nonzero(self.known)
        i, j = np.indices(self.known.shape)
        span_r = np.maximum(i, r.max()) - np.minimum(i, r.min())
        span_c = np.maximum(j, c.max()) - np.minimum(j, c.min())
        return np.logical_or.reduce([(span_r < n) & (span_c < m) for n, m in self.sizes()])

    def placed(self) -> tuple[np.ndarray, np.ndarray]:
        """(ids (N,), pixels (N, 2)) on the board, shifted to its top-left with the colours kept
        (the shift's parity equal to ``parity``, taken on a free side of the board) where the
        lattice leaves one: a board whose corner squares are black (an odd number of squares
        each way, BabelCalib's) cannot follow OpenCV's colour convention when seen whole."""
        r, c = np.nonzero(self.known)
        points = self.p[r, c]
        parity = self.parity
        if r.max() - r.min() + 1 > self.rows or c.max() - c.min() + 1 > self.cols:
            # Grown the other way round (``sizes``): the same corners a quarter turn round. Not
            # transposed: that mirrors the board, which no pose can turn back (seen from its front,
            # a board is never mirrored). The turn moves each corner's colour parity by k.
            k = int(r.max() + r.min())
            r, c = c, k - r
            parity = (parity + k) % 2
        dr, dc = -r.min(), -c.min()
        if (dr + dc + parity) % 2:
            if c.max() - c.min() + 1 < self.cols:
                dc += 1
            elif r.max() - r.min() + 1 < self.rows:
                dr += 1
        ids = (r + dr) * self.cols + (c + dc)
        order = np.argsort(ids)
        return ids[order].astype(np.int64), points[order]


def shift(a: np.ndarray, dr: int, dc: int) -> np.ndarray:
    """out[i, j] = a[i - dr, j - dc], NaN where that falls outside."""
    return Shifted(a, max(abs(dr), abs(dc)))(dr, dc)


class Shifted:
    """``shift(a, dr, dc)`` for every |dr|, |dc| <= reach, as views of one NaN-padded copy of a:
    the lattice arithmetic takes dozens of shifts of a small array, and a copy each cost more
    than the arithmetic."""

    def __init__(self, a: np.ndarray, reach: int):
        R, C = a.shape[:2]
        self.pad = np.full((R + 2 * reach, C + 2 * reach) + a.shape[2:], np.nan)
        self.pad[reach:reach + R, reach:reach + C] = a
        self.reach, self.R, self.C = reach, R, C

    def __call__(self, dr: int, dc: int) -> np.ndarray:
        r0, c0 = self.reach - dr, self.reach - dc
        return self.pad[r0:r0 + self.R, c0:c0 + self.C]


_AXES = ((0, 1), (0, -1), (1, 0), (-1, 0))


def predict(p: np.ndarray) -> np.ndarray:
    """(R, C, 2) predicted pixel of every lattice position from its known neighbours (NaN where
    none can): between two neighbours on a line (a hole, or a row a detector skipped; cubic
    where four are known, following the bending), else quadratic extrapolation along
    rows/columns, else linear, else the nearest cell's parallelogram."""
    return _predict(np.ascontiguousarray(p, dtype=np.float64))


def lattice_steps(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Local steps to the next column and the next row (R, C, 2) each, at known corners (the
    mean of the forward and backward differences) and, one step out, at their neighbours."""
    return _lattice_steps(np.ascontiguousarray(p, dtype=np.float64))


# The lattice arithmetic is compiled: as array expressions it was dozens of NumPy calls on small
# arrays per lattice, each holding the GIL, so images detected on threads waited for each other.
# The kernels do the same floating-point operations in the same order as those expressions did
# (a mean of the finite values among a few is their sum in order, over their count), so they
# give the same numbers to the last bit.


@njit(cache=True, nogil=True)
def _padded(p, m):  # pragma: no cover (compiled)
    """p (R, C, 2) in a NaN margin m wide: the lattice's off-board neighbours read NaN without a test."""
    out = np.full((p.shape[0] + 2 * m, p.shape[1] + 2 * m, 2), np.nan)
    out[m:m + p.shape[0], m:m + p.shape[1]] = p
    return out


@njit(cache=True, nogil=True, inline="always")
def _finite_mean(vals, n):  # pragma: no cover (compiled)
    """Mean of the finite values among vals[:n], summed in order from 0 as NumPy's sum does
    (-0.0 sums to 0.0); NaN if there are none."""
    count = 0
    acc = 0.0
    for m in range(n):
        if np.isfinite(vals[m]):
            acc += vals[m]
            count += 1
    return acc / count if count > 0 else np.nan


_LINE = np.array([[0, 1], [1, 0]])                        # a row, a column
_AXES_A = np.array(_AXES)                                # the four directions along them
_CELLS = np.array([[1, 1], [1, -1], [-1, 1], [-1, -1]])  # the four cells round a position


@njit(cache=True, nogil=True)
def _predict(p):  # pragma: no cover (compiled)
    out = np.empty_like(p)
    vals = np.empty(4)
    q = _padded(p, 3)
    for i in range(3, p.shape[0] + 3):
        for j in range(3, p.shape[1] + 3):
            for k in range(2):
                for a in range(2):   # between two neighbours on a line
                    dr, dc = _LINE[a, 0], _LINE[a, 1]
                    a1, b1 = q[i - dr, j - dc, k], q[i + dr, j + dc, k]
                    a3, b3 = q[i - 3 * dr, j - 3 * dc, k], q[i + 3 * dr, j + 3 * dc, k]
                    cubic = (9 * (a1 + b1) - (a3 + b3)) / 16
                    vals[a] = cubic if np.isfinite(cubic) else 0.5 * (a1 + b1)
                v = _finite_mean(vals, 2)
                if not np.isfinite(v):   # quadratic along a row or column
                    for a in range(4):
                        dr, dc = _AXES_A[a, 0], _AXES_A[a, 1]
                        vals[a] = (3 * q[i - dr, j - dc, k] - 3 * q[i - 2 * dr, j - 2 * dc, k]
                                   + q[i - 3 * dr, j - 3 * dc, k])
                    v = _finite_mean(vals, 4)
                if not np.isfinite(v):   # linear
                    for a in range(4):
                        dr, dc = _AXES_A[a, 0], _AXES_A[a, 1]
                        vals[a] = 2 * q[i - dr, j - dc, k] - q[i - 2 * dr, j - 2 * dc, k]
                    v = _finite_mean(vals, 4)
                if not np.isfinite(v):   # the nearest cell's parallelogram
                    for a in range(4):
                        sr, sc = _CELLS[a, 0], _CELLS[a, 1]
                        vals[a] = q[i - sr, j, k] + q[i, j - sc, k] - q[i - sr, j - sc, k]
                    v = _finite_mean(vals, 4)
                out[i - 3, j - 3, k] = v
    return out


@njit(cache=True, nogil=True)
def _lattice_steps(p):  # pragma: no cover (compiled)
    return _spread(_step_along(p, 0, 1)), _spread(_step_along(p, 1, 0))


@njit(cache=True, nogil=True)
def _step_along(p, dr, dc):  # pragma: no cover (compiled)
    """The step (R, C, 2) to the next lattice position (dr, dc) at known corners."""
    e = np.empty_like(p)
    vals = np.empty(2)
    q = _padded(p, 2)
    for i in range(2, p.shape[0] + 2):
        for j in range(2, p.shape[1] + 2):
            for k in range(2):
                x = q[i, j, k]
                vals[0], vals[1] = q[i + dr, j + dc, k] - x, x - q[i - dr, j - dc, k]
                v = _finite_mean(vals, 2)
                if not np.isfinite(v):
                    # A grid that kept every other board line (grid.expand) has no neighbour one
                    # step away across the skipped lines: half the step to the one two away then.
                    vals[0] = q[i + 2 * dr, j + 2 * dc, k] - x
                    vals[1] = x - q[i - 2 * dr, j - 2 * dc, k]
                    v = 0.5 * _finite_mean(vals, 2)
                e[i - 2, j - 2, k] = v
    return e


@njit(cache=True, nogil=True)
def _spread(e):  # pragma: no cover (compiled)
    """e (R, C, 2) where finite, else the mean of its finite neighbours along the axes."""
    out = e.copy()
    vals = np.empty(4)
    q = _padded(e, 1)
    for i in range(e.shape[0]):
        for j in range(e.shape[1]):
            for k in range(2):
                if not np.isfinite(e[i, j, k]):
                    vals[0], vals[1] = q[i + 1, j, k], q[i + 1, j + 2, k]
                    vals[2], vals[3] = q[i, j + 1, k], q[i + 2, j + 1, k]
                    out[i, j, k] = _finite_mean(vals, 4)
    return out


def _drop_inconsistent(lat: Lattice, rounds: int = 3) -> int:
    """Drop given corners that their neighbours place elsewhere (by more than MAX_SURPRISE of
    a square): a detector's corner at the wrong lattice position (seen: 20 px off on a
    BabelCalib view) can still be a perfect X-junction of the right parity, two steps away.
    One bad corner spoils its neighbours' predictions too, so only the worst in each
    neighbourhood goes per round."""
    before = int(lat.known.sum())
    for _ in range(rounds):
        e_col, e_row = lat.steps()
        bad = _worst_surprises(predict(lat.p), lat.p, corner_refine.nearest_corner(e_col, e_row))
        if not bad.any():
            break
        lat.p[bad] = np.nan
    return before - int(lat.known.sum())


@njit(cache=True, nogil=True, error_model="numpy")
def _worst_surprises(pred, p, spacing):  # pragma: no cover (compiled)
    """(R, C) bool: corners p that their neighbours' prediction pred (R, C, 2) places more than
    MAX_SURPRISE of a square (spacing (R, C) px) away, and at least as far as any of their four
    neighbours is placed (an off-lattice neighbour counts 0)."""
    R, C = spacing.shape
    surprise = np.zeros((R + 2, C + 2))   # margin: NaN there, as np.max over shifted copies gave, taken as 0
    for i in range(R):
        for j in range(C):
            dx, dy = pred[i, j, 0] - p[i, j, 0], pred[i, j, 1] - p[i, j, 1]
            s = np.sqrt(dx * dx + dy * dy) / spacing[i, j]
            surprise[i + 1, j + 1] = s if np.isfinite(s) else 0.0
    bad = np.zeros((R, C), np.bool_)
    for i in range(R):
        for j in range(C):
            s = surprise[i + 1, j + 1]
            on_edge = i == 0 or j == 0 or i == R - 1 or j == C - 1
            around = 0.0 if on_edge else max(surprise[i + 1, j], surprise[i + 1, j + 2],
                                             surprise[i, j + 1], surprise[i + 2, j + 1])
            bad[i, j] = s > MAX_SURPRISE and s >= around
    return bad


def _seed_check(gray: np.ndarray, lat: Lattice) -> tuple[np.ndarray | None, int]:
    """(R, C) bool of the given corners that read as X-junctions, and the colour parity they
    agree with (placement can misread colours on tagged or dim boards); None if too few agree."""
    e_col, e_row = lat.steps()
    k = lat.known & np.isfinite(e_col[..., 0]) & np.isfinite(e_row[..., 0])
    if k.sum() < 4:
        return None, 0
    spacing = corner_refine.nearest_corner(e_col[k], e_row[k])
    even, half = lat.even()[k], corner_refine.half_window(spacing)
    reading = saddle.CornerReading.of(gray, lat.p[k], e_col[k], e_row[k], half)
    tries = [(reading.is_corner(even ^ bool(flip)), flip) for flip in (0, 1)]
    ok, flip = max(tries, key=lambda t: t[0].mean())  # the first on a tie
    if ok.mean() < MIN_SEED_AGREEMENT:
        return None, 0
    keep = np.zeros(lat.known.shape, bool)
    keep[k] = ok
    return keep, flip


def _within_board(lat: Lattice, ci: np.ndarray, cj: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """(N,) bool: new corners that keep the lattice within the board's size. Each alone does
    (``box_allows``), but a front on both sides at once can outgrow it by one: then the side
    with fewer new corners is left out. While the board may lie either way round
    (``Lattice.sizes``), the way that keeps more of them."""
    r, c = np.nonzero(lat.known)
    best = None
    for size_r, size_c in lat.sizes():
        keep = ok.copy()
        for new, old, size in ((ci, r, size_r), (cj, c, size_c)):
            lo, hi = new < old.min(), new > old.max()
            span = max(old.max(), new[keep].max(initial=old.max())) - min(old.min(), new[keep].min(initial=old.min())) + 1
            if span > size:
                keep &= ~(lo if (keep & lo).sum() < (keep & hi).sum() else hi)
        if best is None or keep.sum() > best.sum():
            best = keep
    assert best is not None  # sizes() is never empty
    return best


def _grow_front(gray: np.ndarray, lat: Lattice, tried: np.ndarray, unlit: np.ndarray | UnlitDistance) -> bool:
    """Try every position next to the lattice (one front); True if any corner was added."""
    known = lat.known
    k_at = Shifted(known.astype(float), 1)
    n_nb = sum(k_at(dr, dc) == 1 for dr, dc in _AXES)
    cand = ~known & (n_nb > tried) & lat.box_allows()
    if not cand.any():  # a whole board, seen whole: nothing to predict
        return False
    pred = predict(lat.p)
    e_col, e_row = lat.steps()
    cand &= np.isfinite(pred[..., 0]) & np.isfinite(e_col[..., 0]) & np.isfinite(e_row[..., 0])
    tried[cand] = n_nb[cand]
    return confirm(gray, lat, cand, pred, e_col, e_row, unlit) > 0


def confirm(gray: np.ndarray, lat: Lattice, cand: np.ndarray, guess: np.ndarray, e_col: np.ndarray,
            e_row: np.ndarray, unlit: np.ndarray | UnlitDistance) -> int:
    """Refine the guesses (R, C, 2) at candidate positions cand (R, C) with local steps e_col,
    e_row (R, C, 2); add those confirmed as corners to the lattice. Returns how many."""
    if not cand.any():
        return 0
    ci, cj = np.nonzero(cand)
    guess, ec, er = guess[cand], e_col[cand], e_row[cand]
    spacing = corner_refine.nearest_corner(ec, er)
    half = corner_refine.half_window(spacing)
    h, w = gray.shape
    inside = np.all((guess >= half[:, None] + 1) & (guess <= np.array([w, h]) - 2 - half[:, None]), axis=1)
    if not inside.any():
        return 0
    ci, cj, guess, ec, er, spacing, half = (a[inside] for a in (ci, cj, guess, ec, er, spacing, half))
    captured = corner_refine.refine(gray, guess, corner_refine.capture_window(spacing))
    got = corner_refine.refine(gray, captured, half)
    # A well-defined corner sits where windows of other sizes put it too; one blurred into
    # a curved smear at a fisheye's horizon does not, and is left out rather than guessed.
    stable = np.linalg.norm(corner_refine.refine(gray, captured, np.maximum(half - 1, 2)) - got, axis=1) <= MAX_WOBBLE
    # The refined window, not just its centre, must stay inside the frame and the image circle.
    in_frame = ((got[:, 0] >= half + 1) & (got[:, 0] <= w - 2 - half)
                & (got[:, 1] >= half + 1) & (got[:, 1] <= h - 2 - half))
    x = np.clip(np.rint(got[:, 0]).astype(int), 0, w - 1)
    y = np.clip(np.rint(got[:, 1]).astype(int), 0, h - 1)
    lit = unlit[y, x] > 1.5 * half + 1
    moved = (np.linalg.norm(got - guess, axis=1) <= MAX_MOVE * spacing) & corner_refine.window_holds_one_corner(spacing)
    ok = in_frame & lit & moved & stable & saddle.is_corner(gray, got, ec, er, lat.even()[ci, cj], half)
    ok &= _within_board(lat, ci, cj, ok)
    lat.p[ci[ok], cj[ok]] = got[ok]
    return int(ok.sum())
