"""From the path integrator's linear radiance to the bytes of a png or jpeg (docs/SHADING.md,
"Tone mapping"): scale by 2^exposure, apply the named operator, encode sRGB.

The Whitted integrator's image is display values already (the thesis's Phong sums, clamped): it
is written as it is, without this.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..integrators import ToneMap

# operator name → f(x) for x ≥ 0 (radiance × 2^exposure), in [0, 1] after the final clamp.
OPERATORS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    ToneMap.CLAMP: lambda x: x,  # the radiance itself, 1 and above white
    ToneMap.REINHARD: lambda x: x / (1.0 + x),  # Reinhard et al. 2002, the global operator
    ToneMap.ACES: lambda x: (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14),  # Narkowicz 2015's fit
}


def srgb_encode(c: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1's transfer function of linear values in [0, 1]."""
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(np.maximum(c, 0.0031308), 1.0 / 2.4) - 0.055)


def display_u8(radiance: np.ndarray, operator: str, exposure: float) -> np.ndarray:
    """uint8 sRGB H×W×3 of linear radiance H×W×3: ``floor(255 · srgb(clamp(op(2^e · L))) + 0.5)``."""
    x = np.maximum(np.asarray(radiance, dtype=np.float64), 0.0) * (2.0 ** float(exposure))
    c = np.clip(OPERATORS[operator](x), 0.0, 1.0)
    return np.floor(srgb_encode(c) * 255.0 + 0.5).astype(np.uint8)
