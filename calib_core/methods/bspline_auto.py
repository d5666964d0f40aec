"""``core="auto"``: which model the corners support (the B-spline method's default).

Four candidates, simplest first: OpenCV's 5-coefficient model alone, the
rational model alone, the paper's field, a field over the rational core. Each
is scored by GCV of the corners and the simplest within GCV_TOLERANCE of the
lowest is kept; a core alone comes back as a hybrid whose field is zero and
held. A lens past the pinhole's reach gets the Kannala–Brandt core instead.
One field fit, with its knots and smoothing, is ``bspline.fit_field``.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .. import camera
from ..bspline import BSplineField, clamped_knots
from ..errors import DataError
from ..init import initialise
from ..models.hybrid import HybridModel
from ..solve import Data, spread_views
from .bspline import (GCV_TOLERANCE, BSplineSettings, core_field_problem, fit_core, fit_field, ideal_samples,
                      sample_weights)
from .common import Fit, Progress, no_progress, scaled

# Above this many views, the choice is made on this many (spread over the set).
DECISION_VIEWS = 20


def fit_bspline(data: Data, image_size, s: BSplineSettings, progress: Progress) -> Fit:
    """The paper's model, or a field over a core; ``core="auto"`` chooses
    between them and the parametric cores alone (``choose_model``)."""
    if s.core != "auto":
        return fit_field(data, image_size, s, s.core, progress)[0]
    init = initialise(data, image_size)
    _, seen = ideal_samples(init.model, init.poses, data, "pinhole")
    if not seen.all():
        # Corners past the pinhole's reach: a lens beyond ~170°, where only the
        # Kannala–Brandt core represents every corner.
        chosen = fit_field(data, image_size, s, "fisheye", progress)[0]
        chosen.diagnostics["core_choice"] = f"{int((~seen).sum())} corners lie past the pinhole's reach: Kannala-Brandt core"
        return chosen
    return choose_model(data, image_size, s, progress)


# core="auto": the candidates, simplest first, as (core, field fitted?, label).
CANDIDATES = (("zhang", False, "OpenCV 5-coefficient model alone"),
              ("rational", False, "rational model alone"),
              ("none", True, "field without a core (the paper's model)"),
              ("rational", True, "field over the rational core"))


def choose_model(data: Data, image_size, s: BSplineSettings, progress: Progress) -> Fit:
    """Fit every candidate, score each by GCV of its corners (a core alone
    has no field: its score is the weighted mean squared residual) and keep
    the simplest within GCV_TOLERANCE of the lowest. A field is worth its
    freedom only where it predicts the corners better: over a core that
    already fits the lens (OpenCV's own model) it can only add noise, and the
    core alone is returned, as a hybrid whose field is zero and held.

    Whether a core or a field pays is a property of the lens, not of the
    number of views: on a large set it is decided on DECISION_VIEWS of them,
    and only the chosen model is fitted to all."""
    sample = data if data.n_views <= DECISION_VIEWS else spread_views(data, DECISION_VIEWS)
    share = 1.0 if sample is data else 0.5
    # A model that cannot fit these corners (a core too narrow for the lens, a
    # field with more unknowns than the corners give equations) is out of the
    # running; only if none can is it an error.
    errors: list[str] = []
    cores = {core: _try(errors, fit_core, sample, image_size, core, scaled(progress, lo * share, (lo + 0.05) * share))
             for core, lo in (("zhang", 0.0), ("rational", 0.05))}
    rational = cores["rational"]
    fits = [None if cores["zhang"] is None else _core_alone(cores["zhang"], sample, image_size, s, "zhang"),
            None if rational is None else _core_alone(rational, sample, image_size, s, "rational"),
            _try(errors, fit_field, sample, image_size, s, "none", scaled(progress, 0.1 * share, 0.55 * share)),
            None if rational is None else _try(errors, fit_field, sample, image_size, s, "rational",
                                               scaled(progress, 0.55 * share, share), rational)]
    if all(fit is None for fit in fits):
        raise DataError("no model fits these corners: " + "; ".join(dict.fromkeys(errors)))
    scores = [np.inf if fit is None else fit[1] for fit in fits]
    k = next(i for i, score in enumerate(scores) if score <= min(scores) * (1 + GCV_TOLERANCE))
    core, with_field, label = CANDIDATES[k]
    chosen = fits[k][0]
    if sample is not data:
        if with_field:
            chosen = fit_field(data, image_size, s, core, scaled(progress, share, 1.0))[0]
        else:
            chosen = _core_alone(fit_core(data, image_size, core, scaled(progress, share, 1.0)), data, image_size, s, core)[0]
    chosen.diagnostics["core_choice"] = (
        f"{label}: GCV of the corners "
        + ", ".join((f"{score:.4f} px²" if np.isfinite(score) else "no fit") + f" for the {what}"
                    for (_, _, what), score in zip(CANDIDATES, scores))
        + f"; the simplest within {100 * GCV_TOLERANCE:.0f} % of the lowest is kept"
        + ("" if sample is data else f" (decided on {sample.n_views} of the {data.n_views} views)"))
    chosen.diagnostics["core_candidates"] = [{"model": what, "gcv": score if np.isfinite(score) else None, "chosen": i == k}
                                             for i, ((_, _, what), score) in enumerate(zip(CANDIDATES, scores))]
    return chosen


def _try(errors: list[str], fit_fn, *args):
    """``fit_fn(*args)``, or None (and why, appended to ``errors``) if the
    model cannot fit these corners."""
    try:
        return fit_fn(*args)
    except (DataError, FloatingPointError, np.linalg.LinAlgError) as exc:  # too few corners, diverged, no finite start
        errors.append(str(exc))
        return None


def core_alone_score(fit: Fit, data: Data, s: BSplineSettings) -> float:
    """A parametric fit's GCV score as a field fit's is computed, with no
    field: the weighted mean squared residual, summed over both axes (px²)."""
    used = ~fit.excluded
    pc = camera.transform(fit.result.poses, data.view_index[used], data.object_points[used])
    samples = fit.result.model.project(pc)
    response = data.image_points[used] - samples
    w = sample_weights(samples, response, s)
    return float(np.sum(np.mean(w / w.mean(axis=0) * response**2, axis=0)))


def _core_alone(fit: Fit, data: Data, image_size, s: BSplineSettings, core: str) -> tuple[Fit, float]:
    """A parametric fit as the B-spline method's result: a hybrid whose field
    is zero and held (one interval over the image), the core as fitted; and
    its score."""
    model = fit.result.model
    u0, u1, v0, v1 = core_field_problem(data, image_size, s, core, no_progress, fit)[0].domain  # a field over it would span this
    field = BSplineField.zeros(clamped_knots([u0, u1]), clamped_knots([v0, v1]))
    gauge_point = (float(model.intrinsics[2]), float(model.intrinsics[3]))
    hybrid = HybridModel(model, field, 0.0, 0.0, gauge_point, field_held=True)  # no field fitted, nothing to smooth
    settings = dataclasses.asdict(s)
    settings.update(hybrid.settings_json())
    settings.update(core_used=core, intervals_used=[1, 1])
    score = core_alone_score(fit, data, s)
    return Fit(dataclasses.replace(fit.result, model=hybrid, jac=None), fit.excluded, fit.excluded_reason, settings,
               {**fit.diagnostics, "gcv": score, "smoothing_curve": []}), score
