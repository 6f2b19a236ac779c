"""The GL calls moderngl lacks (renderer.gl.raw_gl): a depth-stencil renderbuffer with 8
stencil bits (one per ray generation of the ray engines) and the stencil states."""

from __future__ import annotations

import numpy as np

from renderer.gl.raw_gl import RawGL
from renderer.limits import STENCIL_BITS


def test_a_depth_stencil_renderbuffer_gives_a_framebuffer_its_stencil_bits(gl_renderer):
    ctx = gl_renderer.ctx
    gl = RawGL()
    tex = ctx.texture((4, 4), 4, dtype="f4")
    fbo = ctx.framebuffer(color_attachments=[tex])
    rb = gl.renderbuffer(4, 4)
    try:
        assert gl.stencil_bits(fbo) == 0
        gl.attach(fbo, rb)
        assert gl.stencil_bits(fbo) >= STENCIL_BITS
        assert gl.point_size_max() >= 1.0
        fbo.use()
        fbo.clear(0.25, 0.5, 0.75, 1.0)
        gl.clear_depth()
        gl.stencil_mark(1)
        gl.stencil_test(1)
        gl.stencil_off()
        np.testing.assert_array_equal(
            np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(4, 4, 4)[0, 0], [0.25, 0.5, 0.75, 1.0]
        )
    finally:
        gl.stencil_off()
        fbo.release()
        tex.release()
        gl.delete_renderbuffer(rb)
