"""Calibration boards: the spec string, the ``board`` JSON object, corner geometry.

Spec strings (CLI and API)::

    chessboard:COLSxROWS:SQUARE            e.g. chessboard:9x6:25mm   (inner corners)
    charuco:SQUARESXxSQUARESY:SQUARE:MARKER:DICT[:legacy]
                                           e.g. charuco:5x7:40mm:20mm:DICT_6X6_250

Lengths take a unit suffix (``mm``, ``cm``, ``m``; none means mm) and are
stored in millimetres. Ids follow ``formats.md``: chessboard ``id = row * cols
+ col``; ChArUco ids are OpenCV's ChArUco corner ids.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import FormatError, SettingsError

TYPES = ("chessboard", "charuco")
_UNITS = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "": 1.0}
# Bounds on what a spec may ask for (a client's spec runs detection on a shared worker:
# a 1000x1000 ChArUco board held one for minutes on a single small image).
MAX_SIDE = 100                         # inner corners (chessboard) or squares (ChArUco) per side
MIN_LENGTH_MM, MAX_LENGTH_MM = 0.001, 10_000.0   # squares and markers: 1 µm to 10 m
_EXAMPLES = "e.g. chessboard:9x6:25mm or charuco:5x7:40mm:20mm:DICT_6X6_250 (add :legacy for the old ChArUco layout)"


def dictionaries() -> list[str]:
    """Names of the ArUco dictionaries this OpenCV build knows."""
    import cv2

    return sorted(n for n in dir(cv2.aruco) if n.startswith("DICT_"))


def _dictionary_size(name: str) -> int:
    import cv2

    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name)).bytesList.shape[0]


@dataclass(frozen=True)
class BoardSpec:
    """A planar calibration board. Lengths in ``units`` (always ``"mm"`` from ``parse``).

    chessboard: ``cols`` × ``rows`` inner corners, ``square_size``.
    charuco:    ``cols`` × ``rows`` squares (``squares_x`` × ``squares_y`` in JSON),
                ``square_size``, ``marker_size``, ``dictionary``, ``legacy``.
    """

    type: str
    cols: int
    rows: int
    square_size: float
    marker_size: float | None = None
    dictionary: str | None = None
    legacy: bool = False
    units: str = "mm"

    def __post_init__(self) -> None:
        if self.type not in TYPES:
            raise SettingsError(f"board type {self.type!r} is unknown; use one of {', '.join(TYPES)} ({_EXAMPLES})")
        least = 2
        what = "inner corners" if self.type == "chessboard" else "squares"
        if self.cols < least or self.rows < least:
            raise SettingsError(f"board {self.cols}x{self.rows}: need at least {least}x{least} {what}")
        if self.cols > MAX_SIDE or self.rows > MAX_SIDE:
            raise SettingsError(f"board {self.cols}x{self.rows}: at most {MAX_SIDE}x{MAX_SIDE} {what}; "
                                "count the board's own (e.g. chessboard:9x6:25mm)")
        self._check_length("square size", self.square_size)
        if self.type == "charuco":
            if self.marker_size is None or not (0 < self.marker_size < self.square_size):
                raise SettingsError(
                    f"ChArUco marker size must be positive and smaller than the square ({self.square_size:g}), "
                    f"got {self.marker_size!r}"
                )
            self._check_length("marker size", self.marker_size)
            if self.dictionary not in dictionaries():
                raise SettingsError(
                    f"ArUco dictionary {self.dictionary!r} is unknown; use one of {', '.join(dictionaries())}"
                )
            markers, held = self.cols * self.rows // 2, _dictionary_size(self.dictionary)
            if markers > held:
                raise SettingsError(f"a {self.cols}x{self.rows} ChArUco board has {markers} markers, more than "
                                    f"{self.dictionary} holds ({held}): check the board's size and dictionary")

    def _check_length(self, what: str, value: float) -> None:
        mm = value * _UNITS.get(self.units, 1.0) if isinstance(value, (int, float)) else float("nan")
        if not MIN_LENGTH_MM <= mm <= MAX_LENGTH_MM:  # NaN fails too
            raise SettingsError(f"board {what} must be a length from {MIN_LENGTH_MM:g} mm to "
                                f"{MAX_LENGTH_MM / 1000:g} m, got {value!r} {self.units}")

    # ---- geometry -------------------------------------------------------
    @property
    def corner_grid(self) -> tuple[int, int]:
        """(cols, rows) of the board's corner lattice (inner corners)."""
        if self.type == "chessboard":
            return self.cols, self.rows
        return self.cols - 1, self.rows - 1

    @property
    def n_corners(self) -> int:
        c, r = self.corner_grid
        return c * r

    def object_points(self, ids: np.ndarray) -> np.ndarray:
        """Board-frame corners (N, 3), Z = 0, of corner ``ids`` (N,).

        Chessboard corner ``row*cols + col`` sits at ``(col, row) * square``;
        ChArUco corner ``i`` at ``(i % (X-1) + 1, i // (X-1) + 1) * square``,
        exactly OpenCV's ``CharucoBoard.getChessboardCorners()``.
        """
        ids = np.asarray(ids, dtype=np.int64).reshape(-1)
        c, _ = self.corner_grid
        if ids.size and (ids.min() < 0 or ids.max() >= self.n_corners):
            raise SettingsError(f"corner ids must lie in [0, {self.n_corners}) for this board")
        off = 0.0 if self.type == "chessboard" else 1.0
        col, row = ids % c + off, ids // c + off
        return np.stack([col * self.square_size, row * self.square_size, np.zeros(len(ids))], axis=-1)

    def _markers(self) -> tuple[float, str]:
        """A ChArUco board's marker size and ArUco dictionary (``validate`` requires both)."""
        if self.marker_size is None or self.dictionary is None:
            raise SettingsError(f"a {self.type} board needs a marker size and an ArUco dictionary")
        return self.marker_size, self.dictionary

    def cv_charuco(self):
        """OpenCV's CharucoBoard for this spec (ChArUco only)."""
        import cv2

        marker_size, dictionary = self._markers()
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
        board = cv2.aruco.CharucoBoard((self.cols, self.rows), float(self.square_size), float(marker_size), d)
        board.setLegacyPattern(bool(self.legacy))
        return board

    # ---- text and JSON --------------------------------------------------
    @classmethod
    def parse(cls, spec: str) -> BoardSpec:
        """``chessboard:9x6:25mm`` or ``charuco:5x7:40mm:20mm:DICT_6X6_250[:legacy]``."""
        if not isinstance(spec, str) or not spec.strip():
            raise SettingsError(f"board spec is empty; {_EXAMPLES}")
        parts = [p.strip() for p in spec.strip().split(":")]
        kind = parts[0].lower()
        if kind == "chessboard":
            if len(parts) != 3:
                raise SettingsError(f"board spec {spec!r}: chessboard takes COLSxROWS:SQUARE (inner corners), {_EXAMPLES}")
            cols, rows = _grid(spec, parts[1])
            return cls("chessboard", cols, rows, _length(spec, parts[2]))
        if kind == "charuco":
            legacy = len(parts) == 6 and parts[5].lower() == "legacy"
            if len(parts) != 5 and not legacy:
                raise SettingsError(
                    f"board spec {spec!r}: charuco takes SQUARESXxSQUARESY:SQUARE:MARKER:DICTIONARY[:legacy], {_EXAMPLES}"
                )
            cols, rows = _grid(spec, parts[1])
            name = parts[4].upper()
            name = name if name.startswith("DICT_") else "DICT_" + name
            return cls("charuco", cols, rows, _length(spec, parts[2]), _length(spec, parts[3]), name, legacy)
        raise SettingsError(f"board spec {spec!r}: unknown board type {parts[0]!r}; {_EXAMPLES}")

    def to_spec(self) -> str:
        if self.type == "chessboard":
            return f"chessboard:{self.cols}x{self.rows}:{self.square_size:g}{self.units}"
        tail = ":legacy" if self.legacy else ""
        return (f"charuco:{self.cols}x{self.rows}:{self.square_size:g}{self.units}:"
                f"{self.marker_size:g}{self.units}:{self.dictionary}{tail}")

    def to_json(self) -> dict[str, Any]:
        """The ``board`` object of ``freecal.observations/1``."""
        if self.type == "chessboard":
            return {"type": "chessboard", "cols": self.cols, "rows": self.rows,
                    "square_size": float(self.square_size), "units": self.units}
        marker_size, dictionary = self._markers()
        return {"type": "charuco", "squares_x": self.cols, "squares_y": self.rows,
                "square_size": float(self.square_size), "marker_size": float(marker_size),
                "dictionary": dictionary, "legacy": bool(self.legacy), "units": self.units}

    @classmethod
    def from_json(cls, doc: dict) -> BoardSpec:
        if not isinstance(doc, dict):
            raise FormatError("board: expected an object like {\"type\": \"chessboard\", \"cols\": 9, ...}")
        kind = doc.get("type")
        try:
            if kind == "chessboard":
                return cls("chessboard", _int(doc, "cols"), _int(doc, "rows"), _num(doc, "square_size"),
                           units=str(doc.get("units", "mm")))
            if kind == "charuco":
                legacy = doc.get("legacy", False)
                if not isinstance(legacy, bool):
                    raise FormatError("board.legacy: expected true or false")
                return cls("charuco", _int(doc, "squares_x"), _int(doc, "squares_y"), _num(doc, "square_size"),
                           _num(doc, "marker_size"), str(doc.get("dictionary")), legacy, str(doc.get("units", "mm")))
        except SettingsError as exc:
            raise FormatError(f"board: {exc}") from None
        raise FormatError(f"board.type: expected 'chessboard' or 'charuco', got {kind!r}")


