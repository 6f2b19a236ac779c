"""Helpers shared by test modules (fixtures live in the conftest.py files)."""

from __future__ import annotations

import math
from pathlib import Path

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
