"""``method="auto"``, the default: the model the corners support, chosen by
how well each candidate predicts views left out of its fit.

Candidates, simplest first: OpenCV's 5-coefficient model, Kannala–Brandt,
the rational model, the paper's B-spline field, and a field over the
rational core (over the 5-coefficient one where the rational model's
distortion turns back inside the image: ``_over_a_core_that_maps``). A lens past the pinhole's reach (corners beyond ~89° off
axis) gets Kannala–Brandt and a field over it instead, the only models that
represent every corner. From SCREEN_MIN_VIEWS views on, the fields are fitted
only where a field over the most flexible core predicts views left out of it
better than no field (``field_screen.py``); on fewer views every field is
fitted. Every candidate fitted is scored on each view
left out of its fit (in closed form, the parametric models the choice
turns on refitted without it: ``_validate``; for a field over a core, the
view leaves the core's own fit too) and the simplest within the
noise of the lowest is kept (``choice.choose``); it is returned as its own
method returns it, so the calibration is written with that model's type
(``opencv``, ``fisheye``, ``bspline``, ``hybrid``) and ``settings.chosen``
names it.

Whether a core or a field pays is a property of the lens, not of the number
of views: on a large set it is decided on ``decision_views`` of them, and only
the chosen model is fitted to all.
"""
from __future__ import annotations

import dataclasses
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from .. import ranges
from ..errors import DataError, SettingsError
from ..fit_report import ChoiceReport
from ..fitting.choice import Candidate, ModelChoice, choose
from ..fitting.crossval import ViewErrors, held_steps, linearised_view_errors, refitted_view_errors
from ..fitting.init import initialise, poses_from_rays
from ..fitting.solve import Data, SolveSettings, levenberg_marquardt, spread_views
from ..models.base import CameraModel, fitted_parameter_count
from ..models.camera import PINHOLE_MAX_ANGLE_DEG
from ..models.unproject import LitEdge, lit_edge
from ..observations import Circle
from .bspline import BSplineSettings, field_design, fit_core, fit_field
from .common import Fit, Progress, named, no_progress, scaled
from .field_screen import FieldScreen, field_screen
from .opencv import pinhole_visible


@dataclass
class AutoSettings:
    decision_views: int = 20  # above this many views, the choice is made on this many (spread over the set)
    # The lens's lit disc (cx, cy, radius) px where its image circle ends inside the frame; None: the whole
    # frame is lit (``calibrate`` takes the observations' ``image_circle``, which detection writes).
    image_circle: Circle | None = None

    def validate(self) -> None:
        ranges.whole("decision_views", self.decision_views, 3, 1000)
        if self.image_circle is not None:
            if not isinstance(self.image_circle, (list, tuple)) or len(self.image_circle) != 3:
                raise SettingsError(f"image_circle: expected [cx, cy, radius] in pixels, got "
                                    f"{ranges.shown(self.image_circle)}")
            cx, cy, r = self.image_circle
            self.image_circle = (ranges.number("image_circle cx", cx, -1e6, 1e6),
                                 ranges.number("image_circle cy", cy, -1e6, 1e6),
                                 ranges.number("image_circle radius", r, 0, 1e6, above_low=True))


@dataclass(frozen=True)
class Spec:
    """A candidate: ``core`` fitted alone (None: no parametric core), and a
    field over it (``field``: the core's name, "none" for the paper's field
    on ideal pixels; None: the core alone)."""

    name: str
    label: str
    core: str | None
    field: str | None


# The field screen holds the core's camera, which few views pin down least, and judges on as
# few views left out: below this many it turned fields away that predicted the views held out
# up to 60x better (docs/model-choice.md, "The field screen on few views"), so every field is
# fitted, which on such small sets costs a second or two.
SCREEN_MIN_VIEWS = 8

CANDIDATES = (Spec("zhang", "OpenCV 5-coefficient model", "zhang", None),
              Spec("fisheye", "Kannala-Brandt model", "fisheye", None),
              Spec("rational", "OpenCV rational model", "rational", None),
              Spec("bspline", "B-spline field (the paper's model)", None, "none"),
              Spec("hybrid-rational", "B-spline field over the rational model", "rational", "rational"))
