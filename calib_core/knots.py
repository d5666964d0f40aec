"""Knot strategies: the paper's adaptive KDE knots (method.md §"Adaptive
knots") and uniform knots. Both return interval breaks ``[lo, …, hi]`` per
direction; ``bspline.clamped_knots`` repeats the ends.

Samples are ideal pixel positions ``(u, v)`` (N, 2) of the observed corners
with their distortion response ``z`` (N, 2) = (Δx, Δy). The domain covers the
ideal positions of the whole image, usually beyond the samples.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial import Delaunay, QhullError

from .errors import SettingsError


@dataclass
class KnotSettings:
    strategy: str = "kde"  # "kde" (the paper) | "uniform"
    bandwidth: str = "scott"  # "scott" | "silverman"
    bandwidth_factor: float = 1.0  # Table 2: Scott × 1.0 (× 1.2 was best on real data)
    window_ratio: float = 0.05  # ρ of the local-std window (the paper leaves it open)
    min_window: int = 5  # m_min
    weight_range: tuple[float, float] = (0.5, 1.5)  # w_min, w_max
    max_intervals: int = 15
    min_support: int | None = None  # None: max(10, N/50)
    coverage_rounds: int = 30
    uniform_intervals: tuple[int, int] = (8, 8)
    extra: dict = field(default_factory=dict)

    def validate(self) -> None:
        if self.strategy not in ("kde", "uniform"):
            raise SettingsError(f"knots: unknown strategy {self.strategy!r}; use 'kde' or 'uniform'")
        if self.bandwidth not in ("scott", "silverman"):
            raise SettingsError(f"bandwidth: unknown rule {self.bandwidth!r}; use 'scott' or 'silverman'")
        if not self.bandwidth_factor > 0:
            raise SettingsError("bandwidth_factor must be positive")
        if not 0 < self.window_ratio < 1:
            raise SettingsError("window_ratio must lie in (0, 1)")
        if self.max_intervals < 1:
            raise SettingsError("max_intervals must be at least 1")
        if min(self.uniform_intervals) < 1:
            raise SettingsError("uniform intervals must be at least 1 per direction")


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


def kde_maxima(d: np.ndarray, w: np.ndarray, h: float, n_bins: int = 2048) -> np.ndarray:
    """Local maxima of the weighted Gaussian KDE (binned, O(N))."""
    lo, hi = d.min(), d.max()
    if hi - lo <= 0:
        return np.array([lo])
    hist, edges = np.histogram(d, bins=n_bins, range=(lo - 3 * h, hi + 3 * h), weights=w / w.sum())
    step = edges[1] - edges[0]
    dens = gaussian_filter1d(hist, sigma=h / step, mode="constant") / step
    centres = 0.5 * (edges[:-1] + edges[1:])
    inner = (dens[1:-1] > dens[:-2]) & (dens[1:-1] >= dens[2:])
    peaks = centres[1:-1][inner]
    return peaks[(peaks > lo) & (peaks < hi)]


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


def candidate_breaks(d: np.ndarray, w: np.ndarray, lo: float, hi: float, settings: KnotSettings) -> np.ndarray:
    """Step 3: domain ends, KDE maxima and quartiles, deduplicated and sorted."""
    h = bandwidth(d, w, settings)
    cands = np.concatenate([[lo, hi], kde_maxima(d, w, h), np.percentile(d, [25, 50, 75])])
    cands = np.sort(cands[(cands >= lo) & (cands <= hi)])
    tol = 1e-6 * (hi - lo)
    return cands[np.concatenate([[True], np.diff(cands) > tol])]


def coverage_merge(samples: np.ndarray, bu: np.ndarray, bv: np.ndarray, rounds: int):
    """Step 5: while a tensor cell inside the samples' convex hull is empty, merge
    along the direction with more empty cells (at most ``rounds`` times).

    Cells outside the hull are never observed by this data; there the
    regularisers govern the field, so they do not force merges (a deviation
    from the paper, whose domain was the data's own range)."""
    try:
        hull = Delaunay(samples)
    except (QhullError, ValueError):
        return bu, bv
    for _ in range(rounds):
        hist = np.histogram2d(samples[:, 0], samples[:, 1], bins=[bu, bv])[0]
        cu, cv = 0.5 * (bu[:-1] + bu[1:]), 0.5 * (bv[:-1] + bv[1:])
        centres = np.stack(np.meshgrid(cu, cv, indexing="ij"), axis=-1).reshape(-1, 2)
        inside = (hull.find_simplex(centres) >= 0).reshape(hist.shape)
        empty = (hist == 0) & inside
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


def adaptive_breaks(samples: np.ndarray, weights: np.ndarray, domain, settings: KnotSettings):
    """The paper's adaptive KDE knots: breaks along u and v from samples (N, 2)
    and their per-direction weights (N, 2)."""
    u0, u1, v0, v1 = domain
    n = len(samples)
    n_min = settings.min_support if settings.min_support is not None else max(10, n // 50)
    out = []
    for axis, (lo, hi) in enumerate(((u0, u1), (v0, v1))):
        d = samples[:, axis]
        breaks = candidate_breaks(d, weights[:, axis], lo, hi, settings)
        out.append(merge_for_support(d, breaks, n_min, settings.max_intervals))
    return coverage_merge(samples, out[0], out[1], settings.coverage_rounds)


def uniform_breaks(domain, intervals: tuple[int, int]):
    u0, u1, v0, v1 = domain
    return np.linspace(u0, u1, intervals[0] + 1), np.linspace(v0, v1, intervals[1] + 1)
