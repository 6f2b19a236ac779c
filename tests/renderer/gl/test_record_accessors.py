"""The GLSL accessors of every node record (renderer.gpu.record_layout, renderer.accel.node_records)
on the GPU (llvmpipe): each field of each record, read by its accessor from an RGBA32UI texture of
records the packer wrote, is what NumPy reads back from those records — bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from renderer.accel.node_records import NODE_RECORDS
from renderer.gpu.record_layout import RecordLayout

VERTEX = "#version 300 es\nin vec2 a_position;\nvoid main() { gl_Position = vec4(a_position, 0.0, 1.0); }\n"
N = 64


def fragment(record: RecordLayout, field: str) -> str:
    f = record.field(field)
    value = f"{record.name}_{field}(i)"
    if f.kind == "float":
        value = f"floatBitsToUint({value})"
    pad = {1: "uvec4({v}, 0u, 0u, 0u)", 2: "uvec4({v}, 0u, 0u)", 3: "uvec4({v}, 0u)", 4: "{v}"}[len(f.components)]
    return (
        "#version 300 es\n"
        + record.glsl_accessors()
        + f"#define {record.binding.name}_at(i) texelFetch(u_rec, ivec2((i), 0), 0)\n"
        + "precision highp float;\nprecision highp int;\nprecision highp usampler2D;\n"
        + "uniform usampler2D u_rec;\nout uvec4 o_value;\n"
        + "void main() {\n    int i = int(gl_FragCoord.x);\n"
        + f"    o_value = {pad.format(v=value)};\n}}\n"
    )


def random_columns(record: RecordLayout, rng: np.random.Generator) -> dict[str, np.ndarray]:
    cols = {}
    for f in record.fields:
        shape = (N,) if len(f.components) == 1 else (N, len(f.components))
        if f.kind == "float":
            cols[f.name] = rng.normal(0.0, 1e3, shape).astype(np.float32)
        else:
            cols[f.name] = rng.integers(0, 1 << f.width, shape, dtype=np.int64)
    return cols


@pytest.mark.parametrize("record", NODE_RECORDS, ids=lambda r: r.name)
def test_each_accessor_reads_the_field_the_packer_wrote(gl_renderer, record):
    ctx = gl_renderer.ctx
    records = record.pack(N, **random_columns(record, np.random.default_rng(7)))
    want = record.unpack(records)
    tex = ctx.texture((len(records), 1), 4, records.tobytes(), dtype="u4")
    out = ctx.texture((N, 1), 4, dtype="u4")
    fbo = ctx.framebuffer(color_attachments=[out])
    vbo = ctx.buffer(np.array([-1, -1, 1, -1, -1, 1, -1, 1, 1, -1, 1, 1], dtype="f4").tobytes())
    try:
        for f in record.fields:
            prog = ctx.program(vertex_shader=VERTEX, fragment_shader=fragment(record, f.name))
            vao = ctx.vertex_array(prog, [(vbo, "2f", "a_position")])
            try:
                tex.use(0)
                prog["u_rec"].value = 0
                fbo.use()
                ctx.viewport = (0, 0, N, 1)
                vao.render()
                got = np.frombuffer(fbo.read(components=4, dtype="u4"), dtype=np.uint32).reshape(N, 4)
            finally:
                vao.release()
                prog.release()
            got = got[:, : len(f.components)]
            expected = np.ascontiguousarray(want[f.name]).view(np.uint32).reshape(N, -1)
            np.testing.assert_array_equal(got, expected, err_msg=f"{record.name}.{f.name}")
    finally:
        for obj in (tex, out, fbo, vbo):
            obj.release()
