"""A calibration's camera in the numbers a user reads first: every parameter
by name with ± one standard deviation, the field of view, how well the
projection is known over the image, and a verdict in plain words.

The standard deviations are the square roots of the diagonal of the model's
covariance ``uncertainty.model_covariance``: σ² (JᵀJ)⁻¹ of the final fit,
linearised at the solution, the intrinsics' block with the poses
marginalised (Schur complement), σ estimated from the residuals. Parameters
the fit holds (a hybrid's core coefficients, OpenCV's absent skew) have no
standard deviation and say why. ``tests/core/test_parameters.py`` checks the
prediction against the spread of refits on synthetic noise.

The field of view is the model's own: rays of the image's edge midpoints and
corners (``Calibration.rays``, principal branch), the angle swept along the
image's midlines and diagonal, so a lens past 180° reads past 180°.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..models import BSplineModel, FisheyeModel, HybridModel, OpenCVModel, camera
from ..models.base import CameraModel, fitted_parameter_count
from ..models.residual_field import ResidualFieldModel
from .verdict import FIELD_ADVICE, uncovered_regions, verdict

if TYPE_CHECKING:
    from ..calibration import Calibration
    from ..fitting.solve import Data

OPENCV_NAMES = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4", "τx", "τy")
INTRINSICS = ("fx", "fy", "cx", "cy", "skew")
FOV_SAMPLES = 400            # rays along each line the field of view is swept over
UNCERTAINTY_CELLS = 32       # projection-uncertainty samples across the image's longer side
HELD_CORE = "held where the core's own fit put them (the field takes what they would)"
HELD_ANGULAR = ("held where the initial camera put it: on an angular base the field follows a turn of the camera, "
                "which would walk it")


def model_in_words(model: CameraModel) -> str:
    """The model as a user names it: "Kannala-Brandt model (k1..k4)", "B-spline field over the rational model"."""
    if isinstance(model, HybridModel):
        core = model_in_words(model.core)
        if model.field_held:
            return f"{core} (its B-spline field held at zero)"
        return f"B-spline field over the {core}, {_grid(model)} knot intervals"
    if isinstance(model, BSplineModel):
        return f"B-spline field over the {model.base} projection (the paper's model), {_grid(model)} knot intervals"
    if isinstance(model, ResidualFieldModel):
        kind = {"mls": "moving-least-squares", "tps": "thin-plate-spline"}.get(model.kind, model.kind)
        return f"{model_in_words(model.parametric)} with a {kind} residual field"
    if isinstance(model, FisheyeModel):
        return f"Kannala-Brandt model (k1..k{len(model.coefficients)})"
    if isinstance(model, OpenCVModel):
        n = len(model.coefficients)
        return {4: "OpenCV model, 4 coefficients (k1, k2, p1, p2)", 5: "OpenCV model, 5 coefficients (k1, k2, p1, p2, k3)",
                8: "OpenCV rational model (8 coefficients)", 12: "OpenCV rational model with thin-prism terms (12)",
                }.get(n, f"OpenCV model with thin-prism and tilt terms ({n} coefficients)")
    return model.kind


def _grid(model: CameraModel) -> str:
    breaks = model.knot_breaks()
    return "?" if breaks is None else f"{len(breaks[0]) - 1} × {len(breaks[1]) - 1}"


def how_chosen(cal: Calibration) -> str:
    """Why this model: method auto's choice in its own words, or the method asked for."""
    choice = cal.diagnostics.model_choice
    if cal.method == "auto" and choice is not None and choice.summary:
        reason = choice.summary.split(": ", 1)[1] if ": " in choice.summary else choice.summary
        return f"chosen by method auto among {len(choice.candidates)} candidates: {reason}"
    if cal.settings.get("chosen_by") == "compare":
        return f"the comparison's verdict: the best of every method compared on these corners (method {cal.method})"
    return f"as asked (method {cal.method})"


