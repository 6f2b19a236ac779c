"""A tiny GL harness for shaders/shapes.glsl: one ray per pixel (origins and directions in
float textures), one shape in uniforms, t and the normal written to a float target
(tests/renderer/gl/test_shapes_glsl.py and bench/shapes_solvers.py)."""

from __future__ import annotations

import time

import numpy as np

from renderer.resources import shader_dir

FUNCTIONS = (
    "intersect_shape",
    "intersect_cylinder",
    "intersect_cone",
    "intersect_disk",
    "intersect_torus",
    "intersect_torus_bracket",
    "intersect_torus_closed",
)


def fragment_source(function: str = "intersect_shape") -> str:
    """The test shader: shapes.glsl between a header that defines BIG and a main that calls ``function``."""
    if function not in FUNCTIONS:
        raise ValueError(function)
    return (
        "#version 300 es\n"
        "precision highp float;\nprecision highp int;\nprecision highp sampler2D;\n"
        "uniform sampler2D u_o;\nuniform sampler2D u_d;\n"
        "uniform vec4 u_v0;\nuniform vec4 u_v1;\nuniform vec4 u_v2;\nuniform float u_tmax;\n"
        "out vec4 o_hit;\n"
        "const float BIG = 3.0e38;\n" + (shader_dir() / "shapes.glsl").read_text() + "\nvoid main() {\n"
        "    ivec2 p = ivec2(gl_FragCoord.xy);\n"
        "    vec3 n;\n"
        "    vec3 o = texelFetch(u_o, p, 0).xyz;\n"
        "    vec3 d = texelFetch(u_d, p, 0).xyz;\n"
        f"    float t = {function}(o, d, u_v0, u_v1, u_v2, u_tmax, n);\n"
        "    o_hit = vec4(n, t);\n"
        "}\n"
    )


VERTEX = "#version 300 es\nin vec2 a_position;\nvoid main() { gl_Position = vec4(a_position, 0.0, 1.0); }\n"


class ShapesGL:
    """Programs per function on one moderngl context; ``run`` intersects rays with one shape."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.programs: dict[str, object] = {}
        quad = np.array([-1, -1, 1, -1, -1, 1, -1, 1, 1, -1, 1, 1], dtype="f4")
        self.vbo = ctx.buffer(quad.tobytes())

    def program(self, function: str):
        if function not in self.programs:
            self.programs[function] = self.ctx.program(vertex_shader=VERTEX, fragment_shader=fragment_source(function))
        return self.programs[function]

    def run(
        self,
        o: np.ndarray,
        d: np.ndarray,
        shape: np.ndarray,
        function: str = "intersect_shape",
        t_max: float = 1e30,
        repeat: int = 0,
    ) -> tuple[np.ndarray, np.ndarray, float]:
        """(t, n, seconds per draw) for rays o, d (N = side², float32) and the shape's (3, 4) records.
        With ``repeat`` > 0 the draw is timed over that many more draws (bench only)."""
        n = len(o)
        side = int(round(np.sqrt(n)))
        assert side * side == n
        ctx = self.ctx
        prog = self.program(function)
        to = ctx.texture((side, side), 4, np.concatenate([o, np.zeros((n, 1))], 1).astype("f4").tobytes(), dtype="f4")
        td = ctx.texture((side, side), 4, np.concatenate([d, np.zeros((n, 1))], 1).astype("f4").tobytes(), dtype="f4")
        for tex in (to, td):
            tex.filter = (ctx.NEAREST, ctx.NEAREST)
        out = ctx.texture((side, side), 4, dtype="f4")
        fbo = ctx.framebuffer(color_attachments=[out])
        vao = ctx.vertex_array(prog, [(self.vbo, "2f", "a_position")])
        try:
            to.use(0)
            td.use(1)
            prog["u_o"].value = 0
            prog["u_d"].value = 1
            for name, v in zip(("u_v0", "u_v1", "u_v2"), shape, strict=True):
                if name in prog:  # a function that never reads v2 has it compiled out
                    prog[name].value = tuple(float(x) for x in v)
            prog["u_tmax"].value = float(t_max)
            fbo.use()
            ctx.viewport = (0, 0, side, side)
            vao.render()
            res = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(n, 4).copy()
            per = 0.0
            if repeat:
                ctx.finish()
                t0 = time.perf_counter()
                for _ in range(repeat):
                    vao.render()
                ctx.finish()
                per = (time.perf_counter() - t0) / repeat
        finally:
            for obj in (vao, fbo, out, to, td):
                obj.release()
        return res[:, 3].copy(), res[:, :3].copy(), per
