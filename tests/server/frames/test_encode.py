"""The encoding of a frame's body (server/frames/encode.py)."""

from __future__ import annotations

import io
import tracemalloc

import numpy as np

from renderer.image.result import RenderResult
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
    """Rules out: a contiguous copy of the array, then np.save's copy of it, then the buffer: the
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


def test_an_image_only_frame_encodes_from_its_read_back_as_from_image_u8():
    """An image-only frame hands the encoder its RGBA8 read-back as it came (bottom row first, a
    pad byte): the png and jpeg bodies are byte for byte those of its image_u8 (flipped, RGB)."""
    from renderer.gl.frame import ImageOnlyResult

    rng = np.random.default_rng(2)
    rows = rng.integers(0, 256, (37, 53, 4), dtype=np.uint8)  # odd sizes: no row padding hides a slip
    only = ImageOnlyResult(rows, "color", {}, {}, None)
    u8 = rows[::-1, :, :3]
    np.testing.assert_array_equal(only.image_u8(), u8)
    assert only.image_rows_rgbx() is rows

    class Plain(RenderResult):
        def image_u8(self) -> np.ndarray:
            return np.ascontiguousarray(u8)

    plain = Plain(image=np.zeros((37, 53, 3), np.float32), depth=None, primid=None, normal=None, mode="color")  # type: ignore[arg-type]
    assert plain.image_rows_rgbx() is None
    for fmt in ("png", "jpeg"):
        assert encode(only, fmt, 85)[0] == encode(plain, fmt, 85)[0], fmt
