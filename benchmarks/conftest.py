"""What the speed suites share."""

from __future__ import annotations

import time
from collections.abc import Callable

import pytest


def _best_of(fn: Callable[[], object], rounds: int) -> float:
    """The least wall time of ``rounds`` calls of ``fn``, in seconds."""
    times = []
    for _ in range(rounds):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


@pytest.fixture
def best_of() -> Callable[[Callable[[], object], int], float]:
    """``best_of(fn, rounds)``: the least wall time of ``rounds`` calls of ``fn``, seconds."""
    return _best_of
