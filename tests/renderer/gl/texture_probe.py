"""A GL harness for shaders/pbr_inputs.glsl: pbr_inputs evaluated at given hit points (a primitive,
a point, a normal and a cone footprint per pixel of float textures), the scene's surface data as the
tracer packs them (renderer/gpu/texture_layout.py), the PBR records from a uniform array through
accessors pbr_<name>(m) made from the material's declaration. The results are read back as float
images: base colour and alpha; metallic, roughness, occlusion, transmission; emissive; the shading
normal; and the hit's UV sets from pbr_uv (tests/renderer/gl/test_textures_gpu.py)."""

from __future__ import annotations

import numpy as np

from renderer.frame.shader_source import read, with_includes
from renderer.gl.textures import upload_textures
from renderer.gpu import gpu_layout, texture_layout
from renderer.materials import glsl_accessors, pack_records, record_texels
from renderer.materials.pbr import PbrMaterial

PBR_TEXELS = record_texels(PbrMaterial)
MAX_PROBE_MATERIALS = 4
VERTEX = "#version 300 es\nin vec2 a_position;\nvoid main() { gl_Position = vec4(a_position, 0.0, 1.0); }\n"
OUTPUTS = ("base", "factors", "emissive", "normal", "uv")


def fragment_source(colors: bool, tangents: bool) -> str:
    flags = {"FEATURE_TRIANGLES": 1, "FEATURE_SHAPES": 0, "FEATURE_TEXTURES": 1}
    flags["FEATURE_VERTEX_COLORS"] = int(colors)
    flags["FEATURE_TANGENTS"] = int(tangents)
    bindings = [gpu_layout.TRIANGLES, gpu_layout.TRI_BASE, gpu_layout.TEXTURES, gpu_layout.TEXTURE_INFO]
    bindings.append(gpu_layout.TRI_UVS)
    if colors:
        bindings.append(gpu_layout.TRI_COLORS)
    if tangents:
        bindings.append(gpu_layout.TRI_TANGENTS)
    return (
        "#version 300 es\nprecision highp float;\nprecision highp int;\nprecision highp sampler2D;\n"
        "precision highp usampler2D;\nprecision highp sampler2DArray;\n"
        + "".join(f"#define {k} {v}\n" for k, v in flags.items())
        + gpu_layout.triangle_constants()
        + f"#define SPHERE_MAT_MASK {gpu_layout.SPHERE_MAT_MASK}u\n"
        + texture_layout.texture_glsl_constants()
        + "int row_shift(ivec2 size) { return int(log2(float(size.x)) + 0.5); }\n"
        + "ivec2 texel(int i, int shift) { return ivec2(i & ((1 << shift) - 1), i >> shift); }\n"
        + gpu_layout.declarations(tuple(bindings))
        + "#define TRI_RECORD(j, k) u_triangles_at(TRIANGLE_TEXELS * (j) + (k))\n"
        + f"uniform vec4 u_probe_mats[{PBR_TEXELS * MAX_PROBE_MATERIALS}];\n"
        + f"#define MATERIAL_TEXEL(m, k) u_probe_mats[(m) * {PBR_TEXELS} + (k)]\n"
        + glsl_accessors(PbrMaterial).replace("#define material_", "#define pbr_")
        + "uniform highp sampler2D u_probe_point;   // p.xyz, primitive id\n"
        + "uniform highp sampler2D u_probe_normal;  // n.xyz, cone footprint\n"
        + with_includes(read("pbr_inputs.glsl"))
        + "layout(location = 0) out vec4 o_base;\nlayout(location = 1) out vec4 o_factors;\n"
        + "layout(location = 2) out vec4 o_emissive;\nlayout(location = 3) out vec4 o_normal;\n"
        + "layout(location = 4) out vec4 o_uv;\n"
        + "void main() {\n"
        "    LAYOUT_INIT();\n"
        "    ivec2 px = ivec2(gl_FragCoord.xy);\n"
        "    vec4 a = texelFetch(u_probe_point, px, 0);\n"
        "    vec4 b = texelFetch(u_probe_normal, px, 0);\n"
        "    int prim = int(a.w);\n"
        "    int j = prim - u_tri_base;\n"
        "    int mat = int(TRI_RECORD(j, 0).w & SPHERE_MAT_MASK);\n"
        "    PbrInputs s = pbr_inputs(mat, prim, a.xyz, b.xyz, b.w);\n"
        "    PbrUv t = pbr_uv(j, triangle_weights(j, a.xyz));\n"
        "    o_base = vec4(s.base_color, s.alpha);\n"
        "    o_factors = vec4(s.metallic, s.roughness, s.occlusion, s.transmission);\n"
        "    o_emissive = vec4(s.emissive, 0.0);\n"
        "    o_normal = vec4(s.n, 0.0);\n"
        "    o_uv = vec4(t.uv[0], t.uv[1]);\n"
        "}\n"
    )


