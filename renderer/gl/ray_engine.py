"""Multi-pass ray tracing: the ray engine and the hierarchical ray engine.

Both are methods of :mod:`renderer.accel.ray_engine` (``rayengine``, ``hre``) whose
capabilities say ``multi_pass``: the GL renderer hands their frames to
:class:`RayEnginePasses` (one per renderer, holding its programs and targets). Rays live in float
textures, primitives are drawn over them, and the Whitted shading of ``docs/SHADING.md`` runs as full-screen passes.

**Ray engine** (Carr et al. 2002, as Szécsi §2.1 restates it). A *layer* is one set of
rays, one per pixel, in two RGBA32F textures the size of the render target: origin and
exclusion code, direction and path weight (weight 0 = no live ray). To intersect a
layer, every primitive is drawn once over the whole target (an instanced full-screen
quad, instance = primitive id: spheres, then planes). Its fragment shader intersects the
pixel's ray with that primitive and writes ``depth_of(t)`` — the bits of ``t`` with the
exponent shifted, exact and monotonic — into a 32-bit float depth buffer
(``DEPTH32F_STENCIL8``), and ``(t, id)`` into an RG target; the depth test "less" keeps
the nearest hit, and because instances are drawn in id order, exactly equal ``t`` keep
the lower id. No tree, no CPU work per ray.

**Hierarchical ray engine** (Szécsi 2006, §3–§5). The target is split into tiles of
``tile_size``² rays (16 by default; the target is padded to whole tiles, padding texels
hold no ray). Per layer, a shader pass builds one enclosing cone per tile with the
incremental algorithm of §4 (``shaders/rayengine_cones.frag``, mirrored in NumPy in
:mod:`renderer.accel.hre_cones`), certified conservative in float32; the small cone texture is
read back and becomes a vertex buffer of the tiles that hold live rays. Each primitive
is then drawn as one point of the tile's size per tile (instanced: instance = primitive),
and the vertex shader moves the point out of view when the primitive's enclosing sphere
cannot meet the tile's cone (the inequality at the end of §4, with margins: when in
doubt, draw). Planes have no enclosing sphere and are drawn over every live tile.

**Generations and layers.** A generation is one recursion level. Whitted rays branch
(reflected and transmitted), so a generation is held as *layers*, one per branch path:
the shading pass of a layer writes its reflected rays into one new layer and its
transmitted rays into another. Layers are traced depth first from a stack (at most
``depth + 1`` alive, the memory of a ``W×H`` ray pair each), the transmitted child
first. Per layer: a mask pass, (hre: the cones), the nearest-hit pass, a surface pass
(hit point, normal), per light a shadow generation (any hit, the rays from the surfaces
to the light; hre: their own cones), and the shading pass, which adds the weighted local
colour into the frame (additive blending) and spawns the children. Layers without a live
ray are skipped (an occlusion query on the mask pass counts them).

**Stencil (§5).** One stencil bit per generation: the mask pass of a generation-``g``
layer sets bit ``g − 1`` where the layer holds a live ray (a ray spawned by a hit of the
parent layer: terminated paths — misses, materials without ``kr``/``kt``, the last
level — never get it), and every later pass of that layer tests it. 8 stencil bits cover
``limits.MAX_RECURSION_DEPTH`` = 8 generations; with fewer bits (``stencil_bits``), the
generations beyond run without stencil exclusion, as §5 allows ("further iterations are
possible without excluding further terminated paths"); the shaders' own test of the
weight keeps the image exact either way, and ``stats["stencil_fallback_levels"]`` says it.

**Modes.** ``color`` and ``recursion`` trace the ray tree (``recursion`` without lights
or shadows, reading each layer's hits back); ``depth``, ``primid``, ``normal`` the
primary layer only. ``heat``: red = 0.05 × spheres drawn over the pixel for its primary
ray (every sphere for ``rayengine``; the spheres whose cone test passed for the pixel's
tile for ``hre``), green and blue 0 (there are no nodes or gaps). ``cones`` (``hre``
only; :class:`SceneError` for ``rayengine``): the cone of each tile of the first layer
of generation ``max_recursion_depth`` in tracing order (the transmitted-first path, the
paper's refraction path), grey ``1 − φ/(π/2)`` (brighter = narrower, Szécsi's Fig. 4),
black where the tile holds no live ray, dark red where no useful cone exists.

**Timings** (ms): ``build`` = the cone passes, their read-back and the tile buffers
(0 for ``rayengine``), ``upload`` = scene textures and ray targets, ``trace`` = every
other pass, ``read`` = reading the frame back, ``total``.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, cast

import moderngl
import numpy as np

from ..accel import hre_cones
from ..accel.ray_engine import RayEngine
from ..frame.features import GENERIC, scene_features
from ..geometry.scene import Scene, SceneError
from ..gpu import gpu_layout
from ..image.result import RenderResult
from ..limits import DEFAULT_TEXTURE_WIDTH, STENCIL_BITS
from ..modes import AVERAGED_MODES, RECURSION_COLORS, depth_grey, primid_colors
from .programs import ProgramCache
from .raw_gl import GL_STENCIL_BUFFER_BIT, RawGL
from .ray_engine_targets import Programs as _Programs, Targets as _Targets
from .textures import upload_textures

if TYPE_CHECKING:
    from ..config.settings import RenderSettings

COUNT_LIMIT = 1 << 20  # (tile, sphere) pairs per pass up to which hre's stats mirror its culling


# --------------------------------------------------------------------------- frame


@dataclass
class _Layer:
    rays: tuple[moderngl.Texture, moderngl.Texture]
    level: int
    branch: str  # path of branches from the primary layer, e.g. "TTR"


@dataclass
class FrameLog:
    """What a frame did (``stats``), and per layer what the tests inspect when ``keep`` is set."""

    layers: int = 0
    layers_skipped: int = 0
    passes: int = 0
    tiles_drawn: int = 0  # (tile, primitive) pairs drawn, hre
    tiles_total: int = 0  # (tile, primitive) pairs a full draw would have
    stencil_fallback_levels: int = 0
    uncounted_passes: int = 0  # hre passes too large for the cull statistics
    keep: bool = False
    records: list[dict] = field(default_factory=list)


# ------------------------------------------------------------------------ the passes


class RayEnginePasses:
    """The ray engines' GL side of one renderer: its raw GL calls, compiled programs and a
    pool of render targets (a frame in flight holds its own; one free set is kept)."""

    def __init__(
        self,
        ctx: moderngl.Context,
        max_texture_width: int = DEFAULT_TEXTURE_WIDTH,
        programs: ProgramCache | None = None,
    ):
        """``programs``: the cache the passes' programs go in (the renderer's; None: one of their own)."""
        self.ctx = ctx
        self.max_texture_width = max_texture_width
        self.gl = RawGL()
        self.programs = _Programs(ctx, programs)
        self._free: list[_Targets] = []
        self.last_bound: set[str] = set()

    def acquire_targets(self, width: int, height: int) -> _Targets:
        for i, t in enumerate(self._free):
            if t.size == (width, height):
                return self._free.pop(i)
        return _Targets(self.ctx, self.gl, width, height)

    def release_targets(self, targets: _Targets) -> None:
        self._free.append(targets)
        while len(self._free) > 1:  # keep the most recent set: most frames repeat a size
            self._free.pop(0).release_all()

    def begin(
        self,
        method: RayEngine,
        scene: Scene,
        settings: RenderSettings,
        *,
        log: FrameLog | None = None,
        batch: int | None = None,
    ) -> RayEngineFrame:
        """A frame of ``method``, uploaded, to be traced slice by slice; ``batch`` primitives
        per draw call (None: each pass in one draw)."""
        return RayEngineFrame(self, method, scene, settings, log=log, batch=batch)

    def cull_matrix(self, scene: Scene, verts: np.ndarray) -> np.ndarray:
        """The vertex shader's decision for each (tile, primitive): bool (tiles, n_primitives), True = drawn.

        ``verts`` are the tile vertices of a hre pass (``FrameLog.records[i]["verts"]``); the
        same ``cone_misses_sphere`` runs in the same vertex shader, only the point goes to
        pixel (primitive, tile) of a small target instead of over the tile (for tests).
        """
        n, tiles = scene.n_primitives, len(verts)
        if n == 0 or tiles == 0:
            return np.zeros((tiles, n), bool)
        ctx = self.ctx
        prog = self.programs.get("rayengine_prim.vert", "rayengine_prim.frag", ("CULL_MATRIX",))
        packed = gpu_layout.pack_primitives(scene, self.max_texture_width)
        tex = packed.textures["u_spheres"]
        t = ctx.texture(tex.size, tex.components, tex.data.tobytes(), dtype=tex.dtype)
        t.filter = (moderngl.NEAREST, moderngl.NEAREST)
        t.use(0)
        cast(moderngl.Uniform, prog["u_spheres"]).value = 0
        for name, value in {**packed.uniforms, "u_matrix_size": (float(n), float(tiles))}.items():
            if name in prog:
                cast(moderngl.Uniform, prog[name]).value = value
        target = ctx.texture((n, tiles), 4, dtype="f4")
        fbo = ctx.framebuffer(color_attachments=[target])
        buf = ctx.buffer(np.ascontiguousarray(verts, dtype=np.float32).tobytes())
        vao = ctx.vertex_array(prog, [(buf, "2f 4f 4f", "a_tile", "a_cone0", "a_cone1")], skip_errors=True)
        try:
            ctx.enable_only(moderngl.NOTHING)
            self.gl.stencil_off()
            fbo.use()
            fbo.clear(0.0, 0.0, 0.0, 0.0)
            ctx.point_size = 1.0
            vao.render(moderngl.POINTS, instances=n)
            out = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(tiles, n, 4)[..., 0] > 0.5
        finally:
            for o in (vao, buf, fbo, target, t):
                o.release()
        return out

    def release(self) -> None:
        while self._free:
            self._free.pop().release_all()


class RayEngineFrame:
    """A ray-engine frame traced slice by slice: :meth:`step` runs one pass, or one batch of
    a primitive pass, then ``glFinish``, and leaves the GL state neutral for other frames.

    Modes that are not averaged (depth, primid, normal) trace one ray through each pixel
    centre whatever ``samples_per_pixel`` says (docs/FORMATS.md); averaged ones trace the
    √s × √s sub-pixels and box-filter them, and their depth, primid and normal arrays
    come from a primary-only frame through the pixel centres, traced first (``centre``).
    """

    def __init__(
        self,
        passes: RayEnginePasses,
        method: RayEngine,
        scene: Scene,
        settings: RenderSettings,
        *,
        log: FrameLog | None = None,
        batch: int | None = None,
    ):
        self.t_start = time.perf_counter()
        self.passes, self.method, self.scene, self.settings = passes, method, scene, settings
        self.ctx, self.gl = passes.ctx, passes.gl
        self.log = log if log is not None else FrameLog()
        self.ts = method.tile(settings.tile_size)
        self.k = settings.supersampling if settings.mode in AVERAGED_MODES else 1
        w, h = settings.width * self.k, settings.height * self.k
        wp, hp = -(-w // self.ts) * self.ts, -(-h // self.ts) * self.ts
        self.features = scene_features(scene) if settings.specialize else GENERIC
        mode = settings.mode
        whitted = mode in ("color", "recursion", "cones")
        max_level = self.features.recursion_depth(settings.max_recursion_depth) if whitted else 1
        if mode == "cones":
            max_level = settings.max_recursion_depth
        self.max_level = max_level
        tg = passes.acquire_targets(wp, hp)
        self.tg: _Targets | None = tg  # None once released
        self.textures: list[moderngl.Texture] = []
        self.slices = 0
        self._result: RenderResult | None = None
        self.centre: RayEngineFrame | None = None
        try:
            if self.k > 1:
                self.centre = RayEngineFrame(
                    passes,
                    method,
                    scene,
                    settings.with_(mode="primid", samples_per_pixel=1, max_recursion_depth=1),
                    batch=batch,
                )
            self.frame = _FrameRun(
                method, self.ctx, self.gl, tg, passes.programs, scene, settings, (w, h), self.ts, max_level, self.log
            )
            self.frame.batch = batch
            self.frame.upload(passes.max_texture_width, self.textures)
        except BaseException:
            self.release()
            raise
        passes.last_bound = self.frame.bound  # what the frame uploads (tests compare it with the programs)
        passes.programs.used.clear()
        self.t_up = time.perf_counter()
        self._neutral()
        self._gen = self.frame.run()

    @property
    def done(self) -> bool:
        return self._result is not None

    @property
    def preview(self) -> RenderResult | None:
        return None

    def _neutral(self) -> None:
        """The GL state the one-pass tracer's slices expect: no tests, no blending."""
        self.ctx.enable_only(moderngl.NOTHING)
        self.gl.stencil_off()
        self.ctx.blend_func = moderngl.DEFAULT_BLENDING  # type: ignore[assignment]  # a pair; moderngl's stubs type it int

    def step(self) -> bool:
        if self.done:
            return True
        if self.centre is not None and not self.centre.done:
            self.centre.step()
            self.slices += 1
            return False
        try:
            try:
                next(self._gen)
                finished = False
            except StopIteration:
                finished = True
            self.ctx.finish()
            self.slices += 1
            if finished:
                self._result = self._compose()
        except BaseException:
            self.release()
            raise
        finally:
            self._neutral()
        if finished:
            self.release()
        return self.done

    def run(self) -> RenderResult:
        while not self.step():
            pass
        return self.result()

    def result(self) -> RenderResult:
        if self._result is None:
            raise RuntimeError("the frame is not complete")
        return self._result

    def release(self) -> None:
        if self.centre is not None:
            self.centre.release()
        held: list[moderngl.Texture | moderngl.Buffer] = [*self.textures]
        if hasattr(self, "frame"):
            held += self.frame.buffers
        for t in held:
            t.release()
        self.textures = []
        if hasattr(self, "frame"):
            self.frame.buffers = []
        if self.tg is not None:
            self.passes.release_targets(self.tg)
            self.tg = None

    def _compose(self) -> RenderResult:
        t_traced = time.perf_counter()
        frame, settings, method, k = self.frame, self.settings, self.method, self.k
        color, primid, depth_t, normal, image = frame.read_back()
        t_end = time.perf_counter()
        if k > 1:
            color = color.reshape(settings.height, k, settings.width, k, 3).mean(axis=(1, 3))
            image = image.reshape(settings.height, k, settings.width, k, 3).mean(axis=(1, 3))
            assert self.centre is not None, "a supersampled frame traces its centres"
            centre = self.centre.result()  # the arrays through the pixel centres
            primid, depth_t, normal = centre.primid, centre.depth, centre.normal
        if settings.mode == "color":
            image = color
        ms = lambda a, b: (b - a) * 1e3
        timings = {
            "build": frame.build_ms,
            "upload": ms(self.t_start, self.t_up),
            "trace": ms(self.t_up, t_traced) - frame.build_ms - frame.stats_ms,
            "read": ms(t_traced, t_end),
            "total": ms(self.t_start, t_end) - frame.stats_ms,
        }
        log = self.log
        if method.hierarchical:
            timings["stats"] = frame.stats_ms
        stats = {
            "method": method.name,
            "recursion_depth": self.max_level,
            "features_removed": list(self.features.defines()),
            "primitives": self.scene.n_primitives,
            "layers": log.layers,
            "layers_skipped": log.layers_skipped,
            "passes": log.passes,
            "stencil_bits": min(method.stencil_bits, frame.tg.stencil_bits),
            "stencil_fallback_levels": log.stencil_fallback_levels,
            "slices": self.slices,
        }
        if method.hierarchical:
            stats.update(
                {
                    "tile_size": self.ts,
                    "tile_prims_drawn": log.tiles_drawn,
                    "tile_prims_total": log.tiles_total,
                    "cull_fraction": 1.0 - log.tiles_drawn / log.tiles_total if log.tiles_total else 0.0,
                    "cull_uncounted_passes": log.uncounted_passes,
                }
            )
        return RenderResult(
            image=np.ascontiguousarray(image, dtype=np.float32),
            depth=depth_t,
            primid=primid,
            normal=np.ascontiguousarray(normal, dtype=np.float32),
            mode=settings.mode,
            timings=timings,
            stats=stats,
        )


