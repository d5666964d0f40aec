"""Choosing among models by how well they predict views they have not seen.

One rule for every choice between models (``method="auto"``'s candidates,
``compare``'s verdict; a field's knot grids, whose smoothing already prices
their flexibility, take the lowest error instead): each candidate's validation
error per view, summed over the folds that left that view out; the lowest
mean error per corner; and the simplest candidate (candidates come simplest
first) within the noise of it: its excess over the lowest, view by view, no
more than one standard error of that excess (the one-standard-error rule of
Hastie, Tibshirani & Friedman, §7.10, on paired differences, as every
candidate is scored on the same views and so shares their noise). A small or
uneven set has a large standard error and so gets the simpler model. A
candidate that a simpler one predicts better is never chosen: each band is the
candidate's own, and on a few views an erratic candidate's is wide enough to
hold the lowest error while a simpler, steadier and better one's is not
(docs/model-choice.md, "A candidate a simpler one beats").

A candidate whose distortion turns back inside the image (a polynomial or
rational model past the reach of its corners: it maps no ray to part of the
lit image's edge) cannot serve the image's corners, whatever its error on the
views: one that turns back a tenth of the way in is left out while another
maps that far, one that turns back only in the outermost tenth while a
simpler one maps the whole edge (docs/model-choice.md, step 3).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

RULE = ("the simplest candidate whose excess over the lowest validation error, view by view, is within one "
        "standard error of that excess (the one-standard-error rule on paired differences; candidates are listed "
        "simplest first) and that no simpler candidate predicts better; a candidate whose distortion turns back "
        "a tenth of the way in from the image's edge is left out while another maps that far, one that turns back "
        "only in the outermost tenth while a simpler one maps all of the edge")


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
    # shares of the lit image's edge, and of the same a tenth of the way in, its model maps no ray
    # to (``unproject.LitEdge.folds``)
    unmapped: float = 0.0
    unmapped_inside: float = 0.0


@dataclass
class ModelChoice:
    candidates: list[Candidate]
    counts: np.ndarray  # (n_views,) corners validated per view
    chosen: int
    best: int  # lowest validation error
    excess_se: np.ndarray  # (n_candidates,) standard error of each one's mean excess over the lowest (px² per corner)
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

    def within_noise(self, k: int) -> bool:
        return bool(self.mse(k) - self.mse(self.best) <= self.excess_se[k])

    def beaten_by(self, k: int) -> int | None:
        """The simpler candidate with the lowest validation error, if it is lower than ``k``'s."""
        simpler = min(range(k), key=self.mse, default=None)
        return simpler if simpler is not None and self.mse(simpler) < self.mse(k) else None

    def _as_rmse(self, excess: float) -> float | None:
        """An excess in mean squared error, as the rmse per axis it adds to the
        lowest's; None (JSON null) when the excess is not finite."""
        best = self.mse(self.best)
        return float(np.sqrt((best + excess) / 2) - np.sqrt(best / 2)) if np.isfinite(excess) else None

    def _beaten_json(self, k: int) -> dict[str, str]:
        simpler = None if self.candidates[k].view_sse is None else self.beaten_by(k)
        return {} if simpler is None else {"beaten_by": self.candidates[simpler].name}

    def summary(self) -> str:
        c = self.candidates[self.chosen]
        if self.chosen == self.best:
            why = "it predicts the views left out of its fit best"
        else:
            b = self.candidates[self.best]
            why = (f"it predicts the views left out of its fit as well as the {b.label} "
                   f"({self.rmse(self.chosen):.4f} against {self.rmse(self.best):.4f} px per axis, within the "
                   f"noise of the difference) and is simpler")
        return f"{c.label}: {why}"

    def to_json(self) -> dict[str, Any]:
        return {
            "chosen": self.name,
            "summary": self.summary(),
            "rule": RULE,
            "how": self.how,
            "n_views": int(len(self.counts)),
            "n_points": int(self.counts.sum()),
            "candidates": [
                {"name": c.name, "label": c.label, "chosen": k == self.chosen,
                 "validation_rmse": None if c.view_sse is None else self.rmse(k),
                 "validation_mse": None if c.view_sse is None else self.mse(k),
                 # one standard error of its excess over the lowest, as rmse per axis: the band within which it
                 # counts as equally good
                 "standard_error_rmse": None if c.view_sse is None else self._as_rmse(float(self.excess_se[k])),
                 "within_noise": None if c.view_sse is None else self.within_noise(k),
                 **self._beaten_json(k),
                 "n_params": c.n_params, **({"error": c.error} if c.error else {}), **c.extra}
                for k, c in enumerate(self.candidates)],
        }


def choose(candidates: list[Candidate], counts: np.ndarray, how: str = "") -> ModelChoice:
    """The one-standard-error choice among ``candidates`` (simplest first),
    on paired per-view differences; ValueError if none was validated."""
    counts = np.asarray(counts, dtype=float)
    _leave_out_folding(candidates, counts)
    scores = np.array([np.inf if c.view_sse is None else c.view_sse.sum() / counts.sum() for c in candidates])
    if not np.isfinite(scores).any():
        raise ValueError("no candidate could be validated")
    best = int(np.argmin(scores))
    n = len(counts)
    excess_se = np.full(len(candidates), np.inf)
    for k, c in enumerate(candidates):
        if c.view_sse is not None:
            excess = (c.view_sse - candidates[best].view_sse) * n / counts.sum()  # its mean is the excess per corner
            excess_se[k] = np.std(excess, ddof=1) / np.sqrt(n) if n > 1 else np.inf
    excess_se[best] = 0.0
    choice = ModelChoice(candidates, counts, best, best, excess_se, how)
    choice.chosen = next(k for k in range(len(candidates))
                         if choice.mse(k) < np.inf and choice.within_noise(k) and choice.beaten_by(k) is None)
    return choice


def _leave_out_folding(candidates: list[Candidate], counts: np.ndarray) -> None:
    """Candidates whose model maps no ray to part of the lit image's edge lose their
    validation, with the reason: one that folds a tenth of the way in, while another
    maps that far; one that folds only in the outermost tenth, while a simpler one maps
    all of the edge. A simple model turning back in the frame's corners, where few boards
    reach, is no reason to take a more flexible one the views left out cannot tell from it
    (docs/model-choice.md, step 3)."""
    validated = [(k, c) for k, c in enumerate(candidates) if c.view_sse is not None]
    inside_mapped = [c for _, c in validated if c.unmapped_inside == 0]
    reasons = {}
    for k, c in validated:
        if c.unmapped == 0:
            continue
        if c.unmapped_inside > 0 and inside_mapped:
            reasons[k] = (f"it maps no ray to {100 * c.unmapped_inside:.1f} % of the image's edge taken a tenth of "
                          "the way in (its distortion turns back inside the image), so it cannot serve the image's "
                          "corners")
        elif c.unmapped_inside == 0:
            simpler = next((d for j, d in validated if j < k and d.unmapped == 0), None)
            if simpler is not None:
                reasons[k] = (f"its distortion turns back in the image's outermost tenth ({100 * c.unmapped:.1f} % "
                              f"of the image's edge maps no ray), where the simpler {simpler.label} maps all of it")
    for k, why in reasons.items():
        c = candidates[k]
        assert c.view_sse is not None  # validated
        rmse = np.sqrt(c.view_sse.sum() / counts.sum() / 2)
        c.error = f"left out: {why}; its error on the views left out was {rmse:.4f} px per axis"
        c.view_sse = None
