"""The View's HTTP side: encode a RenderResult and describe it in headers.

Formats (docs/FORMATS.md): ``png`` and ``jpeg`` carry what the render mode shows as 8-bit
RGB; ``npy`` is one ``.npy`` array (colour uint8 H×W×3, depth float32 H×W with
inf on a miss, primid int32 H×W with −1 on a miss, normal float32 H×W×3); ``exr`` is one
OpenEXR file of float channels (colour linear and unquantised; :mod:`server.frames.exr`).

Headers of every frame:

- ``Server-Timing``: ``queue``, ``pose`` (animated scenes), ``update``, ``build``,
  ``upload``, ``trace``, ``read``, ``encode``, ``total`` as ``name;dur=<ms>`` (total =
  admission to encoded bytes). ``update`` is the time the method took to follow the
  frame — rebuild, refit or selective rebuild, per the ``update`` setting — and equals
  ``build`` (kept for clients that read it);
- ``X-Session-Version`` (frames of a session), ``X-Method``, ``X-Stats``
  (compact JSON of the main BIH statistics), ``X-Frame-Part`` (``preview`` or ``final``:
  the parts of a progressive frame, docs/API.md; ``refine``: a refinement stream's part before its
  last, whose ``X-Refine`` says where the stream stands), ``X-Samples`` (the samples per pixel the image
  is the mean of: an accumulation's, all it holds) and ``Access-Control-Expose-Headers``.
"""

from __future__ import annotations

import io
import json
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from PIL import Image

from renderer.image.result import RenderResult

from ..contract.headers import EXPOSED, TIMING_NAMES
from .exr import MEDIA_TYPE as EXR_MEDIA_TYPE, encode_exr

MEDIA_TYPES = {"png": "image/png", "jpeg": "image/jpeg", "npy": "application/octet-stream", "exr": EXR_MEDIA_TYPE}
STATS_HEADER_KEYS = (
    "method",
    "time",
    "scheme",
    "n_spheres",
    "primitives",
    "inner_nodes",
    "leaves",
    "depth_max",
    "optimized_nodes",
    "forced_leaves",
    "build_ms",
)


@dataclass
class Frame:
    """Encoded image plus what the headers say about it. Timings in ms."""

    body: bytes
    media_type: str
    method: str
    timings: dict[str, float]
    stats: dict[str, Any] | None
    version: int | None = None
    width: int = 0
    height: int = 0
    final: bool = True  # False: the preview of a progressive frame, the final image follows
    samples: int | None = None  # samples per pixel the image is the mean of (an accumulation's: all it holds)


def encode(result: RenderResult, fmt: str, quality: int, png_level: int = 1) -> tuple[bytes, float]:
    """(bytes, encode ms) of ``result`` in ``fmt`` (png | jpeg | npy | exr); quality 1 … 100 for jpeg."""
    t0 = time.perf_counter()
    buf = io.BytesIO()
    if fmt == "exr":
        return encode_exr(result), (time.perf_counter() - t0) * 1e3
    if fmt == "npy":
        return npy_bytes(result.array()), (time.perf_counter() - t0) * 1e3
    else:
        img = pil_image(result)
        if fmt == "jpeg":
            img.save(buf, format="JPEG", quality=int(quality))
        else:
            img.save(buf, format="PNG", compress_level=int(png_level))
    return buf.getvalue(), (time.perf_counter() - t0) * 1e3


def pil_image(result: RenderResult) -> Image.Image:
    """``result.image_u8()`` as a PIL image. PIL keeps an RGB image as four bytes a pixel and
    unpacks whatever it is given into them: from the read-back of an image-only frame (RGBA, bottom
    row first; RenderResult.image_rows_rgbx) its raw decoder takes the rows in reverse and skips the
    pad byte in that one pass, so the flipped RGB copy image_u8 would make first is never made."""
    rows = result.image_rows_rgbx()
    if rows is None:
        return Image.fromarray(result.image_u8(), "RGB")
    h, w = rows.shape[:2]
    return Image.frombytes("RGB", (w, h), np.ascontiguousarray(rows), "raw", "RGBX", 0, -1)


NPY_CHUNK_BYTES = 1 << 20


