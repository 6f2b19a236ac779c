"""The draws of a frame whose first hits are rasterised (:mod:`renderer.frame.first_hits`).

Per pass: the target's colours are cleared to a miss and its depth to 1.0; per band (a
scissor rectangle), the planes' pass — the background variant writing depth — where the
scene has planes, then the spheres' quads, instanced, under the depth test ≤. The target's
own colour attachments are drawn into through a framebuffer of this frame that adds a
float32 depth buffer (GL_DEPTH32F_STENCIL8: the depth is an exact float, not 24 bits).

A band's quads are drawn in *chunks* (:meth:`FirstHitDraws.band_chunks`), one a slice: the quads
that meet the band, in their order, cut where their estimated work in the band passes the slice's
budget — spheres whose quads all cover the same pixels cost their number of fragments per pixel,
and a frame of thousands of them is stopped (its time out, its client gone) within one chunk. The
depth test makes the chunks of a band add up to the one draw of all its quads: the quads come in
the same order, each under ≤ against what the earlier ones wrote; the tiles' quads do not overlap.
"""

from __future__ import annotations

import moderngl
import numpy as np

from ..frame import cost, first_hits as fh
from ..geometry.scene import Scene
from ..gpu import gpu_layout
from ..gpu.gpu_layout import Variant
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
        self.quads: np.ndarray | None = None  # the pass's quads (fh.INSTANCE or fh.TILE_INSTANCE records)
        self.fmt, self.names = fh.INSTANCE_FORMAT, fh.INSTANCE_ATTRIBUTES
        self.count = 0
        self.fragments = 0.0  # the quads' fragments over the frame's passes (stats)
        # A miss as the tracer writes it: black, id −1 (float targets), alpha 1 (the RGBA8 image).
        self.miss = (0.0, 0.0, 0.0, 1.0) if variant.image_only else (0.0, 0.0, 0.0, -1.0)

    def begin_pass(self, grid: tuple[int, int], scale: float, offset: tuple[float, float]) -> None:
        """The pass's quads (its ray grid and sub-pixel), and its target cleared."""
        self._release_quads()
        if self.how == "tiles":
            quads, entries = fh.tile_lists(self.scene, grid, self.size, scale, offset, self.bounds)
            self.fmt, self.names = fh.TILE_FORMAT, fh.TILE_ATTRIBUTES
            packed = gpu_layout.wrap_rows(entries, self.renderer.max_texture_width)
            self.entries = self.ctx.texture(packed.size, packed.components, packed.data.tobytes(), dtype=packed.dtype)
            self.entries.filter = (moderngl.NEAREST, moderngl.NEAREST)
        else:
            quads = fh.instances(self.scene, grid, self.size, scale, offset, self.keys, self.bounds)
            self.fmt, self.names = fh.INSTANCE_FORMAT, fh.INSTANCE_ATTRIBUTES
        self.fragments += fh.covered_fragments(quads, self.size)
        self.count = len(quads)
        self.quads = quads
        self.fbo.scissor = None
        self.fbo.use()
        self.fbo.clear(*self.miss)
        self.gl.clear_depth()

    def bind(self, prog: moderngl.Program, unit: int) -> None:
        """The tiles' entries on texture ``unit`` (after the frame's own), for ``prog``."""
        if self.entries is not None and "u_tile_entries" in prog:
            self.entries.use(unit)
            prog["u_tile_entries"].value = unit  # type: ignore[union-attr]  # a sampler: a Uniform

    def ns_per_unit(self) -> float:
        """Estimated ns of one unit of :meth:`band_work`: a quad's fragment, or a tile's list entry
        tested at one pixel (renderer/frame/cost.py's fitted constants)."""
        if self.how == "tiles":
            return cost.TILES_NS_PAIR / (fh.TILE * fh.TILE)
        return cost.RASTER_NS_FRAGMENT

    def band_rows(self, slice_ms: float | None) -> int:
        """Rows of a band of this pass: as many as keep one quad's work in the band (a quad across
        the whole width; a tile of the longest list) within ``slice_ms``; the whole pass without a
        budget."""
        w, h = self.size
        if not slice_ms:
            return h
        if self.how == "tiles":  # a tile's row: its width times its list
            longest = int(self.quads["list"][:, 1].max()) if self.quads is not None and len(self.quads) else 1
            per_row = fh.TILE * longest * self.ns_per_unit()
        else:
            per_row = w * self.ns_per_unit()
        return max(1, min(h, int(slice_ms * 1e6 / per_row)))

    def band_work(self, y0: int, rows: int) -> np.ndarray:
        """Per quad of the pass, its work inside rows ``y0 … y0 + rows − 1``: the fragments of its
        rectangle there (tiles: times its list's length)."""
        assert self.quads is not None, "begin_pass first"
        w, h = self.size
        r = self.quads["rect"].astype(np.float64)
        x0, x1 = (r[:, 0] + 1.0) * w / 2.0, (r[:, 2] + 1.0) * w / 2.0
        qy0, qy1 = (r[:, 1] + 1.0) * h / 2.0, (r[:, 3] + 1.0) * h / 2.0
        inside = np.clip(np.minimum(qy1, y0 + rows) - np.maximum(qy0, y0), 0.0, None)
        work = (x1 - x0) * inside
        if self.how == "tiles":
            work = work * self.quads["list"][:, 1]
        return work

    def band_chunks(self, y0: int, rows: int, slice_ms: float | None) -> list[np.ndarray]:
        """The quads that meet the band, in their order, cut into chunks of about ``slice_ms`` of
        estimated work (a quad over the budget alone; all of them in one without a budget)."""
        if self.quads is None or not len(self.quads):
            return []
        work = self.band_work(y0, rows)
        meet = np.flatnonzero(work > 0)
        if not len(meet):
            return []
        if not slice_ms:
            return [meet]
        budget = slice_ms * 1e6 / self.ns_per_unit()
        w = work[meet]
        group = np.floor((np.cumsum(w) - w) / budget).astype(np.int64)  # the budget each quad starts in
        return np.split(meet, np.flatnonzero(np.diff(group)) + 1)

    def draws(self, chunk: np.ndarray | None, planes: bool) -> list[tuple[moderngl.Program, moderngl.VertexArray, int]]:
        """(program, vertex array, instances) of one slice, in order: the planes (instances 0: one
        full-screen draw) when ``planes``, then the quads of ``chunk`` (indices into the pass's)."""
        out: list[tuple[moderngl.Program, moderngl.VertexArray, int]] = []
        if planes and self.planes is not None and self.planes[1] is not None:
            out.append((self.planes[0], self.planes[1], 0))
        self._release_vao()
        if chunk is not None and len(chunk):
            assert self.quads is not None
            self.instances = self.ctx.buffer(self.quads[chunk].tobytes())
            self.vao = self.ctx.vertex_array(
                self.spheres_prog,
                [(self.corners, "2f", "a_corner"), (self.instances, self.fmt, *self.names)],
                skip_errors=True,  # a mode that needs no sphere record (none yet) lets the compiler drop it
            )
            out.append((self.spheres_prog, self.vao, len(chunk)))
        return out

    def depth_on(self) -> None:
        self.ctx.enable_only(moderngl.DEPTH_TEST)
        self.ctx.depth_func = "<="
        self.fbo.depth_mask = True
        self.fbo.use()

    def depth_off(self) -> None:
        self.ctx.enable_only(moderngl.NOTHING)

    def _release_vao(self) -> None:
        if self.vao is not None:
            self.vao.release()
        if self.instances is not None:
            self.instances.release()
        self.vao = self.instances = None

    def _release_quads(self) -> None:
        self._release_vao()
        if self.entries is not None:
            self.entries.release()
        self.entries = None
        self.quads = None

    def release(self) -> None:
        self._release_quads()
        self.corners.release()
        self.fbo.release()
        self.gl.delete_renderbuffer(self.rb)
