"""Observations: board corners per view, read and written as ``freecal.observations/1``.

See ``formats.md`` §1. Pixel convention: origin at the centre of the top-left
pixel, x right, y down (OpenCV's).
"""
from __future__ import annotations

import json
import math
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import FormatError

Circle = tuple[float, float, float]  # a lens's image circle: cx, cy, radius in pixels

FORMAT = "freecal.observations/1"
# Board coordinates past this (1000 km in mm) are a wrong value, and at 1e150 the solver's SVD fails to converge.
MAX_OBJECT_COORDINATE = 1e9


@dataclass
class View:
    """One image's corners.

    object_points: (N, 3) float64 board-frame coordinates, in board units.
    image_points:  (N, 2) float64 observed pixels.
    ids:           (N,) int64 board corner ids, or None (matched by position).
    frame:         the moment the image was taken, for rigs (formats.md §4), or None.
    """

    name: str
    object_points: np.ndarray
    image_points: np.ndarray
    ids: np.ndarray | None = None
    frame: str | None = None

    def __len__(self) -> int:
        return len(self.image_points)

    def subset(self, mask: np.ndarray) -> View:
        ids = None if self.ids is None else self.ids[mask]
        return View(self.name, self.object_points[mask], self.image_points[mask], ids, self.frame)


@dataclass
class Observations:
    """All views of one camera. ``image_size`` is (width, height) in pixels."""

    image_size: tuple[int, int]
    views: list[View]
    board: dict[str, Any] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def n_points(self) -> int:
        return sum(len(v) for v in self.views)

    @property
    def image_circle(self) -> Circle | None:
        """The lens's lit disc (cx, cy, radius) px where its image circle ends inside the
        frame, as detection records it (``extra["image_circle"]``); None: lit to the border."""
        return circle_from_json(self.extra.get("image_circle"))

    def view(self, name: str) -> View:
        for v in self.views:
            if v.name == name:
                return v
        raise KeyError(name)

    def select(self, names: list[str]) -> Observations:
        """The views named, in that order."""
        return Observations(self.image_size, [self.view(n) for n in names], self.board, dict(self.extra))

    # ---- JSON -----------------------------------------------------------
    def to_json(self) -> dict[str, Any]:
        views = []
        for v in self.views:
            d: dict[str, Any] = {
                "name": v.name,
                "object_points": v.object_points.tolist(),
                "image_points": v.image_points.tolist(),
            }
            if v.ids is not None:
                d["ids"] = v.ids.tolist()
            if v.frame is not None:
                d["frame"] = v.frame
            views.append(d)
        out: dict[str, Any] = {"format": FORMAT, "image_size": list(self.image_size)}
        if self.board is not None:
            out["board"] = self.board
        out["views"] = views
        # Extra fields (formats.md allows them): e.g. "target", the freecal.target/1 the views come from.
        out.update({k: v for k, v in self.extra.items() if k not in out})
        return out

    @classmethod
    def from_json(cls, doc: Any) -> Observations:
        try:
            return cls._from_json(doc)
        except (TypeError, ValueError, OverflowError) as exc:  # a shape no check below foresaw
            raise FormatError(f"observations: malformed document ({type(exc).__name__}: {exc}); "
                              f"expected {FORMAT} as in docs/formats.md") from None

    @classmethod
    def _from_json(cls, doc: Any) -> Observations:
        if not isinstance(doc, dict):
            raise FormatError("observations: expected a JSON object at the top level")
        fmt = doc.get("format")
        if fmt != FORMAT:
            raise FormatError(
                f"format: expected {FORMAT!r}, got {fmt!r}; this file is not freecal observations "
                "(or was written by a newer version)"
            )
        image_size = _image_size(doc.get("image_size"))
        board = doc.get("board")
        if board is not None and not isinstance(board, dict):
            raise FormatError("board: expected an object like {\"type\": \"chessboard\", ...} or no field at all")
        raw_views = doc.get("views")
        if not isinstance(raw_views, list) or not raw_views:
            raise FormatError("views: expected a non-empty list of views")
        views, seen = [], set()
        for k, rv in enumerate(raw_views):
            view = _view(k, rv)
            _inside(k, rv, view, image_size)
            if view.name in seen:
                raise FormatError(f"views[{k}].name: {view.name!r} appears twice; view names must be unique")
            seen.add(view.name)
            views.append(view)
        extra = {k: v for k, v in doc.items() if k not in ("format", "image_size", "board", "views")}
        return cls(image_size, views, board, extra)

    @classmethod
    def load(cls, path: str | Path) -> Observations:
        return cls.from_json(read_json(path))

    def save(self, path: str | Path) -> None:
        write_json(path, self.to_json())


