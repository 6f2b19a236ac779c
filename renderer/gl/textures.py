"""Packed textures (:mod:`renderer.gpu_layout`) onto the GPU."""

from __future__ import annotations

import moderngl

from .. import gpu_layout


def upload_textures(ctx: moderngl.Context, packed: gpu_layout.PackedScene,
                    textures: list[moderngl.Texture]) -> dict[str, int]:
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
