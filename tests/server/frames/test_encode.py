"""The encoding of a frame's body (server/frames/encode.py)."""

from __future__ import annotations

import io
import tracemalloc

import numpy as np

from renderer.result import RenderResult
from server.frames.encode import encode


def strided_result(side: int) -> RenderResult:
    """A normal result whose array is a strided view (as a read-back's rows turned over are)."""
    rng = np.random.default_rng(1)
    hit = rng.random((side, side, 4), dtype=np.float32)
    return RenderResult(
        image=np.zeros((side, side, 3), np.float32),
        depth=hit[..., 3],
        primid=np.zeros((side, side), np.int32),
        normal=hit[::-1][..., :3],
        mode="normal",
    )


def test_npy_encoding_copies_the_array_once():
    """Was: a contiguous copy of the array, then np.save's copy of it, then the buffer: the
    encoder's peak was 2-3 times the body; now the body and a 1 MiB chunk."""
    result = strided_result(1024)
    tracemalloc.start()
    try:
        body, _ = encode(result, "npy", 85)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 1.2 * len(body), (peak, len(body))
    want = io.BytesIO()
    np.save(want, np.ascontiguousarray(result.normal), allow_pickle=False)
    assert body == want.getvalue()
