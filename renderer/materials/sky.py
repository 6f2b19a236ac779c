"""A procedural daylight sky as an equirectangular HDR image (renderer/materials/envmap.py's convention), the
environment ``{"image": "sky"}`` of scene JSON and the thesis scenarios' ``sky`` option.

A zenith → horizon gradient above the horizon, a darker ground below it (blended over a few
degrees, so the image has no edge there), a glow around the sun and the sun's disk: a bright, small
light, the case importance sampling exists for. Made at SKY_WIDTH × SKY_HEIGHT texels (1.4° each),
the sun's disk SUN_RADIUS_DEG wide so that it covers a few texels; nothing is stored for it.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np

SKY_WIDTH, SKY_HEIGHT = 256, 128
ZENITH = np.array([0.15, 0.32, 0.75])  # radiance, linear RGB
HORIZON = np.array([0.75, 0.82, 0.92])
GROUND = np.array([0.22, 0.2, 0.17])
SUN = np.array([1.0, 0.95, 0.85]) * 350.0  # ≈ 3 of irradiance at normal incidence, the sky's ≈ 1.6
SUN_RADIUS_DEG = 3.0
GLOW_DEG = 10.0  # the glow's angular standard deviation
# The sun: 40° above the horizon, behind the thesis scenarios' camera and to its left.
SUN_DIRECTION = np.array([-0.45, math.sin(math.radians(40.0)), 0.55])
SUN_DIRECTION = SUN_DIRECTION / np.linalg.norm(SUN_DIRECTION)


def sky_radiance(d: np.ndarray) -> np.ndarray:
    """The sky's radiance (…, 3) along unit directions ``d`` (…, 3), before it is made texels."""
    d = np.asarray(d, dtype=np.float64)
    y = d[..., 1:2]
    up = np.sqrt(np.clip(y, 0.0, 1.0))
    sky = HORIZON * (1.0 - up) + ZENITH * up
    ground = GROUND + (HORIZON - GROUND) * np.exp(np.minimum(y, 0.0) * 30.0)
    out = np.where(y >= 0.0, sky, ground)
    cos = np.clip(d @ SUN_DIRECTION, -1.0, 1.0)[..., None]
    angle = np.degrees(np.arccos(cos))
    out = out + 2.0 * HORIZON * np.exp(-0.5 * (angle / GLOW_DEG) ** 2)
    return np.where(angle <= SUN_RADIUS_DEG, out + SUN, out)


@cache
def sky_texels(width: int = SKY_WIDTH, height: int = SKY_HEIGHT) -> np.ndarray:
    """float32 (height, width, 3), read-only: the sky at each texel's direction (column i at
    u = (i + ½) / W, row j at v = j / (H − 1))."""
    u = (np.arange(width) + 0.5) / width
    v = np.arange(height) / (height - 1)
    phi, theta = 2 * np.pi * u[None, :], np.pi * v[:, None]
    d = np.stack(np.broadcast_arrays(np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi)), axis=-1)
    out = np.ascontiguousarray(sky_radiance(d), dtype=np.float32)
    out.setflags(write=False)
    return out
