"""OpenEXR frames (``format=exr``): the float data of a render, unquantised, in one file.

Written with the OpenEXR project's own Python bindings (the ``OpenEXR`` package), ZIP
compressed, one scan-line part, 32-bit channels:

| mode | channels | content |
|---|---|---|
| ``depth`` | ``Z`` (FLOAT) | t of the primary hit, ``inf`` on a miss |
| ``normal`` | ``R``, ``G``, ``B`` (FLOAT) | the outward normal's x, y, z (0 on a miss) |
| ``primid`` | ``id`` (UINT) | the primitive id as the bits of an int32: −1 (a miss) reads 4294967295 |
| every other | ``R``, ``G``, ``B`` (FLOAT) | the image as the tracer computed it, linear, not clamped or quantised |

The header names the mode (``pocketray:mode``). Open it with ``OpenEXR.File(path).channels()``
(numpy arrays), or ``imageio``/OpenCV/Blender/tev; docs/API.md shows how.
"""

from __future__ import annotations

import io

import numpy as np

from renderer.image.result import RenderResult

MEDIA_TYPE = "image/x-exr"


def channels(result: RenderResult) -> dict[str, np.ndarray]:
    """The EXR channels of ``result`` (see the table above)."""
    if result.mode == "depth":
        return {"Z": np.ascontiguousarray(result.depth, dtype=np.float32)}
    if result.mode == "primid":
        return {"id": np.ascontiguousarray(result.primid, dtype=np.int32).view(np.uint32)}
    rgb = result.normal if result.mode == "normal" else result.image
    return {"RGB": np.ascontiguousarray(rgb, dtype=np.float32)}


def encode_exr(result: RenderResult) -> bytes:
    """The bytes of one EXR file holding ``result``."""
    import OpenEXR

    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, "pocketray:mode": result.mode}
    buf = io.BytesIO()
    OpenEXR.File(header, channels(result)).write(buf)
    return buf.getvalue()


def decode_exr(data: bytes) -> dict[str, np.ndarray]:
    """Channel name → array of an EXR file's bytes (``RGB`` grouped, as OpenEXR reads it)."""
    import OpenEXR

    with OpenEXR.File(io.BytesIO(data)) as f:
        return {name: np.array(ch.pixels) for name, ch in f.channels().items()}