def other_model(cal: Calibration) -> str | None:
    """The advice on another model for corners far from this one, agreeing with method
    auto's choice: None for a model with a field; where auto kept a model without one
    over a field that predicted the views left out better, that field and why it was
    not taken (on a few views the difference lies within their noise)."""
    if field_summary(cal) is not None:
        return None
    choice = cal.diagnostics.model_choice
    if cal.method != "auto" or choice is None:
        return FIELD_ADVICE
    kept = choice.chosen_candidate.validation_rmse
    scored = [(c.validation_rmse, c.label) for c in choice.candidates if _has_field(c.name) and c.validation_rmse]
    if kept is None or not scored or min(scored)[0] >= kept:
        return None
    score, label = min(scored)
    return (f"calibrate with the {label}: it predicted the views left out better ({score:.2f} against {kept:.2f} px "
            f"per axis), by less than the noise of {choice.n_views} views, so the default kept the simpler model; "
            "more views let it tell")


def _has_field(candidate: str) -> bool:
    """Is method auto's candidate of this name a field (``bspline``, ``hybrid-<core>``)?"""
    return candidate == "bspline" or candidate.startswith("hybrid-")


def parameter_table(model: CameraModel, cov: np.ndarray | None) -> list[dict[str, Any]]:
    """One row per named parameter: value, standard deviation (None where held
    or not computed), unit, group ("intrinsics" or "distortion") and status."""
    x = model.params()
    std = None if cov is None else np.sqrt(np.clip(np.diag(cov), 0.0, None))
    free = model.free_mask()
    rows: list[dict[str, Any]] = []

    def add(name: str, group: str, index: int | None, unit: str, value: float | None = None, note: str = "") -> None:
        held = index is None or (free is not None and not free[index])
        row: dict[str, Any] = {"name": name, "group": group, "unit": unit,
                               "value": float(x[index]) if index is not None else float(value or 0.0),
                               "std": None if held or std is None else float(std[index]),
                               "status": "fixed" if index is None else "held" if held else "fitted"}
        if note or held:
            row["note"] = note or "not fitted"
        rows.append(row)

    parametric = _parametric_part(model)
    if isinstance(model, BSplineModel):
        for i, name in enumerate(INTRINSICS):
            add(name, "intrinsics", i, "px", note=HELD_ANGULAR if free is not None and not free[i] else "")
        return rows
    if parametric is None:
        return rows
    for i, name in enumerate(INTRINSICS[:4]):
        add(name, "intrinsics", i, "px")
    skew = float(parametric.intrinsics[4])
    add("skew", "intrinsics", None, "px", skew, "held: 0 in a fit, as OpenCV's" if skew == 0 else "held, as the file gave it")
    names = OPENCV_NAMES if isinstance(parametric, OpenCVModel) else tuple(f"k{i + 1}" for i in range(99))
    for j in range(len(parametric.coefficients)):
        unit = "rad" if names[j].startswith("τ") else ""
        note = HELD_CORE if isinstance(model, HybridModel) and free is not None and not free[4 + j] else ""
        add(names[j], "distortion", 4 + j, unit, note=note)
    return rows


def _parametric_part(model: CameraModel):
    if isinstance(model, HybridModel):
        return model.core
    if isinstance(model, ResidualFieldModel):
        return model.parametric
    if isinstance(model, (OpenCVModel, FisheyeModel)):
        return model
    return None


