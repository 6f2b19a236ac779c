"""Headless OpenGL contexts for the renderer.

A context belongs to the thread that made it: use it from that thread only.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable
from typing import Any, cast

import moderngl


class GLUnavailable(RuntimeError):
    """No OpenGL context could be created (no EGL / Mesa on this machine)."""


def _gl_finish() -> Callable[[], None] | None:
    """``glFinish`` through ctypes (which releases the GIL during the call), or None."""
    try:
        egl = ctypes.CDLL("libEGL.so.1")
        egl.eglGetProcAddress.restype = ctypes.c_void_p
        egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
        addr = egl.eglGetProcAddress(b"glFinish")
        if addr:
            return ctypes.CFUNCTYPE(None)(addr)
    except OSError:
        pass
    try:
        return ctypes.CDLL("libGL.so.1").glFinish
    except (OSError, AttributeError):
        return None


class ReleasingContext:
    """A moderngl context whose ``finish()`` lets the other Python threads run.

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
