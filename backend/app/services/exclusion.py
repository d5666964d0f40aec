"""The views a calibration leaves out (``JobCreate.exclude``): checked against the set, bounded.

Names are the set's image names (an image set: known from the upload on, before detection
ends) or view names (uploaded corners). Each must be one of them, at most once; and a
ready set must keep enough views to calibrate, so the mistake is told now, not by a failed job.
"""
from __future__ import annotations

from calib_core import Observations
from calib_core.pipeline import MIN_VIEWS

from ...base.context import Context
from ..errors import ApiError

MAX_NAME = 255      # characters: stored names are at most 200


def check(ctx: Context, exclude: list[str], row: dict | None, inline: Observations | None) -> list[str]:
    """``exclude`` validated against the set ``row`` (or the inline observations); the names, in order."""
    if not exclude:
        return []
    if len(exclude) > ctx.settings.max_files:
        raise ApiError(422, f"exclude: {len(exclude)} names is over the limit of {ctx.settings.max_files} "
                            "(no set holds more views)")
    long = next((n for n in exclude if len(n) > MAX_NAME), None)
    if long is not None:
        raise ApiError(422, f"exclude: a name of {len(long)} characters is no view of this set (at most {MAX_NAME})")
    twice = sorted({n for n in exclude if exclude.count(n) > 1})
    if twice:
        raise ApiError(422, f"exclude: {', '.join(map(repr, twice[:5]))} given more than once")
    known, views = _names(ctx, row, inline)
    unknown = [n for n in exclude if n not in known]
    if unknown:
        listed = ", ".join(repr(n) for n in unknown[:5]) + (" …" if len(unknown) > 5 else "")
        raise ApiError(422, f"exclude: {listed} {'is' if len(unknown) == 1 else 'are'} not in this set; "
                            "give the names of its images as listed in the set")
    if views is not None:
        left = len([v for v in views if v not in set(exclude)])
        if left < MIN_VIEWS:
            raise ApiError(422, f"leaving out {len(exclude)} view(s) keeps {left} of {len(views)}; "
                                f"a calibration needs at least {MIN_VIEWS}: include some again")
    return list(exclude)


def _names(ctx: Context, row: dict | None, inline: Observations | None) -> tuple[set[str], list[str] | None]:
    """(the names that may be excluded, the set's views when they are known yet)."""
    if inline is not None:
        return {v.name for v in inline.views}, [v.name for v in inline.views]
    assert row is not None
    path = ctx.storage.observations_path(row["id"])
    views = [v.name for v in Observations.load(path).views] if path.exists() else None
    if row["source"] == "images":
        return {im["name"] for im in row["images"]}, views
    return set(views or []), views