def field_summary(cal: Calibration) -> dict[str, Any] | None:
    """The field a model carries on top of its core: what it is, its grid, its size over the image."""
    model = cal.model
    if isinstance(model, (BSplineModel, HybridModel)):
        if isinstance(model, HybridModel) and model.field_held:
            return None
        f = model.field
        w, h = cal.image_size
        u, v = np.meshgrid(np.linspace(0, w - 1, 33), np.linspace(0, h - 1, 25))
        offsets = np.hypot(*f(np.column_stack([u.ravel(), v.ravel()])).T)
        breaks = model.knot_breaks()
        assert breaks is not None  # a B-spline field has knots
        out: dict[str, Any] = {
            "type": "B-spline", "degree": 3,
            "over": "the pinhole (on ideal pixels)" if isinstance(model, BSplineModel)
                    else f"the {model_in_words(model.core)} (on its pixels)",
            "knot_intervals": [len(breaks[0]) - 1, len(breaks[1]) - 1],
            "control_points": [f.n_u, f.n_v], "domain_px": [float(d) for d in f.domain],
            "largest_offset_px": float(np.max(offsets)), "median_offset_px": float(np.median(offsets)),
            "lambda_smooth": float(model.lambda_smooth),
        }
        return out
    if isinstance(model, ResidualFieldModel):
        kind = {"mls": "moving least squares", "tps": "thin-plate spline"}.get(model.kind, model.kind)
        doc = model.field.to_json()
        n = len(doc.get("centers", doc.get("samples", [])))
        return {"type": kind, "over": f"the {model_in_words(model.parametric)} (on its pixels)", "centres": n}
    return None


def _lines(image_size) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The image's horizontal and vertical midlines and its diagonal, FOV_SAMPLES
    pixels each (name → (FOV_SAMPLES, 2)), and all of them stacked."""
    w, h = image_size
    ends = {"horizontal": ((0.0, (h - 1) / 2), (w - 1.0, (h - 1) / 2)),
            "vertical": (((w - 1) / 2, 0.0), ((w - 1) / 2, h - 1.0)),
            "diagonal": ((0.0, 0.0), (w - 1.0, h - 1.0))}
    t = np.linspace(0.0, 1.0, FOV_SAMPLES)[:, None]
    lines = {name: np.asarray(a) + t * (np.asarray(b) - np.asarray(a)) for name, (a, b) in ends.items()}
    return lines, np.concatenate(list(lines.values()))


def _line_rays(cal: Calibration) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The lines (``_lines``) and their rays (3, FOV_SAMPLES, 3), NaN where none."""
    lines, pixels = _lines(cal.image_size)
    with np.errstate(all="ignore"):
        return lines, cal.rays(pixels).reshape(len(lines), FOV_SAMPLES, 3)


def field_of_view(cal: Calibration) -> dict[str, float | None]:
    """Degrees swept by the model's rays along the horizontal and vertical
    midlines and the diagonal of the image; None where some pixel on the way
    has no ray (past the model's reach: ``no_ray_beyond``)."""
    lines, rays = _line_rays(cal)
    out: dict[str, float | None] = {}
    for name, r in zip(lines, rays, strict=True):
        if not np.all(np.isfinite(r)):
            out[name] = None
            continue
        steps = np.arccos(np.clip(np.sum(r[1:] * r[:-1], axis=1), -1.0, 1.0))
        out[name] = float(np.degrees(steps.sum()))
    return out


def no_ray_beyond(cal: Calibration) -> dict[str, float]:
    """For each of the image's midlines and its diagonal on which some pixel
    has no ray under the model, how far from the principal point (px) the
    nearest such pixel lies. A model whose distortion turns back (a rational
    model past its fold, a Kannala–Brandt polynomial past its peak) maps no
    ray there: right for a circular fisheye's dark corners, wrong where the
    lens lights the pixels."""
    lines, rays = _line_rays(cal)
    centre = cal.model.intrinsics[2:4]
    out: dict[str, float] = {}
    for (name, pixels), r in zip(lines.items(), rays, strict=True):
        none = ~np.all(np.isfinite(r), axis=1)
        if none.any():
            out[name] = float(np.min(np.hypot(*(pixels[none] - centre).T)))
    return out


def lit_radius(cal: Calibration) -> float | None:
    """How far from the principal point (px) the lens is known to light the
    image: the farthest corner the calibration used (its coverage hull)."""
    hull = np.asarray(cal.diagnostics.coverage_hull or [], dtype=float).reshape(-1, 2)
    return float(np.max(np.hypot(*(hull - cal.model.intrinsics[2:4]).T))) if len(hull) else None


