"""Which moment (frame) each view was taken at: formats.md §4."""
from __future__ import annotations

import re
from collections.abc import Collection, Mapping

from ..errors import DataError
from ..observations import View

_DIGITS = re.compile(r"\d+")


def frame_of(view: View) -> str:
    """The view's ``frame``, or else the last run of digits in its name
    (``left07.jpg`` → ``07``)."""
    if view.frame is not None:
        return view.frame
    runs = _DIGITS.findall(view.name)
    if not runs:
        raise DataError(f"view {view.name!r} names no frame: give it a \"frame\" in the observations, or number the "
                        "images (left07.jpg and right07.jpg are frame 07)")
    return runs[-1]


def frames_of(camera: str, views: list[View]) -> list[str]:
    """Each view's frame; a DataError if one camera has two views of one frame."""
    frames = [frame_of(v) for v in views]
    seen: dict[str, str] = {}
    for v, f in zip(views, frames, strict=True):
        if f in seen:
            raise DataError(f"camera {camera!r}: views {seen[f]!r} and {v.name!r} are both frame {f!r}; "
                            "a camera sees each frame once (set \"frame\" in the observations to tell them apart)")
        seen[f] = v.name
    return frames


def unlinked(frames: Mapping[str, Collection[str]], reference: str) -> list[str]:
    """The cameras (of camera → its frames) that no chain of shared frames
    links to ``reference``: a rig cannot place them."""
    linked, todo = {reference}, [reference]
    while todo:
        here = set(frames[todo.pop()])
        for name, seen in frames.items():
            if name not in linked and here.intersection(seen):
                linked.add(name)
                todo.append(name)
    return [name for name in frames if name not in linked]


def padding_hint(frames: Mapping[str, Collection[str]], reference: str) -> str:
    """Words for cameras ``unlinked`` leaves out that numbers would link (left7.jpg, right007.jpg):
    frames are names, compared as written."""
    as_numbers = {name: {str(int(f)) if f.isdigit() else f for f in seen} for name, seen in frames.items()}
    if len(unlinked(as_numbers, reference)) < len(unlinked(frames, reference)):
        return (" (frames are compared as written: '7' and '007' are different frames; number every camera's "
                "images alike)")
    return ""
