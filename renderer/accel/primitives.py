"""Boxes of primitives, shared by every hierarchy's build."""

from __future__ import annotations

import numpy as np


def sphere_aabbs(centers: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """float32 AABBs, rounded outwards, that hold each sphere in both precisions.

    The GPU sees the sphere rounded to float32, the reference tracer and the
    CPU traversal see it in float64; the two differ by up to one float32 step
    when a centre is not representable, so the box bounds the union of both.
    """
    c64 = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    r64 = np.asarray(radii, dtype=np.float64).reshape(-1, 1)
    c32, r32 = c64.astype(np.float32), r64.astype(np.float32)
    down, up = np.float32(-np.inf), np.float32(np.inf)
    lo = np.minimum(np.nextafter(c32 - r32, down), np.nextafter((c64 - r64).astype(np.float32), down))
    hi = np.maximum(np.nextafter(c32 + r32, up), np.nextafter((c64 + r64).astype(np.float32), up))
    return lo, hi
