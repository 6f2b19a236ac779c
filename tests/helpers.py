"""Helpers shared by test modules (fixtures live in the conftest.py files)."""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import Callable, Coroutine
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import HealthCheck

ROOT = Path(__file__).resolve().parent.parent

# Settings of the property tests: builds of large random scenes are slow on two cores, and
# a deadline would turn a slow example into a flaky failure (no timing assertions).
HYP = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """PSNR in dB of two uint8 images (inf when they are equal)."""
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return math.inf if mse == 0 else 10.0 * math.log10(255.0**2 / mse)


def run_coroutine(coro: Coroutine[Any, Any, Any]) -> Any:
    """``asyncio.run(coro)`` in a thread of its own: Playwright's sync API (the browser tests'
    session fixture) keeps an event loop running in the main thread of the worker that ran
    them, where ``asyncio.run`` refuses to start."""
    with ThreadPoolExecutor(1) as pool:
        return pool.submit(asyncio.run, coro).result()


def load_scaled(quiet_s: float, reference_s: float, factor: float) -> float:
    """A wall-clock bound of a pass/fail test that a loaded machine does not break: ``quiet_s``,
    the bound on a quiet machine, or ``factor`` times ``reference_s`` — a comparable, short piece of
    the same work timed in the test itself just before, on the machine as loaded as it is then —
    when that is longer. The defect a bound catches must take more than ``factor`` such pieces."""
    return max(quiet_s, factor * reference_s)


def median_s(call: Callable[[], object], n: int = 5) -> float:
    """The median wall-clock seconds of ``n`` calls of ``call``."""
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        call()
        times.append(time.perf_counter() - t0)
    return sorted(times)[n // 2]