def npy_bytes(array: np.ndarray) -> bytes:
    """What ``np.save`` writes for ``array`` (format 1.0), with the array's bytes copied once, into
    the body: np.save first copied a strided array whole, then the result, chunk by chunk, into its
    buffer (a 4096² normal frame, 192 MiB, was there three times). Here rows go into the buffer
    1 MiB at a time, straight from the array (a copy only of a strided chunk), and getvalue() hands
    over the buffer itself."""
    buf = io.BytesIO()
    header = np.lib.format.header_data_from_array_1_0(array)
    header["fortran_order"] = False  # the rows below are written in C order, whatever the strides
    np.lib.format.write_array_header_1_0(buf, header)
    if array.ndim == 0 or array.size == 0:
        buf.write(array.tobytes())
        return buf.getvalue()
    rows = max(1, NPY_CHUNK_BYTES // max(1, array[0].nbytes))
    for i in range(0, len(array), rows):
        buf.write(np.ascontiguousarray(array[i : i + rows]).data)
    return buf.getvalue()


# Bytes per pixel of the npy array of each mode (docs/FORMATS.md); the other modes are 8-bit RGB.
NPY_BYTES_PER_PIXEL = {"depth": 4, "primid": 4, "normal": 12, "radiance": 12}  # radiance: the path integrator's


def encoded_nbytes(fmt: str, mode: str, width: int, height: int) -> int:
    """At most the bytes :func:`encode` adds while it encodes a frame and that its body holds
    after: npy, the array itself; exr, the channels' contiguous copy and the file (compressed,
    at most as large); png and jpeg, the 8-bit image PIL holds (4 bytes a pixel) and a body of
    at most the raw RGB bytes."""
    pixels = int(width) * int(height)
    if fmt == "npy":
        return pixels * NPY_BYTES_PER_PIXEL.get(mode, 3)
    if fmt == "exr":
        return 2 * pixels * NPY_BYTES_PER_PIXEL.get(mode, 12)
    return pixels * (4 + 3)


def server_timing(timings: dict[str, float]) -> str:
    return ", ".join(f"{k};dur={timings[k]:.2f}" for k in TIMING_NAMES if k in timings)


def stats_header(stats: dict[str, Any] | None) -> str:
    picked = {
        k: (round(v, 3) if isinstance(v, float) else v) for k, v in (stats or {}).items() if k in STATS_HEADER_KEYS
    }
    return json.dumps(picked, separators=(",", ":"))


def frame_headers(frame: Frame) -> dict[str, str]:
    headers = {
        "Server-Timing": server_timing(frame.timings),
        "X-Method": frame.method,
        "X-Stats": stats_header(frame.stats),
        "Cache-Control": "no-store",
        "Access-Control-Expose-Headers": ", ".join(EXPOSED),
    }
    if frame.version is not None:
        headers["X-Session-Version"] = str(frame.version)
    headers["X-Frame-Part"] = "final" if frame.final else "preview"
    if frame.samples is not None:
        headers["X-Samples"] = str(frame.samples)
    return headers


FRAME_RESPONSE_DOC: dict[str, Any] = {
    "description": "the frame: PNG, JPEG, one .npy array (format=npy) or an OpenEXR file of float channels "
    "(format=exr)",
    "content": {
        "image/png": {"schema": {"type": "string", "format": "binary"}},
        "image/jpeg": {"schema": {"type": "string", "format": "binary"}},
        "application/octet-stream": {"schema": {"type": "string", "format": "binary"}},
        "multipart/mixed": {
            "schema": {"type": "string", "format": "binary"},
            "description": "progressive=1: the preview part, then the final part",
        },
        EXR_MEDIA_TYPE: {"schema": {"type": "string", "format": "binary"}},
    },
    "headers": {
        "Server-Timing": {
            "description": "queue, pose, update, build, upload, trace, read, encode, total as name;dur=ms",
            "schema": {"type": "string"},
        },
        "X-Method": {"description": "acceleration method used", "schema": {"type": "string"}},
        "X-Stats": {
            "description": "compact JSON: method, primitives, inner_nodes, leaves, depth_max, …",
            "schema": {"type": "string"},
        },
        "X-Session-Version": {
            "description": "session version the frame shows (session frames only)",
            "schema": {"type": "string"},
        },
        "X-Samples": {
            "description": "samples per pixel the image is the mean of (accumulate=1: all the session's "
            "accumulation holds)",
            "schema": {"type": "string"},
        },
    },
}
