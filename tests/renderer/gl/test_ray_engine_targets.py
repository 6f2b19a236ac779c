"""What the ray engines' passes draw with (renderer.gl.ray_engine_targets): programs compiled
once per (shaders, defines) and recorded as used, and targets whose ray layers are pooled."""

from __future__ import annotations

from renderer.gl.raw_gl import RawGL
from renderer.gl.ray_engine_targets import Programs, Targets
from renderer.limits import STENCIL_BITS


def test_programs_are_compiled_once_and_recorded_as_used(gl_renderer):
    progs = Programs(gl_renderer.ctx)
    prog, vao = progs.fullscreen("rayengine_pass.frag", ("PASS_PRIMARY",))
    assert progs.fullscreen("rayengine_pass.frag", ("PASS_PRIMARY",)) == (prog, vao)
    assert progs.used == {("fullscreen.vert", "rayengine_pass.frag", ("PASS_PRIMARY",))}
    assert progs.get("rayengine_prim.vert", "rayengine_prim.frag", ("CULL_MATRIX",)) is not prog
    assert len(progs.progs) == 2 and len(progs.used) == 2


def test_targets_share_one_depth_stencil_and_pool_their_layers(gl_renderer):
    t = Targets(gl_renderer.ctx, RawGL(), 8, 4)
    try:
        assert t.stencil_bits >= STENCIL_BITS and t.hit.size == (8, 4)
        a = t.layer()
        b = t.layer()
        assert a != b and len(t.all_layers) == 2
        t.release(a)
        assert t.layer() is a and len(t.all_layers) == 2
        assert t.layer_fbo(a) is t.layer_fbo(a)
        assert t.shade_fbo(a, b) is t.shade_fbo(a, b)
    finally:
        t.release_all()