# ------------------------------------------------------------------------- one run


class _FrameRun:
    """The passes of one frame."""

    def __init__(
        self,
        method: RayEngine,
        ctx,
        gl: RawGL,
        tg: _Targets,
        progs: _Programs,
        scene: Scene,
        settings,
        size: tuple[int, int],
        ts: int,
        max_level: int,
        log: FrameLog,
    ):
        self.m, self.ctx, self.gl, self.tg, self.progs = method, ctx, gl, tg, progs
        self.scene, self.settings, self.size, self.ts, self.max_level, self.log = (
            scene,
            settings,
            size,
            ts,
            max_level,
            log,
        )
        self.hre = method.hierarchical
        self.mode = settings.mode
        self.n_prims = scene.n_primitives
        self.bits = min(method.stencil_bits, tg.stencil_bits, STENCIL_BITS)
        self.build_ms = 0.0
        self.stats_ms = 0.0
        self.uniforms: dict[str, Any] = {}
        self.units: dict[str, int] = {}
        self.bound: set[str] = set()  # scene bindings uploaded for this frame
        self.primary: dict[str, np.ndarray] = {}
        self.deepest = np.zeros((tg.size[1], tg.size[0]), np.int32) if self.mode == "recursion" else None
        self.cone_image: np.ndarray | None = None
        self.buffers: list[Any] = []  # the GL objects the frame releases (buffers, vertex arrays, targets)
        self.batch: int | None = None  # primitives per draw call (None: all in one)
        self.scene_textures: list[moderngl.Texture] = []
        self.heat: np.ndarray | None = None
        if self.hre:
            wp, hp = tg.size
            self.tiles_xy = (wp // ts, hp // ts)
            self.cone_targets = [ctx.texture(self.tiles_xy, 4, dtype="f4") for _ in range(2)]
            self.cone_fbo = ctx.framebuffer(color_attachments=self.cone_targets)
            self.buffers.extend([self.cone_fbo, *self.cone_targets])
            if ts > gl.point_size_max():
                raise SceneError(
                    "tile_size", f"tile size {ts} exceeds this GPU's largest point ({gl.point_size_max():g})"
                )

    # -- setup ----------------------------------------------------------------------
    def scene_bindings(self) -> list[gpu_layout.Binding]:
        """The scene's textures and uniforms this frame's passes read: the geometry whenever
        a primitive pass runs (not for the cones of the primary layer alone), materials
        and lights whenever a shading pass runs (every colour frame; a recursion or cones
        frame that spawns rays). The pass programs are shared by the modes (``u_shade``
        selects at run time), so this is per frame, not per program."""
        geometry = not (self.mode == "cones" and self.max_level == 1)
        shades = self.mode == "color" or (self.mode in ("recursion", "cones") and self.max_level > 1)
        reads = {"always": geometry, "materials": shades, "lights": shades}
        return [b for b in gpu_layout.RAY_ENGINE_SCENE_BINDINGS if reads[b.group]]

    def upload(self, max_width: int, textures: list) -> None:
        packed = gpu_layout.pack_primitives(self.scene, max_width)
        wanted = {b.name for b in self.scene_bindings()}
        self.units.update(
            upload_textures(
                self.ctx, gpu_layout.PackedScene({n: t for n, t in packed.textures.items() if n in wanted}), textures
            )
        )
        self.scene_textures = list(textures)
        self.uniforms.update({n: v for n, v in packed.uniforms.items() if n in wanted})
        self.bound = wanted
        self.uniforms.update(gpu_layout.camera_uniforms(self.scene.camera, *self.size))
        self.uniforms.update(
            {
                "u_max_level": self.max_level,
                "u_min_weight": float(self.settings.min_weight),
                "u_shade": 1 if self.mode == "color" else 0,
                "u_tile_size": float(self.ts),
                "u_target": (float(self.tg.size[0]), float(self.tg.size[1])),
            }
        )
        self.n_units = len(textures)

    def _bind(self, prog: moderngl.Program, samplers: dict[str, moderngl.Texture], **uniforms) -> None:
        for unit, tex in enumerate(self.scene_textures):  # another frame's slice may have used the units
            tex.use(unit)
        for name, unit in self.units.items():
            if name in prog:
                cast(moderngl.Uniform, prog[name]).value = unit
        for i, (name, tex) in enumerate(samplers.items()):
            unit = self.n_units + i
            tex.use(unit)
            if name in prog:
                cast(moderngl.Uniform, prog[name]).value = unit
        for name, value in {**self.uniforms, **uniforms}.items():
            if name in prog:
                cast(moderngl.Uniform, prog[name]).value = value

    def _stencil_bit(self, level: int) -> int:
        if level > self.bits:
            return 0
        return 1 << (level - 1)

    # -- passes ----------------------------------------------------------------------
    def _fullscreen(self, fbo, frag_define: str, samplers: dict, **uniforms):
        prog, vao = self.progs.fullscreen("rayengine_pass.frag", (frag_define,))
        self._bind(prog, samplers, **uniforms)
        fbo.use()
        vao.render(moderngl.TRIANGLES)
        self.log.passes += 1

    def _primary(self, layer: _Layer) -> None:
        fbo = self.tg.layer_fbo(layer.rays)
        self.ctx.enable_only(moderngl.NOTHING)
        self.gl.stencil_off()
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0)
        self._fullscreen(fbo, "PASS_PRIMARY", {})

    def _mask(self, layer: _Layer, bit: int) -> int:
        """Set the generation's stencil bit where the layer holds a live ray; count them."""
        fbo = self.tg.fbo_hit
        self.ctx.enable_only(moderngl.NOTHING)
        fbo.color_mask = (False, False, False, False)
        fbo.use()
        query = self.ctx.query(samples=True)
        if bit:
            self.gl.stencil_mark(bit)
        else:
            self.gl.stencil_off()
        with query:
            self._fullscreen(fbo, "PASS_MASK", {"u_ray_d": layer.rays[1]})
        fbo.color_mask = (True, True, True, True)
        live = int(query.samples)

        return live

    def _cones(self, layer: _Layer | None, light: int = -1):
        """Cone pass (§4) + read-back → (cones, tile vertices, vertex buffer of the live tiles)."""
        t0 = time.perf_counter()
        defines = (f"TILE {self.ts}",) + (("SHADOW",) if light >= 0 else ())
        prog, vao = self.progs.fullscreen("rayengine_cones.frag", defines)
        if light >= 0:
            samplers = {"u_surf0": self.tg.surf0, "u_surf1": self.tg.surf1}
        else:
            assert layer is not None, "a radiance cone pass reads its layer's rays"
            samplers = {"u_ray_o": layer.rays[0], "u_ray_d": layer.rays[1]}
        self._bind(prog, samplers, u_light=max(light, 0))
        self.ctx.enable_only(moderngl.NOTHING)
        self.gl.stencil_off()
        self.cone_fbo.use()
        vao.render(moderngl.TRIANGLES)
        self.log.passes += 1
        tx, ty = self.tiles_xy
        c0 = np.frombuffer(self.cone_fbo.read(components=4, dtype="f4", attachment=0), np.float32).reshape(ty, tx, 4)
        c1 = np.frombuffer(self.cone_fbo.read(components=4, dtype="f4", attachment=1), np.float32).reshape(ty, tx, 4)
        cones = np.concatenate([c0, c1], axis=2).reshape(-1, 8)
        live = np.flatnonzero(cones[:, 3] != hre_cones.NO_RAYS)
        jy, ix = np.divmod(live, tx)
        verts = np.concatenate(
            [np.stack([ix * self.ts, jy * self.ts], axis=1).astype(np.float32), cones[live]], axis=1
        ).astype(np.float32)
        buf = self.ctx.buffer(verts.tobytes()) if len(live) else None
        if buf is not None:
            self.buffers.append(buf)
        self.build_ms += (time.perf_counter() - t0) * 1e3
        return cones, verts, buf

    def _prim_defines(self, shadow: bool, count: bool = False) -> tuple[str, ...]:
        d = ("HRE",) if self.hre else ()
        return d + (("ANY_HIT",) if shadow else ()) + (("COUNT",) if count else ())

    def _draw_prims(self, prog: moderngl.Program, tiles, setup) -> Iterator[None]:
        """Draw every primitive (instance = id) over the whole target (rayengine) or as one
        point per live tile (hre), in batches of ``self.batch`` instances in id order (the
        depth test keeps the nearest hit and, drawn in id order, the lower id of equal t, as
        one draw does), yielding after each batch: a slice. ``setup()`` (re)establishes the
        pass's GL state and bindings before each batch, since another frame's slice may run
        in between."""
        n = self.n_prims
        if n == 0:
            return
        if self.hre:
            _, verts, buf = tiles
            if buf is None:
                return
            self.log.tiles_total += len(verts) * n
            vao = self.ctx.vertex_array(prog, [(buf, "2f 4f 4f", "a_tile", "a_cone0", "a_cone1")], skip_errors=True)
            self.buffers.append(vao)
            mode = moderngl.POINTS
        else:
            vao, owned = self.progs.quad_vao(prog)
            if owned:  # its program was evicted meanwhile: the frame releases this one
                self.buffers.append(vao)
            mode = moderngl.TRIANGLES
        batch = max(1, int(self.batch or n))
        for first in range(0, n, batch):
            setup()
            if self.hre:
                self.ctx.point_size = float(self.ts)
            cast(moderngl.Uniform, prog["u_instance_base"]).value = first
            vao.render(mode, instances=min(batch, n - first))
            yield
        self.log.passes += 1

    def _intersect(self, layer: _Layer, bit: int, tiles) -> Iterator[None]:
        fbo = self.tg.fbo_hit
        self.ctx.enable_only(moderngl.NOTHING)
        self.gl.stencil_off()
        fbo.use()
        fbo.clear(0.0, -1.0, 0.0, 0.0)
        self.gl.clear_depth()
        prog = self.progs.get("rayengine_prim.vert", "rayengine_prim.frag", self._prim_defines(False))

        def setup() -> None:
            self._bind(prog, {"u_ray_o": layer.rays[0], "u_ray_d": layer.rays[1]})
            self.ctx.enable_only(moderngl.DEPTH_TEST)
            self.ctx.depth_func = "<"
            fbo.depth_mask = True
            fbo.use()
            self.gl.stencil_test(bit)

        yield from self._draw_prims(prog, tiles, setup)
        fbo.depth_mask = False

    def _surface(self, layer: _Layer, bit: int) -> None:
        fbo = self.tg.fbo_surf
        self.ctx.enable_only(moderngl.NOTHING)
        self.gl.stencil_off()
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, -1.0)
        self.gl.stencil_test(bit)
        self._fullscreen(
            fbo, "PASS_SURFACE", {"u_ray_o": layer.rays[0], "u_ray_d": layer.rays[1], "u_hit": self.tg.hit}
        )

    def _shadows(self, bit: int) -> Iterator[None]:
        for f in self.tg.fbo_blocked:
            self.ctx.enable_only(moderngl.NOTHING)
            self.gl.stencil_off()
            f.use()
            f.clear(0.0, 0.0, 0.0, 0.0)
        for light in range(len(self.scene.lights)):
            tiles = self._cones(None, light) if self.hre else None
            if self.hre:
                yield
                self._record("shadow", light, tiles)
                self.log.tiles_drawn += self._count_drawn(tiles)
            fbo = self.tg.fbo_blocked[light // 4]
            prog = self.progs.get("rayengine_prim.vert", "rayengine_prim.frag", self._prim_defines(True))

            def setup(prog=prog, fbo=fbo, light=light) -> None:
                self._bind(prog, {"u_surf0": self.tg.surf0, "u_surf1": self.tg.surf1}, u_light=light)
                self.ctx.enable_only(moderngl.NOTHING)
                fbo.color_mask = tuple(i == light % 4 for i in range(4))
                fbo.use()
                self.gl.stencil_test(bit)

            yield from self._draw_prims(prog, tiles, setup)
            fbo.color_mask = (True, True, True, True)
            yield

    def _shade(self, layer: _Layer, bit: int) -> tuple[_Layer, _Layer]:
        refl, trans = self.tg.layer(), self.tg.layer()
        self.ctx.enable_only(moderngl.NOTHING)
        self.gl.stencil_off()
        for pair in (refl, trans):
            f = self.tg.layer_fbo(pair)
            f.use()
            f.clear(0.0, 0.0, 0.0, 0.0)
        fbo = self.tg.shade_fbo(refl, trans)
        fbo.use()
        self.ctx.enable_only(moderngl.BLEND)
        self.ctx.blend_func = (moderngl.ONE, moderngl.ONE)
        self.ctx.blend_equation = moderngl.FUNC_ADD
        self.gl.stencil_test(bit)
        self._fullscreen(
            fbo,
            "PASS_SHADE",
            {
                "u_ray_o": layer.rays[0],
                "u_ray_d": layer.rays[1],
                "u_hit": self.tg.hit,
                "u_surf0": self.tg.surf0,
                "u_surf1": self.tg.surf1,
                "u_blocked0": self.tg.blocked0,
                "u_blocked1": self.tg.blocked1,
            },
            u_level=layer.level,
        )
        self.ctx.enable_only(moderngl.NOTHING)
        return (_Layer(refl, layer.level + 1, layer.branch + "R"), _Layer(trans, layer.level + 1, layer.branch + "T"))

    def _heat(self, layer: _Layer, bit: int, tiles) -> Iterator[None]:
        fbo = self.tg.fbo_surf  # reuse surf0 as the counter
        self.ctx.enable_only(moderngl.NOTHING)
        self.gl.stencil_off()
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0)
        prog = self.progs.get("rayengine_prim.vert", "rayengine_prim.frag", self._prim_defines(False, count=True))

        def setup() -> None:
            self._bind(prog, {"u_ray_o": layer.rays[0], "u_ray_d": layer.rays[1]})
            fbo.use()
            self.ctx.enable_only(moderngl.BLEND)
            self.ctx.blend_func = (moderngl.ONE, moderngl.ONE)
            self.gl.stencil_test(bit)

        yield from self._draw_prims(prog, tiles, setup)
        self.ctx.enable_only(moderngl.NOTHING)
        self.heat = self._read(self.tg.surf0)[..., 0].copy()

    def _read(self, tex: moderngl.Texture) -> np.ndarray:
        wp, hp = self.tg.size
        return np.frombuffer(tex.read(), np.float32).reshape(hp, wp, 4)

    def _record(self, kind: str, light: int, tiles, layer: _Layer | None = None) -> None:
        """Keep what the tests check: rays, cones, tile vertices (only when log.keep)."""
        if not self.log.keep:
            return
        rec = {
            "kind": kind,
            "light": light,
            "level": layer.level if layer else None,
            "branch": layer.branch if layer else None,
            "verts": tiles[1] if tiles else None,
            "cones": tiles[0] if tiles else None,
        }
        if kind == "radiance":
            assert layer is not None, "a radiance record is a layer's"
            rec["ray_o"], rec["ray_d"] = self._read(layer.rays[0]).copy(), self._read(layer.rays[1]).copy()
        else:
            rec["surf0"], rec["surf1"] = self._read(self.tg.surf0).copy(), self._read(self.tg.surf1).copy()
        self.log.records.append(rec)

    # -- the frame ----------------------------------------------------------------------
    def run(self) -> Iterator[None]:
        """The frame's passes, yielding after each one (and after each batch of primitives):
        the slices of :class:`RayEngineFrame`."""
        tg = self.tg
        self.ctx.enable_only(moderngl.NOTHING)
        self.gl.stencil_off()
        tg.fbo_hit.use()
        self.gl.glStencilMask(0xFF)
        self.gl.glClearStencil(0)
        self.gl.glClear(GL_STENCIL_BUFFER_BIT)
        color_fbo = self.ctx.framebuffer(color_attachments=[tg.color])
        color_fbo.use()
        color_fbo.clear(0.0, 0.0, 0.0, 0.0)
        color_fbo.release()
        first = _Layer(tg.layer(), 1, "")
        self._primary(first)
        yield
        stack = [first]
        need_cones_at = self.max_level if self.mode == "cones" else None
        while stack:
            layer = stack.pop()
            bit = self._stencil_bit(layer.level)
            if bit == 0:
                self.log.stencil_fallback_levels = max(self.log.stencil_fallback_levels, layer.level - self.bits)
            live = self._mask(layer, bit)
            yield
            if live == 0:
                self.log.layers_skipped += 1
                tg.release(layer.rays)
                continue
            self.log.layers += 1
            tiles = None
            if self.hre:
                tiles = self._cones(layer)
                yield
                self._record("radiance", -1, tiles, layer)
                self.log.tiles_drawn += self._count_drawn(tiles)
                if need_cones_at is not None and layer.level == need_cones_at:
                    self.cone_image = self._cone_picture(tiles[0])
                    tg.release(layer.rays)
                    for rest in stack:
                        tg.release(rest.rays)
                    break
            if self.mode == "heat":
                yield from self._heat(layer, bit, tiles)
            yield from self._intersect(layer, bit, tiles)
            if self.deepest is not None:
                ids = self._read(tg.hit)[..., 1]
                self.deepest = np.where(ids >= 0, np.maximum(self.deepest, layer.level), self.deepest)
            self._surface(layer, bit)
            yield
            if layer.level == 1:
                self.primary = {"hit": self._read(tg.hit).copy(), "surf1": self._read(tg.surf1).copy()}
            if self.mode in ("color", "recursion", "cones"):
                if self.mode == "color" and len(self.scene.lights):
                    yield from self._shadows(bit)
                if self.mode == "color" or layer.level < self.max_level:
                    refl, trans = self._shade(layer, bit)
                    yield
                    if layer.level < self.max_level:
                        stack.extend([refl, trans])  # transmitted first (popped first)
                    else:
                        tg.release(refl.rays)
                        tg.release(trans.rays)
            tg.release(layer.rays)

    def _count_drawn(self, tiles) -> int:
        """(tile, primitive) pairs that the vertex shader will draw: the float64 mirror of its
        test (statistics only; the GPU decides). Passes of more than ``COUNT_LIMIT`` pairs
        count as fully drawn (the mirror would cost more than the pass); its time is
        reported as ``timings["stats"]`` and left out of ``trace``."""
        _, verts, buf = tiles
        if buf is None or self.n_prims == 0:
            return 0
        if len(verts) * self.scene.n_spheres > COUNT_LIMIT:
            self.log.uncounted_passes += 1
            return len(verts) * self.n_prims
        t0 = time.perf_counter()
        try:
            return self._count_drawn_now(verts)
        finally:
            self.stats_ms += (time.perf_counter() - t0) * 1e3

    def _count_drawn_now(self, verts) -> int:
        n = self.scene.n_spheres
        cones = verts[:, 2:10].astype(np.float64)
        drawn = len(verts) * (self.n_prims - n)  # planes: always
        if n:
            step = max(1, (1 << 18) // max(1, n))
            for a in range(0, len(cones), step):
                miss = hre_cones.cone_misses_sphere(
                    cones[a : a + step], self.scene.sphere_centers, self.scene.sphere_radii
                )
                drawn += int((~miss).sum())
        return drawn

    def _cone_picture(self, cones: np.ndarray) -> np.ndarray:
        tx, ty = self.tiles_xy
        phi = cones[:, 3].reshape(ty, tx)
        grey = np.clip(1.0 - phi / (np.pi / 2), 0.0, 1.0)
        img = np.repeat(grey[..., None], 3, axis=2)
        img[phi == hre_cones.NO_RAYS] = 0.0
        img[phi == hre_cones.NO_CULL] = (0.25, 0.0, 0.0)
        return np.repeat(np.repeat(img, self.ts, axis=0), self.ts, axis=1)

    def read_back(self):
        w, h = self.size
        mode = self.mode
        color = self._read(self.tg.color)[:h, :w, :3][::-1].astype(np.float32)
        if self.primary:
            hit = self.primary["hit"][:h, :w][::-1]
            surf1 = self.primary["surf1"][:h, :w][::-1]
            primid = hit[..., 1].astype(np.int32)
            depth = np.where(primid >= 0, hit[..., 0], np.float32(np.inf)).astype(np.float32)
            normal = np.where((primid >= 0)[..., None], surf1[..., :3], 0.0).astype(np.float32)
        else:
            primid = np.full((h, w), -1, np.int32)
            depth = np.full((h, w), np.inf, np.float32)
            normal = np.zeros((h, w, 3), np.float32)
        hit = primid >= 0
        image: np.ndarray
        if mode == "color":
            image = color
        elif mode == "depth":
            d = np.float32(np.linalg.norm(np.subtract(self.scene.camera.target, self.scene.camera.position)))
            image = np.repeat(depth_grey(depth, d)[..., None], 3, axis=2)
        elif mode == "primid":
            image = primid_colors(primid)
        elif mode == "normal":
            image = np.where(hit[..., None], 0.5 * (normal + 1.0), 0.0)
        elif mode == "recursion":
            assert self.deepest is not None, "a recursion frame counts its levels"
            image = RECURSION_COLORS[self.deepest[:h, :w][::-1]]
        elif mode == "heat":
            tests = self.heat[:h, :w][::-1] if self.heat is not None else np.zeros((h, w))
            image = np.stack([np.minimum(0.05 * tests, 1.0), np.zeros_like(tests), np.zeros_like(tests)], axis=2)
        elif mode == "cones":
            image = self.cone_image[:h, :w][::-1] if self.cone_image is not None else np.zeros((h, w, 3))
        else:
            raise SceneError("mode", f"unknown mode {mode!r}")
        return color, primid, depth, normal, np.asarray(image, dtype=np.float32)