def _grid(spec: str, text: str) -> tuple[int, int]:
    m = re.fullmatch(r"(\d+)\s*[xX×]\s*(\d+)", text)
    if not m:
        raise SettingsError(f"board spec {spec!r}: expected a grid like 9x6, got {text!r}")
    if max(len(m.group(1)), len(m.group(2))) > 6:  # past any bound (and int() refuses 4300 digits)
        raise SettingsError(f"board spec {spec!r}: at most {MAX_SIDE}x{MAX_SIDE} inner corners or squares")
    return int(m.group(1)), int(m.group(2))


def _length(spec: str, text: str) -> float:
    m = re.fullmatch(r"(\d+(?:\.\d*)?|\.\d+)\s*(mm|cm|m|)", text.lower())
    if not m:
        raise SettingsError(f"board spec {spec!r}: expected a length like 25mm, 2.5cm or 0.025m, got {text!r}")
    return float(m.group(1)) * _UNITS[m.group(2)]


def _int(doc: dict, key: str) -> int:
    v = doc.get(key)
    if not isinstance(v, int) or isinstance(v, bool):
        raise FormatError(f"board.{key}: expected an integer, got {v!r}")
    return v


def _num(doc: dict, key: str) -> float:
    v = doc.get(key)
    if not isinstance(v, (int, float)) or isinstance(v, bool):
        raise FormatError(f"board.{key}: expected a number, got {v!r}")
    return float(v)
