"""The few GL calls moderngl does not wrap, through ctypes: stencil state and a
depth-stencil renderbuffer (the ray engines' passes need both).

They act on the context current in the calling thread (the renderer's); moderngl does
not cache any of this state. One ``RawGL`` belongs to one renderer.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable
from typing import Any

import moderngl

GL_FRAMEBUFFER = 0x8D40
GL_RENDERBUFFER = 0x8D41
GL_DEPTH_STENCIL_ATTACHMENT = 0x821A
GL_STENCIL_ATTACHMENT = 0x8D20
GL_DEPTH32F_STENCIL8 = 0x8CAD
GL_FRAMEBUFFER_COMPLETE = 0x8CD5
GL_FRAMEBUFFER_ATTACHMENT_STENCIL_SIZE = 0x8217
GL_STENCIL_TEST = 0x0B90
GL_STENCIL_BUFFER_BIT = 0x0400
GL_DEPTH_BUFFER_BIT = 0x0100
GL_ALWAYS, GL_EQUAL = 0x0207, 0x0202
GL_KEEP, GL_REPLACE = 0x1E00, 0x1E01
GL_ALIASED_POINT_SIZE_RANGE = 0x846E


class RawGL:
    """The few GL calls moderngl does not wrap: stencil state and a depth-stencil renderbuffer.

    They act on the context current in this thread (the renderer's); moderngl does not
    cache any of this state.
    """

    # The library's functions, set in __init__ with their ctypes signatures.
    glEnable: Callable[..., Any]
    glDisable: Callable[..., Any]
    glStencilFunc: Callable[..., Any]
    glStencilOp: Callable[..., Any]
    glStencilMask: Callable[..., Any]
    glClearStencil: Callable[..., Any]
    glClear: Callable[..., Any]
    glClearDepth: Callable[..., Any]
    glGenRenderbuffers: Callable[..., Any]
    glDeleteRenderbuffers: Callable[..., Any]
    glBindRenderbuffer: Callable[..., Any]
    glRenderbufferStorage: Callable[..., Any]
    glBindFramebuffer: Callable[..., Any]
    glFramebufferRenderbuffer: Callable[..., Any]
    glCheckFramebufferStatus: Callable[..., Any]
    glGetIntegerv: Callable[..., Any]
    glGetFramebufferAttachmentParameteriv: Callable[..., Any]
    glDepthMask: Callable[..., Any]

    def __init__(self) -> None:
        lib = None
        for name in ("libOpenGL.so.0", "libGL.so.1", "libGL.so"):
            try:
                lib = ctypes.CDLL(name)
                break
            except OSError:
                continue
        if lib is None:  # pragma: no cover - depends on the machine
            raise RuntimeError("cannot load libOpenGL / libGL for stencil state")
        self.lib = lib
        u, i = ctypes.c_uint, ctypes.c_int
        sig = {
            "glEnable": [u],
            "glDisable": [u],
            "glStencilFunc": [u, i, u],
            "glStencilOp": [u, u, u],
            "glStencilMask": [u],
            "glClearStencil": [i],
            "glClear": [u],
            "glClearDepth": [ctypes.c_double],
            "glGenRenderbuffers": [i, ctypes.POINTER(u)],
            "glDeleteRenderbuffers": [i, ctypes.POINTER(u)],
            "glBindRenderbuffer": [u, u],
            "glRenderbufferStorage": [u, u, i, i],
            "glBindFramebuffer": [u, u],
            "glFramebufferRenderbuffer": [u, u, u, u],
            "glCheckFramebufferStatus": [u],
            "glGetIntegerv": [u, ctypes.POINTER(i)],
            "glGetFramebufferAttachmentParameteriv": [u, u, u, ctypes.POINTER(i)],
            "glDepthMask": [ctypes.c_ubyte],
        }
        for name, args in sig.items():
            fn = getattr(lib, name)
            fn.argtypes = args
            fn.restype = u if name == "glCheckFramebufferStatus" else None
            setattr(self, name, fn)

    def renderbuffer(self, width: int, height: int) -> int:
        rb = ctypes.c_uint(0)
        self.glGenRenderbuffers(1, ctypes.byref(rb))
        self.glBindRenderbuffer(GL_RENDERBUFFER, rb.value)
        self.glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH32F_STENCIL8, width, height)
        return rb.value

    def delete_renderbuffer(self, rb: int) -> None:
        r = ctypes.c_uint(rb)
        self.glDeleteRenderbuffers(1, ctypes.byref(r))

    def attach(self, fbo: moderngl.Framebuffer, rb: int) -> None:
        self.glBindFramebuffer(GL_FRAMEBUFFER, fbo.glo)
        self.glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_STENCIL_ATTACHMENT, GL_RENDERBUFFER, rb)
        status = self.glCheckFramebufferStatus(GL_FRAMEBUFFER)
        if status != GL_FRAMEBUFFER_COMPLETE:
            raise RuntimeError(f"ray-engine framebuffer incomplete (0x{status:x})")

    def stencil_bits(self, fbo: moderngl.Framebuffer) -> int:
        v = ctypes.c_int(0)
        self.glBindFramebuffer(GL_FRAMEBUFFER, fbo.glo)
        self.glGetFramebufferAttachmentParameteriv(
            GL_FRAMEBUFFER, GL_STENCIL_ATTACHMENT, GL_FRAMEBUFFER_ATTACHMENT_STENCIL_SIZE, ctypes.byref(v)
        )
        return int(v.value)

    def point_size_max(self) -> float:
        v = (ctypes.c_float * 2)()
        self.lib.glGetFloatv.argtypes = [ctypes.c_uint, ctypes.POINTER(ctypes.c_float)]
        self.lib.glGetFloatv(GL_ALIASED_POINT_SIZE_RANGE, v)
        return float(v[1])

    # stencil states --------------------------------------------------------------
    def stencil_off(self) -> None:
        self.glDisable(GL_STENCIL_TEST)
        self.glStencilMask(0xFF)

    def stencil_test(self, bit: int) -> None:
        """Pass where ``bit`` is set; write nothing. ``bit`` 0: no test."""
        if not bit:
            self.stencil_off()
            return
        self.glEnable(GL_STENCIL_TEST)
        self.glStencilFunc(GL_EQUAL, bit, bit)
        self.glStencilOp(GL_KEEP, GL_KEEP, GL_KEEP)
        self.glStencilMask(0)

    def stencil_mark(self, bit: int) -> None:
        """Clear ``bit`` everywhere (the bound framebuffer), then set it where fragments pass."""
        self.glEnable(GL_STENCIL_TEST)
        self.glStencilMask(bit)
        self.glClearStencil(0)
        self.glClear(GL_STENCIL_BUFFER_BIT)
        self.glStencilFunc(GL_ALWAYS, 0xFF, 0xFF)
        self.glStencilOp(GL_KEEP, GL_KEEP, GL_REPLACE)

    def clear_depth(self) -> None:
        self.glDepthMask(1)
        self.glClearDepth(1.0)
        self.glClear(GL_DEPTH_BUFFER_BIT)
