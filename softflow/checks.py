"""Input checks shared by the public functions: clear ValueErrors, never silent casts."""

from __future__ import annotations

import numpy as np


def as_real_array(x, name: str, shape: tuple, *, allow_unbatched: bool = False) -> tuple[np.ndarray, bool]:
    """Return ``x`` as a finite float64 array of ``shape`` (``None`` = any size).

    With ``allow_unbatched`` an array missing the leading batch axis is accepted and
    gets one; the second return value says whether that happened.
    """
    expected = "(" + ", ".join("any" if n is None else str(n) for n in shape) + ")"
    try:
        arr = np.asarray(x)
    except Exception as exc:  # ragged lists and the like
        raise ValueError(f"{name} must be a numeric array of shape {expected}; got {type(x).__name__}") from exc
    if arr.dtype == bool or not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
        raise ValueError(f"{name} must hold real numbers (float or int); got dtype {arr.dtype}")
    added_batch = False
    if allow_unbatched and arr.ndim == len(shape) - 1:
        arr, added_batch = arr[None], True
    if arr.ndim != len(shape) or any(n is not None and n != m for n, m in zip(shape, arr.shape)):
        raise ValueError(f"{name} must have shape {expected}; got {arr.shape}")
    arr = arr.astype(np.float64)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite; it contains NaN or inf")
    return arr, added_batch


def check_choice(value, name: str, choices) -> None:
    if value not in choices:
        raise ValueError(f"{name} must be one of {list(choices)}; got {value!r}")
