"""One rendered frame (renderer.image.result): its 8-bit image, its ``npy`` array, and the bytes a frame holds."""

from __future__ import annotations

import numpy as np
import pytest

from renderer.image.result import (
    IMAGE_ONLY_BYTES_PER_PIXEL,
    RESULT_BYTES_PER_PIXEL,
    TARGET_BYTES_PER_PIXEL,
    TARGET_BYTES_PER_PIXEL_RGBA8,
    RenderResult,
    traced_nbytes,
)


def result(mode: str, image) -> RenderResult:
    h, w = np.shape(image)[:2]
    return RenderResult(
        np.asarray(image, np.float32),
        np.full((h, w), 2.5, np.float64),
        np.full((h, w), 7, np.int64),
        np.zeros((h, w, 3), np.float64),
        mode,
    )


def test_image_u8_rounds_half_up_and_clamps():
    r = result("color", [[[-1.0, 0.0, 0.5 / 255], [1.5 / 255, 1.0, 2.0]]])
    np.testing.assert_array_equal(r.image_u8(), [[[0, 0, 1], [2, 255, 255]]])
    assert r.image_u8().dtype == np.uint8


@pytest.mark.parametrize(
    "mode,dtype,shape",
    [
        ("depth", np.float32, (1, 2)),
        ("primid", np.int32, (1, 2)),
        ("normal", np.float32, (1, 2, 3)),
        ("color", np.uint8, (1, 2, 3)),
    ],
)
def test_the_npy_array_of_each_mode(mode, dtype, shape):
    a = result(mode, np.full((1, 2, 3), 0.5)).array()
    assert a.dtype == dtype and a.shape == shape


def test_traced_nbytes_adds_the_target_the_result_and_the_grid():
    assert traced_nbytes(10, 20) == 200 * (2 * TARGET_BYTES_PER_PIXEL + RESULT_BYTES_PER_PIXEL)
    assert traced_nbytes(10, 20, 4) == traced_nbytes(10, 20) + 200 * 16 * 16
    assert traced_nbytes(10, 20, image_only=True) == 200 * (
        2 * TARGET_BYTES_PER_PIXEL_RGBA8 + IMAGE_ONLY_BYTES_PER_PIXEL
    )