WIDE_CANDIDATES = (Spec("fisheye", "Kannala-Brandt model", "fisheye", None),
                   Spec("hybrid-fisheye", "B-spline field over the Kannala-Brandt model", "fisheye", "fisheye"))


def fit_auto(data: Data, image_size, s: AutoSettings, progress: Progress) -> Fit:
    sample = data if data.n_views <= s.decision_views else spread_views(data, s.decision_views)
    init = initialise(sample, image_size)  # cached, before the candidates share it from two threads
    past = past_pinhole(init.model, data)
    wide = bool(past.any())
    specs = WIDE_CANDIDATES if wide else CANDIDATES
    share = 1.0 if sample is data else 0.8
    edge = lit_edge(image_size, s.image_circle, wide, init.model)
    specs, fits, why_not, screen, folds = _fit_candidates(specs, sample, image_size, edge,
                                                          scaled(progress, 0.0, 0.8 * share))
    if all(f is None for f in fits):
        raise DataError("no model fits these corners: " + "; ".join(dict.fromkeys(e for e in why_not if e)))
    progress("model choice", 0.8 * share)
    choice = _validate(specs, fits, why_not, sample, edge, folds)
    if screen is not None:
        choice.how += (f"; fields were fitted only if one over the {_core_label(specs, screen.core)} predicted the "
                       f"views left out of it better than no field (it did{'' if screen.pays else ' not'}: "
                       f"{screen.words()})")
    elif sample.n_views < SCREEN_MIN_VIEWS and any(sp.field is not None for sp in specs):
        choice.how += (f"; with {sample.n_views} views (fewer than {SCREEN_MIN_VIEWS}) every field was fitted, "
                       "as too few views are left out to tell beforehand whether one pays")
    if wide:
        choice.how += f"; {int(past.sum())} corners lie past the pinhole's reach, so only models that reach them ran"
    if sample is not data:
        choice.how += f"; decided on {sample.n_views} of the {data.n_views} views"
    spec = specs[choice.chosen]
    fit = fits[choice.chosen]
    if sample is not data:
        core_fit = next((f for sp, f in zip(specs, fits, strict=True) if sp.field is None and sp.core == spec.core), None)
        fit = _on_all_views(spec, fit, core_fit, data, image_size,
                            named(scaled(progress, share, 1.0), f"{spec.label}, on all {data.n_views} views"))
    settings = {**fit.settings, "chosen": spec.name, "decision_views": s.decision_views}
    return dataclasses.replace(fit, settings=settings, model_choice=ChoiceReport.from_json(choice.to_json()))


def past_pinhole(model: CameraModel, data: Data) -> np.ndarray:
    """(N,) bool: the corners an initial camera ``model`` puts past the pinhole's reach."""
    with np.errstate(invalid="ignore"):  # a pixel with no ray under the initial camera is not known to be past
        return model.rays(data.image_points)[:, 2] < np.cos(np.radians(PINHOLE_MAX_ANGLE_DEG))


def _on_all_views(spec: Spec, fit: Fit, core_fit: Fit | None, data: Data, image_size, progress: Progress) -> Fit:
    """The model chosen on the sample (``fit``; ``core_fit``: its core's fit
    to the sample), fitted to every view. A parametric model or the paper's
    field starts where the sample left it (``_refined``). A field over a core
    is fitted again on its grid and smoothing over its core refined so: its
    knots then follow the core's residuals on every view (kept from the
    sample, they predicted views it had not seen worse: docs/model-choice.md,
    "Speed, and how it scales")."""
    if spec.core is None or spec.field is None or core_fit is None:
        return _refined(fit, data, progress)
    core = _refined(core_fit, data, scaled(progress, 0.0, 0.3))
    grid = {"intervals": tuple(fit.settings["intervals_used"]), "lambda_smooth": float(fit.settings["lambda_smooth"])}
    return _fit_spec(spec, data, image_size, {spec.core: core}, scaled(progress, 0.3, 1.0), **grid)