def read_json(path: str | Path) -> Any:
    """Read a JSON file, turning every failure into a FormatError that names the file."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise FormatError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise FormatError(f"{path}: cannot be read as UTF-8 text ({exc})") from None
    return parse_json(text, str(path))


# The deepest freecal document nests 5 levels (document > views > view > points > point); every
# walk after parsing (checks, messages that quote a value) then stays far from Python's recursion limit.
MAX_DEPTH = 32
# The only way JSON text gives a lone surrogate: a \uD800-\uDFFF escape (UTF-8 decoding refuses encoded ones).
SURROGATE_ESCAPE = re.compile(r"\\u[dD][89a-fA-F]")


def parse_json(text: str, source: str) -> Any:
    """JSON text from ``source`` (a file name, "standard input"), a FormatError naming it if it is not JSON,
    nests more than ``MAX_DEPTH`` levels, has an integer Python will not convert, or text that is not Unicode."""
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise FormatError(f"{source}: not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})") from None
    except RecursionError:
        doc = None
        deep = True
    except ValueError:  # an integer of more than sys.get_int_max_str_digits() digits
        raise FormatError(f"{source}: a number is too long (over {sys.get_int_max_str_digits()} digits); no "
                          "freecal field needs more than a few: check the program that wrote the file") from None
    else:
        deep = not depth_within(doc, MAX_DEPTH)
    if deep:
        raise FormatError(f"{source}: nests arrays and objects more than {MAX_DEPTH} levels deep: "
                          "no freecal document needs that many; give the document itself")
    bad = not_unicode(doc) if SURROGATE_ESCAPE.search(text) else None
    if bad is not None:
        raise FormatError(f"{source}: {bad or 'the document'}: not valid Unicode text (an unpaired surrogate "
                          "escape such as \\ud800); other programs cannot read it either: fix the text")
    return doc


def depth_within(doc: Any, limit: int) -> bool:
    """Whether ``doc`` nests at most ``limit`` levels (iterative: no recursion, whatever the depth)."""
    stack = [(doc, 1)]
    while stack:
        value, depth = stack.pop()
        if depth > limit:
            return False
        if not isinstance(value, (dict, list)):  # a document may be a bare null, number or string
            continue
        children = value.values() if isinstance(value, dict) else value
        stack.extend([(c, depth + 1) for c in children if isinstance(c, (dict, list))])
    return True


def not_unicode(doc: Any) -> str | None:
    """Where (``views[2].name``; "" for the document itself) the first string or key holding a lone
    surrogate ("\\ud800": valid JSON, but no character; it cannot be printed, stored or sent as UTF-8)
    is, or None, in the document's order. Iterative, like ``depth_within``; only non-ASCII text is
    encoded to check."""
    stack: list[tuple[Any, str]] = [(doc, "")]
    while stack:
        value, where = stack.pop()
        if isinstance(value, str):
            if not _valid(value):
                return where
            continue
        if isinstance(value, dict):
            bad_key = next((k for k in value if not _valid(k)), None)
            if bad_key is not None:
                return f"{where}.{bad_key.encode('utf-8', 'backslashreplace').decode()}".lstrip(".") + " (a key)"
            children = [(v, f"{where}.{k}".lstrip(".")) for k, v in value.items()]
        elif isinstance(value, list):
            children = [(v, f"{where}[{i}]") for i, v in enumerate(value)]
        else:
            continue
        stack.extend(reversed([c for c in children if isinstance(c[0], (str, dict, list))]))  # popped in order
    return None


def _valid(text: str) -> bool:
    if text.isascii():
        return True
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def json_text(doc: Any) -> str:
    """A document as freecal writes its files: strict JSON (no NaN), one space of indent, a final newline."""
    return json.dumps(doc, indent=1, allow_nan=False) + "\n"


def write_json(path: str | Path, doc: Any) -> None:
    """Write atomically: a reader never sees a half-written file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json_text(doc), encoding="utf-8")
    tmp.replace(path)


