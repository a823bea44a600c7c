"""Shape and value checks in one place (the kornia ``core/check`` idea).

Each helper returns the validated array so that it can be used inline::

    p_cam = as_points(p_cam, "p_cam")          # (N, 3) float64, finite
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from vishap._core.errors import ShapeError

__all__ = ["check_shape", "as_points", "as_array", "check_finite", "as_transform"]


def _fmt(shape: Sequence[int | None]) -> str:
    return "(" + ", ".join("N" if s is None or s < 0 else str(s) for s in shape) + ")"


def check_shape(arr: np.ndarray, shape: Sequence[int | None], name: str) -> np.ndarray:
    """Raise :class:`ShapeError` unless ``arr.shape`` matches ``shape``.

    ``None`` or a negative number in ``shape`` matches any length on that axis.
    """
    if arr.ndim != len(shape) or any(
        s is not None and s >= 0 and a != s for a, s in zip(arr.shape, shape)
    ):
        raise ShapeError(f"{name}: expected shape {_fmt(shape)}, got {tuple(arr.shape)}")
    return arr


def check_finite(arr: np.ndarray, name: str) -> np.ndarray:
    """Raise :class:`ShapeError` if ``arr`` holds NaN or inf."""
    if not np.all(np.isfinite(arr)):
        raise ShapeError(f"{name}: contains NaN or inf")
    return arr


def as_array(x, shape: Sequence[int | None], name: str, *, finite: bool = True) -> np.ndarray:
    """Convert ``x`` to a float64 array of the given shape (and finite unless told otherwise)."""
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ShapeError(f"{name}: not a numeric array ({exc})") from None
    check_shape(arr, shape, name)
    if finite:
        check_finite(arr, name)
    return arr


def as_points(x, name: str, dim: int = 3, *, finite: bool = True) -> np.ndarray:
    """Return ``x`` as an ``(N, dim)`` float64 array; a single point ``(dim,)`` becomes ``(1, dim)``."""
    arr = np.asarray(x, dtype=np.float64) if not isinstance(x, np.ndarray) else x.astype(np.float64, copy=False)
    if arr.ndim == 1:
        arr = arr[None, :]
    check_shape(arr, (None, dim), name)
    if finite:
        check_finite(arr, name)
    return arr


def as_transform(T, name: str) -> np.ndarray:
    """Return ``T`` as a finite 4×4 float64 homogeneous transform with a proper rotation block."""
    from vishap._core.pose import is_rotation

    arr = as_array(T, (4, 4), name)
    if not np.allclose(arr[3], [0.0, 0.0, 0.0, 1.0]):
        raise ShapeError(f"{name}: last row must be [0, 0, 0, 1], got {arr[3].tolist()}")
    if not is_rotation(arr[:3, :3]):
        raise ShapeError(f"{name}: rotation block is not orthonormal with det +1")
    return arr
