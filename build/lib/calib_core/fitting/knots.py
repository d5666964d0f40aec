"""Knot strategies: the paper's adaptive KDE knots (method.md §"Adaptive
knots") and uniform knots. Both return interval breaks ``[lo, …, hi]`` per
direction; ``bspline.clamped_knots`` repeats the ends.

Samples are ideal pixel positions ``(u, v)`` (N, 2) of the observed corners
with their distortion response ``z`` (N, 2) = (Δx, Δy). The domain covers the
ideal positions of the whole image, usually beyond the samples.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial import Delaunay, QhullError

from .. import ranges
from ..errors import SettingsError

STRATEGIES = ("kde", "kde-paper", "uniform", "explicit")
# Knot intervals per direction: the grid has (n + 3)² control points, and the solver's
# matrices grow with their square (1 000 000 intervals asked for 14.6 TiB). 50 is over
# three times what the automatic choice ever takes (15).
MAX_INTERVALS = 50
MAX_BANDWIDTH_FACTOR = 100.0


@dataclass
class KnotSettings:
    strategy: str = "kde"  # "kde" | "kde-paper" | "uniform"
    bandwidth: str = "scott"  # "scott" | "silverman"
    bandwidth_factor: float = 1.0  # Table 2: Scott × 1.0 (× 1.2 was best on real data)
    window_ratio: float = 0.05  # ρ of the local-std window (the paper leaves it open)
    min_window: int = 5  # m_min
    weight_range: tuple[float, float] = (0.5, 1.5)  # w_min, w_max
    max_intervals: int = 15
    min_support: int | None = None  # None: max(10, N/50)
    coverage_rounds: int = 30
    intervals: tuple[int, int] = (10, 10)  # uniform grid, or KDE-quantile intervals for "kde"
    interior: tuple[tuple[float, ...], tuple[float, ...]] | None = None  # "explicit": interior knots (u, v)

    def validate(self) -> None:
        if self.strategy not in STRATEGIES:
            raise SettingsError(f"knots: unknown strategy {self.strategy!r}; use one of {STRATEGIES}")
        if self.bandwidth not in ("scott", "silverman"):
            raise SettingsError(f"bandwidth: unknown rule {self.bandwidth!r}; use 'scott' or 'silverman'")
        ranges.number("bandwidth_factor", self.bandwidth_factor, 0, MAX_BANDWIDTH_FACTOR, above_low=True)
        ranges.number("window_ratio", self.window_ratio, 0, 1, above_low=True, below_high=True)
        ranges.whole("max_intervals", self.max_intervals, 1, MAX_INTERVALS)
        for n in self.intervals:
            ranges.whole("intervals (per direction)", n, 1, MAX_INTERVALS)
        if self.min_support is not None:
            ranges.whole("min_support", self.min_support, 1, 1_000_000, alternative="null (automatic)")
        if self.strategy == "explicit" and (self.interior is None or len(self.interior) != 2):
            raise SettingsError("knots 'explicit' needs interior_knots: [[u knots...], [v knots...]]")
        for axis in self.interior or ():
            if not isinstance(axis, (list, tuple)) or len(axis) > MAX_INTERVALS - 1:
                raise SettingsError(f"interior_knots: expected two lists of at most {MAX_INTERVALS - 1} knots "
                                    f"(pixels) each, got {ranges.shown(self.interior)}")
            for knot in axis:
                ranges.number("interior_knots", knot, -1e6, 1e6)


def local_std_weights(d: np.ndarray, z: np.ndarray, settings: KnotSettings) -> np.ndarray:
    """w_k: the sliding-window std of the response along ``d``, mapped linearly
    to [w_min, w_max] (method.md step 1). Returned in the input order."""
    n = len(d)
    order = np.argsort(d, kind="stable")
    zs = z[order]
    m = max(settings.min_window, 2 * int(np.floor(n * settings.window_ratio / 2)) + 1)
    half = (m - 1) // 2
    k = np.arange(n)
    lo, hi = np.maximum(0, k - half), np.minimum(n, k + half + 1)
    c1 = np.concatenate([[0.0], np.cumsum(zs)])
    c2 = np.concatenate([[0.0], np.cumsum(zs * zs)])
    cnt = hi - lo
    mean = (c1[hi] - c1[lo]) / cnt
    s = np.sqrt(np.maximum((c2[hi] - c2[lo]) / cnt - mean * mean, 0.0))
    out = np.empty(n)
    out[order] = _to_range(s, settings)
    return out


WEIGHTINGS = ("local_std", "uniform", "magnitude", "gradient")


def _to_range(s: np.ndarray, settings: KnotSettings) -> np.ndarray:
    w_min, w_max = settings.weight_range
    span = s.max() - s.min()
    if span <= 1e-12 * max(1.0, abs(s.max())):
        return np.ones_like(s)
    return w_min + (w_max - w_min) * (s - s.min()) / span


def sample_weights(d: np.ndarray, z: np.ndarray, how: str, settings: KnotSettings) -> np.ndarray:
    """Per-sample weights along one direction (Table 12's options); ``local_std`` is the paper's."""
    if how == "local_std":
        return local_std_weights(d, z, settings)
    if how == "uniform":
        return np.ones(len(d))
    if how == "magnitude":
        return _to_range(np.abs(z), settings)
    if how == "gradient":
        order = np.argsort(d, kind="stable")
        grad = np.abs(np.gradient(z[order], d[order] + 1e-9 * np.arange(len(d))))
        out = np.empty(len(d))
        out[order] = _to_range(grad, settings)
        return out
    raise SettingsError(f"weighting: unknown {how!r}; use one of {WEIGHTINGS}")


def bandwidth(d: np.ndarray, w: np.ndarray, settings: KnotSettings) -> float:
    """Weighted Scott (σ n_eff^(−1/5)) or Silverman bandwidth, times the factor."""
    wn = w / w.sum()
    mean = float(wn @ d)
    sigma = float(np.sqrt(wn @ (d - mean) ** 2))
    n_eff = w.sum() ** 2 / np.sum(w * w)
    if settings.bandwidth == "scott":
        h = sigma * n_eff ** (-1 / 5)
    else:
        q75, q25 = np.percentile(d, [75, 25])
        h = 0.9 * min(sigma, (q75 - q25) / 1.34) * n_eff ** (-1 / 5)
    return settings.bandwidth_factor * max(h, 1e-9 * max(1.0, abs(mean)))


def weighted_kde(d: np.ndarray, w: np.ndarray, h: float, n_bins: int = 2048):
    """The weighted Gaussian KDE on a grid (binned, O(N)): centres and density."""
    lo, hi = d.min(), d.max()
    hist, edges = np.histogram(d, bins=n_bins, range=(lo - 3 * h, hi + 3 * h), weights=w / w.sum())
    step = edges[1] - edges[0]
    dens = gaussian_filter1d(hist, sigma=h / step, mode="constant") / step
    return 0.5 * (edges[:-1] + edges[1:]), dens


def kde_maxima(d: np.ndarray, w: np.ndarray, h: float) -> np.ndarray:
    """Local maxima of the weighted KDE inside the samples' range."""
    lo, hi = d.min(), d.max()
    if hi - lo <= 0:
        return np.array([lo])
    centres, dens = weighted_kde(d, w, h)
    inner = (dens[1:-1] > dens[:-2]) & (dens[1:-1] >= dens[2:])
    peaks = centres[1:-1][inner]
    return peaks[(peaks > lo) & (peaks < hi)]


def kde_quantiles(d: np.ndarray, w: np.ndarray, h: float, intervals: int) -> np.ndarray:
    """Interior breaks that split the weighted KDE's mass into ``intervals``
    equal parts: more knots where corners are dense and the distortion varies."""
    if intervals < 2 or d.max() <= d.min():
        return np.zeros(0)
    centres, dens = weighted_kde(d, w, h)
    cdf = np.cumsum(dens)
    cdf /= cdf[-1]
    q = np.interp(np.arange(1, intervals) / intervals, cdf, centres)
    return q[(q > d.min()) & (q < d.max())]


def _counts(d: np.ndarray, breaks: np.ndarray) -> np.ndarray:
    # np.histogram closes the last interval, as the method asks.
    return np.histogram(d, bins=breaks)[0]


def _merge_once(breaks: np.ndarray, counts: np.ndarray, r: int) -> np.ndarray:
    """Merge interval r into its less populated neighbour (drop one interior break)."""
    n = len(counts)
    if r == 0:
        drop = 1
    elif r == n - 1:
        drop = n - 1
    else:
        drop = r if counts[r - 1] <= counts[r + 1] else r + 1
    return np.delete(breaks, drop)


def merge_for_support(d: np.ndarray, breaks: np.ndarray, n_min: int, max_intervals: int) -> np.ndarray:
    """Step 4: merge intervals with fewer than ``n_min`` samples, then cap the count."""
    while len(breaks) > 2:
        counts = _counts(d, breaks)
        if counts.min() >= n_min and len(counts) <= max_intervals:
            break
        breaks = _merge_once(breaks, counts, int(np.argmin(counts)))
    return breaks


def candidate_breaks(d: np.ndarray, w: np.ndarray, lo: float, hi: float, settings: KnotSettings,
                     quantile_intervals: int = 0) -> np.ndarray:
    """Step 3: domain ends, KDE maxima and quartiles (the paper), and with
    ``quantile_intervals`` the KDE's equal-mass quantiles; deduplicated, sorted."""
    h = bandwidth(d, w, settings)
    cands = np.concatenate([kde_maxima(d, w, h), np.percentile(d, [25, 50, 75]),
                            kde_quantiles(d, w, h, quantile_intervals)])
    # Interior candidates only, at least tol from the ends and from each other:
    # the domain ends themselves stay exact (a corner at the edge of the
    # domain once replaced its end by 519.9999999999999).
    tol = 1e-6 * (hi - lo)
    cands = np.sort(cands[(cands > lo + tol) & (cands < hi - tol)])
    cands = cands[np.concatenate([[True], np.diff(cands) > tol])] if len(cands) else cands
    return np.concatenate([[lo], cands, [hi]])


def inside_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """(N,) bool: even-odd rule, vectorised over points and edges."""
    x, y = points[:, 0:1], points[:, 1:2]
    x0, y0 = polygon[:, 0], polygon[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    crosses = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_at = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    return np.sum(crosses & (x < x_at), axis=1) % 2 == 1


def coverage_merge(samples: np.ndarray, bu: np.ndarray, bv: np.ndarray, rounds: int,
                   footprint: np.ndarray | None = None):
    """Step 5: while a tensor cell the camera can see is empty, merge along the
    direction with more empty cells (at most ``rounds`` times).

    "Can see" means the cell's centre lies inside ``footprint``, the image
    border in the field's coordinates (or, without one, the samples' convex
    hull). Cells outside are never observed; the regularisers govern the
    field there, so they do not force merges (the paper's domain was the
    image itself, where the two rules agree)."""
    if footprint is not None:
        def seen(c):
            return inside_polygon(c, footprint)
    else:
        try:
            hull = Delaunay(samples)
        except (QhullError, ValueError):
            return bu, bv

        def seen(c):
            return hull.find_simplex(c) >= 0
    for _ in range(rounds):
        hist = np.histogram2d(samples[:, 0], samples[:, 1], bins=[bu, bv])[0]
        cu, cv = 0.5 * (bu[:-1] + bu[1:]), 0.5 * (bv[:-1] + bv[1:])
        centres = np.stack(np.meshgrid(cu, cv, indexing="ij"), axis=-1).reshape(-1, 2)
        empty = (hist == 0) & seen(centres).reshape(hist.shape)
        if not empty.any():
            break
        per_u, per_v = empty.sum(axis=1), empty.sum(axis=0)  # empty cells per u / v interval
        if per_u.sum() >= per_v.sum() and len(bu) > 2:
            bu = _merge_once(bu, hist.sum(axis=1), int(np.argmax(per_u)))
        elif len(bv) > 2:
            bv = _merge_once(bv, hist.sum(axis=0), int(np.argmax(per_v)))
        else:
            break
    return bu, bv


def adaptive_breaks(samples: np.ndarray, weights: np.ndarray, domain, settings: KnotSettings,
                    footprint: np.ndarray | None = None):
    """Adaptive KDE knots: breaks along u and v from samples (N, 2) and their
    per-direction weights (N, 2).

    ``kde-paper`` takes the paper's candidates only (domain ends, KDE maxima,
    quartiles). With a Scott bandwidth the KDE of a calibration set has few
    maxima, so that gives few, centre-heavy intervals (6 × 6 on the paper's
    synthetic lenses) and the fit stays well above the noise floor. ``kde``
    adds the equal-mass quantiles of the same weighted KDE and caps the count
    at ``intervals`` per direction (at most ``max_intervals``); the merging
    rules (support, least-populated first, 2-D coverage) are the paper's.
    """
    u0, u1, v0, v1 = domain
    n = len(samples)
    n_min = settings.min_support if settings.min_support is not None else max(10, n // 50)
    out = []
    for axis, (lo, hi) in enumerate(((u0, u1), (v0, v1))):
        d = samples[:, axis]
        if settings.strategy == "kde":
            target = min(settings.intervals[axis], settings.max_intervals)
            breaks = candidate_breaks(d, weights[:, axis], lo, hi, settings, target)
        else:
            target = settings.max_intervals
            breaks = candidate_breaks(d, weights[:, axis], lo, hi, settings)
        out.append(merge_for_support(d, breaks, n_min, target))
    return coverage_merge(samples, out[0], out[1], settings.coverage_rounds, footprint)


def breaks_for(samples: np.ndarray, weights: np.ndarray, domain, settings: KnotSettings,
               footprint: np.ndarray | None = None):
    """Interval breaks along u and v by the chosen strategy."""
    if settings.strategy == "uniform":
        return uniform_breaks(domain, settings.intervals)
    if settings.strategy == "explicit":
        return explicit_breaks(domain, settings.interior)
    return adaptive_breaks(samples, weights, domain, settings, footprint)


def explicit_breaks(domain, interior):
    """The domain ends around given interior knots (those outside the domain dropped)."""
    out = []
    for (lo, hi), knots in zip(((domain[0], domain[1]), (domain[2], domain[3])), interior, strict=True):
        k = np.unique(np.asarray(knots, dtype=float))
        out.append(np.concatenate([[lo], k[(k > lo) & (k < hi)], [hi]]))
    return out[0], out[1]


def uniform_breaks(domain, intervals: tuple[int, int]):
    u0, u1, v0, v1 = domain
    return np.linspace(u0, u1, intervals[0] + 1), np.linspace(v0, v1, intervals[1] + 1)