def _image_size(raw: Any) -> tuple[int, int]:
    ok = (
        isinstance(raw, list)
        and len(raw) == 2
        and all(_is_number(x) for x in raw)
        and all(float(x).is_integer() and 0 < x < 2**31 for x in raw)
    )
    if not ok:
        raise FormatError(f"image_size: expected [width, height] as two positive integers, got {raw!r}")
    return int(raw[0]), int(raw[1])


def _where(k: int, rv: Any) -> str:
    name = rv.get("name") if isinstance(rv, dict) else None
    return f"views[{k}]" + (f" ({name!r})" if isinstance(name, str) else "")


def _points(where: str, key: str, raw: Any, dim: int) -> np.ndarray:
    what = "[x, y]" if dim == 2 else "[X, Y, Z]"
    if not isinstance(raw, list):
        raise FormatError(f"{where}.{key}: expected a list of {what} points")
    for j, p in enumerate(raw):
        if not (isinstance(p, list) and len(p) == dim and all(_is_number(x) for x in p)):
            raise FormatError(f"{where}.{key}[{j}]: expected {what} numbers, got {p!r}")
        if not all(math.isfinite(x) for x in p):
            raise FormatError(f"{where}.{key}[{j}]: {p!r} is not finite (NaN or Inf)")
    points = np.asarray(raw, dtype=np.float64).reshape(-1, dim)
    if dim == 3 and len(points) and np.abs(points).max() > MAX_OBJECT_COORDINATE:
        j = int(np.argmax(np.abs(points).max(axis=1)))
        raise FormatError(f"{where}.{key}[{j}]: {raw[j]!r} is out of range: board coordinates are at most "
                          f"{MAX_OBJECT_COORDINATE:g} board units from the origin (check the units: mm or m)")
    return points


def _inside(k: int, rv: Any, view: View, image_size: tuple[int, int]) -> None:
    """Observed corners lie in the image; one a whole image width or height outside is a wrong value."""
    w, h = image_size
    far = ((view.image_points < [-w, -h]) | (view.image_points > [2 * w, 2 * h])).any(axis=1)
    if far.any():
        j = int(np.argmax(far))
        raise FormatError(f"{_where(k, rv)}.image_points[{j}]: {view.image_points[j].tolist()} lies far outside "
                          f"the {w}x{h} image; image points are pixels of that image (check image_size and units)")


def _is_number(x: Any) -> bool:
    """A JSON number that fits a float64 (10**400 does not)."""
    if not isinstance(x, (int, float)) or isinstance(x, bool):
        return False
    try:
        float(x)
    except OverflowError:
        return False
    return True


def _view(k: int, rv: Any) -> View:
    where = _where(k, rv)
    if not isinstance(rv, dict):
        raise FormatError(f"{where}: expected an object with name, object_points, image_points")
    name = rv.get("name")
    if not isinstance(name, str) or not name:
        raise FormatError(f"{where}.name: expected a non-empty string")
    obj = _points(where, "object_points", rv.get("object_points"), 3)
    img = _points(where, "image_points", rv.get("image_points"), 2)
    if len(obj) != len(img):
        raise FormatError(
            f"{where}: object_points has {len(obj)} points but image_points has {len(img)}; "
            "they must pair up one to one"
        )
    ids = rv.get("ids")
    if ids is not None:
        if not (isinstance(ids, list) and all(isinstance(i, int) and not isinstance(i, bool) and 0 <= i < 2**63
                                              for i in ids)):
            raise FormatError(f"{where}.ids: expected a list of non-negative integers")
        if len(ids) != len(img):
            raise FormatError(f"{where}.ids: has {len(ids)} entries for {len(img)} points")
        if len(set(ids)) != len(ids):
            raise FormatError(f"{where}.ids: a corner id appears twice")
        ids = np.asarray(ids, dtype=np.int64)
    frame = rv.get("frame")
    if frame is not None and (not isinstance(frame, str) or not frame):
        raise FormatError(f"{where}.frame: expected a non-empty string naming the moment the image was taken")
    return View(name, obj, img, ids, frame)


def circle_from_json(doc: object) -> Circle | None:
    """``{"cx", "cy", "radius"}`` (``coverage.circle_json``) read back; None for anything else
    (no circle recorded, or another tool's field)."""
    try:
        return float(doc["cx"]), float(doc["cy"]), float(doc["radius"])  # type: ignore[index]
    except (TypeError, KeyError, ValueError):
        return None