def probe(ctx, scene, prim: np.ndarray, p: np.ndarray, n: np.ndarray, footprint: np.ndarray, max_width: int = 4096):
    """pbr_inputs at ``len(prim)`` hit points (triangle ids ``prim``, points ``p``, outward normals
    ``n``, cone footprints ``footprint``): a dict of float64 (N, 4) arrays named by :data:`OUTPUTS`."""
    if len(scene.materials) > MAX_PROBE_MATERIALS:
        raise ValueError("the probe holds few materials")
    surface = texture_layout.pack_surface_data(scene, max_width)
    colors = gpu_layout.TRI_COLORS.name in surface.packed.textures
    tangents = gpu_layout.TRI_TANGENTS.name in surface.packed.textures
    prog = ctx.program(vertex_shader=VERTEX, fragment_shader=fragment_source(colors, tangents))
    count = len(prim)
    width = min(count, 256)
    height = -(-count // width)

    def grid(a: np.ndarray) -> np.ndarray:
        out = np.zeros((width * height, 4), np.float32)
        out[:count] = a
        return out.reshape(height, width, 4)

    point = grid(np.concatenate([p, np.asarray(prim, dtype=np.float64)[:, None]], axis=1))
    normal = grid(np.concatenate([n, np.asarray(footprint, dtype=np.float64)[:, None]], axis=1))
    packed = gpu_layout.merged(
        gpu_layout.PackedScene(
            {gpu_layout.TRIANGLES.name: gpu_layout.wrap_rows(gpu_layout.triangle_records(scene), max_width)}, {}
        ),
        surface.packed,
    )
    held: list = []
    units = upload_textures(ctx, packed, held)
    for name, arr in (("u_probe_point", point), ("u_probe_normal", normal)):
        tex = ctx.texture((width, height), 4, arr.tobytes(), dtype="f4")
        tex.filter = (0x2600, 0x2600)  # NEAREST
        unit = len(held)
        tex.use(unit)
        held.append(tex)
        units[name] = unit
    for name, unit in units.items():
        if name in prog:
            prog[name].value = unit
    prog["u_tri_base"].value = scene.triangle_id_base
    mats = np.zeros((PBR_TEXELS * MAX_PROBE_MATERIALS, 4), np.float32)
    pbr = [m if isinstance(m, PbrMaterial) else PbrMaterial() for m in scene.materials]
    mats[: PBR_TEXELS * len(pbr)] = pack_records(pbr, PbrMaterial)
    prog["u_probe_mats"].value = [tuple(float(x) for x in v) for v in mats]
    targets = [ctx.texture((width, height), 4, dtype="f4") for _ in OUTPUTS]
    fbo = ctx.framebuffer(color_attachments=targets)
    quad = np.array([-1, -1, 1, -1, -1, 1, -1, 1, 1, -1, 1, 1], dtype="f4")
    vbo = ctx.buffer(quad.tobytes())
    vao = ctx.vertex_array(prog, [(vbo, "2f", "a_position")])
    try:
        fbo.use()
        vao.render()
        out = {}
        for name, i in zip(OUTPUTS, range(len(OUTPUTS)), strict=True):
            raw = np.frombuffer(fbo.read(components=4, attachment=i, dtype="f4"), np.float32)
            out[name] = raw.reshape(-1, 4)[:count].astype(np.float64)
        return out
    finally:
        for obj in (vao, vbo, fbo, *targets, *held, prog):
            obj.release()
