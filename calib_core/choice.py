"""Choosing among models by how well they predict views they have not seen.

One rule for every choice between models (``method="auto"``'s candidates,
``compare``'s verdict): each candidate's validation error per view, summed
over the folds that left that view out; the lowest mean error per corner; and
the simplest candidate (candidates come simplest first) within the noise of
it: at most ``tolerance`` above it, or one standard error of it, the views
taken as independent draws (the one-standard-error rule of Hastie,
Tibshirani & Friedman, §7.10). A small or uneven set has a large standard
error and so gets the simpler model.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

TOLERANCE = 0.02
RULE = ("the simplest candidate whose validation error is within {tol:.0f} % or one standard error of the "
        "lowest (the one-standard-error rule; candidates are listed simplest first)")


@dataclass
class Candidate:
    """One model's validation: ``view_sse`` (n_views,) squared left-out
    residuals per view (px², both axes), or None with the ``error`` that kept
    it out."""

    name: str
    label: str
    view_sse: np.ndarray | None = None
    error: str = ""
    n_params: int | None = None
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass
class ModelChoice:
    candidates: list[Candidate]
    counts: np.ndarray  # (n_views,) corners validated per view
    chosen: int
    best: int  # lowest validation error
    standard_error: float  # of the lowest's mean squared error per corner
    tolerance: float
    how: str = ""  # how the errors were measured, in words

    @property
    def name(self) -> str:
        return self.candidates[self.chosen].name

    def mse(self, k: int) -> float:
        c = self.candidates[k]
        return np.inf if c.view_sse is None else float(c.view_sse.sum() / self.counts.sum())

    def rmse(self, k: int) -> float:
        """Validation rmse per axis (px), as ``rmse_axis`` elsewhere."""
        return float(np.sqrt(self.mse(k) / 2))

    def threshold(self) -> float:
        best = self.mse(self.best)
        return best + max(self.tolerance * best, self.standard_error)

    def summary(self) -> str:
        c = self.candidates[self.chosen]
        if self.chosen == self.best:
            why = "it predicts the views left out of its fit best"
        else:
            b = self.candidates[self.best]
            why = (f"it predicts the views left out of its fit as well as the {b.label} "
                   f"({self.rmse(self.chosen):.4f} against {self.rmse(self.best):.4f} px per axis, within the "
                   f"noise of the lowest) and is simpler")
        return f"{c.label}: {why}"

    def to_json(self) -> dict[str, Any]:
        best = self.mse(self.best)
        se_rmse = self.standard_error / (2 * np.sqrt(2 * best)) if best > 0 else 0.0
        return {
            "chosen": self.name,
            "summary": self.summary(),
            "rule": RULE.format(tol=100 * self.tolerance),
            "how": self.how,
            "n_views": int(len(self.counts)),
            "n_points": int(self.counts.sum()),
            "standard_error_rmse": float(se_rmse),
            "threshold_rmse": float(np.sqrt(self.threshold() / 2)),
            "candidates": [
                {"name": c.name, "label": c.label, "chosen": k == self.chosen,
                 "validation_rmse": None if c.view_sse is None else self.rmse(k),
                 "validation_mse": None if c.view_sse is None else self.mse(k),
                 "n_params": c.n_params, **({"error": c.error} if c.error else {}), **c.extra}
                for k, c in enumerate(self.candidates)],
        }


def choose(candidates: list[Candidate], counts: np.ndarray, tolerance: float = TOLERANCE, how: str = "",
           paired: bool = False) -> ModelChoice:
    """The one-standard-error choice among ``candidates`` (simplest first);
    ValueError if none was validated. ``paired``: a candidate is within the
    noise when its excess over the lowest, view by view, is within one
    standard error of that excess (for candidates that share the views'
    noise, as knot grids of one field do)."""
    counts = np.asarray(counts, dtype=float)
    scores = np.array([np.inf if c.view_sse is None else c.view_sse.sum() / counts.sum() for c in candidates])
    if not np.isfinite(scores).any():
        raise ValueError("no candidate could be validated")
    best = int(np.argmin(scores))
    n = len(counts)
    per_view = candidates[best].view_sse * n / counts.sum()  # its mean is scores[best]
    standard_error = float(np.std(per_view, ddof=1) / np.sqrt(n)) if n > 1 else np.inf
    limit = scores[best] + max(tolerance * scores[best], standard_error)
    if paired:
        within = []
        for k, c in enumerate(candidates):
            if c.view_sse is None:
                within.append(False)
                continue
            excess = (c.view_sse - candidates[best].view_sse) * n / counts.sum()
            se = np.std(excess, ddof=1) / np.sqrt(n) if n > 1 else np.inf
            within.append(excess.mean() <= max(tolerance * scores[best], se))
        chosen = int(np.flatnonzero(within)[0])
    else:
        chosen = int(np.flatnonzero(scores <= limit)[0])
    return ModelChoice(candidates, counts, chosen, best, standard_error, tolerance, how)
