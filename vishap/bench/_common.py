"""Helpers every benchmark uses: robust timing; JSON conversion and chart output from :mod:`vishap._core.results`."""
from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from vishap._core.results import machine_info, new_figure, save_figure, to_jsonable

__all__ = ["time_calls", "median_us", "to_jsonable", "machine_info", "new_figure", "save_figure"]


def time_calls(fn: Callable[[], object], n: int, *, warmup: int = 3) -> np.ndarray:
    """Call ``fn`` ``n`` times and return each call's duration in seconds (after ``warmup`` calls)."""
    for _ in range(warmup):
        fn()
    out = np.empty(n)
    clock = time.perf_counter
    for i in range(n):
        t0 = clock()
        fn()
        out[i] = clock() - t0
    return out


def median_us(durations_s: np.ndarray) -> float:
    return float(np.median(durations_s) * 1e6)
