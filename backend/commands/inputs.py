"""Reading a command's documents: a file, or ``-`` for standard input (one per run),
so that ``freecal detect … --json | freecal calibrate -`` works."""
from __future__ import annotations

import sys
from typing import Any

from calib_core import Calibration, Observations
from calib_core.errors import FormatError, SettingsError
from calib_core.observations import parse_json, read_json

STDIN = "-"
STDIN_NAME = "standard input"


def read_document(path: str) -> Any:
    """The JSON document in ``path``, or on standard input for ``-``."""
    if path != STDIN:
        return read_json(path)
    if sys.stdin is None or sys.stdin.isatty():
        raise SettingsError("- reads standard input, but nothing is piped in: e.g. "
                            "freecal detect PHOTOS --board SPEC --json | freecal calibrate -")
    raw = sys.stdin.buffer.read() if hasattr(sys.stdin, "buffer") else sys.stdin.read().encode("utf-8")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise FormatError(f"{STDIN_NAME}: cannot be read as UTF-8 text ({exc})") from None
    if not text.strip():
        raise FormatError(f"{STDIN_NAME}: empty; the command before the pipe wrote nothing (did it fail?)")
    return parse_json(text, STDIN_NAME)


def one_stdin(*paths: str | None) -> None:
    """Standard input holds one document: refuse ``-`` for two inputs."""
    if sum(p == STDIN for p in paths) > 1:
        raise SettingsError("only one input can be read from standard input (-); give the others as files")


def load_observations(path: str) -> Observations:
    return Observations.from_json(read_document(path))


def load_calibration(path: str) -> Calibration:
    return Calibration.from_json(read_document(path))