def _refined(fit: Fit, data: Data, progress: Progress) -> Fit:
    """``fit``'s model (its camera, knots and smoothing) fitted to every view
    of ``data``, each view posed on the model's rays first."""
    model = fit.result.model
    poses = poses_from_rays(model, data)
    if poses is None:
        raise DataError("could not pose every view under the chosen model; remove views with very few corners")
    ok = pinhole_visible(poses, data) if model.base == "pinhole" else np.ones(data.n_points, dtype=bool)
    sub = data.points(ok)
    progress("joint optimisation", 0.0)
    res = levenberg_marquardt(model, poses, sub, _solve_settings(fit),
                              lambda it, _: progress("joint optimisation", it / (it + 3)))
    diagnostics = dict(fit.diagnostics)
    if model.bspline_field is not None:
        diagnostics["design"] = field_design(res.model, res.poses, sub, BSplineSettings())
    return dataclasses.replace(fit, result=res, excluded=~ok, diagnostics=diagnostics)


def _solve_settings(fit: Fit) -> SolveSettings:
    """How ``fit``'s own method converges a fit of its model."""
    return fit.solve_settings or SolveSettings(fit.settings["max_iterations"], fit.settings["ftol"])


def _fit_spec(spec: Spec, data: Data, image_size, cores: dict[str, Fit | None], progress: Progress,
              **field_settings) -> Fit:
    """One candidate fitted to ``data`` (``cores``: its core fitted alone, if
    done; ``field_settings``: the field's, default its own search)."""
    core_fit = None if spec.core is None else cores.get(spec.core)
    if spec.field is not None:
        s = BSplineSettings(core=spec.field, **field_settings)
        s.validate()
        return fit_field(data, image_size, s, spec.field, progress, core_fit)
    if spec.core is None:
        raise ValueError(f"candidate {spec.name!r} has neither a core nor a field")
    return core_fit or fit_core(data, image_size, spec.core, progress)


def _fit_candidates(specs, sample: Data, image_size, edge: LitEdge | None, progress: Progress):
    """The candidates (``_over_a_core_that_maps``), each one's fit (None if it
    cannot fit these corners, or if no field pays), why not, the field screen
    (None when not run), and the folds measured so far (by model, ``LitEdge.folds``).
    The parametric models fit first. From SCREEN_MIN_VIEWS views on, a field
    is fitted only where one over the most flexible core predicts the views
    left out of it better than no field (``field_screen``): on a lens its
    parametric models represent, the fields cost most of the choice and win
    nothing. Of the fields, the one
    with no parametric core (the paper's) depends on no other: it runs on
    the second core meanwhile (the heavy parts, the compiled kernels and
    LAPACK, release the GIL), reporting no progress of its own."""
    why_not = [""] * len(specs)
    cores: dict[str, Fit | None] = {}
    fits: list[Fit | None] = [None] * len(specs)

    def part(i: int) -> Progress:
        return named(scaled(progress, i / len(specs), (i + 1) / len(specs)), specs[i].label)

    for i, spec in enumerate(specs):
        if spec.field is None:
            cores[spec.core] = fits[i] = _try(why_not, i, fit_core, sample, image_size, spec.core, part(i),
                                              cores.get("zhang"))
    specs, folds = _over_a_core_that_maps(specs, cores, edge)
    fields = [i for i, spec in enumerate(specs) if spec.field is not None]
    progress("whether a field pays", min(fields, default=len(specs)) / len(specs))
    screen = _screen(specs, cores, sample, image_size)
    if screen is not None and not screen.pays:
        for i in fields:
            why_not[i] = (f"not fitted: a field over the {_core_label(specs, screen.core)} predicts the views left "
                          f"out of it no better than no field ({screen.words()})")
        return specs, fits, why_not, screen, folds
    alone = [i for i in fields if specs[i].core is None]
    with ThreadPoolExecutor(max_workers=1) as pool:
        background = {i: pool.submit(_try, why_not, i, _fit_spec, specs[i], sample, image_size, {}, no_progress)
                      for i in alone}
        for i in fields:
            if i in background:
                continue
            if cores.get(specs[i].core) is None:
                why_not[i] = why_not[i] or f"its {specs[i].core} core cannot fit these corners"
                continue
            fits[i] = _try(why_not, i, _fit_spec, specs[i], sample, image_size, cores, part(i))
        for i, future in background.items():
            if not future.done():
                progress(f"{specs[i].label}: finishing (fitted alongside the others)", 1.0)
            fits[i] = future.result()
    return specs, fits, why_not, screen, folds


