"""The bounded program cache (renderer.gl.programs): least recently used out at its bound, an
evicted program deleted only once no frame in flight holds it, frames right after an evicted
variant is compiled again; and draws that let other Python threads run (renderer.gl.context)."""

from __future__ import annotations

import gc
import threading
import time
import uuid

import numpy as np
import pytest

from renderer.config.settings import RenderSettings
from renderer.frame.shader_source import vertex_source
from renderer.gl.programs import ProgramCache
from renderer.gl.renderer import GLRenderer
from renderer.limits import MAX_PROGRAMS
from renderer.scenes.scenarios import scenario


class _GLObject:
    def __init__(self, log: list, name: str):
        self.log, self.name = log, name

    def release(self) -> None:
        self.log.append(self.name)


class _Program:
    """Stands in for a moderngl program: what the cache touches (``mglo.release()``)."""

    def __init__(self, log: list, name: str):
        self.mglo = _GLObject(log, name)


def test_the_least_recently_used_goes_first_and_is_deleted_when_unreferenced():
    deleted: list[str] = []
    cache = ProgramCache(2, trim=False)
    a = cache.get("a", lambda: _Program(deleted, "a"))  # type: ignore[arg-type,return-value]
    cache.get("b", lambda: _Program(deleted, "b"))  # type: ignore[arg-type,return-value]
    assert cache.get("a", lambda: pytest.fail("held: not compiled again")) is a  # a is the most recent now
    cache.get("c", lambda: _Program(deleted, "c"))  # type: ignore[arg-type,return-value]
    assert cache.keys() == ["a", "c"] and (cache.compiled, cache.evicted) == (3, 1)
    assert deleted == ["b"] and cache.retired == 0
    held = a.program  # a frame in flight still draws with a
    cache.get("d", lambda: _Program(deleted, "d"))  # type: ignore[arg-type,return-value]
    assert cache.keys() == ["c", "d"] and deleted == ["b"] and cache.retired == 1
    del a, held
    assert cache.sweep() == 1 and deleted == ["b", "a"] and cache.released == 2


def test_charging_runs_before_a_compile_only_and_may_refuse_it():
    deleted: list[str] = []
    cache = ProgramCache(4, trim=False)
    charged: list[str] = []
    with cache.charging(lambda: charged.append("x")):
        cache.get("a", lambda: _Program(deleted, "a"))  # type: ignore[arg-type,return-value]
        cache.get("a", lambda: _Program(deleted, "a"))  # type: ignore[arg-type,return-value]
    assert charged == ["x"]

    def refuse() -> None:
        raise RuntimeError("over the rate")

    with cache.charging(refuse), pytest.raises(RuntimeError):
        cache.get("b", lambda: pytest.fail("refused before compiling"))
    assert "b" not in cache and cache.compiled == 1
    cache.get("b", lambda: _Program(deleted, "b"))  # type: ignore[arg-type,return-value]  # charging ended
    assert "b" in cache


def test_a_bound_below_one_is_refused():
    with pytest.raises(ValueError, match="max_programs"):
        ProgramCache(0)
    assert ProgramCache().max_programs == MAX_PROGRAMS


def _settings(depth: int) -> RenderSettings:
    # a generic variant per recursion depth, one program a frame (no background, no first hits; float
    # arrays, as an image-only frame's ``image`` would trace its float twin)
    return RenderSettings(
        width=24, height=20, max_recursion_depth=depth, specialize=False, first_hits="trace", format="npy"
    )


def test_frames_render_right_after_their_evicted_variant_is_compiled_again(gl_renderer):
    scene = scenario(1, 27)
    small = GLRenderer(gl_renderer.ctx, max_programs=2, background=False)
    first = small.render(scene, _settings(1)).image
    small.render(scene, _settings(2))
    small.render(scene, _settings(3))  # evicts depth 1
    assert len(small.programs) == 2 and small.programs.evicted == 1
    gc.collect()
    small.programs.sweep()
    assert small.programs.released == 2  # its program and its vertex array: deleted
    again = small.render(scene, _settings(1))
    assert small.programs.compiled == 4
    np.testing.assert_array_equal(again.image, first)
    # … and the same image as a renderer that never evicted
    np.testing.assert_array_equal(gl_renderer.render(scene, _settings(1)).image, first)


def test_a_frame_in_flight_keeps_its_evicted_program_until_it_is_done(gl_renderer):
    scene = scenario(1, 27)
    small = GLRenderer(gl_renderer.ctx, max_programs=1, background=False)
    whole = gl_renderer.render(scene, _settings(2)).image
    frame = small.begin(scene, _settings(2), band_rows=5)
    frame.step()
    small.render(scene, _settings(3))  # evicts the variant the frame draws with
    gc.collect()
    small.programs.sweep()
    assert small.programs.evicted == 1 and small.programs.retired == 2  # not deleted under the frame
    np.testing.assert_array_equal(frame.run().image, whole)
    frame.release()
    del frame
    gc.collect()
    assert small.programs.sweep() == 2 and small.programs.retired == 0


def test_a_draw_lets_other_threads_run_while_llvmpipe_compiles(gl_renderer):
    ctx = gl_renderer.ctx
    # A text no earlier run compiled (Mesa's shader cache would skip the compile otherwise).
    frag = (
        "#version 300 es\nprecision highp float;\nout vec4 c;\n"
        f"// {uuid.uuid4()}\n"
        "void main() { float s = 0.0; for (int i = 0; i < 64; i++) { s += sin(float(i) * gl_FragCoord.x); }"
        " c = vec4(s); }\n"
    )
    prog = ctx.program(vertex_shader=vertex_source(), fragment_shader=frag)
    quad = ctx.buffer(np.array([-1, -1, 1, -1, 1, 1], dtype=np.float32).tobytes())
    vao = ctx.vertex_array(prog, [(quad, "2f", "a_position")])
    target = ctx.simple_framebuffer((4, 4))
    ticks = [0]
    stop = threading.Event()

    def tick() -> None:
        while not stop.is_set():
            ticks[0] += 1
            time.sleep(0)

    ticker = threading.Thread(target=tick, daemon=True)
    try:
        target.use()
        ticker.start()
        while ticks[0] == 0:
            time.sleep(0)
        before = ticks[0]
        vao.render()  # the first draw: llvmpipe compiles the program's machine code here
        during = ticks[0] - before
    finally:
        stop.set()
        ticker.join()
        for obj in (vao, quad, target, prog):
            obj.release()
    assert during > 10  # held, it would see at most the switches at the call's edges
