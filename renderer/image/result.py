"""What a render returns, whichever tracer made it (GPU or reference)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .tonemap import display_u8


@dataclass
class RenderResult:
    """One rendered frame. Row 0 of every array is the top row of the image.

    image:  float32 H×W×3 in [0, 1], what the render mode shows (docs/SHADING.md); of the path
            integrator (``display`` set), linear radiance ≥ 0, unbounded.
    depth:  float32 H×W, t of the primary hit, ``inf`` on a miss.
    primid: int32 H×W, primitive id of the primary hit, -1 on a miss.
    normal: float32 H×W×3, outward normal at the primary hit (0 on a miss).
    mode:   the render mode ``image`` shows.
    timings: milliseconds per stage (``build``, ``upload``, ``trace``, ``read``…).
    stats:  acceleration-structure statistics (JSON-able) or None.
    display: (tone-mapping operator, exposure) when ``image`` is radiance (the path integrator):
            :meth:`image_u8` tone-maps it (renderer/image/tonemap.py), :meth:`array` gives it as it is.
    samples: of the path integrator, the samples per pixel ``image`` is the mean of (an
            accumulation's: all it holds); None otherwise.
    sample_sum: of a frame that went on from an accumulation, float32 H×W×3, the sum of those
            ``samples`` (what the accumulation holds next); None otherwise.
    guides: of a path frame traced for the denoiser (``denoise`` on), (albedo, normal), float32
            H×W×3 each: the means over the frame's samples of their first hit's albedo and normal
            (renderer/image/denoise.py); None otherwise.
    """

    image: np.ndarray
    depth: np.ndarray
    primid: np.ndarray
    normal: np.ndarray
    mode: str
    timings: dict[str, float] = field(default_factory=dict)
    stats: dict[str, Any] | None = None
    display: tuple[str, float] | None = None
    samples: int | None = None
    sample_sum: np.ndarray | None = None
    guides: tuple[np.ndarray, ...] | None = None

    def image_u8(self) -> np.ndarray:
        """The image as uint8 H×W×3: ``floor(255 · clamp(c, 0, 1) + 0.5)``; radiance tone-mapped
        and sRGB-encoded."""
        if self.display is not None:
            return display_u8(self.image, *self.display)
        # The same operations in place on clip's copy: no three more image-sized temporaries.
        x = np.clip(self.image, 0.0, 1.0)
        x *= 255.0
        x += 0.5
        return np.floor(x, out=x).astype(np.uint8)

    def image_rows_rgbx(self) -> np.ndarray | None:
        """The bytes of :meth:`image_u8` as the frame already holds them, where it holds them so:
        uint8 H×W×4 (RGB and a pad byte) with row 0 the *bottom* row (an image-only GPU frame's
        read-back, renderer/gl/frame.py). An encoder reads them flipped and unpadded as it unpacks
        them, without the copy :meth:`image_u8` makes. None: use :meth:`image_u8`."""
        return None

    def array(self) -> np.ndarray:
        """The ``format=npy`` array of this result's mode (docs/FORMATS.md): the result's own
        array where it already has the type (not a copy: a 4096² normal array is 192 MiB)."""
        if self.mode == "depth":
            return self.depth.astype(np.float32, copy=False)
        if self.mode == "primid":
            return self.primid.astype(np.int32, copy=False)
        if self.mode == "normal":
            return self.normal.astype(np.float32, copy=False)
        if self.display is not None:  # the path integrator: linear radiance, float32 H×W×3
            return self.image.astype(np.float32, copy=False)
        return self.image_u8()


# Bytes per pixel of what a frame of the one-pass tracer holds on its way to the client
# (renderer/gl/frame.py, renderer/gl/targets.py): its render target (two RGBA32F attachments,
# or one RGBA8 for a png/jpeg frame at one sample per pixel), the target's read-back, the
# result's arrays (float image and normal, depth, primid) and, of a supersampled frame, the grid
# of sub-pixel images.
TARGET_BYTES_PER_PIXEL = 2 * 4 * 4
TARGET_BYTES_PER_PIXEL_RGBA8 = 4
RESULT_BYTES_PER_PIXEL = 3 * 4 + 3 * 4 + 4 + 4
IMAGE_ONLY_BYTES_PER_PIXEL = 3 + 3  # the 8-bit image cut from the read-back, and its copy for the encoder


def traced_nbytes(width: int, height: int, supersampling: int = 1, image_only: bool = False) -> int:
    """An upper bound of the bytes one frame holds from its render target to its result: the sum
    of the target, its read-back, the result's arrays and a supersampled frame's grid. (They do
    not all live at once — the read-back goes as the result is made — but on llvmpipe the memory
    of a released target stays with the driver until the next target takes it.) The frame budget
    of the service (POCKETRAY_MAX_FRAME_BYTES_IN_FLIGHT) adds these up; the encoded body comes on
    top (server/frames/encode.py)."""
    pixels = int(width) * int(height)
    if image_only:
        return pixels * (2 * TARGET_BYTES_PER_PIXEL_RGBA8 + IMAGE_ONLY_BYTES_PER_PIXEL)
    k = max(1, int(supersampling))
    grid = pixels * k * k * 4 * 4 if k > 1 else 0
    return pixels * (2 * TARGET_BYTES_PER_PIXEL + RESULT_BYTES_PER_PIXEL) + grid
