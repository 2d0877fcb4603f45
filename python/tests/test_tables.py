"""isocube.tables: the classes derived from the cube's symmetry group, checked against their
definition, and the same rows as `isocube tables`."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

import isocube

from .test_save import cli

GROUPS = ["rotations", "rotations+flip", "all"]


def digits(configs: np.ndarray, base: int) -> np.ndarray:
    """Each configuration's eight corner digits (corner i is digit i, least significant first)."""
    return (configs[:, None] // base ** np.arange(8)) % base


@pytest.mark.parametrize("kind,base", [("binary", 2), ("ternary", 3)])
@pytest.mark.parametrize("group", GROUPS)
def test_every_configuration_is_its_representative_moved(kind: str, base: int, group: str) -> None:
    t = isocube.tables(kind, group)
    n = base**8
    assert np.array_equal(t["config"], np.arange(n))
    ours = digits(t["config"], base)
    theirs = digits(t["representative"], base)
    moved = np.take_along_axis(theirs, t["perm"].astype(np.int64), axis=1)
    moved = np.where(t["flipped"][:, None], base - 1 - moved, moved)
    assert np.array_equal(ours, moved)
    # The representative is the smallest of its class, and the orbit sizes count the class.
    classes, counts = np.unique(t["class"], return_counts=True)
    for c, count in zip(classes, counts):
        members = t["config"][t["class"] == c]
        assert t["representative"][members[0]] == members.min()
        assert (t["orbit_size"][members] == count).all()
    # The flipped configuration's class.
    flipped = (base - 1 - ours) @ base ** np.arange(8)
    assert np.array_equal(t["flip_class"], t["class"][flipped])


def test_the_class_counts() -> None:
    count = {
        (k, g): len(np.unique(isocube.tables(k, g)["class"]))
        for k in ("binary", "ternary")
        for g in GROUPS
    }
    assert [count["binary", g] for g in GROUPS] == [23, 15, 14]
    assert count["ternary", "rotations"] == 333 and count["ternary", "rotations+flip"] == 183
    t = isocube.tables("ternary", "rotations")
    assert len(np.unique(t["class"][t["class"] == t["flip_class"]])) == 33


@pytest.mark.parametrize("kind", ["binary", "ternary"])
def test_rows_are_the_command_lines(kind: str) -> None:
    for group in GROUPS:
        t = isocube.tables(kind, group)
        rows = ["config\trepresentative\tclass\torbit_size\tflip_class\tperm\tflipped\treversed"]
        for i in range(len(t["config"])):
            perm = "".join(str(p) for p in t["perm"][i])
            rows.append(
                f"{t['config'][i]}\t{t['representative'][i]}\t{t['class'][i]}\t"
                f"{t['orbit_size'][i]}\t{t['flip_class'][i]}\t{perm}\t"
                f"{int(t['flipped'][i])}\t{int(t['reversed'][i])}"
            )
        printed = subprocess.run(
            [cli(), "tables", f"--{kind}", "--group", group],
            check=True,
            capture_output=True,
            text=True,
        ).stdout
        assert "\n".join(rows) + "\n" == printed
    p = isocube.tables(kind, polygons=True)
    header = list(p)
    rows = ["\t".join(header)]
    for i in range(len(p["config"])):
        rows.append("\t".join(str(p[name][i]) for name in header))
    printed = subprocess.run(
        [cli(), "tables", f"--{kind}", "--polygons"], check=True, capture_output=True, text=True
    ).stdout
    assert "\n".join(rows) + "\n" == printed
    assert p["config"].dtype == np.int64 and p["polygons"].dtype.kind == "U"


def test_bad_names_are_refused() -> None:
    with pytest.raises(isocube.InputError, match="kind"):
        isocube.tables("quaternary")
    with pytest.raises(isocube.InputError, match="group"):
        isocube.tables("binary", "reflections")
