"""Arrays as the extension module takes them: the checks and conversions every call shares."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Union

import numpy as np

from ._isocube import InputError

ArrayLike = Union[np.ndarray, Sequence[Any]]


def _volume(volume: ArrayLike) -> np.ndarray:
    """The volume as a 3-D float32 array, the given one where it already is one (any strides)."""
    a = np.asarray(volume)
    if a.ndim != 3:
        raise InputError(f"the volume must have three dimensions, not {a.ndim}")
    if a.dtype != np.float32 or any(s < 0 or s % 4 for s in a.strides):
        a = np.asarray(a, dtype=np.float32)
        if any(s < 0 or s % 4 for s in a.strides):
            a = np.ascontiguousarray(a)
    return a


def _triple(name: str, value: ArrayLike) -> tuple[float, float, float]:
    t = tuple(float(x) for x in np.asarray(value, dtype=np.float64).ravel())
    if len(t) != 3:
        raise InputError(f"`{name}` must consist of three numbers, not {len(t)}")
    return (t[0], t[1], t[2])


def _matrix(value: ArrayLike) -> list[list[float]]:
    m = np.asarray(value, dtype=np.float64)
    if m.shape != (3, 3):
        raise InputError(f"`direction` must be a 3 × 3 matrix, not of shape {m.shape}")
    return [[float(x) for x in row] for row in m]


def _labels(labels: ArrayLike) -> np.ndarray:
    """A labelled volume as float32 (integers up to 2**24 in magnitude are held exactly)."""
    a = np.asarray(labels)
    if a.ndim != 3:
        raise InputError(f"the labels must have three dimensions, not {a.ndim}")
    if a.dtype.kind in "iub" and a.size and (np.abs(a.astype(np.int64)).max() > 2**24):
        raise InputError("labels beyond 2**24 in magnitude cannot be held exactly as float32")
    return _volume(a)