def describe_camera(cal: Calibration, data: Data, poses: np.ndarray) -> dict[str, Any]:
    """The ``diagnostics.camera`` block: model in words, parameters ± σ, field,
    field of view, projection uncertainty over the covered image, verdict.
    ``data``: the inlier corners the final fit used, ``poses`` their views'."""
    from .uncertainty import full_covariance, projection_uncertainty

    out: dict[str, Any] = {"model": model_in_words(cal.model), "chosen": how_chosen(cal),
                           "fitted_parameters": fitted_parameter_count(cal.model)}
    cov, full = None, None
    try:
        # one covariance for both: its model block is the parameters' (poses marginalised, as the
        # Schur complement gives it), the whole of it the projection's in the boards' frame
        full = full_covariance(cal.model, poses, data)
        cov = full[0][: cal.model.n_params, : cal.model.n_params]
        # tr(H⁻¹ JᵀJ) less the poses' 6 each: what the model itself costs the data
        out.update(sigma_px=full[1], effective_parameters=float(max(full[2] - 6 * data.n_views, 0.0)))
    except (np.linalg.LinAlgError, ValueError, FloatingPointError) as exc:
        out["uncertainty_error"] = f"the covariance could not be computed ({exc})"
    out["parameters"] = parameter_table(cal.model, cov)
    out["field"] = field_summary(cal)
    out["field_of_view_deg"] = field_of_view(cal)
    out["no_ray_beyond_px"] = no_ray_beyond(cal)
    # the corners' own rays (board points through their fitted poses): how far off axis the data reaches,
    # the one angle a circular fisheye's frame (no ray at its black corners) still has
    pc = camera.transform(poses, data.view_index, data.object_points)
    angles = np.degrees(camera.off_axis(pc))
    out["max_corner_angle_deg"] = float(angles.max()) if angles.size else None
    unc = None
    if full is not None:
        w, h = cal.image_size
        with np.errstate(all="ignore"):
            um = projection_uncertainty(cal.model, poses, data, cal.image_size, step=max(w, h) / UNCERTAINTY_CELLS,
                                        covariance=full)
        worst, ok = um.std_worst, np.all(np.isfinite(um.rays), axis=-1)
        covered = um.covered & np.isfinite(worst)
        if covered.any():
            unc = {"median_px": float(np.median(worst[covered])), "p95_px": float(np.percentile(worst[covered], 95)),
                   "covered_share": float(covered.sum() / max(ok.sum(), 1)),
                   "uncovered_regions": uncovered_regions(covered, ok),
                   "measure": "worst-direction standard deviation of a projected direction (boards frame), "
                              "over the image cells with an observed corner nearby"}
    out["projection_uncertainty"] = unc
    out["verdict"] = verdict(_fit_rmse(cal), unc, out["no_ray_beyond_px"], lit_radius(cal), other_model(cal))
    return out


def describe_without_corners(cal: Calibration) -> dict[str, Any]:
    """The ``diagnostics.camera`` block from the calibration alone: without the
    corners it was fitted to there is no covariance, so no ± and no projection
    uncertainty (the calibration file holds neither)."""
    no_ray = no_ray_beyond(cal)
    return {"model": model_in_words(cal.model), "chosen": how_chosen(cal),
            "fitted_parameters": fitted_parameter_count(cal.model),
            "parameters": parameter_table(cal.model, None), "field": field_summary(cal),
            "field_of_view_deg": field_of_view(cal), "no_ray_beyond_px": no_ray, "projection_uncertainty": None,
            "uncertainty_error": "no standard deviations: they need the corners the calibration was fitted to",
            "verdict": verdict(_fit_rmse(cal), None, no_ray, lit_radius(cal), other_model(cal))}


def _fit_rmse(cal: Calibration) -> float:
    return np.nan if cal.metrics is None else cal.metrics.rmse
