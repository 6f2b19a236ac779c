"""One frame of the one-pass tracer as a sequence of slices of GPU work.

A frame is traced in *passes* and each pass in *bands* of rows; one band is one draw call
with a scissor rectangle, followed by ``glFinish``: a *slice*. Between slices the GL
thread may trace another frame's slice, or drop this frame (cancellation), so no frame
holds the thread for longer than one slice.

Passes (docs/FORMATS.md, "Camera and pixels"):

1. the **pixel centres**: one ray per pixel, ``W × H``. It gives the depth, primid and
   normal arrays of every mode, the whole image of the modes that are not averaged
   (depth, primid, normal) and of every frame at one sample per pixel, and the *preview*
   of a supersampled frame (:attr:`TracerFrame.preview`);
2. for a supersampled image (colour, recursion, heat at ``samples_per_pixel`` = k² > 1):
   one pass per sub-pixel ``(sx, sy)`` of the ``kW × kH`` grid, each ``W × H``. Their
   results are interleaved into the full grid and box-filtered exactly as one draw of
   the whole grid was (the shader's sub-pixel arithmetic is exact), so the final image is
   bit for bit the one a single ``kW × kH`` draw gives.

Uniforms, texture units and uniform-block bindings are program state, and frames of the
same variant share a program, so every slice binds its own frame's before drawing.

A frame is split by :func:`renderer.gpu.gpu_layout.frame_regions`: inside the rectangle the
spheres' box projects to, the tracer; outside it, where no primary ray can meet a sphere
— and, in colour and recursion frames, whose hits spawn rays, where it meets no plane
either — the *background* variant, the same shader without the traversal (llvmpipe runs
a loop's body once even when no lane enters it, so a pixel that misses the box still
paid for the traversal). The pixels are the same either way, bit for bit.

What a frame uploads is what its variant declares (:func:`check_bindings`): record arrays
the renderer chose to read from uniform blocks (``variant.blocks``) as 64 KiB buffers,
everything else as textures. A png or jpeg frame at one sample per pixel
(:func:`image_only`) renders into one RGBA8 target, the shader rounding the colour as
``RenderResult.image_u8`` does; its result (:class:`ImageOnlyResult`) carries those bytes,
and its float image, depth, primid and normal arrays are traced again (with float
targets) only if someone reads them — the service never does for those formats.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import moderngl
import numpy as np

from ..config.methods import PreparedMethod
from ..frame import first_hits
from ..frame.shader_source import known_bindings, tracer_bindings
from ..geometry.scene import Scene
from ..gpu import gpu_layout, texture_layout
from ..gpu.gpu_layout import PackedScene, Variant
from ..image.result import RenderResult
from ..limits import MAX_BAND_GROWTH, PATH_SAMPLES_PER_PASS
from ..modes import AVERAGED_MODES, PRIMARY_MODES
from .first_hits import FirstHitDraws
from .textures import upload_blocks, upload_textures

if TYPE_CHECKING:
    from ..config.settings import RenderSettings


@dataclass(frozen=True)
class Pass:
    """One pass: the pixel centres (``sub`` None) or one sub-pixel of a ``scale``² grid; of the
    path integrator, ``samples`` = (first, count): those samples of every pixel, summed; ``cell``:
    where in its sub-pixel the ray goes (a Whitted accumulation's jittered slice; None: the centre)."""

    scale: int
    sub: tuple[int, int] | None
    samples: tuple[int, int] | None = None
    cell: tuple[float, float] | None = None

    @property
    def name(self) -> str:
        if self.samples is not None:
            return f"samples {self.samples[0]}…{self.samples[0] + self.samples[1] - 1}"
        return "centre" if self.sub is None else f"sample {self.sub[0]},{self.sub[1]}"


def image_only(settings: RenderSettings) -> bool:
    """Whether a frame needs only its 8-bit image: png or jpeg at one sample per pixel (a
    supersampled frame keeps float sub-pixels, so its box filter is the same)."""
    return (
        settings.format in ("png", "jpeg") and settings.samples_per_pixel == 1 and not settings.path_traced
    )  # radiance, tone-mapped later


class ImageOnlyResult(RenderResult):
    """The result of an image-only frame: :meth:`image_u8` gives the bytes the shader wrote
    (those of ``image_u8()`` of the float image); ``image``, ``depth``, ``primid`` and
    ``normal`` are those of the same frame traced again with float targets, on first use
    (from the thread that owns the renderer).

    It holds the RGBA8 read-back as it came (GL rows, bottom first): flipping it and dropping
    the alpha byte was a strided copy of the whole image (2.7 ms at 640 × 1088, twice the
    JPEG encoder's time) that the encoder does for free while it unpacks
    (:meth:`image_rows_rgbx`)."""

    def __init__(self, rgba_rows: np.ndarray, mode: str, timings: dict, stats: dict, arrays):
        self._rgba_rows, self.mode, self.timings, self.stats = rgba_rows, mode, timings, stats
        self._arrays = arrays
        self._full: RenderResult | None = None

    def image_u8(self) -> np.ndarray:
        return np.ascontiguousarray(self._rgba_rows[::-1, :, :3])

    def image_rows_rgbx(self) -> np.ndarray:
        return self._rgba_rows

    def _traced(self) -> RenderResult:
        if self._full is None:
            self._full = self._arrays()
            self._arrays = None
        return self._full

    image = property(lambda self: self._traced().image)
    depth = property(lambda self: self._traced().depth)
    primid = property(lambda self: self._traced().primid)
    normal = property(lambda self: self._traced().normal)


# Modes whose pixels outside the spheres' box (and, for colour and recursion, outside every
# plane) owe nothing to the spheres (heat is left out: brute force counts its tests on
# every ray); of those, the modes that trace the primary ray only.
BACKGROUND_MODES = ("depth", "primid", "normal", "color", "recursion")


def plan_path_passes(samples: int, per_pass: int, first: int = 0) -> list[Pass]:
    """The path integrator's passes: ``samples`` per pixel from sample index ``first`` on, at most
    ``per_pass`` in each. A pixel's sample i is the same path in whichever pass (or frame) traces it
    (its random numbers depend on the pixel and i alone), so the frame's sum is the same however it
    is cut (up to float rounding) — and frames that go on from ``first`` = the samples held sum to
    one frame of them all (an accumulation, ``TracerFrame(accumulated=…)``)."""
    per_pass = max(1, int(per_pass))
    return [Pass(1, None, (first + s, min(per_pass, samples - s))) for s in range(0, samples, per_pass)]


def plan_whitted_slices(k: int, first: int, count: int) -> list[Pass]:
    """A Whitted accumulation's passes after the pixel centres: slices ``first`` … ``first + count − 1``,
    each the k × k sub-pixel grid with every sub-pixel's ray at the slice's point of the R2 sequence
    inside it (:func:`renderer.gpu.gpu_layout.subpixel_cell`: the same for every pixel and sub-pixel).
    Slice 0 is the cell centres — the passes of today's frame (at k = 1 the centre pass itself, so
    none here) — and every slice adds k² samples per pixel."""
    out: list[Pass] = []
    for j in range(first, first + count):
        if j == 0:
            out += [Pass(k, (sx, sy)) for sy in range(k) for sx in range(k)] if k > 1 else []
        else:
            cell = gpu_layout.subpixel_cell(j)
            out += [Pass(k, (sx, sy), cell=cell) for sy in range(k) for sx in range(k)]
    return out


def plan_passes(mode: str, k: int) -> list[Pass]:
    """The passes of a frame of ``mode`` at k × k samples per pixel (sy from the bottom)."""
    passes = [Pass(1, None)]
    if k > 1 and mode in AVERAGED_MODES:
        passes += [Pass(k, (sx, sy)) for sy in range(k) for sx in range(k)]
    return passes


class TracerFrame:
    """A frame of the one-pass tracer, traced slice by slice (:meth:`step`).

    ``renderer``: the :class:`~renderer.gl.renderer.GLRenderer` that owns the context, the
    programs and the target pool. ``band_rows``: rows of the first band (None: each pass in
    one draw); with ``slice_ms`` the next bands are resized from the measured time of the last
    one, so that a slice costs about ``slice_ms`` even where the cost model is off (a leaf of
    thousands of spheres costs 4× its estimate). ``one_shot``: trace a
    supersampled image the way it was before passes existed — one draw of the whole
    ``kW × kH`` grid, ids from its middle sub-pixel — for tests and benchmarks that
    compare against it.

    ``accumulated`` (the path integrator's colour, or Whitted's): the samples an accumulation
    holds (their float32 sum, image rows, or None; their count) — the frame goes on from them and
    its result hands the new sum back. A Whitted colour frame then traces ``slices`` jittered
    slices of its k × k grid (:func:`plan_whitted_slices`), from slice count ÷ k² on, so frames of
    one slice each add up to one frame of them all; its first slice alone is the plain frame.
    """

    def __init__(
        self,
        renderer,
        scene: Scene,
        settings: RenderSettings,
        variant: Variant,
        prepared: PreparedMethod,
        stats: dict,
        *,
        band_rows: int | None = None,
        one_shot: bool = False,
        t_start: float | None = None,
        slice_ms: float | None = None,
        samples_per_pass: int = PATH_SAMPLES_PER_PASS,
        accumulated: tuple[np.ndarray | None, int] | None = None,
        slices: int = 1,
    ):
        self.renderer, self.ctx = renderer, renderer.ctx
        self.scene, self.settings, self.variant, self.prepared = scene, settings, variant, prepared
        self.stats = stats
        self.t_start = t_start if t_start is not None else time.perf_counter()
        self.k = settings.supersampling
        self.one_shot = one_shot and self.k > 1
        self.width, self.height = settings.width, settings.height
        self.path = variant.path
        # An accumulation goes on from the samples it holds: (their float32 sum, image rows, or None
        # when it holds none yet; their count); the result hands the new sum back.
        self.whitted_acc = accumulated is not None and not self.path and settings.mode == "color" and not one_shot
        self.accumulated = accumulated if self.path or self.whitted_acc else None
        self._held = 0 if self.accumulated is None else int(self.accumulated[1])
        self._wsum: np.ndarray | None = None  # a Whitted accumulation's sum of this frame's samples (GL rows)
        self._new = 0  # … and their count per pixel
        if self.path:
            self.passes = plan_path_passes(settings.samples_per_pixel, samples_per_pass, self._held)
        elif self.whitted_acc:
            s, n = self.k * self.k, max(1, int(slices))
            self._first_slice = self._held // s
            self._new = n * s
            self.passes = [Pass(1, None), *plan_whitted_slices(self.k, self._first_slice, n)]
        else:
            self.passes = [Pass(self.k, None)] if self.one_shot else plan_passes(settings.mode, self.k)
        self._sum: np.ndarray | None = None  # the path integrator's sum of samples (GL rows), float64
        # A path frame with the denoiser's guides: their sums over this frame's samples (GL rows).
        self.guides = self.path and "GUIDES" in variant.features
        self._guide_sums: list[np.ndarray] | None = None
        self.band_rows = band_rows
        self._first_band = int(band_rows or 1)
        self.slice_ms = slice_ms
        self.prog, self.vao = renderer.program(
            variant.method, variant.mode, variant.depth, variant.features, variant.blocks, variant.image_only
        )
        # The pixels whose primary ray can meet no sphere (no primitive at all, when hits spawn
        # rays) are drawn by the background variant.
        self.regions: list[tuple[int, int, int, int, bool]] | None = None
        # (Not for paths: their primary rays are spread over the pixel, and the environment lights every miss.)
        if (
            getattr(renderer, "background", False)
            and variant.mode in BACKGROUND_MODES
            and not self.one_shot
            and not self.path
        ):
            self.regions = gpu_layout.frame_regions(
                scene, self.width, self.height, planes=variant.mode not in PRIMARY_MODES
            )
            if self.regions is not None:
                self.bg_prog, self.bg_vao = renderer.program(
                    variant.method, variant.mode, variant.depth, variant.features, (), variant.image_only, False
                )
                stats["background_pixels"] = sum(w * h for _, _, w, h, tracer in self.regions if not tracer)
        self.textures: list[moderngl.Texture | moderngl.TextureArray] = []
        self.buffers: list[moderngl.Buffer] = []
        self.fbo: moderngl.Framebuffer | None = None
        # Rasterised first hits (renderer/frame/first_hits.py) instead of the traversal, when chosen.
        self.raster = (
            "" if self.one_shot else first_hits.chosen(scene, settings, variant.path, variant.method, prepared.stats)
        )
        if self.raster:
            self.regions = None
        if variant.mode in PRIMARY_MODES and not self.one_shot:
            stats["first_hits"] = self.raster or "trace"
        self.first_hits: FirstHitDraws | None = None
        self.timings = {
            "build": prepared.build_ms,
            "update": prepared.build_ms,
            "upload": 0.0,
            "trace": 0.0,
            "read": 0.0,
        }
        self.slices = 0
        self._pass_index = 0
        self._row = 0
        # A band of rasterised first hits in progress: its rows and the chunks of quads left to draw.
        self._raster_rows = 0
        self._chunks: list[np.ndarray] | None = None
        # image, hit of the centre pass (GL rows); an image-only frame reads no hit
        self._centre: tuple[np.ndarray, np.ndarray | None] | None = None
        self._subs: dict[tuple[int, int], np.ndarray] = {}  # (sx, sy) → that sub-pixel pass's image (GL rows)
        self._preview: RenderResult | None = None
        self._result: RenderResult | None = None
        self._sample_sum: np.ndarray | None = None  # an accumulation's new float32 sum (image rows)
        self._guides: tuple[np.ndarray, ...] | None = None  # the denoiser's (albedo, normal), image rows
        self._upload()

    # ---- set-up ------------------------------------------------------------------------------
    def _upload(self) -> None:
        """Upload exactly what the variant declares (see :func:`check_bindings`) and take a target."""
        t0 = time.perf_counter()
        surface = texture_layout.pack_surface_data(self.scene, self.renderer.max_texture_width)
        parts = [
            gpu_layout.pack_primitives(self.scene, self.renderer.max_texture_width),
            self.prepared.packed,
            PackedScene({}, gpu_layout.frame_uniforms(self.scene, self.settings.min_weight)),
            surface.packed,
        ]
        if surface.nbytes:  # a textured scene's GPU bytes in the frame's statistics
            self.stats["texture_bytes"] = surface.nbytes.get(gpu_layout.TEXTURES.name, 0)
            self.stats["attribute_bytes"] = sum(v for k, v in surface.nbytes.items() if k != gpu_layout.TEXTURES.name)
            if surface.array is not None and surface.array.notices:
                self.stats["texture_notices"] = list(surface.array.notices)
        tex, self.uniforms = check_bindings(self.variant, parts)
        blocks = {n: t for n, t in tex.items() if n in self.variant.blocks}
        self.units = upload_textures(
            self.ctx, PackedScene({n: t for n, t in tex.items() if n not in blocks}), self.textures
        )
        self.block_units = upload_blocks(self.ctx, blocks, self.buffers)
        w, h = self._target_size()
        self.fbo = self.renderer.targets.acquire(w, h, self.variant.image_only, self.guides)
        if self.raster:
            how = "tiles" if self.raster == "tiles" else "spheres"
            self.first_hits = FirstHitDraws(self.renderer, self.scene, self.variant, self.fbo, how)
        self.ctx.finish()
        self.timings["upload"] = (time.perf_counter() - t0) * 1e3

    def _target_size(self) -> tuple[int, int]:
        return (self.width * self.k, self.height * self.k) if self.one_shot else (self.width, self.height)

    def _bind(self, p: Pass, prog: moderngl.Program | None = None) -> None:
        """This frame's textures, uniforms and the pass's camera terms onto the shared program
        (``prog``: the background variant's instead)."""
        prog = self.prog if prog is None else prog
        for unit, tex in enumerate(self.textures):
            tex.use(unit)
        for name, unit in self.units.items():
            if name in prog:
                cast(moderngl.Uniform, prog[name]).value = unit
        for binding, (name, buf) in enumerate(self.block_units.items()):
            if name in prog:
                buf.bind_to_uniform_block(binding)
                cast(moderngl.UniformBlock, prog[name]).binding = binding
        if self.one_shot:  # the whole k × k grid in one draw: each fragment is one sub-pixel
            grid, pass_terms = self._target_size(), gpu_layout.pass_uniforms(1)
        else:
            grid = (self.width * p.scale, self.height * p.scale)
            pass_terms = gpu_layout.pass_uniforms(p.scale, p.sub or (0, 0), p.cell or (0.5, 0.5))
        camera = gpu_layout.camera_uniforms(self.scene.camera, *grid)
        if p.samples is not None:
            pass_terms = {**pass_terms, **gpu_layout.path_uniforms(*p.samples)}
        for name, value in {**self.uniforms, **camera, **pass_terms}.items():
            if name in prog:
                set_uniform(prog[name], value)

    # ---- slices ------------------------------------------------------------------------------
    @property
    def done(self) -> bool:
        return self._result is not None

    @property
    def pixels_total(self) -> int:
        """Fragments the frame shades in all (its passes' areas)."""
        w, h = self._target_size()
        return w * h * len(self.passes)

    @property
    def pixels_left(self) -> int:
        if self.done:
            return 0
        w, h = self._target_size()
        return w * h * (len(self.passes) - self._pass_index) - w * self._row

    def step(self) -> bool:
        """Trace the next band (one draw + glFinish; of rasterised first hits, the next chunk of a
        band's quads); True when the frame is complete."""
        if self.done:
            return True
        p = self.passes[self._pass_index]
        w, h = self._target_size()
        rows = h - self._row if self.band_rows is None else min(max(1, int(self.band_rows)), h - self._row)
        t0 = time.perf_counter()
        assert self.fbo is not None, "the target is held until the last pass"
        if self.first_hits is not None:
            rows = self._raster_slice(p, w, h)
            if not rows:  # more chunks of the band to draw
                self.ctx.finish()
                self.timings["trace"] += (time.perf_counter() - t0) * 1e3
                self.slices += 1
                return False
        else:
            self.fbo.use()
            for prog, vao, scissor in self._draws(w, h, self._row, rows):
                self._bind(p, prog)
                self.fbo.scissor = scissor
                vao.render(moderngl.TRIANGLES)
        self.ctx.finish()
        ms = (time.perf_counter() - t0) * 1e3
        self.timings["trace"] += ms
        self.slices += 1
        if self.slice_ms and self.band_rows is not None and self.first_hits is None:
            # Rows cost alike within a pass; at most doubling keeps one cheap band (sky) from
            # sizing the next, dearer one (the scene) far over the budget.
            # Nor beyond MAX_BAND_GROWTH × the first band (sized for the scene's rows by the cost
            # model): doubling band after band of sky would reach the scene with a band of most of it.
            fit = int(self.slice_ms * rows / max(ms, 1e-3))
            self.band_rows = max(1, min(fit, 2 * rows, self._first_band * MAX_BAND_GROWTH, h))
        self._row += rows
        if self._row >= h:
            self._finish_pass(p)
            self._row = 0
            self._pass_index += 1
            if self._pass_index == len(self.passes):
                # The target first (everything is read back): on llvmpipe it is host memory, as much
                # as the read-back, and need not wait for the result's arrays to be made.
                self.release()
                self._result = self._compose()
                self._centre = None  # (an image-only frame's) the result holds what it needs
                self._subs = {}
        return self.done

    def _raster_slice(self, p: Pass, w: int, h: int) -> int:
        """One slice of a frame with rasterised first hits: at a band's start the planes' pass and
        its first chunk of quads, then its next chunk (:meth:`FirstHitDraws.band_chunks`, each about
        ``slice_ms`` of estimated work). Returns the band's rows once its last chunk is drawn, else 0."""
        fh = self.first_hits
        assert fh is not None
        first = self._chunks is None
        if first:
            if self._row == 0:
                sub, cell = p.sub or (0, 0), p.cell or (0.5, 0.5)  # as _bind's pass uniforms
                grid = (self.width * p.scale, self.height * p.scale)
                fh.begin_pass(grid, float(p.scale), (sub[0] + cell[0], sub[1] + cell[1]))
                # bands sized for the budget, or as asked (a frame traced without one)
                self._raster_rows = fh.band_rows(self.slice_ms) if self.slice_ms else int(self.band_rows or h)
            self._raster_rows = min(self._raster_rows, h - self._row)
            self._chunks = fh.band_chunks(self._row, self._raster_rows, self.slice_ms)
        assert self._chunks is not None
        rows = self._raster_rows
        chunk = self._chunks.pop(0) if self._chunks else None
        fh.depth_on()
        fh.fbo.scissor = (0, self._row, w, rows) if rows < h else None
        for prog, vao, instances in fh.draws(chunk, planes=first):
            self._bind(p, prog)
            fh.bind(prog, len(self.textures))
            if instances:
                vao.render(moderngl.TRIANGLES, instances=instances)
            else:
                vao.render(moderngl.TRIANGLES)
        fh.depth_off()
        if self._chunks:
            return 0
        self._chunks = None
        return rows

    def _draws(self, w: int, h: int, y0: int, rows: int) -> list:
        """(program, vertex array, scissor) of the draws of one band of rows: the tracer, or
        for a split frame each region's variant on its part of the band."""
        if self.regions is None:
            return [(self.prog, self.vao, (0, y0, w, rows) if rows < h else None)]
        out = []
        for x, y, rw, rh, tracer in self.regions:
            a, b = max(y, y0), min(y + rh, y0 + rows)
            if b > a:
                out.append(
                    (self.prog, self.vao, (x, a, rw, b - a))
                    if tracer
                    else (self.bg_prog, self.bg_vao, (x, a, rw, b - a))
                )
        return out

    def run(self) -> RenderResult:
        """Every remaining slice, then the result."""
        while not self.step():
            pass
        return self.result()

    def _finish_pass(self, p: Pass) -> None:
        t0 = time.perf_counter()
        w, h = self._target_size()
        assert self.fbo is not None, "the target is held until the last pass"
        self.fbo.scissor = None  # type: ignore[assignment]  # None: no scissor (moderngl's stubs omit it)
        if self.variant.image_only:
            u8 = np.frombuffer(self.fbo.read(components=4, dtype="f1", attachment=0), np.uint8).reshape(h, w, 4)
            self._centre = (u8, None)
            self.timings["read"] += (time.perf_counter() - t0) * 1e3
            return
        img = np.frombuffer(self.fbo.read(components=4, dtype="f4", attachment=0), np.float32).reshape(h, w, 4)
        if p.samples is not None:
            # Sums of each pass's samples, added in float64: the frame's sum does not depend on
            # how its samples are cut into passes beyond the float32 sums of the passes.
            if self._sum is None:
                self._sum = img[..., :3].astype(np.float64)
                hit = np.frombuffer(self.fbo.read(components=4, dtype="f4", attachment=1), np.float32).reshape(h, w, 4)
                self._centre = (img, hit)  # primid, normal and depth: the first sample's primary ray
                held = None if self.accumulated is None else self.accumulated[0]
                if held is not None:  # the samples held before this frame's
                    self._sum += held[::-1]
                    if len(self.passes) > 1:
                        mean = (self._sum[::-1] / (self._held + p.samples[1])).astype(np.float32)
                        self._preview = self._result_of([img[::-1], hit[::-1], mean], final=False)
                elif len(self.passes) > 1:  # the first pass's mean: the preview of a progressive frame
                    mean = (img[::-1][..., :3] / p.samples[1]).astype(np.float32)
                    self._preview = self._result_of([img[::-1], hit[::-1], mean], final=False)
            else:
                self._sum += img[..., :3]
            if self.guides:  # albedo and normal sums of the pass's samples
                sums = [
                    np.frombuffer(self.fbo.read(components=4, dtype="f4", attachment=a), np.float32).reshape(h, w, 4)[
                        ..., :3
                    ]
                    for a in (2, 3)
                ]
                if self._guide_sums is None:
                    self._guide_sums = [x.astype(np.float64) for x in sums]
                else:
                    for total, x in zip(self._guide_sums, sums, strict=True):
                        total += x
        elif p.sub is None:
            hit = np.frombuffer(self.fbo.read(components=4, dtype="f4", attachment=1), np.float32).reshape(h, w, 4)
            self._centre = (img, hit)
            if self.whitted_acc and self.k == 1 and self._first_slice == 0:  # slice 0 at k = 1: the centres
                self._wsum = img[..., :3].astype(np.float64)
            if len(self.passes) > 1 and not (self.whitted_acc and self._held):  # (not below what is held)
                self._preview = self._result_of([img[::-1], hit[::-1], img[::-1][..., :3]], final=False)
        elif self.whitted_acc and not (self._first_slice == 0 and len(self.passes) == 1 + self.k * self.k):
            # a jittered slice's sub-pixel (or slice 0's beside others): only its sum is kept
            if self._wsum is None:
                self._wsum = img[..., :3].astype(np.float64)
            else:
                self._wsum += img[..., :3]
        else:
            assert p.sub is not None, "a sub-pixel pass"
            self._subs[p.sub] = img  # the read-back as it came: the box filter reads it in place
        self.timings["read"] += (time.perf_counter() - t0) * 1e3

    # ---- results -----------------------------------------------------------------------------
    def _compose(self) -> RenderResult:
        assert self._centre is not None, "the centre pass is read back"
        if self.variant.image_only:
            u8 = self._centre[0]  # GL rows, RGBA: ImageOnlyResult flips when asked
            timings = {**self.timings, "total": (time.perf_counter() - self.t_start) * 1e3}
            stats = {**self.stats, "tracer_passes": len(self.passes), "slices": self.slices}
            r, scene, settings, prepared = self.renderer, self.scene, self.settings, self.prepared
            return ImageOnlyResult(
                u8,
                settings.mode,
                timings,
                stats,
                lambda: r.begin(scene, settings.with_(format="npy"), prepared=prepared).run(),
            )
        img, hit = self._centre
        self._centre = None  # the arrays below are the read-back's last references
        assert hit is not None, "a float frame reads the hit target too"
        img, hit = img[::-1], hit[::-1]  # image row 0 at the top
        k, W, H = self.k, self.width, self.height
        if self.one_shot:  # the old way: ids from the middle sub-pixel
            color = img[..., :3].reshape(H, k, W, k, 3).mean(axis=(1, 3))
            img, hit = img[k // 2 :: k, k // 2 :: k], hit[k // 2 :: k, k // 2 :: k]
        elif self._sum is not None:  # the mean of the path samples: a box filter over the pixel
            color = (self._sum[::-1] / (self._held + self.settings.samples_per_pixel)).astype(np.float32)
            if self.accumulated is not None:  # what the accumulation holds next (committed by the caller)
                self._sample_sum = self._sum[::-1].astype(np.float32)
            self._sum = None
            if self._guide_sums is not None:  # means over this frame's samples (an accumulation's too)
                n = self.settings.samples_per_pixel
                self._guides = tuple((g[::-1] / n).astype(np.float32) for g in self._guide_sums)
                self._guide_sums = None
        elif self._subs:  # the box filter over the sub-pixel passes
            color = box_filter(self._subs, k)
            if self.whitted_acc:  # one slice, the first: the plain frame's image, and its sum
                total = box_filter(self._subs, k, np.float64)
                self._sample_sum = self._whitted_total(total).astype(np.float32)
            self._subs = {}
        elif self._wsum is not None:  # a Whitted accumulation: the mean of all its samples
            total = self._whitted_total(self._wsum[::-1])
            self._wsum = None
            self._sample_sum = total.astype(np.float32)
            if self._held == 0 and self._new == 1:  # slice 0 at k = 1 alone: the centres as they are
                color = img[..., :3]
            else:
                color = (total / (self._held + self._new)).astype(np.float32)
            del total
        else:
            color = img[..., :3]
        arrays = [img, hit, color]
        del img, hit, color
        return self._result_of(arrays, final=True)

    def _whitted_total(self, total: np.ndarray) -> np.ndarray:
        """A Whitted accumulation's new sum (float64, image rows): the held one plus ``total``, this
        frame's sum of samples (float64, image rows)."""
        held = None if self.accumulated is None else self.accumulated[0]
        return total if held is None else total + held

    def _result_of(self, arrays: list[np.ndarray], final: bool) -> RenderResult:
        """The result made of ``[img, hit, colour]`` (image rows, top first), which it empties: each
        read-back is freed as soon as what is made of it exists (where nothing else holds it), so
        a 4096² frame holds one of its two 256 MiB read-backs beside its new arrays, not both."""
        img, hit, color = arrays
        arrays.clear()
        primid = img[..., 3].astype(np.int32)
        image = np.ascontiguousarray(color, dtype=np.float32)
        del img, color
        depth_t = np.where(primid >= 0, hit[..., 3], np.float32(np.inf)).astype(np.float32, copy=False)
        normal = np.ascontiguousarray(hit[..., :3])
        del hit
        timings = {**self.timings, "total": (time.perf_counter() - self.t_start) * 1e3}
        stats = {**self.stats, "tracer_passes": len(self.passes), "slices": self.slices}
        if not final:
            stats["preview"] = True
        display = (self.settings.tone_map, float(self.settings.exposure)) if self.path else None
        samples = None
        if self.path:  # samples per pixel the image is the mean of (an accumulation's included)
            first = self.passes[0].samples or (0, 0)  # a preview is the first pass's mean
            samples = self._held + (self.settings.samples_per_pixel if final else first[1])
            stats["samples"] = samples
        elif self.whitted_acc and final:  # sub-pixel samples per pixel the accumulation's mean holds
            samples = self._held + self._new
            stats["samples"] = samples
        return RenderResult(
            image=image,
            depth=depth_t,
            primid=primid,
            normal=normal,
            mode=self.settings.mode,
            timings=timings,
            stats=stats,
            display=display,
            samples=samples,
            sample_sum=self._sample_sum if final else None,
            guides=self._guides if final else None,
        )

    @property
    def preview(self) -> RenderResult | None:
        """The pixel-centre image of a frame with more passes to come, once it exists."""
        return self._preview

    def result(self) -> RenderResult:
        if self._result is None:
            raise RuntimeError("the frame is not complete")
        return self._result

    def release(self) -> None:
        """Give the GPU memory back (at the end, or when the frame is cancelled)."""
        for t in self.textures:
            t.release()
        self.textures = []
        for b in self.buffers:
            b.release()
        self.buffers = []
        if self.first_hits is not None:
            self.stats["first_hit_quads"] = self.first_hits.count
            self.stats["first_hit_fragments"] = round(self.first_hits.fragments)
            self.first_hits.release()
            self.first_hits = None
        if self.fbo is not None:
            self.fbo.scissor = None  # type: ignore[assignment]  # None: no scissor (moderngl's stubs omit it)
            self.renderer.targets.release(self.fbo)
            self.fbo = None


def box_filter(subs: dict[tuple[int, int], np.ndarray], k: int, dtype: type = np.float32) -> np.ndarray:
    """The k × k box filter over the sub-pixel passes' images (``subs``: (sx, sy) → H × W × 4, GL rows):
    image rows, H × W × 3 — the mean (``dtype`` float32) or, with float64, the sum. Bit for bit what
    interleaving them into the kH × kW grid and taking ``grid[::-1][..., :3].reshape(H, k, W, k,
    3).mean(axis=(1, 3))`` (or ``.sum(…, dtype=np.float64)``) gives: NumPy adds a pixel's sub-pixels in
    the grid's memory order — image rows of sub-pixels from the top (sy from k − 1 down), sx across —
    and divides as ``mean`` does; done here pass by pass, without the 4 × k² bytes-a-pixel grid and its
    strided reduction (0.1–0.2 s of a 640 × 1088 frame at 2 × 2 on llvmpipe's two cores here)."""
    order = [subs[(sx, sy)][::-1, :, :3] for sy in reversed(range(k)) for sx in range(k)]
    acc: np.ndarray = order[0].astype(dtype)  # a contiguous copy
    for img in order[1:]:
        np.add(acc, img, out=acc, dtype=dtype)
    if dtype is np.float32:
        np.true_divide(acc, np.intp(k * k), out=acc, casting="unsafe")  # as ndarray.mean divides
    return acc


def set_uniform(u, value) -> None:
    """Set a uniform; of an array the compiler shortened (a specialised variant indexes only
    the planes it has), the elements it kept."""
    if isinstance(value, list) and u.array_length < len(value):
        value = value[0] if u.array_length == 1 else value[: u.array_length]
    u.value = value


def check_bindings(variant: Variant, parts: list[PackedScene]) -> tuple[dict, dict]:
    """The textures and uniforms of ``parts`` that ``variant`` declares.

    Every packed name must be a binding some layout declares (KeyError otherwise: a
    misspelt name is an error, never skipped); those the variant does not read are left
    out; a binding it reads that nothing packed is an error too. (The camera and pass
    uniforms are set per pass.)
    """
    known = known_bindings()
    per_pass = {b.name for b in (*gpu_layout.CAMERA_BINDINGS, *gpu_layout.PASS_BINDINGS, *gpu_layout.PATH_BINDINGS)}
    declared = {b.name for b in tracer_bindings(variant)} - per_pass
    tex: dict[str, Any] = {}
    uni: dict[str, Any] = {}
    for part in parts:
        for name in (*part.textures, *part.uniforms):
            if name not in known:
                raise KeyError(
                    f"{name!r} is packed but no layout declares it "
                    "(renderer/gpu/gpu_layout.py, renderer/accel/*_layout.py)"
                )
        tex.update((n, t) for n, t in part.textures.items() if n in declared)
        uni.update((n, v) for n, v in part.uniforms.items() if n in declared)
    missing = declared - set(tex) - set(uni)
    if missing:
        raise KeyError(f"the {variant.method} shader reads {sorted(missing)} but nothing packed them")
    return tex, uni
