"""Calibration boards: the spec string, the ``board`` JSON object, corner geometry.

Spec strings (CLI and API)::

    chessboard:COLSxROWS:SQUARE            e.g. chessboard:9x6:25mm   (inner corners)
    charuco:SQUARESXxSQUARESY:SQUARE:MARKER:DICT[:legacy]
                                           e.g. charuco:5x7:40mm:20mm:DICT_6X6_250
    aprilgrid:TAGSXxTAGSY:TAG:SPACING[:DICT] e.g. aprilgrid:6x6:88mm:0.3   (Kalibr's AprilGrid)

Lengths take a unit suffix (``mm``, ``cm``, ``m``; none means mm) and are
stored in millimetres. Ids follow ``formats.md``: chessboard ``id = row * cols
+ col``; ChArUco ids are OpenCV's ChArUco corner ids; AprilGrid ids are
Kalibr's point indices (``aprilgrid.py``).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import FormatError, SettingsError

TYPES = ("chessboard", "charuco", "aprilgrid")
APRILGRID_DICTIONARY = "DICT_APRILTAG_36h11"   # Kalibr's only tag family
_UNITS = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "": 1.0}
# Bounds on what a spec may ask for (a client's spec runs detection on a shared worker:
# a 1000x1000 ChArUco board held one for minutes on a single small image).
MAX_SIDE = 100                         # inner corners (chessboard) or squares (ChArUco) per side
MIN_LENGTH_MM, MAX_LENGTH_MM = 0.001, 10_000.0   # squares and markers: 1 µm to 10 m
_EXAMPLES = ("e.g. chessboard:9x6:25mm, charuco:5x7:40mm:20mm:DICT_6X6_250 (add :legacy for the old ChArUco "
             "layout) or aprilgrid:6x6:88mm:0.3 (Kalibr's: tags across x down, tag size, spacing ratio)")


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
    aprilgrid:  Kalibr's AprilGrid: ``cols`` × ``rows`` tags (``tag_cols`` × ``tag_rows``),
                ``square_size`` the tag's edge (``tag_size``), ``tag_spacing`` the gap
                between tags over the tag's edge, ``dictionary`` (AprilTag 36h11).

    ``first_marker`` (ChArUco, AprilGrid): the id of the board's first marker; its
    markers are ids ``first_marker`` … ``first_marker + n_markers − 1`` (several
    boards of one dictionary in one image each take their own range).
    """

    type: str
    cols: int
    rows: int
    square_size: float
    marker_size: float | None = None
    dictionary: str | None = None
    legacy: bool = False
    units: str = "mm"
    first_marker: int = 0
    tag_spacing: float | None = None

    def __post_init__(self) -> None:
        if self.type not in TYPES:
            raise SettingsError(f"board type {self.type!r} is unknown; use one of {', '.join(TYPES)} ({_EXAMPLES})")
        least = 2
        what = {"chessboard": "inner corners", "charuco": "squares", "aprilgrid": "tags"}[self.type]
        if self.cols < least or self.rows < least:
            raise SettingsError(f"board {self.cols}x{self.rows}: need at least {least}x{least} {what}")
        if self.cols > MAX_SIDE or self.rows > MAX_SIDE:
            raise SettingsError(f"board {self.cols}x{self.rows}: at most {MAX_SIDE}x{MAX_SIDE} {what}; "
                                "count the board's own (e.g. chessboard:9x6:25mm)")
        self._check_length("tag size" if self.type == "aprilgrid" else "square size", self.square_size)
        if not isinstance(self.first_marker, int) or self.first_marker < 0:
            raise SettingsError(f"first_marker must be a marker id (a whole number >= 0), got {self.first_marker!r}")
        if self.type == "aprilgrid":
            self._check_aprilgrid()
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
            markers, held = self.n_markers, _dictionary_size(self.dictionary)
            if self.first_marker + markers > held:
                raise SettingsError(f"a {self.cols}x{self.rows} ChArUco board has {markers} markers, ids "
                                    f"{self.first_marker}-{self.first_marker + markers - 1}, past what "
                                    f"{self.dictionary} holds ({held}): check the board's size, dictionary and "
                                    "first marker")

    def _check_aprilgrid(self) -> None:
        spacing = self.tag_spacing
        if not isinstance(spacing, (int, float)) or isinstance(spacing, bool) or not 0 < spacing <= 1:
            raise SettingsError(f"AprilGrid tag spacing is the gap between tags over the tag's size, more than 0 "
                                f"and at most 1 (Kalibr's tagSpacing, e.g. 0.3), got {spacing!r}")
        if self.dictionary not in dictionaries() or not self.dictionary.startswith("DICT_APRILTAG"):
            raise SettingsError(f"an AprilGrid's tags are AprilTags: use {APRILGRID_DICTIONARY} (Kalibr's), got "
                                f"{self.dictionary!r}")
        held = _dictionary_size(self.dictionary)
        if self.first_marker + self.n_markers > held:
            raise SettingsError(f"a {self.cols}x{self.rows} AprilGrid has {self.n_markers} tags, ids "
                                f"{self.first_marker}-{self.first_marker + self.n_markers - 1}, past what "
                                f"{self.dictionary} holds ({held})")

    @property
    def n_markers(self) -> int:
        """ArUco markers (ChArUco) or AprilTags (AprilGrid) on the board; 0 on a chessboard."""
        if self.type == "charuco":
            return self.cols * self.rows // 2
        return self.cols * self.rows if self.type == "aprilgrid" else 0

    def _check_length(self, what: str, value: float) -> None:
        mm = value * _UNITS.get(self.units, 1.0) if isinstance(value, (int, float)) else float("nan")
        if not MIN_LENGTH_MM <= mm <= MAX_LENGTH_MM:  # NaN fails too
            raise SettingsError(f"board {what} must be a length from {MIN_LENGTH_MM:g} mm to "
                                f"{MAX_LENGTH_MM / 1000:g} m, got {value!r} {self.units}")

    # ---- geometry -------------------------------------------------------
    @property
    def corner_grid(self) -> tuple[int, int]:
        """(cols, rows) of the board's corner lattice (inner corners; an AprilGrid's tag corners)."""
        if self.type == "chessboard":
            return self.cols, self.rows
        if self.type == "aprilgrid":
            return 2 * self.cols, 2 * self.rows
        return self.cols - 1, self.rows - 1

    @property
    def n_corners(self) -> int:
        c, r = self.corner_grid
        return c * r

    def object_points(self, ids: np.ndarray) -> np.ndarray:
        """Board-frame corners (N, 3), Z = 0, of corner ``ids`` (N,).

        Chessboard corner ``row*cols + col`` sits at ``(col, row) * square``;
        ChArUco corner ``i`` at ``(i % (X-1) + 1, i // (X-1) + 1) * square``,
        exactly OpenCV's ``CharucoBoard.getChessboardCorners()``; AprilGrid
        point ``r * 2X + c`` where Kalibr puts it (``detection/aprilgrid.py``).
        """
        ids = np.asarray(ids, dtype=np.int64).reshape(-1)
        c, _ = self.corner_grid
        if ids.size and (ids.min() < 0 or ids.max() >= self.n_corners):
            raise SettingsError(f"corner ids must lie in [0, {self.n_corners}) for this board")
        if self.type == "aprilgrid":  # Kalibr's createGridPoints (detection/aprilgrid.py): tag corners, y up the page
            step = (1.0 + float(self.tag_spacing or 0.0)) * self.square_size
            row, col = ids // (2 * self.cols), ids % (2 * self.cols)
            return np.stack([(col // 2) * step + (col % 2) * self.square_size,
                             (row // 2) * step + (row % 2) * self.square_size, np.zeros(len(ids))], axis=-1)
        off = 0.0 if self.type == "chessboard" else 1.0
        x, y = (ids % c + off) * self.square_size, (ids // c + off) * self.square_size
        return np.stack([x, y, np.zeros(len(ids))], axis=-1)

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
        ids = np.arange(self.first_marker, self.first_marker + self.n_markers, dtype=np.int32)
        board = cv2.aruco.CharucoBoard((self.cols, self.rows), float(self.square_size), float(marker_size), d, ids)
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
            name = _dictionary_name(name if name.startswith("DICT_") else "DICT_" + name)
            return cls("charuco", cols, rows, _length(spec, parts[2]), _length(spec, parts[3]), name, legacy)
        if kind == "aprilgrid":
            if len(parts) not in (4, 5):
                raise SettingsError(f"board spec {spec!r}: aprilgrid takes TAGSXxTAGSY:TAG:SPACING[:DICTIONARY] "
                                    "(Kalibr's tagCols x tagRows, tagSize, tagSpacing), e.g. aprilgrid:6x6:88mm:0.3")
            cols, rows = _grid(spec, parts[1])
            try:
                spacing = float(parts[3])
            except ValueError:
                raise SettingsError(f"board spec {spec!r}: the tag spacing is a ratio like 0.3, got {parts[3]!r}") from None
            name = parts[4].upper() if len(parts) == 5 else APRILGRID_DICTIONARY
            name = _dictionary_name(name if name.startswith("DICT_") else "DICT_" + name)
            return cls("aprilgrid", cols, rows, _length(spec, parts[2]), None, name, tag_spacing=spacing)
        raise SettingsError(f"board spec {spec!r}: unknown board type {parts[0]!r}; {_EXAMPLES}")

    def to_spec(self) -> str:
        if self.type == "chessboard":
            return f"chessboard:{self.cols}x{self.rows}:{self.square_size:g}{self.units}"
        if self.type == "aprilgrid":
            tail = "" if self.dictionary == APRILGRID_DICTIONARY else f":{self.dictionary}"
            return f"aprilgrid:{self.cols}x{self.rows}:{self.square_size:g}{self.units}:{self.tag_spacing:g}{tail}"
        tail = ":legacy" if self.legacy else ""
        return (f"charuco:{self.cols}x{self.rows}:{self.square_size:g}{self.units}:"
                f"{self.marker_size:g}{self.units}:{self.dictionary}{tail}")

    def to_json(self) -> dict[str, Any]:
        """The ``board`` object of ``freecal.observations/1``."""
        if self.type == "chessboard":
            return {"type": "chessboard", "cols": self.cols, "rows": self.rows,
                    "square_size": float(self.square_size), "units": self.units}
        first = {"first_marker": self.first_marker} if self.first_marker else {}
        if self.type == "aprilgrid":
            return {"type": "aprilgrid", "tag_cols": self.cols, "tag_rows": self.rows,
                    "tag_size": float(self.square_size), "tag_spacing": float(self.tag_spacing or 0.0),
                    "dictionary": self.dictionary, **first, "units": self.units}
        marker_size, dictionary = self._markers()
        return {"type": "charuco", "squares_x": self.cols, "squares_y": self.rows,
                "square_size": float(self.square_size), "marker_size": float(marker_size),
                "dictionary": dictionary, "legacy": bool(self.legacy), **first, "units": self.units}

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
                           _num(doc, "marker_size"), str(doc.get("dictionary")), legacy, str(doc.get("units", "mm")),
                           _int(doc, "first_marker", 0))
            if kind == "aprilgrid":
                return cls("aprilgrid", _int(doc, "tag_cols"), _int(doc, "tag_rows"), _num(doc, "tag_size"), None,
                           _dictionary_name(str(doc.get("dictionary", APRILGRID_DICTIONARY))),
                           units=str(doc.get("units", "mm")), first_marker=_int(doc, "first_marker", 0),
                           tag_spacing=_num(doc, "tag_spacing"))
        except SettingsError as exc:
            raise FormatError(f"board: {exc}") from None
        raise FormatError(f"board.type: expected 'chessboard', 'charuco' or 'aprilgrid', got {kind!r}")


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


def _dictionary_name(name: str) -> str:
    """OpenCV's spelling of a dictionary named in any case (DICT_APRILTAG_36H11 → DICT_APRILTAG_36h11)."""
    known = {n.upper(): n for n in dictionaries()}
    return known.get(name.upper(), name)


def _int(doc: dict, key: str, default: int | None = None) -> int:
    v = doc.get(key, default)
    if not isinstance(v, int) or isinstance(v, bool):
        raise FormatError(f"board.{key}: expected an integer, got {v!r}")
    return v


def _num(doc: dict, key: str) -> float:
    v = doc.get(key)
    if not isinstance(v, (int, float)) or isinstance(v, bool):
        raise FormatError(f"board.{key}: expected a number, got {v!r}")
    return float(v)
