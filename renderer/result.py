"""What a render returns, whichever tracer made it (GPU or reference)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class RenderResult:
    """One rendered frame. Row 0 of every array is the top row of the image.

    image:  float32 H×W×3 in [0, 1], what the render mode shows (docs/SHADING.md).
    depth:  float32 H×W, t of the primary hit, ``inf`` on a miss.
    primid: int32 H×W, primitive id of the primary hit, -1 on a miss.
    normal: float32 H×W×3, outward normal at the primary hit (0 on a miss).
    mode:   the render mode ``image`` shows.
    timings: milliseconds per stage (``build``, ``upload``, ``trace``, ``read``…).
    stats:  acceleration-structure statistics (JSON-able) or None.
    """
    image: np.ndarray
    depth: np.ndarray
    primid: np.ndarray
    normal: np.ndarray
    mode: str
    timings: dict[str, float] = field(default_factory=dict)
    stats: dict[str, Any] | None = None

    def image_u8(self) -> np.ndarray:
        """The image as uint8 H×W×3: ``floor(255 · clamp(c, 0, 1) + 0.5)``."""
        return np.floor(np.clip(self.image, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)

    def array(self) -> np.ndarray:
        """The ``format=npy`` array of this result's mode (docs/FORMATS.md)."""
        if self.mode == "depth":
            return self.depth.astype(np.float32)
        if self.mode == "primid":
            return self.primid.astype(np.int32)
        if self.mode == "normal":
            return self.normal.astype(np.float32)
        return self.image_u8()
