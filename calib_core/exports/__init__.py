"""Exports of a calibration for other tools: OpenCV FileStorage YAML, ROS
``camera_info``, mrcal ``.cameramodel``, COLMAP ``cameras.txt``, nerfstudio
``transforms.json``, Kalibr camchain YAML, each of a model fitted to the
calibration (``lean_fit``, ``splined``) when the calibration is not that model
already; ``targets.export`` chooses and writes (docs/exports.md)."""
from __future__ import annotations

from .lean_fit import LEAN_MODELS, FitError, LeanFit, LeanFitError, exact_name, fit_lean, parametric_part
from .mrcal import MRCAL_MODELS, cameramodel
from .opencv_yaml import lean_yaml, opencv_yaml, read_opencv_yaml
from .ros import ROS_MODELS, ros_yaml
from .targets import MODELS, TARGETS, Export, Target, export, fit_model

__all__ = ["LEAN_MODELS", "FitError", "LeanFit", "LeanFitError", "exact_name", "fit_lean", "MRCAL_MODELS",
           "cameramodel", "lean_yaml", "opencv_yaml", "parametric_part", "read_opencv_yaml", "ROS_MODELS",
           "ros_yaml", "MODELS", "TARGETS", "Export", "Target", "export", "fit_model"]
