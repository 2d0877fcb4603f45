"""Errors that are isocube's and Python's built-in ones at once, so that code written for
scikit-image (which raises ``RuntimeError`` and ``ValueError``) and code written for isocube
(``isocube.Error``) both catch them."""

from __future__ import annotations

from typing import Any

import numpy as np

from ._isocube import InputError


class EmptySurfaceError(InputError, RuntimeError):
    """No cell crosses the level: the surface is empty. The message gives the values' range.

    :func:`isocube.extract` raises it unless ``allow_empty=True``;
    :func:`isocube.marching_cubes` where scikit-image raises ``RuntimeError('No surface found
    at the given iso value.')``.

    >>> import numpy as np
    >>> import isocube
    >>> try:
    ...     isocube.extract(np.zeros((3, 3, 3)), 1.0)
    ... except RuntimeError as e:
    ...     print(type(e).__name__, isinstance(e, isocube.Error), str(e).split(" (")[0])
    LevelOutsideError True no cell crosses the level 1: its values range from 0 to 0
    """


class LevelOutsideError(EmptySurfaceError, ValueError):
    """The level lies outside the values' range (or no value is finite): no surface at all.
    Also a ``ValueError``, as scikit-image raises ``ValueError('Surface level must be within
    volume data range.')`` there."""


def _number(x: Any) -> str:
    """A single-precision number as the extension module prints it (shortest, no ``.0``)."""
    return str(np.format_float_positional(np.float32(x), trim="-"))


def empty_surface(level: float, lo: Any, hi: Any, lead: str = "", hint: str = "") -> InputError:
    """The error for an empty surface at `level` over values from `lo` to `hi` (NaN: none
    finite), in the words the extension module uses (``ExtractError::EmptySurface``)."""
    finite = bool(np.isfinite(lo) and np.isfinite(hi))
    if finite:
        why = f"its values range from {_number(lo)} to {_number(hi)}"
    else:
        why = "it has no finite value"
    message = f"{lead}no cell crosses the level {_number(level)}: {why}{hint}"
    if not finite or level < float(lo) or level > float(hi):
        return LevelOutsideError(message)
    return EmptySurfaceError(message)
