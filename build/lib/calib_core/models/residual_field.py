"""Residual-field models (``formats.md``, "Residual-field models"): a
parametric camera gives a pixel ``p``, a smooth field adds an offset there::

    uv = p + f(p),   p = parametric.pixel_of(xn)

The field (``tps.py``, ``mls.py``) is fitted in closed form to the residuals
of the parametric calibration; in Levenberg–Marquardt only the parametric
part moves (the field is held), so ``params`` are the parametric model's.
"""
from __future__ import annotations

from typing import Any, Protocol, Self

import numpy as np

from ..errors import FormatError
from .base import CameraModel, core_inverse_start
from .opencv import OpenCVModel


class Field(Protocol):
    def evaluate(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Offsets (N, 2) at pixels (N, 2) and their gradient ∂f/∂p (N, 2, 2)."""

    def to_json(self) -> dict[str, Any]: ...


class ResidualFieldModel(CameraModel):
    kind = "residual-field"  # subclasses name their distortion.type

    def __init__(self, parametric: OpenCVModel, field: Field):
        self.parametric = parametric
        self.field = field
        self.intrinsics = parametric.intrinsics
        self.base = parametric.base

    @property
    def n_params(self) -> int:
        return self.parametric.n_params

    def params(self) -> np.ndarray:
        return self.parametric.params()

    def with_params(self, x: np.ndarray) -> Self:
        return type(self)(self.parametric.with_params(x), self.field)

    def pixel_of(self, xn: np.ndarray, jacobian: bool = False):
        if not jacobian:
            p = self.parametric.pixel_of(xn)
            return p + self.field.evaluate(p)[0]
        p, d_p, cols, vals = self.parametric.pixel_of(xn, jacobian=True)
        off, grad = self.field.evaluate(p)
        a = grad + np.eye(2)  # ∂uv/∂p
        # Row u of the result mixes rows u and v of the parametric Jacobian
        # (through a[0, 1]), so each row lists both sets of columns.
        both = np.concatenate([cols[:, 0], cols[:, 1]], axis=1)  # (N, 2c)
        new_cols = np.stack([both, both], axis=1)
        new_vals = np.concatenate([a[:, :, 0:1] * vals[:, None, 0], a[:, :, 1:2] * vals[:, None, 1]], axis=2)
        return p + off, a @ d_p, new_cols, new_vals

    def newton_start(self, uv: np.ndarray) -> np.ndarray:
        return core_inverse_start(self, self.parametric, uv, self.field.evaluate(uv)[0])

    def distortion_json(self) -> dict[str, Any]:
        return {"type": self.kind, "parametric": self.parametric.distortion_json(), **self.field.to_json()}

    @classmethod
    def parametric_from_json(cls, intrinsics: np.ndarray, distortion: dict[str, Any], base: str) -> OpenCVModel:
        core = distortion.get("parametric")
        if not isinstance(core, dict) or core.get("type") != "opencv":
            raise FormatError(f"distortion.parametric: a {cls.kind} model sits on an opencv model; "
                              "expected {\"type\": \"opencv\", \"coefficients\": [...]}")
        return OpenCVModel.from_json(intrinsics, core, base)


def float_array(doc: dict[str, Any], key: str, shape_tail: tuple[int, ...], n: int | None = None) -> np.ndarray:
    """``doc[key]`` as a finite float array (n, *shape_tail), or a FormatError naming the field."""
    try:
        arr = np.asarray(doc[key], dtype=np.float64)
    except (KeyError, TypeError, ValueError):
        raise FormatError(f"distortion.{key}: missing or not numeric") from None
    if arr.ndim != 1 + len(shape_tail) or arr.shape[1:] != shape_tail or (n is not None and len(arr) != n):
        want = f"{n if n is not None else 'N'} × {' × '.join(map(str, shape_tail))}" if shape_tail else f"{n} values"
        raise FormatError(f"distortion.{key}: expected {want}, got shape {list(arr.shape)}")
    if not np.all(np.isfinite(arr)):
        raise FormatError(f"distortion.{key}: contains NaN or Inf")
    return arr


def positive(doc: dict[str, Any], key: str) -> float:
    val = doc.get(key)
    if not isinstance(val, (int, float)) or isinstance(val, bool) or not np.isfinite(val) or val <= 0:
        raise FormatError(f"distortion.{key}: expected a positive number, got {val!r}")
    return float(val)
