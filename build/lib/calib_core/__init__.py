"""freecal's science: B-spline and classic camera calibration, no web, no globals.

    from calib_core import Observations, calibrate
    cal = calibrate(Observations.load("obs.json"), method="bspline")
    cal.save("cal.json")
"""
from .calibration import Calibration
from .errors import CalibError, DataError, FormatError, SettingsError
from .evaluation.evaluate import evaluate
from .observations import Observations, View
from .pipeline import calibrate

__all__ = ["calibrate", "evaluate", "Calibration", "Observations", "View",
           "CalibError", "DataError", "FormatError", "SettingsError"]
