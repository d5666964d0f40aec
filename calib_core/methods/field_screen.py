"""Whether a field pays over a parametric core: checked before any field is fitted.

On a lens a parametric model represents, the fields were most of the default's
cost (docs/model-choice.md, "Speed"). The screen fits a field to what the core
leaves, at the cost of a λ curve or two, and scores it on the views left out of
it against no field. Two questions, the second asked only where the first says no:

- **the core's poses held** (10 × 10 grid): the field's first stage as the
  field-over-core candidate fits it;
- **each view's pose refit** (``posed_cv``, 6 × 6 grid): where the core's fit has
  tilted each view's pose to absorb part of a non-radial error, a different part
  in each view, the held question finds no field; this one does. Its grid is
  coarse: what poses hide is smooth over the image (a pose absorbs a view's
  projective warp), and a 6 × 6 grid costs a tenth of a 10 × 10 one here (the
  two components are solved together).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fitting import knots
from ..fitting.posed_cv import posed_cv_curve
from ..fitting.smoothing import LAMBDA_GRID, groups_of
from ..fitting.solve import Data, SolveSettings, residuals_and_jacobian
from ..models.bspline import GAUGE_WEIGHT, gauge_rows
from ..models.bspline_basis import BSplineField, clamped_knots
from .bspline import BSplineSettings, core_field_problem, field_cv, sample_weights
from .common import Fit, no_progress

SCREEN_INTERVALS = (10, 10)
POSED_SCREEN_INTERVALS = (6, 6)
# The share of no field's left-out error the posed field must take away: on lenses with
# no field to find it stayed within -0.65 % to +0.18 % (60 sets), on elliptic lenses it
# reached 6-61 % (11 of 13 sets; docs/model-choice.md, "Poses that hide a field").
POSED_MIN_SHARE = 0.01


@dataclass
class FieldScreen:
    """``gain``: the mean squared left-out residual per corner (px², both axes)
    that the field over the core takes away, the core's poses held, and one
    standard error of it over the views (paired, as ``choice.choose`` pairs
    candidates). ``posed_*``: the same with each view's pose refit, and its
    share of no field's error (None: not asked, the held question said yes)."""

    core: str
    gain: float
    standard_error: float
    posed_gain: float | None = None
    posed_standard_error: float | None = None
    posed_share: float | None = None

    @property
    def pays(self) -> bool:
        # Held: any gain, not one beyond the noise. Held at the core's camera, which
        # the joint fit frees, the field shows only part of what it wins; on residuals
        # that are noise alone the smoothing's own cost keeps the gain below zero.
        return self.gain > 0 or (self.posed_share is not None and self.posed_share > POSED_MIN_SHARE)

    def words(self) -> str:
        """The scores, for the choice's ``how``."""
        held = f"{self.gain:.2g} ± {self.standard_error:.2g} px² per corner with the core's poses held"
        if self.posed_gain is None:
            return held
        return (f"{held}; {self.posed_gain:.2g} ± {self.posed_standard_error:.2g} px² with each view's pose refit, "
                f"{100 * (self.posed_share or 0.0):.2g} % of no field's error (at least {100 * POSED_MIN_SHARE:g} % pays)")


def field_screen(data: Data, image_size, core: str, core_fit: Fit) -> FieldScreen:
    """The field over ``core_fit`` scored on the views left out of it, against no
    field: its poses held, then (only if that finds no gain) each view's pose refit."""
    s = BSplineSettings(core=core)
    problem, start, poses, ok, _ = core_field_problem(data, image_size, s, core, no_progress, core_fit)
    sub = data.points(ok)
    samples, response, views = problem.samples(start, poses, sub)
    weights = sample_weights(samples, response, s)

    def field_on(intervals) -> BSplineField:
        breaks = knots.breaks_for(samples, weights, problem.domain, s.knot_settings(intervals), problem.footprint)
        return BSplineField.zeros(clamped_knots(breaks[0]), clamped_knots(breaks[1]))

    cv = field_cv(problem, field_on(SCREEN_INTERVALS), samples, response, weights, views, s.lambda_reg, LAMBDA_GRID,
                   refine=True)
    groups = groups_of(views)
    none = np.bincount(groups, weights=np.sum(response**2, axis=1))  # a core's field's prior is zero
    screen = FieldScreen(core, *_gain(none, cv.group_sse[:, cv.best], cv.counts))
    if screen.pays:
        return screen
    field = field_on(POSED_SCREEN_INTERVALS)
    _, jacobian = residuals_and_jacobian(start, poses, sub, SolveSettings(fix_model=True))
    posed, posed_none = posed_cv_curve(
        field.design(samples).matrix(field.n_controls), weights / weights.mean(axis=0), field.bending(),
        gauge_rows(field, problem.gauge_point) * GAUGE_WEIGHT, response, jacobian[: 2 * sub.n_points],
        sub.view_index, s.lambda_reg, groups, LAMBDA_GRID)
    field_sse = posed.group_sse[:, posed.best]
    screen.posed_gain, screen.posed_standard_error = _gain(posed_none, field_sse, posed.counts)
    screen.posed_share = 1.0 - float(field_sse.sum()) / max(float(posed_none.sum()), 1e-300)
    return screen


def _gain(none: np.ndarray, field: np.ndarray, counts: np.ndarray) -> tuple[float, float]:
    """(mean gain per corner, one standard error) of a field's left-out SSE per group against no field's."""
    n = len(none)
    gain = (none - field) * n / counts.sum()  # its mean is the gain per corner
    return float(gain.mean()), float(np.std(gain, ddof=1) / np.sqrt(n)) if n > 1 else np.inf
