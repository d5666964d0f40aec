"""What a calibration records of its fit beside the model: the error figures
(``metrics``) and the ``diagnostics`` other code reads (the solver's report,
the points left out, the corners' hull, method auto's choice, a restart).

Each is a small dataclass with ``to_json()``, its object in the calibration file
(``metrics``: formats.md §2; ``diagnostics`` go beyond the contract: docs/python.md),
and ``from_json()``, which names the field of a malformed one in a FormatError.
``Calibration`` (``calibration.py``) holds them and reads and writes them.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .errors import FormatError
from .fitting.metrics import summary
from .json_fields import json_object, number, number_or_null, optional_number, required, text, whole


# ---- metrics ---------------------------------------------------------------------
@dataclass(frozen=True)
class FitMetrics:
    """The fit's error over the inlier corners (px): per-point rmse (OpenCV's
    figure), per-axis rmse (mrcal's), rmse over the image's central half and
    outside it (``fitting.metrics.centre_mask``); NaN where no corner falls."""

    rmse: float
    rmse_axis: float
    rmse_center: float
    rmse_edge: float
    n_points: int

    def to_json(self) -> dict[str, Any]:
        return {"rmse": number_or_null(self.rmse), "rmse_axis": number_or_null(self.rmse_axis),
                "rmse_center": number_or_null(self.rmse_center), "rmse_edge": number_or_null(self.rmse_edge),
                "n_points": self.n_points}

    @classmethod
    def of(cls, residuals: np.ndarray, image_points: np.ndarray, image_size) -> FitMetrics:
        """The figures of residuals (N, 2) at observed pixels (N, 2), by ``fitting.metrics.summary``."""
        s = summary(residuals, image_points, image_size)
        return cls(s["rmse"], s["rmse_axis"], s["rmse_center"], s["rmse_edge"], int(s["n_points"]))

    @classmethod
    def from_json(cls, raw: Any) -> FitMetrics:
        doc = json_object(raw, "metrics")

        def figure(key: str) -> float:
            return number(required(doc, key, "metrics"), f"metrics.{key}")

        return cls(figure("rmse"), figure("rmse_axis"), figure("rmse_center"), figure("rmse_edge"),
                   whole(required(doc, "n_points", "metrics"), "metrics.n_points"))


# ---- diagnostics -----------------------------------------------------------------
@dataclass(frozen=True)
class SolverReport:
    """How the final Levenberg–Marquardt run ended (``fitting.solve``) and what the whole calibration took."""

    iterations: int
    status: str  # "converged", "stalled", "max_iterations", ...
    message: str
    cost: float
    n_unknowns: int  # model parameters and 6 per view
    seconds: float

    def to_json(self) -> dict[str, Any]:
        return {"iterations": self.iterations, "status": self.status, "message": self.message,
                "cost": number_or_null(self.cost), "n_unknowns": self.n_unknowns, "seconds": number_or_null(self.seconds)}

    @classmethod
    def from_json(cls, raw: Any) -> SolverReport:
        w = "diagnostics.solver"
        doc = json_object(raw, w)
        return cls(whole(required(doc, "iterations", w), f"{w}.iterations"),
                   text(required(doc, "status", w), f"{w}.status"),
                   text(doc.get("message", ""), f"{w}.message"),
                   number(doc.get("cost"), f"{w}.cost"),
                   whole(required(doc, "n_unknowns", w), f"{w}.n_unknowns"),
                   number(doc.get("seconds"), f"{w}.seconds"))


@dataclass(frozen=True)
class ExcludedPoints:
    """Corners left out of the fit: outliers (each among its view's ``outliers``), of which
    ``misplaced`` were set aside before the fit (far beyond the image, or contradicted by
    their board neighbours: ``fitting.misplaced``), and those the model cannot represent
    (and why)."""

    outliers: int
    outside_model: int
    outside_model_reason: str = ""  # written when some are outside the model
    misplaced: int = 0

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"outliers": self.outliers, "outside_model": self.outside_model}
        if self.outside_model:
            out["outside_model_reason"] = self.outside_model_reason
        if self.misplaced:  # written when some were set aside (files from before it read back the same)
            out["misplaced"] = self.misplaced
        return out

    @classmethod
    def from_json(cls, raw: Any) -> ExcludedPoints:
        w = "diagnostics.excluded_points"
        doc = json_object(raw, w)
        return cls(whole(required(doc, "outliers", w), f"{w}.outliers"),
                   whole(required(doc, "outside_model", w), f"{w}.outside_model"),
                   text(doc.get("outside_model_reason", ""), f"{w}.outside_model_reason"),
                   whole(doc.get("misplaced", 0), f"{w}.misplaced"))


@dataclass(frozen=True)
class RestartFit:
    """One of a restart's two fits: its rmse (px), focal lengths and iterations."""

    rmse: float
    fx: float
    fy: float
    iterations: int

    def to_json(self) -> dict[str, Any]:
        return {"rmse": number_or_null(self.rmse), "fx": self.fx, "fy": self.fy, "iterations": self.iterations}

    @classmethod
    def from_json(cls, raw: Any, where: str) -> RestartFit:
        doc = json_object(raw, where)

        def figure(key: str) -> float:
            return number(required(doc, key, where), f"{where}.{key}")

        return cls(figure("rmse"), figure("fx"), figure("fy"),
                   whole(required(doc, "iterations", where), f"{where}.iterations"))


@dataclass(frozen=True)
class Restart:
    """A field fit that ended far from a parametric camera, fitted again from
    that camera (``methods.bspline.wrong_camera``): why, both fits, the one kept,
    and a warning when even the kept one is off."""

    reason: str
    first: RestartFit
    restarted: RestartFit
    kept: str  # "first" or "restarted"
    warning: str = ""

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"reason": self.reason, "first": self.first.to_json(),
                               "restarted": self.restarted.to_json(), "kept": self.kept}
        if self.warning:
            out["warning"] = self.warning
        return out

    @classmethod
    def from_json(cls, raw: Any) -> Restart:
        w = "diagnostics.restart"
        doc = json_object(raw, w)
        return cls(text(required(doc, "reason", w), f"{w}.reason"),
                   RestartFit.from_json(required(doc, "first", w), f"{w}.first"),
                   RestartFit.from_json(required(doc, "restarted", w), f"{w}.restarted"),
                   text(required(doc, "kept", w), f"{w}.kept"), text(doc.get("warning", ""), f"{w}.warning"))


@dataclass(frozen=True)
class CandidateScore:
    """One candidate of a model choice as recorded: its validation scores (None where it was not validated)."""

    name: str
    label: str
    chosen: bool
    validation_rmse: float | None = None  # per axis (px), on views left out of its fit
    validation_mse: float | None = None
    standard_error_rmse: float | None = None  # the band within which it counts as good as the best
    within_noise: bool | None = None
    n_params: int | None = None
    error: str = ""  # why it was not validated
    beaten_by: str = ""  # the simpler candidate that predicts better, which rules it out

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"name": self.name, "label": self.label, "chosen": self.chosen,
                               "validation_rmse": self.validation_rmse, "validation_mse": self.validation_mse,
                               "standard_error_rmse": self.standard_error_rmse, "within_noise": self.within_noise,
                               "n_params": self.n_params}
        if self.error:
            out["error"] = self.error
        if self.beaten_by:
            out["beaten_by"] = self.beaten_by
        return out

    @classmethod
    def from_json(cls, raw: Any, where: str) -> CandidateScore:
        doc = json_object(raw, where)
        chosen, within = doc.get("chosen"), doc.get("within_noise")
        if not isinstance(chosen, bool) or not (within is None or isinstance(within, bool)):
            raise FormatError(f"{where}: expected chosen and within_noise as true/false")
        n_params = doc.get("n_params")

        def score(key: str) -> float | None:
            return optional_number(doc.get(key), f"{where}.{key}")

        return cls(text(required(doc, "name", where), f"{where}.name"),
                   text(doc.get("label", ""), f"{where}.label"), chosen,
                   score("validation_rmse"), score("validation_mse"), score("standard_error_rmse"), within,
                   None if n_params is None else whole(n_params, f"{where}.n_params"),
                   text(doc.get("error", ""), f"{where}.error"), text(doc.get("beaten_by", ""), f"{where}.beaten_by"))


