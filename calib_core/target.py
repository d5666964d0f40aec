"""Calibration objects of several boards: ``freecal.target/1`` (docs/targets.md, freecal's own).

A target lists boards (each a ``board`` object of ``freecal.observations/1``:
chessboard, ChArUco with its dictionary and first marker, AprilGrid) and,
for each board fixed to the object, its pose in the object's frame:
``P_object = R(rvec) · P_board + tvec`` (OpenCV's Rodrigues convention).
A board with no pose is loose: found and labelled, but kept as a planar view
of its own.

Corner ids of a target run over its boards in order: board ``k``'s corner
``i`` is target corner ``offset_k + i``, ``offset_k`` the number of corners of
the boards before it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from .board import BoardSpec
from .errors import FormatError, SettingsError
from .observations import Observations, View, read_json, write_json

FORMAT = "freecal.target/1"
MAX_BOARDS = 64


@dataclass(frozen=True)
class TargetBoard:
    name: str
    spec: BoardSpec
    pose: tuple[float, ...] | None   # (rvec, tvec) board → object, None: a loose board
    offset: int                      # target id of the board's corner 0

    @property
    def fixed(self) -> bool:
        return self.pose is not None

    def in_object(self, points: np.ndarray) -> np.ndarray:
        """Board-frame points (N, 3) in the object's frame (a fixed board)."""
        if self.pose is None:
            raise ValueError(f"board {self.name!r} has no pose in the target")
        pose = np.asarray(self.pose)
        return Rotation.from_rotvec(pose[:3]).apply(points) + pose[3:]

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"name": self.name, "board": self.spec.to_json()}
        if self.pose is not None:
            out["rvec"], out["tvec"] = list(self.pose[:3]), list(self.pose[3:])
        return out


@dataclass(frozen=True)
class Target:
    boards: tuple[TargetBoard, ...]
    units: str = "mm"

    @property
    def n_corners(self) -> int:
        return sum(b.spec.n_corners for b in self.boards)

    def object_points(self, ids: np.ndarray) -> np.ndarray:
        """Object-frame points (N, 3) of target corner ``ids`` (N,), all on fixed boards."""
        ids = np.asarray(ids, dtype=np.int64).reshape(-1)
        out = np.zeros((len(ids), 3))
        board = self.board_index(ids)
        for k, b in enumerate(self.boards):   # a loop over the boards, each vectorised
            m = board == k
            if m.any():
                out[m] = b.in_object(b.spec.object_points(ids[m] - b.offset))
        return out

    def board_index(self, ids: np.ndarray) -> np.ndarray:
        """Which board (N,) each target corner id (N,) is on."""
        offsets = np.array([b.offset for b in self.boards] + [self.n_corners])
        ids = np.asarray(ids, dtype=np.int64)
        if ids.size and (ids.min() < 0 or ids.max() >= self.n_corners):
            raise SettingsError(f"target corner ids must lie in [0, {self.n_corners})")
        return np.searchsorted(offsets, ids, side="right") - 1

    def split(self, obs: Observations, min_corners: int = 6) -> Observations:
        """The same corners as planar views, one per board seen in a view (at
        least ``min_corners``), in the board's own frame and ids, named
        ``VIEW/BOARD``: what a calibration of one board per view is given."""
        views = []
        for v in obs.views:
            if v.ids is None:
                raise FormatError(f"view {v.name!r} has no ids: its corners cannot be told apart by board")
            board = self.board_index(v.ids)
            for k, b in enumerate(self.boards):
                m = board == k
                if m.sum() >= min_corners:
                    own = v.ids[m] - b.offset
                    views.append(View(f"{v.name}/{b.name}", b.spec.object_points(own), v.image_points[m], own))
        return Observations(obs.image_size, views, None)

    def describe(self) -> str:
        return ", ".join(f"{b.name} ({b.spec.to_spec()})" for b in self.boards)

    # ---- JSON -----------------------------------------------------------
    def to_json(self) -> dict[str, Any]:
        return {"format": FORMAT, "units": self.units, "boards": [b.to_json() for b in self.boards]}

    def save(self, path: str | Path) -> None:
        write_json(path, self.to_json())

    @classmethod
    def load(cls, path: str | Path) -> Target:
        return cls.from_json(read_json(path))

    @classmethod
    def from_json(cls, doc: Any) -> Target:
        if not isinstance(doc, dict):
            raise FormatError("target: expected a JSON object at the top level")
        if doc.get("format") != FORMAT:
            raise FormatError(f"format: expected {FORMAT!r}, got {doc.get('format')!r}; this file is not a freecal "
                              "target (docs/targets.md)")
        units = doc.get("units", "mm")
        if not isinstance(units, str) or units not in ("mm", "cm", "m"):
            raise FormatError(f"units: expected \"mm\", \"cm\" or \"m\", got {units!r}")
        raw = doc.get("boards")
        if not isinstance(raw, list) or not raw:
            raise FormatError("boards: expected a non-empty list of {\"name\", \"board\", \"rvec\", \"tvec\"} objects")
        if len(raw) > MAX_BOARDS:
            raise FormatError(f"boards: {len(raw)} boards, at most {MAX_BOARDS}")
        boards: list[TargetBoard] = []
        offset = 0
        for k, rb in enumerate(raw):
            b = _board(k, rb, units, offset)
            if any(o.name == b.name for o in boards):
                raise FormatError(f"boards[{k}].name: {b.name!r} appears twice; board names must be unique")
            boards.append(b)
            offset += b.spec.n_corners
        target = cls(tuple(boards), units)
        _check_distinct(target)
        return target