def _core_label(specs, core: str) -> str:
    """The words for a core among the candidates ("OpenCV rational model")."""
    return next(sp.label for sp in specs if sp.field is None and sp.core == core)


def _over_a_core_that_maps(specs, cores: dict[str, Fit | None], edge: LitEdge | None):
    """The candidates, the field over a core moved onto the most flexible core that maps
    the lit image where its own does not; and the folds measured (by model).

    A field over a core inherits the core's fold: where the rational model's distortion
    turns back inside the image (a polynomial past the reach of its corners), the field
    over it would be left out with it by the fold rule (``choice._leave_out_folding``)
    however well it predicts, and the lens's own shape away from the corners taken by no
    field at all (docs/model-choice.md, "Lenses drawn at random"). Its field then goes
    over the most flexible core, by parameters, that fits these corners and maps as far
    as the rule asks (the same tiers: a tenth of the way in, else the whole edge)."""
    folds: dict[int, tuple[float, float]] = {}  # id(model) → (share of the edge, of a tenth in) unmapped
    if edge is None:
        return specs, folds

    def folds_of(fit: Fit) -> tuple[float, float]:
        key = id(fit.result.model)
        if key not in folds:
            folds[key] = edge.folds(fit.result.model)
        return folds[key]

    out = list(specs)
    for i, spec in enumerate(specs):
        own = cores.get(spec.core) if spec.field is not None and spec.field == spec.core else None
        if own is None or folds_of(own) == (0.0, 0.0):
            continue
        others = [(sp, fit) for sp in specs if sp.field is None and sp.core != spec.core
                  and (fit := cores.get(sp.core)) is not None]
        others.sort(key=lambda pair: fitted_parameter_count(pair[1].result.model), reverse=True)
        tier = 1 if folds_of(own)[1] > 0 else 0  # 1: judged a tenth of the way in; 0: at the edge itself
        better = next((sp for sp, fit in others if folds_of(fit)[tier] == 0), None)
        if better is not None:
            out[i] = Spec(f"hybrid-{better.core}", f"B-spline field over the {better.label}", better.core, better.core)
    return tuple(out), folds


def _screen(specs, cores: dict[str, Fit | None], sample: Data, image_size) -> FieldScreen | None:
    """The field screen over the core of the last field-over-core candidate
    (the most flexible core), or None when that core did not fit or the views
    are fewer than SCREEN_MIN_VIEWS."""
    core = next((spec.core for spec in reversed(specs) if spec.field is not None and spec.core), None)
    core_fit = None if core is None else cores.get(core)
    if core is None or core_fit is None or sample.n_views < SCREEN_MIN_VIEWS:
        return None
    try:
        return field_screen(sample, image_size, core, core_fit)
    except (DataError, np.linalg.LinAlgError):  # too few corners for the grid: let the fields say so
        return None


