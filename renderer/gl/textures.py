"""Packed textures (:mod:`renderer.gpu.gpu_layout`) onto the GPU."""

from __future__ import annotations

import ctypes
from functools import cache

import moderngl
import numpy as np

from ..gpu import gpu_layout

GL_TEXTURE_2D_ARRAY = 0x8C1A
GL_RGBA = 0x1908
GL_UNSIGNED_BYTE = 0x1401


@cache
def _tex_sub_image_3d():
    """glTexSubImage3D (moderngl writes level 0 of an array only), for the context current in the thread."""
    for name in ("libOpenGL.so.0", "libGL.so.1", "libGL.so"):
        try:
            fn = ctypes.CDLL(name).glTexSubImage3D
        except (OSError, AttributeError):
            continue
        u, i = ctypes.c_uint, ctypes.c_int
        fn.argtypes = [u, i, i, i, i, i, i, i, u, u, ctypes.c_void_p]
        fn.restype = None
        return fn
    raise RuntimeError("cannot load libOpenGL / libGL for glTexSubImage3D")  # pragma: no cover


def upload_texture_array(ctx: moderngl.Context, tex: gpu_layout.PackedTextureArray, unit: int) -> moderngl.TextureArray:
    """An RGBA8 ``sampler2DArray`` with the packed mip levels (made on the CPU from linear values,
    renderer/gpu/texture_layout.py; GL's own mipmaps would average sRGB bytes), bound to ``unit``.
    NEAREST_MIPMAP_NEAREST: every level is complete and the shader reads them with texelFetch."""
    w, h = tex.size
    arr = ctx.texture_array((w, h, tex.layers), 4, np.ascontiguousarray(tex.levels[0]).tobytes(), dtype="f1")
    if len(tex.levels) > 1:
        arr.build_mipmaps(0, len(tex.levels) - 1)  # allocates the levels; their texels are written below
    arr.filter = (moderngl.NEAREST_MIPMAP_NEAREST if len(tex.levels) > 1 else moderngl.NEAREST, moderngl.NEAREST)
    arr.use(unit)
    sub = _tex_sub_image_3d()
    for level, data in enumerate(tex.levels[1:], start=1):
        buf = np.ascontiguousarray(data, dtype=np.uint8)
        layers, lh, lw = buf.shape[:3]
        sub(GL_TEXTURE_2D_ARRAY, level, 0, 0, 0, lw, lh, layers, GL_RGBA, GL_UNSIGNED_BYTE, buf.ctypes.data)
    return arr


def upload_textures(
    ctx: moderngl.Context, packed: gpu_layout.PackedScene, textures: list[moderngl.Texture | moderngl.TextureArray]
) -> dict[str, int]:
    """Create the packed textures and bind them to the next free units.

    Appends them to ``textures`` (the caller releases them after the frame) and
    returns sampler name → texture unit.
    """
    units = {}
    for name, tex in packed.textures.items():
        if isinstance(tex, gpu_layout.PackedTextureArray):
            unit = len(textures)
            textures.append(upload_texture_array(ctx, tex, unit))
            units[name] = unit
            continue
        gl_tex = ctx.texture(tex.size, tex.components, tex.data.tobytes(), dtype=tex.dtype)
        # Integer textures are incomplete with LINEAR filtering; texelFetch ignores it otherwise.
        gl_tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        unit = len(textures)
        gl_tex.use(unit)
        textures.append(gl_tex)
        units[name] = unit
    return units


def upload_blocks(
    ctx: moderngl.Context, packed: dict[str, gpu_layout.PackedTexture], buffers: list[moderngl.Buffer]
) -> dict[str, moderngl.Buffer]:
    """Record arrays as uniform-block buffers: the packed texture's elements in order (element
    i is record i), zero-padded to the block's declared size (gpu_layout.BLOCK_BYTES).

    Appends them to ``buffers`` (the caller releases them after the frame) and returns block
    name → buffer; the frame binds each to a binding point before every slice."""
    out = {}
    for name, tex in packed.items():
        data = np.ascontiguousarray(tex.data, dtype="<u4").tobytes()
        if len(data) > gpu_layout.BLOCK_BYTES:
            raise ValueError(f"{name}: {len(data)} bytes do not fit a {gpu_layout.BLOCK_BYTES}-byte uniform block")
        buf = ctx.buffer(data + bytes(gpu_layout.BLOCK_BYTES - len(data)))
        buffers.append(buf)
        out[name] = buf
    return out
