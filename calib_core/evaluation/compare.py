"""Every method on the same corners, side by side, and a verdict.

``compare(observations)`` runs each method through the same pipeline
(``pipeline.calibrate``) and answers three questions:

- how well does it fit (overall and per-view rmse; centre vs edge);
- how well does it predict views it has not seen: k-fold cross-validation
  over the views (each view validated once; the model is held and only the
  validated views' poses are refit, as in ``evaluate.py``), and, when given,
  a separate hold-out set;
- which to trust: ``method="auto"``'s rule (``choice.py``), and we test whether
  the winner's validation residuals still show spatial structure (neighbouring
  corners' residuals correlated beyond what shuffling them gives).

It returns a ``Comparison``; its ``to_json()`` is what ``freecal compare --json``
prints and the web service stores: ``{"methods": {name: {...}}, "verdict": name, ...}``.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from ..calibration import Calibration
from ..errors import CalibError, DataError, SettingsError
from ..fit_report import FitMetrics
from ..fitting import metrics
from ..fitting.choice import Candidate, choose
from ..fitting.crossval import folds
from ..fitting.init import initialise
from ..fitting.view_set import check_views
from ..methods import METHODS
from ..methods.auto import past_pinhole
from ..methods.common import Progress, named, no_progress, scaled
from ..models.base import fitted_parameter_count
from ..models.unproject import LitEdge, lit_edge
from ..observations import Observations
from ..pipeline import MIN_VIEWS, calibrate, to_data, usable_views
from . import quality
from .evaluate import validation_residuals

DEFAULT_METHODS = ("zhang", "rational", "fisheye", "mls", "tps", "bspline")
SETTINGS = ("methods", "splits")  # what a caller may set of compare(): the service's compare jobs
# The verdict's order of simplicity: parametric models by their number of
# coefficients, then the fields.
SIMPLEST_FIRST = ("zhang", "fisheye", "rational", "bspline", "mls", "tps")
STRUCTURE_P_VALUE = 0.01  # below this, the residuals are called spatially structured
N_PERMUTATIONS = 200


@dataclass
class MethodScores:
    """One method's fit of the corners, and how it predicts views it has not seen."""

    fit: FitMetrics                    # the fit's error over its corners (Calibration.metrics)
    views: list[dict[str, Any]]        # per view: name, rmse, rmse_axis, n_points
    n_params: int                      # the parameters the fit moved
    quality: dict[str, Any]            # the paper's Table 7 (quality.py), or {"error": why}
    holdout: dict[str, float] | None = None   # holdout_rmse, _axis, _center, _edge, with a hold-out set
    cv: dict[str, Any] | None = None          # the folds over the views (None without cross-validation)
    folds: tuple[float, float] = (0.0, 0.0)  # what its model maps no ray to (``unproject.LitEdge.folds``)

    @property
    def cv_validation_rmse(self) -> float | None:
        return None if self.cv is None else self.cv["validation_rmse"]["mean"]

    def to_json(self) -> dict[str, Any]:
        out = {**self.fit.to_json(), "views": self.views, "n_params": self.n_params, "quality": self.quality,
               **(self.holdout or {})}
        if self.cv is not None:
            out.update(cv=self.cv, cv_validation_rmse=self.cv_validation_rmse)
        return out


@dataclass
class MethodFailure:
    """A method that cannot handle these corners, and why."""

    error: str

    def to_json(self) -> dict[str, Any]:
        return {"error": self.error}


@dataclass
class Comparison:
    """Every method on the same corners and the one to trust (``verdict``)."""

    methods: dict[str, MethodScores | MethodFailure]
    n_views: int
    n_points: int
    splits: int
    quality_raw: dict[str, Any]                   # Table 7 of the raw image (or {"error": why})
    verdict: str | None = None
    verdict_detail: dict[str, Any] = field(default_factory=dict)

    @property
    def scored(self) -> dict[str, MethodScores]:
        return {n: m for n, m in self.methods.items() if isinstance(m, MethodScores)}

    def to_json(self) -> dict[str, Any]:
        return {"methods": {n: m.to_json() for n, m in self.methods.items()}, "n_views": self.n_views,
                "n_points": self.n_points, "splits": self.splits, "quality_raw": self.quality_raw,
                "verdict": self.verdict, "verdict_detail": self.verdict_detail}