def _board(k: int, rb: Any, units: str, offset: int) -> TargetBoard:
    where = f"boards[{k}]"
    if not isinstance(rb, dict):
        raise FormatError(f"{where}: expected an object with name, board, rvec and tvec")
    name = rb.get("name", f"board {k + 1}")
    if not isinstance(name, str) or not name.strip():
        raise FormatError(f"{where}.name: expected a non-empty string")
    board_doc = rb.get("board")
    if not isinstance(board_doc, dict):
        raise FormatError(f"{where}.board: expected a board object (docs/formats.md §1), e.g. "
                          "{\"type\": \"charuco\", \"squares_x\": 5, ...}")
    if board_doc.get("units", units) != units:
        raise FormatError(f"{where}.board.units: {board_doc.get('units')!r} differs from the target's {units!r}; "
                          "give every length of a target in its units")
    try:
        spec = BoardSpec.from_json({**board_doc, "units": units})
    except FormatError as exc:
        raise FormatError(f"{where}.{exc}") from None
    has = ("rvec" in rb, "tvec" in rb)
    if has[0] != has[1]:
        raise FormatError(f"{where}: give both rvec and tvec (the board's pose in the object's frame), or neither "
                          "for a loose board")
    pose = None
    if has[0]:
        pose = tuple(_vector(f"{where}.rvec", rb["rvec"]) + _vector(f"{where}.tvec", rb["tvec"]))
    return TargetBoard(name.strip(), spec, pose, offset)


def _vector(where: str, raw: Any) -> list[float]:
    ok = isinstance(raw, list) and len(raw) == 3 and all(
        isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in raw)
    if not ok:
        raise FormatError(f"{where}: expected three finite numbers, got {raw!r}")
    return [float(x) for x in raw]


def _check_distinct(target: Target) -> None:
    """Two boards whose markers could be confused make every label a guess: refused."""
    ranges: dict[str, list[tuple[int, int, str]]] = {}
    for board in target.boards:
        if board.spec.n_markers:
            ranges.setdefault(str(board.spec.dictionary), []).append(
                (board.spec.first_marker, board.spec.first_marker + board.spec.n_markers, board.name))
    for dictionary, spans in ranges.items():
        spans.sort()
        for (_, hi_a, a), (lo_b, hi_b, b) in zip(spans, spans[1:], strict=False):
            if lo_b < hi_a:
                raise FormatError(
                    f"boards {a!r} and {b!r} share markers {lo_b}-{min(hi_a, hi_b) - 1} of {dictionary}: "
                    "two boards of one dictionary need distinct marker ids (give each its own first_marker)")
