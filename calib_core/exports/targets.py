"""Every export target, and the one way a calibration becomes one.

A target knows a few lens models (``Target.models``: freecal's name → the
consumer's). ``export`` writes the calibration as the model it already is
when the target knows it (exactly: nothing is fitted), as the model asked
for, or else as the closest of the target's candidates (``Target.auto``):
each is fitted over the covered region and the smallest rms wins. The fits
tried are kept, so a reader is told what the choice was between.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..calibration import Calibration
from ..errors import SettingsError
from ..products.rectify import RectifiedCamera, rectified_camera
from .colmap import COLMAP_MODELS, cameras_txt
from .kalibr import KALIBR_MODELS, camchain_yaml
from .lean_fit import LEAN_MODELS, LeanFit, LeanFitError, evaluate, exact_name, fit_lean, parametric_part
from .mrcal import MRCAL_MODELS, cameramodel
from .nerfstudio import NERFSTUDIO_MODELS, transforms_json
from .opencv_yaml import lean_yaml
from .ros import ROS_MODELS, ros_yaml
from .splined import NAME as SPLINED
from .splined import fit_splined

Rectify = Callable[[LeanFit], RectifiedCamera]  # the rectified camera (ROS's P) of an exported model


@dataclass(frozen=True)
class Target:
    name: str
    label: str  # what the consumer calls the file
    models: dict[str, str]  # freecal's model → the consumer's name for it
    auto: tuple[str, ...]  # the candidates when the calibration is none of ``models``
    file_name: str  # the consumer's usual name for the file
    write: Callable[[LeanFit, Calibration, RectifiedCamera | None], str]
    # How far off axis (degrees) the consumer takes a model's rays, where it reaches further than
    # OpenCV computes that model (``lean_fit.REACH_DEG``)
    reach: dict[str, float] = field(default_factory=dict)


def _opencv(fit: LeanFit, source: Calibration, camera: RectifiedCamera | None) -> str:
    return lean_yaml(fit, source)


TARGETS: dict[str, Target] = {t.name: t for t in (
    Target("opencv", "OpenCV FileStorage YAML", {m: ("fisheye" if m == "kb4" else "opencv") for m in LEAN_MODELS},
           ("opencv8", "kb4"), "calibration.yaml", _opencv),
    Target("ros", "ROS camera_info YAML", ROS_MODELS, ("opencv8", "kb4"), "camera_info.yaml",
           lambda fit, source, camera: ros_yaml(fit, camera=camera)),
    Target("mrcal", "mrcal .cameramodel", MRCAL_MODELS, ("opencv8", SPLINED), "camera.cameramodel",
           lambda fit, source, camera: cameramodel(fit)),
    Target("colmap", "COLMAP cameras.txt", COLMAP_MODELS, ("opencv8", "kb4"), "cameras.txt",
           lambda fit, source, camera: cameras_txt(fit)),
    Target("nerfstudio", "nerfstudio transforms.json", NERFSTUDIO_MODELS, ("opencv5", "kb4"), "transforms.json",
           lambda fit, source, camera: transforms_json(fit),
           reach={"kb4": 179.0}),  # its OPENCV_FISHEYE casts rays up to θ = π (cameras.py), not only in front
    Target("kalibr", "Kalibr camchain YAML", KALIBR_MODELS, ("opencv4", "kb4"), "camchain.yaml",
           lambda fit, source, camera: camchain_yaml(fit)),
)}
MODELS = (*LEAN_MODELS, SPLINED)  # every model some target knows


@dataclass
class Export:
    target: Target
    fit: LeanFit  # what was written
    text: str
    tried: list[LeanFit] = field(default_factory=list)  # the candidates fitted when the choice was freecal's
    camera: RectifiedCamera | None = None  # ROS's P

    @property
    def consumer_model(self) -> str:
        return self.target.models[self.fit.name]


def fit_model(cal: Calibration, name: str, covered: np.ndarray | None = None) -> LeanFit:
    """``cal`` as the model ``name`` (a key of ``LEAN_MODELS``, or ``splined``)."""
    if name == SPLINED:
        return fit_splined(cal, covered)
    return fit_lean(cal, name, covered=covered)


def closeness(fit: LeanFit) -> tuple[bool, float, float]:
    """How far an export strays, for choosing between candidates: first whether it throws a ring of
    the image's rays to infinity (``pole_radius``), then the share of the image's rays it cannot
    represent at all (to a hundredth: its error there is no number, and a model that reaches less
    would otherwise score better on what is left), then the larger rms (px)."""
    return (fit.pole_radius is not None, round(fit.n_beyond / max(fit.image.n + fit.n_beyond, 1), 2),
            max(fit.covered.rms, fit.image.rms))


def export(cal: Calibration, to: str, model: str = "auto", covered: np.ndarray | None = None,
           rectify: Rectify | None = None) -> Export:
    """``cal`` written for the target ``to`` (``TARGETS``) as ``model`` (``auto``: module
    text), fitted over the hull of ``covered`` pixels (default: the recorded coverage)."""
    if to not in TARGETS:
        raise SettingsError(f"export target: expected one of {sorted(TARGETS)}, got {to!r}")
    target = TARGETS[to]
    if model != "auto" and model not in target.models:
        raise SettingsError(f"{target.label} has no {model} model; it knows {', '.join(target.models)}")
    cal = parametric_part(cal) or cal  # a hybrid with a held zero field is its core, exactly

    def fitted(name: str) -> LeanFit:
        fit = fit_model(cal, name, covered)
        if name not in target.reach:
            return fit
        scored = evaluate(fit.model, cal, name, target.reach[name], fit.exact, covered=covered)
        return dataclasses.replace(scored, pole_radius=fit.pole_radius)

    tried: list[LeanFit] = []
    own = exact_name(cal)
    if model != "auto":
        fit = fitted(model)
    elif own in target.models:
        fit = fitted(own)
    else:
        tried, why_not = [], []
        for m in target.auto:
            try:
                tried.append(fitted(m))
            except LeanFitError as exc:  # another candidate may serve
                why_not.append(str(exc))
        if not tried:
            raise LeanFitError("; ".join(why_not))
        tried.sort(key=closeness)
        fit = tried[0]
    camera = None
    if to == "ros":
        camera = (rectify or (lambda f: rectified_camera(f.calibration, 0.0)))(fit)
    return Export(target, fit, target.write(fit, cal, camera), tried, camera)