def neighbour_correlation(residuals: np.ndarray, object_points: np.ndarray, view_index: np.ndarray,
                          seed: int = 0) -> dict[str, float]:
    """Do neighbouring corners share their error? residuals (N, 2), object_points (N, 3), view_index (N,).

    ρ = Σ_pairs r_i·r_j / Σ_pairs (|r_i|² + |r_j|²)/2 over board neighbours (one
    square apart) within each view: ≈ 0 for independent noise, → 1 when a
    smooth error is left. The p-value is the share of within-view shufflings
    of the residuals that reach the observed ρ."""
    rng = np.random.default_rng(seed)
    neighbours = []
    for k in np.unique(view_index):
        idx = np.flatnonzero(view_index == k)
        if len(idx) < 3:
            continue
        pts = object_points[idx]
        tree = cKDTree(pts)
        spacing = tree.query(pts, k=2)[0][:, 1].min()
        p = tree.query_pairs(1.01 * spacing, output_type="ndarray")
        neighbours.append(idx[p])
    if not neighbours:
        return {"rho": float("nan"), "p_value": float("nan"), "n_pairs": 0}
    pairs = np.concatenate(neighbours)
    r = residuals - residuals.mean(axis=0)

    def rho(rr: np.ndarray) -> float:
        a, b = rr[pairs[:, 0]], rr[pairs[:, 1]]
        return float(np.sum(a * b) / (0.5 * np.sum(a * a + b * b)))

    observed = rho(r)
    groups = [np.flatnonzero(view_index == k) for k in np.unique(view_index)]
    count = 0
    for _ in range(N_PERMUTATIONS):
        perm = np.arange(len(r))
        for g in groups:  # shuffle within each view: keeps each view's error level
            perm[g] = rng.permutation(g)
        count += rho(r[perm]) >= observed
    return {"rho": observed, "p_value": (1 + count) / (1 + N_PERMUTATIONS), "n_pairs": int(len(pairs))}


def _mean_std(values: list[float]) -> dict[str, float]:
    a = np.asarray(values, dtype=float)
    return {"mean": float(np.mean(a)), "std": float(np.std(a, ddof=1)) if len(a) > 1 else 0.0}


def _cross_validate(obs: Observations, method: str, splits: int) -> tuple[dict[str, Any], tuple]:
    """k-fold over views: calibrate on the rest, validate the held views."""
    names = [v.name for v in obs.views]
    cal_rmse, val_rmse, rows = [], [], []
    all_res, all_obj, all_view = [], [], []
    for k, held in enumerate(folds(len(names), splits)):
        val_names = [names[i] for i in held]
        train = obs.select([n for n in names if n not in val_names])
        cal = calibrate(train, method)
        r, data, _ = validation_residuals(cal, obs.select(val_names))
        cal_rmse.append(_fit_metrics(cal).rmse)
        val_rmse.append(metrics.rmse(r))
        rows.append({"validated": val_names, "calibration_rmse": cal_rmse[-1], "validation_rmse": val_rmse[-1],
                     "increase": val_rmse[-1] - cal_rmse[-1]})
        all_res.append(r)
        all_obj.append(data.object_points)
        all_view.append(data.view_index + 1000 * k)  # distinct ids per split
    out = {
        "splits": rows,
        "calibration_rmse": _mean_std(cal_rmse),
        "validation_rmse": _mean_std(val_rmse),
        "increase": _mean_std([v - c for v, c in zip(val_rmse, cal_rmse, strict=True)]),
    }
    return out, (np.concatenate(all_res), np.concatenate(all_obj), np.concatenate(all_view))


def compare(observations: Observations, methods: list[str] | None = None, splits: int = 5,
            holdout: Observations | None = None, progress: Progress | None = None) -> Comparison:
    """Run ``methods`` (default: every baseline and bspline) on the same corners.
    ``splits``: folds over the views (≥ 2), or 0 to skip cross-validation
    (the verdict then uses the hold-out set, or the training rmse)."""
    methods = list(methods) if methods else [m for m in DEFAULT_METHODS if m in METHODS]
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise SettingsError(f"unknown method(s) {unknown}; available: {sorted(METHODS)}")
    n_views = len(observations.views)
    if splits == 1 or splits < 0:
        raise SettingsError("splits: expected 0 (no cross-validation) or at least 2")
    if splits:
        if splits > n_views:
            raise SettingsError(f"splits: {splits} folds need at least {splits} views; there are {n_views}")
        if n_views - int(np.ceil(n_views / splits)) < MIN_VIEWS:
            raise DataError(f"cross-validation with {splits} splits leaves fewer than {MIN_VIEWS} views to calibrate "
                            f"on ({n_views} views): use fewer splits (--splits), or 0 to skip it")
    if holdout is not None and tuple(holdout.image_size) != tuple(observations.image_size):
        raise DataError("the hold-out views come from a camera with another image_size")
    check_views(observations)  # a degenerate set fails as a whole, before any method runs
    progress = progress or no_progress
    out = Comparison({}, n_views, observations.n_points, splits, _quality(quality.raw_quality, observations))
    cv_residuals: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    edge = _lit_edge(observations)
    for i, name in enumerate(methods):
        part = named(scaled(progress, i / len(methods), (i + 1) / len(methods)), name)
        try:
            out.methods[name] = _scores(observations, name, splits, holdout, part, cv_residuals, edge)
        except CalibError as exc:  # a method that cannot handle these corners says why
            out.methods[name] = MethodFailure(str(exc))
    out.verdict, out.verdict_detail = _verdict(out.scored, cv_residuals)
    progress("done", 1.0)
    return out


