"""``core="auto"``: which model the corners support (the B-spline method's default).

Five candidates, simplest first: OpenCV's 5-coefficient model alone,
Kannala–Brandt alone, the rational model alone, the paper's field, a field
over the rational core. Each is scored by how well it predicts views left out
of its fit (cross-validation over the views) and the simplest within the
noise of the lowest is kept; a core alone comes back as a hybrid whose field
is zero and held. A lens past the pinhole's reach gets a field over the
Kannala–Brandt core instead. One field fit, with its knots and smoothing
(chosen by GCV of the corners: cheap, and within one model GCV is a fair
judge), is ``bspline.fit_field``.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .. import camera
from ..bspline import BSplineField, clamped_knots
from ..crossval import simplest_within_noise, view_errors
from ..errors import DataError
from ..init import initialise
from ..models.hybrid import HybridModel
from ..solve import Data, SolveSettings, levenberg_marquardt, spread_views
from .bspline import (GCV_TOLERANCE, BSplineSettings, core_field_problem, fit_core, fit_field, ideal_samples,
                      sample_weights)
from .common import Fit, Progress, no_progress, scaled

# Above this many views, the choice is made on this many (spread over the set).
DECISION_VIEWS = 20
# Cross-validation of the candidates: splits of the views, the relative margin
# within which a simpler model is as good, the solver iterations of a refit
# (from the full fit: a few are needed; fewer than ~20 stopped the rational
# model short of where it diverges on a fisheye and hid its failure), and the
# GCV ratio to the lowest beyond which a candidate is not worth validating.
CV_SPLITS = 5
CV_TOLERANCE = 0.02
CV_MAX_ITERATIONS = 50
CV_SCREEN = 4.0


def fit_bspline(data: Data, image_size, s: BSplineSettings, progress: Progress) -> Fit:
    """The paper's model, or a field over a core; ``core="auto"`` chooses
    between them and the parametric cores alone (``choose_model``)."""
    if s.core != "auto":
        return fit_field(data, image_size, s, s.core, progress)[0]
    init = initialise(data, image_size)
    _, seen = ideal_samples(init.model, init.poses, data, "pinhole")
    if not seen.all():
        return choose_model(data, image_size, s, progress, WIDE_CANDIDATES,
                            f"{int((~seen).sum())} corners lie past the pinhole's reach")
    return choose_model(data, image_size, s, progress, CANDIDATES)


# core="auto": the candidates, simplest first, as (core, field fitted?, label).
CANDIDATES = (("zhang", False, "OpenCV 5-coefficient model alone"),
              ("fisheye", False, "Kannala-Brandt model alone"),
              ("rational", False, "rational model alone"),
              ("none", True, "field without a core (the paper's model)"),
              ("rational", True, "field over the rational core"))
# A lens beyond ~170°, corners past the pinhole's reach: only Kannala-Brandt
# represents every corner.
WIDE_CANDIDATES = (("fisheye", False, "Kannala-Brandt model alone"),
                   ("fisheye", True, "field over the Kannala-Brandt core"))


def choose_model(data: Data, image_size, s: BSplineSettings, progress: Progress, candidates=CANDIDATES,
                 why: str = "") -> Fit:
    """Fit every candidate, score each by how well it predicts views left out
    of its fit (``_cross_validate``) and keep the simplest within the noise of
    the lowest. A field is worth its freedom only where it predicts new views
    better: over a core that already fits the lens (OpenCV's own model) it can
    only add noise, and the core alone is returned, as a hybrid whose field
    is zero and held. ``why`` these candidates, if not the usual ones.

    Whether a core or a field pays is a property of the lens, not of the
    number of views: on a large set it is decided on DECISION_VIEWS of them,
    and only the chosen model is fitted to all."""
    sample = data if data.n_views <= DECISION_VIEWS else spread_views(data, DECISION_VIEWS)
    share = 1.0 if sample is data else 0.5
    # A model that cannot fit these corners (a core too narrow for the lens, a
    # field with more unknowns than the corners give equations) is out of the
    # running; only if none can is it an error.
    why_not: list[str] = []
    names = list(dict.fromkeys(core for core, _, _ in candidates if core != "none"))
    cores = {core: _try(why_not, fit_core, sample, image_size, core,
                        scaled(progress, 0.1 * i / len(names) * share, 0.1 * (i + 1) / len(names) * share))
             for i, core in enumerate(names)}
    fits, n_fields, done = [], sum(with_field for _, with_field, _ in candidates), 0
    for core, with_field, _ in candidates:
        if not with_field:
            fits.append(None if cores[core] is None else _core_alone(cores[core], sample, image_size, s, core))
            continue
        part = scaled(progress, (0.1 + 0.7 * done / n_fields) * share, (0.1 + 0.7 * (done + 1) / n_fields) * share)
        done += 1
        without_core = core != "none" and cores[core] is None
        fits.append(None if without_core else _try(why_not, fit_field, sample, image_size, s, core, part, cores.get(core)))
    if all(fit is None for fit in fits):
        raise DataError("no model fits these corners: " + "; ".join(dict.fromkeys(why_not)))
    progress("model choice", 0.8 * share)
    gcv = [np.inf if fit is None else fit[1] for fit in fits]
    # What is cross-validated: a core alone as its own method fitted it.
    fitted = [None if fit is None else (fit[0] if with_field else cores[core])
              for fit, (core, with_field, _) in zip(fits, candidates)]
    cv, k = _cross_validate(sample, fitted, gcv, [cores.get(core) for core, _, _ in candidates])
    core, with_field, label = candidates[k]
    chosen = fits[k][0]
    if sample is not data:
        if with_field:
            chosen = fit_field(data, image_size, s, core, scaled(progress, share, 1.0))[0]
        else:
            chosen = _core_alone(fit_core(data, image_size, core, scaled(progress, share, 1.0)), data, image_size, s, core)[0]
    by_cv = any(np.isfinite(cv))

    def scores(values) -> str:
        return ", ".join((f"{v:.4f} px²" if np.isfinite(v) else "-") + f" for the {what}"
                         for (_, _, what), v in zip(candidates, values))

    chosen.diagnostics["core_choice"] = (
        f"{label}: " + (f"{why}; " if why else "")
        + (f"validation error over {min(CV_SPLITS, sample.n_views)} splits of the views {scores(cv)}; "
           f"the simplest within {100 * CV_TOLERANCE:.0f} % or one standard error of the lowest is kept"
           if by_cv else
           f"GCV of the corners {scores(gcv)} (no candidate could be cross-validated over the views); "
           f"the simplest within {100 * GCV_TOLERANCE:.0f} % of the lowest is kept")
        + ("" if sample is data else f" (decided on {sample.n_views} of the {data.n_views} views)"))
    chosen.diagnostics["core_candidates"] = [
        {"model": what, "cv": c if np.isfinite(c) else None, "gcv": g if np.isfinite(g) else None, "chosen": i == k}
        for i, ((_, _, what), c, g) in enumerate(zip(candidates, cv, gcv))]
    return chosen


def _cross_validate(sample: Data, fitted: list[Fit | None], gcv: list[float], cores: list[Fit | None]):
    """(validation error per candidate (px² per corner, inf when not
    validated), index chosen). Each candidate is refit without each of
    CV_SPLITS interleaved groups of views and predicts them (``crossval``),
    on the corners every candidate could use; the simplest within the noise
    of the lowest is chosen (``crossval.simplest_within_noise``). ``cores``:
    each candidate's core fitted alone (None for the paper's field).

    GCV of the corners cannot see what matters here: it scores prediction at
    the views already fitted, and a field there also fits what the views do
    not share (a warped board, a detector's bias; GoPro's wide lens: GCV
    preferred the paper's field, which predicted new views 1.7x worse than
    Kannala-Brandt alone), and a core's extrapolation beyond those corners
    (a rational fit of a fisheye's corners up to 88° off axis: the GCV of
    Kannala-Brandt, 2.5x its validation error). Candidates whose GCV is
    beyond CV_SCREEN times the lowest are not validated; if none can be, GCV
    decides."""
    kept = np.logical_and.reduce([~f.excluded for f in fitted if f is not None])
    counts = np.bincount(sample.view_index[kept], minlength=sample.n_views)
    splits = min(CV_SPLITS, sample.n_views)
    errors = [view_errors(_fold_refit(f, core), f.result.poses, sample, ~f.excluded, kept, splits)
              if f is not None and g <= CV_SCREEN * min(gcv) else None for f, g, core in zip(fitted, gcv, cores)]
    cv = [np.inf if e is None else float(e.sum() / counts.sum()) for e in errors]
    if any(np.isfinite(cv)):
        return cv, simplest_within_noise(errors, counts, CV_TOLERANCE)
    return cv, next(i for i, g in enumerate(gcv) if g <= min(gcv) * (1 + GCV_TOLERANCE))


def _fold_refit(fit: Fit, core: Fit | None):
    """How a fit is refit to one split's views: by the solver that fitted it,
    from the full fit's camera and poses. A field over a core refits the core
    alone first (``core``, as fitted alone), as the method does: its joint
    fit holds the core's coefficients, and held as fitted to every view they
    would flatter it."""
    def settings(f: Fit) -> SolveSettings:
        return dataclasses.replace(f.solve_settings or SolveSettings(), max_iterations=CV_MAX_ITERATIONS)

    model = fit.result.model

    def refit(train: Data, poses: np.ndarray):
        if isinstance(model, HybridModel):
            alone = levenberg_marquardt(core.result.model, poses, train, settings(core))
            start = HybridModel(alone.model, model.field, model.lambda_reg, model.lambda_smooth, model.gauge_point)
            return levenberg_marquardt(start, alone.poses, train, settings(fit)).model
        return levenberg_marquardt(model, poses, train, settings(fit)).model
    return refit


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
