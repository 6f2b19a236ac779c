"""What the ray engines' passes draw with: their compiled programs and their render targets
(:mod:`renderer.gl.ray_engine` runs the passes)."""

from __future__ import annotations

import moderngl
import numpy as np

from ..frame.shader_source import pass_source, vertex_source
from .programs import CachedProgram, ProgramCache
from .raw_gl import RawGL

FULLSCREEN = np.array([-1, -1, 1, -1, 1, 1, -1, -1, 1, 1, -1, 1], dtype=np.float32)


# ------------------------------------------------------------------------ programs


class Programs:
    """Compiled programs of one context, by (vertex, fragment, defines), held in ``cache`` (the
    renderer's: one bound for the tracer's variants and these passes together)."""

    def __init__(self, ctx: moderngl.Context, cache: ProgramCache | None = None):
        self.ctx = ctx
        self.cache = cache if cache is not None else ProgramCache()
        self.quad = ctx.buffer(FULLSCREEN.tobytes())
        self.used: set[tuple] = set()  # keys of the programs the current frame asked for

    @property
    def progs(self) -> dict[tuple, moderngl.Program]:
        """The passes' programs held now, by (vertex, fragment, defines)."""
        held = ((key, self.cache.peek(key)) for key in self.cache.keys())
        return {
            key[1:]: entry.program
            for key, entry in held
            if entry is not None and isinstance(key, tuple) and key[:1] == ("rayengine",)
        }

    def _entry(self, vert: str, frag: str, defines: tuple[str, ...]) -> CachedProgram:
        key = (vert, frag, defines)
        self.used.add(key)

        def compile() -> moderngl.Program:
            vs = vertex_source() if vert == "fullscreen.vert" else pass_source(vert, defines)
            return self.ctx.program(vertex_shader=vs, fragment_shader=pass_source(frag, defines))

        return self.cache.get(("rayengine", *key), compile)

    def get(self, vert: str, frag: str, defines: tuple[str, ...]) -> moderngl.Program:
        return self._entry(vert, frag, defines).program

    def _quad_vao(self, prog: moderngl.Program) -> moderngl.VertexArray:
        return self.ctx.vertex_array(prog, [(self.quad, "2f", "a_position")])

    def fullscreen(self, frag: str, defines: tuple[str, ...]) -> tuple[moderngl.Program, moderngl.VertexArray]:
        entry = self._entry("fullscreen.vert", frag, defines)
        return entry.program, entry.vao("quad", self._quad_vao)

    def quad_vao(self, prog: moderngl.Program) -> tuple[moderngl.VertexArray, bool]:
        """A full-screen quad's vertex array for ``prog`` (a program of :meth:`get`), and whether the
        caller owns it: True when ``prog`` was evicted meanwhile (the caller releases it)."""
        entry = self.cache.find(prog)
        if entry is None:
            return self._quad_vao(prog), True
        return entry.vao("quad", self._quad_vao), False


# ------------------------------------------------------------------------ targets


class Targets:
    """The frame's textures on one padded size: shared depth-stencil, hit, surface,
    blocked, colour targets, and a pool of ray layers."""

    def __init__(self, ctx: moderngl.Context, gl: RawGL, width: int, height: int):
        self.ctx, self.size = ctx, (width, height)
        self.gl = gl
        self.rb = self.gl.renderbuffer(width, height)
        tex = lambda: self._tex(width, height)
        self.hit, self.surf0, self.surf1, self.blocked0, self.blocked1, self.color = (tex() for _ in range(6))
        self.fbo_hit = self._fbo([self.hit], depth=True)
        self.fbo_surf = self._fbo([self.surf0, self.surf1])
        self.fbo_blocked = [self._fbo([self.blocked0]), self._fbo([self.blocked1])]
        self.stencil_bits = self.gl.stencil_bits(self.fbo_hit)
        self.pool: list[tuple[moderngl.Texture, moderngl.Texture]] = []
        self.all_layers: list[tuple[moderngl.Texture, moderngl.Texture]] = []
        self.fbos: list[moderngl.Framebuffer] = [self.fbo_hit, self.fbo_surf, *self.fbo_blocked]
        self.shade_fbos: dict[tuple[int, ...], moderngl.Framebuffer] = {}
        self.layer_fbos: dict[int, moderngl.Framebuffer] = {}

    def _tex(self, w: int, h: int) -> moderngl.Texture:
        t = self.ctx.texture((w, h), 4, dtype="f4")
        t.filter = (moderngl.NEAREST, moderngl.NEAREST)
        return t

    def _fbo(self, color: list, depth: bool = False) -> moderngl.Framebuffer:
        fbo = self.ctx.framebuffer(color_attachments=color)
        self.gl.attach(fbo, self.rb)
        fbo.depth_mask = depth
        return fbo

    def layer(self) -> tuple[moderngl.Texture, moderngl.Texture]:
        if self.pool:
            return self.pool.pop()
        pair = (self._tex(*self.size), self._tex(*self.size))
        self.all_layers.append(pair)
        return pair

    def release(self, pair) -> None:
        self.pool.append(pair)

    def layer_fbo(self, pair) -> moderngl.Framebuffer:
        """Framebuffer writing a layer (primary rays; clearing)."""
        key = pair[0].glo
        if key not in self.layer_fbos:
            self.layer_fbos[key] = self._fbo(list(pair))
        return self.layer_fbos[key]

    def shade_fbo(self, refl, trans) -> moderngl.Framebuffer:
        key = (refl[0].glo, trans[0].glo)
        if key not in self.shade_fbos:
            self.shade_fbos[key] = self._fbo([self.color, refl[0], refl[1], trans[0], trans[1]])
        return self.shade_fbos[key]

    def release_all(self) -> None:
        for f in [*self.fbos, *self.shade_fbos.values(), *self.layer_fbos.values()]:
            f.release()
        for t in (self.hit, self.surf0, self.surf1, self.blocked0, self.blocked1, self.color):
            t.release()
        for a, b in self.all_layers:
            a.release()
            b.release()
        self.gl.delete_renderbuffer(self.rb)
