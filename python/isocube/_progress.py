"""Progress reports for long work: a tqdm bar, a line on stderr, or the caller's function."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, Optional

Report = Optional[Callable[[int, int], object]]


class _Line:
    """A percentage rewritten in place on stderr: what ``progress=True`` shows without tqdm."""

    def __init__(self, what: str) -> None:
        self.what = what
        self.shown = False
        self.started = time.perf_counter()

    def __call__(self, done: int, total: int) -> None:
        percent = 100.0 * done / total if total else 0.0
        elapsed = time.perf_counter() - self.started
        sys.stderr.write(f"\r{self.what}: {percent:5.1f} % ({elapsed:.1f} s)")
        sys.stderr.flush()
        self.shown = True

    def close(self) -> None:
        if self.shown:
            sys.stderr.write("\n")
            sys.stderr.flush()


class _Bar:
    """A tqdm bar counting cells, told where the work is."""

    def __init__(self, what: str) -> None:
        from tqdm.auto import tqdm

        self.bar: Any = tqdm(desc=what, unit="cell", unit_scale=True, leave=False)

    def __call__(self, done: int, total: int) -> None:
        if self.bar.total != total:
            self.bar.total = total
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        if self.bar.total:
            self.bar.update(self.bar.total - self.bar.n)
        self.bar.close()


@contextmanager
def _progress_bar(progress: bool | Callable[[int, int], object], what: str) -> Iterator[Report]:
    """The report function the extension calls for `progress` (``None`` for none), closed
    (the bar finished and removed) when the work ends, however it ends."""
    if progress is False or progress is None:
        yield None
        return
    if callable(progress):
        yield progress
        return
    shown: _Bar | _Line
    try:
        shown = _Bar(what)
    except ImportError:
        shown = _Line(what)
    try:
        yield shown
    finally:
        shown.close()
