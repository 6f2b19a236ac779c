"""The draws of a frame whose first hits are rasterised (:mod:`renderer.first_hits`).

Per pass: the target's colours are cleared to a miss and its depth to 1.0; per band (a
scissor rectangle), the planes' pass — the background variant writing depth — where the
scene has planes, then the spheres' quads, instanced, under the depth test ≤. The target's
own colour attachments are drawn into through a framebuffer of this frame that adds a
float32 depth buffer (GL_DEPTH32F_STENCIL8: the depth is an exact float, not 24 bits).
"""

from __future__ import annotations

import moderngl
import numpy as np

from .. import first_hits as fh, gpu_layout
from ..gpu_layout import Variant
from ..scene import Scene
from .raw_gl import RawGL

CORNERS = np.array([0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1], dtype=np.float32)  # two triangles of the unit square


class FirstHitDraws:
    """What one frame draws its rasterised first hits with (made by :class:`~renderer.gl.frame.TracerFrame`)."""

    def __init__(self, renderer, scene: Scene, variant: Variant, target: moderngl.Framebuffer, how: str = "spheres"):
        self.ctx: moderngl.Context = renderer.ctx
        self.renderer, self.scene = renderer, scene
        self.gl: RawGL = renderer.raw_gl
        w, h = target.size
        self.size = (w, h)
        self.rb = self.gl.renderbuffer(w, h)
        self.fbo = self.ctx.framebuffer(color_attachments=list(target.color_attachments))
        self.gl.attach(self.fbo, self.rb)
        self.fbo.depth_mask = True
        args = (variant.method, variant.mode, variant.depth, variant.features, (), variant.image_only, False)
        self.planes = renderer.program(*args, first_hits="planes") if scene.planes else None
        self.how = how  # "spheres": a quad per sphere; "tiles": a quad per tile and its list
        self.spheres_prog, _ = renderer.program(*args, first_hits=how)
        self.entries: moderngl.Texture | None = None
        self.corners = self.ctx.buffer(CORNERS.tobytes())
        self.bounds = fh.image_bounds(scene) if scene.n_spheres else None
        self.keys = gpu_layout.sphere_keys(scene)
        self.instances: moderngl.Buffer | None = None
        self.vao: moderngl.VertexArray | None = None
        self.count = 0
        self.fragments = 0.0  # the quads' fragments over the frame's passes (stats)
        # A miss as the tracer writes it: black, id −1 (float targets), alpha 1 (the RGBA8 image).
        self.miss = (0.0, 0.0, 0.0, 1.0) if variant.image_only else (0.0, 0.0, 0.0, -1.0)

    def begin_pass(self, grid: tuple[int, int], scale: float, offset: tuple[float, float]) -> None:
        """The pass's quads (its ray grid and sub-pixel), and its target cleared."""
        self._release_quads()
        if self.how == "tiles":
            quads, entries = fh.tile_lists(self.scene, grid, self.size, scale, offset, self.bounds)
            fmt, names = fh.TILE_FORMAT, fh.TILE_ATTRIBUTES
            packed = gpu_layout.wrap_rows(entries, self.renderer.max_texture_width)
            self.entries = self.ctx.texture(packed.size, packed.components, packed.data.tobytes(), dtype=packed.dtype)
            self.entries.filter = (moderngl.NEAREST, moderngl.NEAREST)
        else:
            quads = fh.instances(self.scene, grid, self.size, scale, offset, self.keys, self.bounds)
            fmt, names = fh.INSTANCE_FORMAT, fh.INSTANCE_ATTRIBUTES
        self.fragments += fh.covered_fragments(quads, self.size)
        self.count = len(quads)
        if self.count:
            self.instances = self.ctx.buffer(quads.tobytes())
            self.vao = self.ctx.vertex_array(
                self.spheres_prog,
                [(self.corners, "2f", "a_corner"), (self.instances, fmt, *names)],
                skip_errors=True,  # a mode that needs no sphere record (none yet) lets the compiler drop it
            )
        self.fbo.scissor = None
        self.fbo.use()
        self.fbo.clear(*self.miss)
        self.gl.clear_depth()

    def bind(self, prog: moderngl.Program, unit: int) -> None:
        """The tiles' entries on texture ``unit`` (after the frame's own), for ``prog``."""
        if self.entries is not None and "u_tile_entries" in prog:
            self.entries.use(unit)
            prog["u_tile_entries"].value = unit  # type: ignore[union-attr]  # a sampler: a Uniform

    def draws(self) -> list[tuple[moderngl.Program, moderngl.VertexArray, int]]:
        """(program, vertex array, instances) of a band, in order: planes (instances 0: one
        full-screen draw), then the spheres' quads."""
        out: list[tuple[moderngl.Program, moderngl.VertexArray, int]] = []
        if self.planes is not None and self.planes[1] is not None:
            out.append((self.planes[0], self.planes[1], 0))
        if self.vao is not None:
            out.append((self.spheres_prog, self.vao, self.count))
        return out

    def depth_on(self) -> None:
        self.ctx.enable_only(moderngl.DEPTH_TEST)
        self.ctx.depth_func = "<="
        self.fbo.depth_mask = True
        self.fbo.use()

    def depth_off(self) -> None:
        self.ctx.enable_only(moderngl.NOTHING)

    def _release_quads(self) -> None:
        if self.vao is not None:
            self.vao.release()
        if self.instances is not None:
            self.instances.release()
        if self.entries is not None:
            self.entries.release()
        self.vao = self.instances = self.entries = None

    def release(self) -> None:
        self._release_quads()
        self.corners.release()
        self.fbo.release()
        self.gl.delete_renderbuffer(self.rb)
