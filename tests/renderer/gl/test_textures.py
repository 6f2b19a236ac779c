"""Packed data onto the GPU (renderer.gl.textures): textures on consecutive units, record
arrays as uniform blocks of the declared size."""

from __future__ import annotations

import numpy as np
import pytest

from renderer.gl.textures import upload_blocks, upload_textures
from renderer.gpu import gpu_layout
from renderer.gpu.gpu_layout import wrap_rows


def test_textures_take_the_next_free_units_and_keep_their_data(gl_renderer):
    ctx = gl_renderer.ctx
    a = wrap_rows(np.arange(12, dtype=np.float32).reshape(3, 4), 8)
    b = wrap_rows(np.arange(8, dtype=np.uint32).reshape(4, 2), 8)
    held = ["an earlier texture"]
    units = upload_textures(ctx, gpu_layout.PackedScene({"u_a": a, "u_b": b}), held)
    try:
        assert units == {"u_a": 1, "u_b": 2} and len(held) == 3
        got = np.frombuffer(held[1].read(), np.float32).reshape(a.data.shape)
        np.testing.assert_array_equal(got, a.data)
        got = np.frombuffer(held[2].read(), np.uint32).reshape(b.data.shape)
        np.testing.assert_array_equal(got, b.data)
    finally:
        for t in held[1:]:
            t.release()


def test_a_block_is_zero_padded_to_its_size_and_a_larger_one_refused(gl_renderer):
    ctx = gl_renderer.ctx
    records = wrap_rows(np.arange(16, dtype=np.uint32).reshape(4, 4), 8)
    buffers: list = []
    out = upload_blocks(ctx, {"u_records": records}, buffers)
    try:
        assert list(out) == ["u_records"] and buffers == [out["u_records"]]
        data = out["u_records"].read()
        assert len(data) == gpu_layout.BLOCK_BYTES
        n = records.data.nbytes
        assert data[:n] == records.data.astype("<u4").tobytes() and not any(data[n:])
    finally:
        for buf in buffers:
            buf.release()
    too_big = wrap_rows(np.zeros((gpu_layout.BLOCK_BYTES // 16 + 1, 4), np.uint32), 4096)
    with pytest.raises(ValueError, match="do not fit"):
        upload_blocks(ctx, {"u_big": too_big}, [])
