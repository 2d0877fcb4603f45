"""The cube's configurations and their classes under its symmetry group."""

from __future__ import annotations

import numpy as np

from . import _isocube
from ._isocube import InputError

# Integer columns of the polygons table; the others are text.
_POLYGON_NUMBERS = ("config", "class", "representative", "transform")


def tables(
    kind: str = "binary", group: str = "rotations+flip", *, polygons: bool = False
) -> dict[str, np.ndarray]:
    """The configurations of a cube's eight corners and their classes under a symmetry
    group, derived from the group (24 rotations, with the mirror, with the sign flip), as
    ``isocube tables`` prints them: one row per configuration, as NumPy columns.

    Parameters
    ----------
    kind : {'binary', 'ternary'}
        The 256 configurations of corners below / above the level (index Σ 2**i over the
        corners above), or the 6561 with corners on it too (index Σ d_i·3**i, d 0 below,
        1 on, 2 above).
    group : {'rotations', 'rotations+flip', 'all'}
        The symmetries that make two configurations one class: the 24 rotations, those and
        the sign flip, or all 96 (the mirror too).
    polygons : bool
        Instead of the classes, the derived table's polygons for every configuration (one row
        per face-decision pattern): text columns ``digits``, ``decisions``, ``polygons`` and
        integer ``config``, ``class``, ``representative``, ``transform``.

    Returns
    -------
    dict of str to ndarray
        ``config``, ``representative`` (the smallest configuration of the class), ``class``
        (1-based), ``orbit_size``, ``flip_class`` (the class of the sign-flipped
        configuration), ``perm`` ((N, 8) uint8: this configuration's corner ``i`` is the
        representative's corner ``perm[i]``), ``flipped`` and ``reversed`` (whether the
        transform flips signs, and whether it reverses triangles' winding).

    Examples
    --------
    >>> import numpy as np
    >>> import isocube
    >>> groups = ("rotations", "rotations+flip", "all")
    >>> [len(np.unique(isocube.tables("binary", g)["class"])) for g in groups]
    [23, 15, 14]
    >>> t = isocube.tables("ternary", "rotations")
    >>> len(np.unique(t["class"])), len(np.unique(t["class"][t["class"] == t["flip_class"]]))
    (333, 33)
    >>> len(np.unique(isocube.tables("ternary", "rotations+flip")["class"]))
    183
    """
    if polygons:
        text = _isocube.tables(kind, group, True)
        assert isinstance(text, str)
        lines = text.splitlines()
        header = lines[0].split("\t")
        rows = [line.split("\t") for line in lines[1:]]
        columns: dict[str, np.ndarray] = {}
        for i, name in enumerate(header):
            values = [row[i] for row in rows]
            if name in _POLYGON_NUMBERS:
                columns[name] = np.array([int(v) for v in values], dtype=np.int64)
            else:
                columns[name] = np.array(values, dtype=str)
        return columns
    if group not in ("rotations", "rotations+flip", "all"):
        raise InputError(f"group '{group}': expected 'rotations', 'rotations+flip' or 'all'")
    table = _isocube.tables(kind, group, False)
    assert isinstance(table, dict)
    return dict(table)
