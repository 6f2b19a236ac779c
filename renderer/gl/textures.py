"""Packed textures (:mod:`renderer.gpu_layout`) onto the GPU."""

from __future__ import annotations

import moderngl
import numpy as np

from .. import gpu_layout


def upload_textures(
    ctx: moderngl.Context, packed: gpu_layout.PackedScene, textures: list[moderngl.Texture]
) -> dict[str, int]:
    """Create the packed textures and bind them to the next free units.

    Appends them to ``textures`` (the caller releases them after the frame) and
    returns sampler name → texture unit.
    """
    units = {}
    for name, tex in packed.textures.items():
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
