"""Errors a user can cause. Each message says what went wrong and what to do."""


class CalibError(Exception):
    """Base class: the service answers these with a 4xx and the message."""


class FormatError(CalibError):
    """A JSON document does not follow its format (names the field and view)."""


class DataError(CalibError):
    """The data cannot support the requested calibration (too few views, points...)."""


class DegenerateViews(DataError):
    """The views cannot determine the camera (duplicates, one pose, no tilt): says what to shoot."""


class SettingsError(CalibError):
    """A setting is out of range or unknown."""
