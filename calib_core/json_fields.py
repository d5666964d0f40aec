"""Reading and writing the numbers and fields of freecal's JSON documents:
each reader names the field of a malformed value in a ``FormatError``."""
from __future__ import annotations

import math
import re
from typing import Any

from .errors import FormatError


def json_object(raw: Any, where: str) -> dict[str, Any]:
    if not isinstance(raw, dict):
        raise FormatError(f"{where}: expected an object, got {raw!r}")
    return raw


def required(doc: dict[str, Any], key: str, where: str) -> Any:
    if key not in doc:
        raise FormatError(f"{where}: missing {key!r}")
    return doc[key]


def number(raw: Any, where: str) -> float:
    """A number, or null for a figure that could not be measured (NaN)."""
    if raw is None:
        return math.nan
    if not isinstance(raw, (int, float)) or isinstance(raw, bool):
        raise FormatError(f"{where}: expected a number or null, got {raw!r}")
    return float(raw)


def optional_number(raw: Any, where: str) -> float | None:
    return None if raw is None else number(raw, where)


def whole(raw: Any, where: str) -> int:
    if not isinstance(raw, int) or isinstance(raw, bool) or raw < 0:
        raise FormatError(f"{where}: expected a whole number ≥ 0, got {raw!r}")
    return raw


# A camera's name becomes a YAML value and a ROS topic (/NAME/image_raw) in the exports: letters, digits and
# _ . - only, so no control character and no YAML indicator (- : # & * ! | > ' " % @ `). The web service and the
# command line both read names with this rule.
CAMERA_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")
CAMERA_NAME_RULE = "use 1 to 64 letters, digits and _ . - (starting with a letter or digit), e.g. left, right, cam0"


def is_camera_name(name: Any) -> bool:
    return isinstance(name, str) and CAMERA_NAME.fullmatch(name) is not None  # fullmatch: "cam0\n" is refused too


def text(raw: Any, where: str) -> str:
    if not isinstance(raw, str):
        raise FormatError(f"{where}: expected a string, got {raw!r}")
    return raw


def number_or_null(x: float) -> float | None:
    """JSON has no NaN: null instead."""
    return float(x) if math.isfinite(x) else None
