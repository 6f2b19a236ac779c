"""Render targets reused between frames and bounded in bytes (renderer.gl.targets)."""

from __future__ import annotations

from renderer.gl.targets import BYTES_PER_PIXEL, BYTES_PER_PIXEL_RGBA8, TargetPool


def test_a_released_target_is_handed_out_again_for_the_same_size_and_kind(gl_renderer):
    pool = TargetPool(gl_renderer.ctx, max_bytes=1 << 30)
    try:
        a = pool.acquire(8, 4)
        assert [t.dtype for t in a.color_attachments] == ["f4", "f4"] and a.size == (8, 4)
        rgba8 = pool.acquire(8, 4, image_only=True)
        assert [t.dtype for t in rgba8.color_attachments] == ["f1"]
        assert pool.nbytes == 32 * (BYTES_PER_PIXEL + BYTES_PER_PIXEL_RGBA8)
        pool.release(a)
        assert pool.acquire(8, 4) is a, "the free one of that size"
        assert pool.acquire(8, 4) is not a, "busy targets are never shared"
        pool.release(a)
        pool.release(a)  # a second release is ignored
        assert pool.sizes.count((8, 4)) == 3
    finally:
        pool.clear()
    assert pool.nbytes == 0


def test_free_targets_beyond_the_budget_are_released_least_recent_first(gl_renderer):
    one = TargetPool.nbytes_of(16, 16)
    pool = TargetPool(gl_renderer.ctx, max_bytes=2 * one)
    try:
        a, b = pool.acquire(16, 16), pool.acquire(16, 16)
        pool.release(a)
        pool.release(b)
        c = pool.acquire(16, 8)  # needs room: the least recently released (a) goes
        assert pool.nbytes == one + TargetPool.nbytes_of(16, 8)
        assert pool.acquire(16, 16) is b
        d = pool.acquire(16, 16)  # over the budget while all are busy: made anyway
        assert pool.nbytes > pool.max_bytes and d not in (a, b, c)
    finally:
        pool.clear()