def _validate(specs, fits: list[Fit | None], why_not: list[str], sample: Data,
              edge: LitEdge | None, folds_known: dict[int, tuple[float, float]]) -> ModelChoice:
    """Each candidate's error on each view left out of its fit, on the corners
    every candidate could use, and the one-standard-error choice among them;
    ``edge``: pixels along the edge of the lit image, which a candidate must map
    rays to (``choice.choose``; None: not known).

    Every candidate is first scored in closed form
    (``crossval.linearised_view_errors``). That flatters a parametric model
    that misfits the lens or trades parameters along a flat valley, never a
    field that fits it (docs/model-choice.md, "Views left out, refitted"), so
    the parametric models the choice turns on are then refitted without each
    view (``crossval.refitted_view_errors``), and the choice made again,
    until every one it turns on is: the chosen, the lowest, and a simpler one
    that passes over a candidate within the noise. A refit only raises a
    model's own error (measured: by up to 2x, or lowers it by at most 2 %), so
    a candidate left in closed form could not have changed the choice. The
    core of a field over one is refitted from the start: the field answers
    its core's moves, and its error can go either way."""
    kept = np.logical_and.reduce([~f.excluded for f in fits if f is not None])
    counts = np.bincount(sample.view_index[kept], minlength=sample.n_views)
    reasons = list(why_not)
    lovo: list[ViewErrors | None] = [None] * len(specs)
    folds = [(0.0, 0.0)] * len(specs)
    core_of = {spec.core: i for i, spec in enumerate(specs) if spec.field is None}
    # A field over a core is scored with its core's moves: refitting the core can lower the
    # field's error as well as raise it, so a fitted field's core is refitted from the start.
    refitted = {core_of[spec.core] for spec, fit in zip(specs, fits, strict=True)
                if fit is not None and spec.field is not None and spec.core in core_of and fits[core_of[spec.core]]}

    def score(i: int) -> None:
        """Candidate i's errors on the views left out of it (the core's first: specs list cores first)."""
        spec, fit = specs[i], fits[i]
        assert fit is not None
        used = ~fit.excluded
        model, poses, data = fit.result.model, fit.result.poses, sample.points(used)
        core = core_of.get(spec.core) if spec.field is not None else None
        core_fit, core_lovo = (None, None) if core is None else (fits[core], lovo[core])
        try:
            if i in refitted:
                lovo[i] = refitted_view_errors(model, poses, data, kept[used])
            else:
                held = None if core_fit is None or core_lovo is None else held_steps(
                    model, core_fit.result.model, core_lovo.steps)
                lovo[i] = linearised_view_errors(model, poses, data, kept[used], held)
        except np.linalg.LinAlgError:
            lovo[i], reasons[i] = None, "its fit without some view is undetermined"

    for i, fit in enumerate(fits):
        if fit is not None:
            score(i)
            if lovo[i] is not None and edge is not None:
                model = fit.result.model
                folds[i] = folds_known[id(model)] if id(model) in folds_known else edge.folds(model)
    if all(v is None for v in lovo):
        raise DataError("no model could be validated on these corners: "
                        + "; ".join(dict.fromkeys(f"{sp.label}: {r}" for sp, r in zip(specs, reasons, strict=True) if r)))
    while True:
        choice = choose([Candidate(spec.name, spec.label, None if v is None else v.errors, reason,
                                   None if fit is None else fitted_parameter_count(fit.result.model),
                                   unmapped=f[0], unmapped_inside=f[1])
                         for spec, fit, v, reason, f in zip(specs, fits, lovo, reasons, folds, strict=True)],
                        counts, how=_how(sample.n_views, [specs[i].label for i in sorted(refitted)]))
        turns_on = {choice.chosen, choice.best} | {
            b for j in range(choice.chosen) if choice.within_noise(j) and (b := choice.beaten_by(j)) is not None}
        parametric = (k if specs[k].field is None else core_of.get(specs[k].core) for k in turns_on)
        to_refit = {k for k in parametric if k is not None and lovo[k] is not None} - refitted
        if not to_refit:
            return choice
        refitted |= to_refit
        for i in to_refit:
            score(i)


def _how(n_views: int, refitted: list[str]) -> str:
    """How the candidates' errors were measured, in words."""
    closed = ("one Gauss-Newton step from the full fit without the view, or a refit where that step leaves the "
              "linear regime")
    if refitted:
        scored = (f"{', '.join(refitted)} refitted without the view (the parametric models the choice turns on, "
                  f"and the cores of the fields over one); the others {closed}")
    else:
        scored = closed
    return f"error per axis on each of the {n_views} views left out of the fit ({scored}; then only the view's pose refit)"


def _try(why_not: list[str], i: int, fit_fn, *args):
    """``fit_fn(*args)``, or None (and why, in ``why_not[i]``) if the model
    cannot fit these corners."""
    try:
        return fit_fn(*args)
    except (DataError, FloatingPointError, np.linalg.LinAlgError) as exc:  # too few corners, diverged, no finite start
        why_not[i] = str(exc)
        return None
