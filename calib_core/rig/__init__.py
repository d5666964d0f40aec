"""Rigs: several cameras fixed to each other, calibrated together
(``freecal.rig/1``, formats.md §4). Each camera is calibrated alone first (any
method, the default's choice included); then the cameras' poses relative to
the reference camera and the board's pose at every frame are fitted to every
camera's corners at once, each camera's model held."""
from .calibrate import calibrate_rig
from .evaluate import evaluate_rig
from .frames import frame_of
from .rig import Rig, RigCamera, RigFrame, RigMetrics

__all__ = ["Rig", "RigCamera", "RigFrame", "RigMetrics", "calibrate_rig", "evaluate_rig", "frame_of"]