@dataclass(frozen=True)
class ChoiceReport:
    """Method auto's choice as recorded (``fitting.choice.ModelChoice.to_json``): the
    model chosen, why in words, the rule, how the errors were measured, and every candidate's scores."""

    chosen: str
    summary: str
    rule: str
    how: str
    n_views: int
    n_points: int
    candidates: tuple[CandidateScore, ...]

    @property
    def chosen_candidate(self) -> CandidateScore:
        return next(c for c in self.candidates if c.chosen)

    def status(self, c: CandidateScore) -> str:
        """A candidate's standing in the choice, in words (the score tables' last column)."""
        if c.chosen:
            return "chosen"
        if c.error:
            return c.error
        if c.beaten_by:
            simpler = next((o.label for o in self.candidates if o.name == c.beaten_by), c.beaten_by)
            return f"the simpler {simpler} predicts better"
        return "within the noise" if c.within_noise else ""

    def to_json(self) -> dict[str, Any]:
        return {"chosen": self.chosen, "summary": self.summary, "rule": self.rule, "how": self.how,
                "n_views": self.n_views, "n_points": self.n_points,
                "candidates": [c.to_json() for c in self.candidates]}

    @classmethod
    def from_json(cls, raw: Any) -> ChoiceReport:
        w = "diagnostics.model_choice"
        doc = json_object(raw, w)
        rows = required(doc, "candidates", w)
        if not isinstance(rows, list) or sum(1 for c in rows if isinstance(c, dict) and c.get("chosen") is True) != 1:
            raise FormatError(f"{w}.candidates: expected a list with exactly one chosen candidate")
        return cls(text(required(doc, "chosen", w), f"{w}.chosen"), text(doc.get("summary", ""), f"{w}.summary"),
                   text(doc.get("rule", ""), f"{w}.rule"), text(doc.get("how", ""), f"{w}.how"),
                   whole(doc.get("n_views", 0), f"{w}.n_views"), whole(doc.get("n_points", 0), f"{w}.n_points"),
                   tuple(CandidateScore.from_json(c, f"{w}.candidates[{k}]") for k, c in enumerate(rows)))


