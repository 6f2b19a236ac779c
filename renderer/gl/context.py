"""Headless OpenGL contexts for the renderer.

A context belongs to the thread that made it: use it from that thread only.
"""

from __future__ import annotations

import ctypes
import weakref
from collections.abc import Callable
from typing import Any, cast

import moderngl


class GLUnavailable(RuntimeError):
    """No OpenGL context could be created (no EGL / Mesa on this machine)."""


def _gl_function(name: str, *argtypes: Any) -> Callable[..., None] | None:
    """The GL function ``name`` through ctypes (which releases the GIL during the call), or None."""
    try:
        egl = ctypes.CDLL("libEGL.so.1")
        egl.eglGetProcAddress.restype = ctypes.c_void_p
        egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
        addr = egl.eglGetProcAddress(name.encode())
        if addr:
            return ctypes.CFUNCTYPE(None, *argtypes)(addr)
    except OSError:
        pass
    try:
        fn = getattr(ctypes.CDLL("libGL.so.1"), name)
    except (OSError, AttributeError):
        return None
    fn.argtypes, fn.restype = list(argtypes), None
    return fn


def _gl_finish() -> Callable[[], None] | None:
    """``glFinish`` through ctypes (which releases the GIL during the call), or None."""
    return _gl_function("glFinish")


class ReleasingDraw:
    """``VertexArray.render`` through ctypes: the draw call lets the other Python threads run.

    llvmpipe compiles a program's machine code (LLVM) on its first draw in each state, inside
    the draw call — 0.5-2 s of a new variant, measured — and moderngl makes that call holding
    the GIL, so /api/health stood still as long. The same calls moderngl's ``render`` makes
    (use the program, bind the vertex array, draw instanced; no index buffers here), made
    through ctypes, release it.
    """

    def __init__(self) -> None:
        u, i = ctypes.c_uint, ctypes.c_int
        self.use_program = _gl_function("glUseProgram", u)
        self.bind_vertex_array = _gl_function("glBindVertexArray", u)
        self.draw = _gl_function("glDrawArraysInstanced", u, i, i, i)

    @property
    def available(self) -> bool:
        return None not in (self.use_program, self.bind_vertex_array, self.draw)

    def install(self, vao: moderngl.VertexArray) -> moderngl.VertexArray:
        """``vao`` whose ``render`` draws through ctypes (moderngl's own where it has an index buffer)."""
        if not self.available or vao.index_buffer is not None:
            return vao
        use, bind, draw = self.use_program, self.bind_vertex_array, self.draw
        assert use is not None and bind is not None and draw is not None
        # Weakly: the method is the vertex array's own attribute, and a strong reference would be a
        # cycle that keeps it (and its program) alive until the cyclic collector runs.
        ref = weakref.ref(vao)

        def render(mode: int | None = None, vertices: int = -1, first: int = 0, instances: int = -1) -> None:
            vao = ref()
            assert vao is not None, "called through the vertex array"
            n = vao.vertices if vertices < 0 else vertices
            if n < 0:
                raise moderngl.Error("cannot detect the number of vertices")
            use(vao.program.glo)
            bind(vao.glo)
            draw(vao.mode if mode is None else mode, first, n, vao.instances if instances < 0 else instances)

        vao.render = render  # the same signature, the GIL released
        return vao


class ReleasingContext:
    """A moderngl context whose ``finish()`` and draws let the other Python threads run.

    moderngl calls ``glFinish`` while holding the GIL, and with llvmpipe that
    call *is* the ray tracing (hundreds of ms): measured, the whole process —
    HTTP handling, /api/health, the 503 answers of a full queue — stood still
    for 1.6 s during one frame. The same ``glFinish`` called through ctypes
    releases the GIL (the longest stall left is ~15 ms, the pixel read-back).
    Everything else is delegated to the real context.
    """

    def __init__(self, ctx: Any):
        object.__setattr__(self, "_ctx", ctx)
        object.__setattr__(self, "_finish", _gl_finish())
        object.__setattr__(self, "_draw", ReleasingDraw())

    def vertex_array(self, *args: Any, **kwargs: Any) -> moderngl.VertexArray:
        """moderngl's vertex array whose draws release the GIL (:class:`ReleasingDraw`)."""
        return self._draw.install(self._ctx.vertex_array(*args, **kwargs))

    def finish(self) -> None:
        if self._finish is not None:
            self._finish()
        else:  # pragma: no cover - no libEGL/libGL to call directly
            self._ctx.finish()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._ctx, name)

    def __setattr__(self, name: str, value: Any) -> None:
        setattr(self._ctx, name, value)


def create_context() -> moderngl.Context:
    """A headless OpenGL ≥ 3.3 context through EGL (Mesa's llvmpipe without a GPU).

    Wrapped in :class:`ReleasingContext`, so waiting for a frame does not stop
    the process's other threads.
    """
    try:
        ctx = moderngl.create_standalone_context(backend="egl")  # type: ignore[arg-type]  # stubs: every keyword a dict
    except Exception as egl_error:  # pragma: no cover - depends on the machine
        try:
            ctx = moderngl.create_standalone_context()
        except Exception:
            raise GLUnavailable(f"cannot create an OpenGL context: {egl_error}") from egl_error
    return cast(moderngl.Context, ReleasingContext(ctx))  # it stands in for the context: every attribute delegated