def _scores(observations: Observations, name: str, splits: int, holdout: Observations | None, part: Progress,
            cv_residuals: dict, edge: LitEdge | None) -> MethodScores:
    """``edge``: the pixels its model must map rays to (``unproject.lit_edge``; None: not known)."""
    cal = calibrate(observations, name, scaled(part, 0.0, 0.5 if splits else 0.9))
    scores = MethodScores(
        fit=_fit_metrics(cal),
        views=[{"name": v.name, "rmse": v.rmse, "rmse_axis": v.rmse_axis, "n_points": v.n_points} for v in cal.views],
        n_params=fitted_parameter_count(cal.model),  # what the fit moved, not what the model could
        quality=_quality(quality.geometric_quality, cal, observations),  # paper Table 7
        folds=(0.0, 0.0) if edge is None else edge.folds(cal.model))
    if holdout is not None:
        r, data, _ = validation_residuals(cal, holdout)
        s = metrics.summary(r, data.image_points, holdout.image_size)
        scores.holdout = {"holdout_rmse": s["rmse"], "holdout_rmse_axis": s["rmse_axis"],
                          "holdout_rmse_center": s["rmse_center"], "holdout_rmse_edge": s["rmse_edge"]}
    if splits:
        part(f"cross-validation over {splits} splits", 0.5)
        scores.cv, cv_residuals[name] = _cross_validate(observations, name, splits)
    return scores


def _lit_edge(observations: Observations) -> LitEdge | None:
    """The pixels every method's model must map rays to, as ``method="auto"`` asks (``lit_edge``)."""
    obs, _ = usable_views(observations)
    data, _, _ = to_data(obs)
    try:
        first = initialise(data, obs.image_size).model
    except (CalibError, np.linalg.LinAlgError, FloatingPointError):  # no first camera: the methods will say why
        return None
    return lit_edge(observations.image_size, observations.image_circle, bool(past_pinhole(first, data).any()), first)


def _fit_metrics(cal: Calibration) -> FitMetrics:
    """The error figures of a calibration ``calibrate`` made: it measures every fit."""
    if cal.metrics is None:
        raise ValueError(f"the {cal.method} calibration records no fit")
    return cal.metrics


def _quality(fn: Callable[..., dict[str, Any]], *args) -> dict[str, Any]:
    """Table 7's metrics (``quality.py``), or why they cannot be measured on these boards."""
    try:
        return fn(*args)
    except CalibError as exc:
        return {"error": str(exc)}


def _verdict(ok: dict[str, MethodScores], cv_residuals: dict) -> tuple[str | None, dict[str, Any]]:
    """The method to trust. With cross-validation, ``method="auto"``'s rule
    (``choice.choose``): the simplest method (``SIMPLEST_FIRST``) within the
    noise of the lowest validation error that no simpler method predicts
    better; otherwise the lowest hold-out or training error."""
    if not ok:
        return None, {"reason": "every method failed on these corners"}
    order = sorted(ok, key=lambda n: SIMPLEST_FIRST.index(n) if n in SIMPLEST_FIRST else len(SIMPLEST_FIRST))
    detail: dict[str, Any]
    if all(n in cv_residuals for n in order):
        candidates = []
        counts = np.zeros(0, dtype=np.int64)  # points per view: the same for every candidate
        for n in order:
            r, _, view = cv_residuals[n]
            ids, index = np.unique(view, return_inverse=True)
            candidates.append(Candidate(n, n, np.bincount(index, np.sum(r * r, axis=1), minlength=len(ids)),
                                        unmapped=ok[n].folds[0], unmapped_inside=ok[n].folds[1]))
            counts = np.bincount(index, minlength=len(ids))
        choice = choose(candidates, counts, how="validation error per axis over the folds of the views")
        best = choice.name
        detail = {"by": "cv_validation_rmse", "value": ok[best].cv_validation_rmse, "model_choice": choice.to_json()}
    else:
        flat = {n: m.to_json() for n, m in ok.items()}
        key = next(k for k in ("holdout_rmse", "rmse") if all(k in r for r in flat.values()))
        best = min(order, key=lambda n: flat[n][key])
        detail = {"by": key, "value": flat[best][key]}
    if best in cv_residuals:
        r, obj, view = cv_residuals[best]
        s: dict[str, Any] = neighbour_correlation(r, obj, view)
        s["structured"] = bool(s["p_value"] < STRUCTURE_P_VALUE)
        s["test"] = ("correlation of validation residuals between neighbouring corners, against "
                     f"{N_PERMUTATIONS} within-view shufflings")
        detail["spatial_structure"] = s
    return best, detail