@dataclass
class Diagnostics:
    """The calibration's ``diagnostics``: typed where code other than their writer
    reads them, and ``extra`` for what a method records of its own search
    (``design``, ``initialisation``, ``domain``, ``smoothing_curve``,
    ``grid_search``) and any key a reader does not know, kept as read.

    ``camera`` is the report's parameters block (``evaluation.parameters.describe_camera``),
    added after the fit by the CLI and the service; ``excluded_views`` the names the service's
    user left out. Mutable: those two are set on a finished calibration."""

    extra: dict[str, Any] = field(default_factory=dict)
    restart: Restart | None = None
    model_choice: ChoiceReport | None = None
    solver: SolverReport | None = None
    coverage_hull: list[list[float]] | None = None  # (M, 2) pixels: the convex hull of the corners used
    excluded_points: ExcludedPoints | None = None
    camera: dict[str, Any] | None = None
    excluded_views: list[str] | None = None

    def to_json(self) -> dict[str, Any]:
        """``extra`` first, then the typed parts in the order the pipeline writes them."""
        out = dict(self.extra)
        typed: dict[str, Any] = {
            "restart": _json_of(self.restart), "model_choice": _json_of(self.model_choice),
            "solver": _json_of(self.solver), "coverage_hull": self.coverage_hull,
            "excluded_points": _json_of(self.excluded_points), "camera": self.camera,
            "excluded_views": self.excluded_views}
        out.update({k: v for k, v in typed.items() if v is not None})
        return out

    @classmethod
    def from_json(cls, raw: Any) -> Diagnostics:
        doc = dict(json_object(raw, "diagnostics"))
        restart, choice, solver = doc.pop("restart", None), doc.pop("model_choice", None), doc.pop("solver", None)
        hull, excluded = doc.pop("coverage_hull", None), doc.pop("excluded_points", None)
        camera, excluded_views = doc.pop("camera", None), doc.pop("excluded_views", None)
        return cls(extra=doc,  # what is left: the method's own records
                   restart=None if restart is None else Restart.from_json(restart),
                   model_choice=None if choice is None else ChoiceReport.from_json(choice),
                   solver=None if solver is None else SolverReport.from_json(solver),
                   coverage_hull=None if hull is None else _hull(hull),
                   excluded_points=None if excluded is None else ExcludedPoints.from_json(excluded),
                   camera=None if camera is None else json_object(camera, "diagnostics.camera"),
                   excluded_views=None if excluded_views is None else _names(excluded_views))


def grid_score(entry: dict[str, Any]) -> float | None:
    """A scored knot grid's figure in ``diagnostics.smoothing_curve``: the error
    (px² per corner) on views left out of its joint fit, which chose the grid,
    or, where no joint fit scored it (one grid; calibrations from before),
    its control points' left out at the held camera (``cv``)."""
    value = entry.get("validation")
    return entry.get("cv") if value is None else value


def _json_of(part: Restart | ChoiceReport | SolverReport | ExcludedPoints | None) -> dict[str, Any] | None:
    return None if part is None else part.to_json()


def _hull(raw: Any) -> list[list[float]]:
    if not isinstance(raw, list) or not all(isinstance(p, list) and len(p) == 2 for p in raw):
        raise FormatError("diagnostics.coverage_hull: expected a list of [x, y] pixels")
    return [[number(x, "diagnostics.coverage_hull"), number(y, "diagnostics.coverage_hull")] for x, y in raw]


def _names(raw: Any) -> list[str]:
    if not isinstance(raw, list):
        raise FormatError("diagnostics.excluded_views: expected a list of view names")
    return [text(n, "diagnostics.excluded_views") for n in raw]
