"""Timing: samples of a measurement, the timing loop, and fits over measured points."""

from __future__ import annotations

import dataclasses
import math
import statistics
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np


@dataclasses.dataclass
class Stat:
    """Samples of one measurement (ms unless said otherwise): median and min–max spread."""

    samples: list[float]

    @property
    def median(self) -> float:
        return float(statistics.median(self.samples)) if self.samples else math.nan

    @property
    def lo(self) -> float:
        return float(min(self.samples)) if self.samples else math.nan

    @property
    def hi(self) -> float:
        return float(max(self.samples)) if self.samples else math.nan

    @property
    def runs(self) -> int:
        return len(self.samples)

    def fmt(self, digits: int = 1) -> str:
        """``median (min–max)``, or just the value for one run."""
        if not self.samples:
            return "—"
        m = f"{self.median:,.{digits}f}"
        if self.runs == 1:
            return m
        return f"{m} ({self.lo:,.{digits}f}–{self.hi:,.{digits}f})"

    def to_json(self) -> dict:
        return {"median": self.median, "min": self.lo, "max": self.hi, "samples": self.samples}

    @classmethod
    def from_json(cls, d: dict) -> Stat:
        """The Stat that ``to_json`` saved (a report reads its numbers back from the saved data)."""
        return cls(list(d["samples"]))


def measure(
    fn: Callable[[], Any],
    runs: int,
    warmup: int = 1,
    budget_s: float | None = None,
    on_result: Callable[[Any], None] | None = None,
) -> tuple[Stat, Any]:
    """Wall time of ``fn`` in ms over ``runs`` calls after ``warmup`` untimed ones.

    With ``budget_s`` the runs stop early once that much time was spent timing
    (at least one run is always kept): the number of runs is ``Stat.runs``.
    ``on_result`` sees the result of every timed call, outside the timed interval.
    """
    last = None
    for _ in range(warmup):
        last = fn()
    samples: list[float] = []
    spent = 0.0
    for _ in range(max(1, runs)):
        t0 = time.perf_counter()
        last = fn()
        dt = time.perf_counter() - t0
        samples.append(dt * 1e3)
        if on_result is not None:
            on_result(last)
        spent += dt
        if budget_s is not None and spent > budget_s:
            break
    return Stat(samples), last


def crossover_n(ns: Sequence[int], ours: Sequence[float], theirs: Sequence[float]) -> tuple[float, int]:
    """The n from which ``ours`` < ``theirs`` at every larger measured n: ``(n, i)``.

    ``i`` is the first index of the final run where ours is smaller; n interpolates
    log(ours / theirs) = 0 between ``ns[i-1]`` and ``ns[i]`` in log n. ``i = 0``: ours is
    smaller everywhere (n = ns[0]); ``i = len(ns)``: not at the largest n (n = inf).
    """
    faster = [a < b for a, b in zip(ours, theirs, strict=True)]
    if all(faster):
        return float(ns[0]), 0
    if not faster[-1]:
        return math.inf, len(ns)
    i = max(k for k, ok in enumerate(faster) if not ok) + 1
    r0, r1 = math.log(ours[i - 1] / theirs[i - 1]), math.log(ours[i] / theirs[i])
    x0, x1 = math.log(ns[i - 1]), math.log(ns[i])
    x = x0 + (x1 - x0) * r0 / (r0 - r1) if r0 != r1 else x1
    return math.exp(x), i


@dataclasses.dataclass
class RenderTiming:
    """One render configuration measured: wall time per frame and every stage of ``timings``."""

    total: Stat
    stages: dict[str, Stat]
    result: Any  # the last RenderResult
    first_ms: float  # the warm-up frame (shader compile included when the variant was new)

    def to_json(self) -> dict:
        return {
            "total": self.total.to_json(),
            "first_ms": self.first_ms,
            "stages": {k: v.to_json() for k, v in self.stages.items()},
        }


def fit_power(ns: Sequence[float], ys: Sequence[float]) -> tuple[float, float]:
    """Least-squares fit of ``y = a · n^k`` in log–log space: returns ``(k, a)``."""
    x = np.log(np.asarray(ns, dtype=float))
    y = np.log(np.asarray(ys, dtype=float))
    if len(x) < 2:
        return math.nan, math.nan
    k, log_a = np.polyfit(x, y, 1)
    return float(k), float(math.exp(log_a))
