"""Headless contexts (renderer.gl.context): the renderer's context waits for a frame through
``glFinish`` without the GIL and delegates everything else to moderngl's context."""

from __future__ import annotations

from renderer.gl.context import ReleasingContext


class _Fake:
    def __init__(self):
        self.viewport = (0, 0, 1, 1)


def test_attributes_are_read_and_written_on_the_wrapped_context():
    fake = _Fake()
    ctx = ReleasingContext(fake)
    assert ctx.viewport == (0, 0, 1, 1)
    ctx.viewport = (0, 0, 8, 4)
    assert fake.viewport == (0, 0, 8, 4) and "viewport" not in vars(ctx)


def test_the_renderers_context_is_a_releasing_opengl_33_context(gl_renderer):
    ctx = gl_renderer.ctx
    assert isinstance(ctx, ReleasingContext)
    assert ctx.version_code >= 330
    assert ctx._finish is not None, "glFinish found through libEGL or libGL: it releases the GIL"
    ctx.finish()
